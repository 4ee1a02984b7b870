// Chamfer and Hausdorff distances: the point-to-point metrics of README.md, "Metric conventions".
#include <ATen/ATen.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "pumeta/core/tensor_checks.h"
#include "pumeta/metrics/metrics.h"
#include "pumeta/metrics/nearest_distances.h"

namespace pumeta {

namespace {

/// Squared nearest-neighbour distances in both directions, after checking the inputs.
struct TwoWay {
    std::vector<double> pred_to_gt;
    std::vector<double> gt_to_pred;
};

TwoWay two_way_sq_distances(const at::Tensor& pred, const at::Tensor& gt) {
    check_points(pred, "prediction", 1);
    check_points(gt, "ground truth", 1);
    return {nearest_sq_distances(pred, gt), nearest_sq_distances(gt, pred)};
}

double mean(const std::vector<double>& values) {
    return std::accumulate(values.begin(), values.end(), 0.0) / values.size();
}

double max(const std::vector<double>& values) {
    return *std::max_element(values.begin(), values.end());
}

}  // namespace

double chamfer_distance(const at::Tensor& pred, const at::Tensor& gt) {
    TwoWay d = two_way_sq_distances(pred, gt);
    return mean(d.pred_to_gt) + mean(d.gt_to_pred);
}

double hausdorff_distance(const at::Tensor& pred, const at::Tensor& gt) {
    TwoWay d = two_way_sq_distances(pred, gt);
    return std::sqrt(std::max(max(d.pred_to_gt), max(d.gt_to_pred)));
}

double hausdorff_distance_legacy(const at::Tensor& pred, const at::Tensor& gt) {
    TwoWay d = two_way_sq_distances(pred, gt);
    return max(d.pred_to_gt) + max(d.gt_to_pred);
}

}  // namespace pumeta
