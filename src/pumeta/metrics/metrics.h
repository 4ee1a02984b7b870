// Point-cloud quality metrics, with the project's conventions (README.md, "Metric
// conventions"): every function takes pred and gt in the same frame; evaluate() first maps
// both into the GT frame (GT bounding-box centre -> 0, GT largest radius -> 1).
//
// Point arguments are float32 tensors of shape [N,3] with N >= 1, on any device (the metrics
// copy them to the CPU and compute in float64); any other shape or dtype, or an empty cloud,
// throws InputError (core/tensor_checks.h, check_points). Results are plain doubles.
#pragma once

#include <ATen/core/Tensor.h>

#include <optional>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta {

/// Chamfer distance: mean_a min_b |a-b|^2 + mean_b min_a |a-b|^2 (squared distances, sum of
/// the two means). pred: float32 [N,3]; gt: float32 [M,3]. Returns a double >= 0.
double chamfer_distance(const at::Tensor& pred, const at::Tensor& gt);

/// Hausdorff distance: max of the two directed maxima of (unsquared) distances.
/// pred: float32 [N,3]; gt: float32 [M,3]. Returns a double >= 0.
double hausdorff_distance(const at::Tensor& pred, const at::Tensor& gt);

/// PU-GCN's "Hausdorff": sum of the two directed maxima of squared distances (kept only for
/// comparison with published tables). pred: float32 [N,3]; gt: float32 [M,3]. Returns a
/// double >= 0.
double hausdorff_distance_legacy(const at::Tensor& pred, const at::Tensor& gt);

/// PSNR as MPEG pc_error D1 computes it: both clouds moved by GT's bounding-box minimum and
/// scaled so GT's longest side is 1023; exact duplicates of each cloud merged; one-way
/// MSE(A->B) = mean over A of the squared NN distance in B; PSNR = 10 log10(3 p^2 / MSE),
/// p = 1023; result = min of the two directions, in dB. pred: float32 [N,3]; gt: float32
/// [M,3]. Returns a double; +infinity when the clouds coincide.
double psnr_d1(const at::Tensor& pred, const at::Tensor& gt);

/// Mean unsquared distance from each predicted point to the mesh surface (exact
/// point-to-triangle distances through a bounding-volume hierarchy). pred: float32 [N,3];
/// mesh.vertices: float32 [V,3], V >= 1; mesh.faces: int64 [F,3] indexing the vertices
/// (check_faces). Returns a double >= 0.
double point_to_face_distance(const at::Tensor& pred, const TriangleMesh& mesh);

struct MetricReport {
    double cd = 0;
    double hd = 0;
    double hd_legacy = 0;
    double psnr = 0;
    std::optional<double> p2f;
    int64_t n_pred = 0;
    int64_t n_gt = 0;
};

/// All metrics in the GT frame (pred and mesh transformed with GT's normalisation).
/// pred: float32 [N,3]; gt: float32 [M,3]; `mesh`, when given (vertices float32 [V,3], faces
/// int64 [F,3]), must be in the same coordinates as gt. The report holds doubles: cd, hd,
/// hd_legacy, psnr (dB) and p2f (only with a mesh), plus the counts n_pred = N and n_gt = M.
MetricReport evaluate(const at::Tensor& pred, const at::Tensor& gt,
                      const TriangleMesh* mesh = nullptr);

}  // namespace pumeta
