// The scores of the published PU-GAN and PU1K tables. Unlike evaluate() (metrics/metrics.h),
// which maps the prediction into the GT's frame so that a shifted or scaled prediction counts
// as wrong, these tables normalise the prediction and the GT each to its own unit sphere
// (centroid -> 0, farthest point -> 1) before the point-to-point scores, as their evaluation
// scripts do; numbers from here compare with theirs, not with pumeta's own tables.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta {

/// One object's scores, in unit-sphere units (the tables print them × 10³).
struct BenchmarkScores {
    /// Chamfer distance: mean over pred of the squared distance to the nearest GT point plus
    /// mean over GT of the squared distance to the nearest predicted point, each cloud on its
    /// own unit sphere.
    double cd = 0;
    /// Hausdorff distance: the larger of the two directed maxima of the (unsquared) nearest-
    /// neighbour distances, in the same frames.
    double hd = 0;
    /// PU-GCN's evaluation script's "Hausdorff": the sum of the two directed maxima of squared
    /// distances (what tables copied from that script print), in the same frames.
    double hd_legacy = 0;
    /// float64 [N]: each predicted point's distance to the mesh surface, both as given (the
    /// mesh's own coordinates, as the published tables); undefined without a mesh.
    at::Tensor p2f;
};

/// Scores pred (float32 [N,3]) against gt (float32 [M,3]) and, when given, the object's mesh
/// (vertices float32 [V,3] in gt's coordinates, faces int64 [F,3]). InputError for an empty
/// or malformed cloud or mesh (metrics/metrics.h's checks).
BenchmarkScores score_benchmark_object(const at::Tensor& pred, const at::Tensor& gt,
                                       const TriangleMesh* mesh = nullptr);

/// The table row of a set of objects: CD and HD averaged over objects, P2F pooled over the
/// points of every object that has a mesh (mean and population standard deviation).
class BenchmarkTally {
  public:
    void add(const BenchmarkScores& scores);

    int64_t objects() const { return objects_; }
    int64_t objects_with_mesh() const { return objects_with_mesh_; }
    int64_t p2f_points() const { return p2f_points_; }
    /// Means over the objects added; NaN before the first.
    double cd() const;
    double hd() const;
    double hd_legacy() const;
    /// Over all p2f values of all objects added; NaN when none had a mesh.
    double p2f_mean() const;
    double p2f_std() const;

  private:
    int64_t objects_ = 0, objects_with_mesh_ = 0, p2f_points_ = 0;
    double cd_sum_ = 0, hd_sum_ = 0, hd_legacy_sum_ = 0;
    double p2f_mean_ = 0, p2f_m2_ = 0;  // running mean and sum of squared deviations
};

/// A one-line description of the protocol, recorded in every benchmark summary.
const char* benchmark_protocol_description();

}  // namespace pumeta
