#include "pumeta/eval/benchmark_protocol.h"

#include <ATen/ATen.h>

#include <cmath>
#include <limits>

#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/normalize.h"
#include "pumeta/metrics/metrics.h"
#include "pumeta/metrics/triangle_bvh.h"

namespace pumeta {

BenchmarkScores score_benchmark_object(const at::Tensor& pred, const at::Tensor& gt,
                                       const TriangleMesh* mesh) {
    check_points(pred, "prediction", 1);
    check_points(gt, "ground truth", 1);
    const Normalization pred_frame = unit_sphere_normalization(pred, CenterMode::kCentroid);
    const Normalization gt_frame = unit_sphere_normalization(gt, CenterMode::kCentroid);
    const at::Tensor own_pred = pred_frame.apply(pred), own_gt = gt_frame.apply(gt);
    BenchmarkScores scores;
    scores.cd = chamfer_distance(own_pred, own_gt);
    scores.hd = hausdorff_distance(own_pred, own_gt);
    scores.hd_legacy = hausdorff_distance_legacy(own_pred, own_gt);
    if (mesh) {
        check_points(mesh->vertices, "mesh vertices", 1);
        // As the published tables (PU-GCN's CGAL program reads the mesh and the saved
        // prediction as they are): the prediction in the mesh's own coordinates, which the
        // benchmark meshes already scale to the unit sphere.
        const TriangleBvh surface({mesh->vertices, mesh->faces});
        scores.p2f = surface.distances(pred);
    }
    return scores;
}

void BenchmarkTally::add(const BenchmarkScores& scores) {
    ++objects_;
    cd_sum_ += scores.cd;
    hd_sum_ += scores.hd;
    hd_legacy_sum_ += scores.hd_legacy;
    if (!scores.p2f.defined()) return;
    ++objects_with_mesh_;
    const at::Tensor d = scores.p2f.to(at::kDouble).contiguous();
    const int64_t n = d.numel();
    if (n == 0) return;
    // Chan et al.'s combination of two groups' means and squared deviations.
    const double mean = d.mean().item<double>();
    const double m2 = (d - mean).pow(2).sum().item<double>();
    const double total = static_cast<double>(p2f_points_ + n);
    const double delta = mean - p2f_mean_;
    p2f_mean_ += delta * static_cast<double>(n) / total;
    p2f_m2_ +=
        m2 + delta * delta * static_cast<double>(p2f_points_) * static_cast<double>(n) / total;
    p2f_points_ += n;
}

namespace {
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
}

double BenchmarkTally::cd() const { return objects_ ? cd_sum_ / objects_ : kNan; }
double BenchmarkTally::hd() const { return objects_ ? hd_sum_ / objects_ : kNan; }
double BenchmarkTally::hd_legacy() const { return objects_ ? hd_legacy_sum_ / objects_ : kNan; }
double BenchmarkTally::p2f_mean() const { return p2f_points_ ? p2f_mean_ : kNan; }
double BenchmarkTally::p2f_std() const {
    return p2f_points_ ? std::sqrt(p2f_m2_ / static_cast<double>(p2f_points_)) : kNan;
}

const char* benchmark_protocol_description() {
    return "PU-GAN/PU1K tables: prediction and GT each normalised to its own unit sphere "
           "(centroid to 0, farthest point to 1); CD = mean squared nearest-neighbour distance "
           "pred->GT + GT->pred; HD = max of the two directed maxima of Euclidean "
           "nearest-neighbour distances (hd_legacy: PU-GCN's script, the sum of the two "
           "directed maxima of squared distances); P2F = point-to-triangle distances of the "
           "prediction to the mesh, both in the mesh's own coordinates (as PU-GCN's CGAL "
           "program reads them), pooled over all points "
           "of all objects with a mesh (mean and population std); CD and HD averaged over "
           "objects; all values x 1e3";
}

}  // namespace pumeta
