// PSNR as MPEG pc_error computes its D1 (point-to-point) PSNR.
#include <ATen/ATen.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "pumeta/core/tensor_checks.h"
#include "pumeta/metrics/metrics.h"
#include "pumeta/metrics/nearest_distances.h"

namespace pumeta {

namespace {

constexpr double kPeak = 1023;

using Point = std::array<double, 3>;
static_assert(sizeof(Point) == 3 * sizeof(double), "rows of [N,3] are read as Points");

/// Rows of a float64 [N,3] tensor with exact duplicates merged, as pc_error does before
/// measuring (a duplicated point would otherwise count twice in the mean).
at::Tensor unique_points(const at::Tensor& points) {
    at::Tensor contiguous = points.contiguous();
    const auto* begin = reinterpret_cast<const Point*>(contiguous.data_ptr<double>());
    std::vector<Point> unique(begin, begin + points.size(0));
    std::sort(unique.begin(), unique.end());
    unique.erase(std::unique(unique.begin(), unique.end()), unique.end());
    at::Tensor result = at::empty({static_cast<int64_t>(unique.size()), 3}, at::kDouble);
    std::copy(unique.begin(), unique.end(), reinterpret_cast<Point*>(result.data_ptr<double>()));
    return result;
}

/// One-way PSNR(A, B) = 10 log10(3 p^2 / MSE(A->B)); the factor 3 is pc_error's.
double one_way_psnr(const at::Tensor& from, const at::Tensor& to) {
    std::vector<double> sq = nearest_sq_distances(from, to);
    double mse = std::accumulate(sq.begin(), sq.end(), 0.0) / sq.size();
    if (mse == 0) return std::numeric_limits<double>::infinity();
    return 10 * std::log10(3 * kPeak * kPeak / mse);
}

}  // namespace

double psnr_d1(const at::Tensor& pred, const at::Tensor& gt) {
    check_points(pred, "prediction", 1);
    check_points(gt, "ground truth", 1);
    at::Tensor g = gt.to(at::kCPU, at::kDouble);
    at::Tensor p = pred.to(at::kCPU, at::kDouble);
    // GT's bounding-box minimum -> 0, its longest side -> 1023. A GT of one repeated point
    // has no extent: only the translation applies then.
    at::Tensor lo = std::get<0>(g.min(0));
    double longest = (std::get<0>(g.max(0)) - lo).max().item<double>();
    double scale = longest > 0 ? kPeak / longest : 1.0;
    at::Tensor p_frame = unique_points((p - lo) * scale);
    at::Tensor g_frame = unique_points((g - lo) * scale);
    return std::min(one_way_psnr(p_frame, g_frame), one_way_psnr(g_frame, p_frame));
}

}  // namespace pumeta
