#include "pumeta/nn/uniform_loss.h"

#include <ATen/ATen.h>

#include <cmath>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/sampling.h"

namespace pumeta {

namespace {

constexpr const char* kWhat = "uniform_loss";
// The original's guards: under the square root of a squared distance, and in the division
// by the expected spacing.
constexpr double kDistanceEps = 1e-8;
constexpr double kSpacingEps = 1e-8;
const double kPi = std::acos(-1.0);

void check_options(const UniformLossOptions& options) {
    if (options.percentages.empty()) throw_input_error(kWhat, "needs at least one percentage");
    for (double p : options.percentages)
        if (!(p > 0 && p <= 1))
            throw_input_error(kWhat, "percentages must lie in (0, 1], found {}", p);
    if (!(options.seed_fraction > 0 && options.seed_fraction <= 1))
        throw_input_error(kWhat, "seed_fraction must lie in (0, 1], found {}",
                          options.seed_fraction);
}

// rows [B,M,C] and int64 indices [B,...] -> [B,...,C], differentiable in rows.
at::Tensor gather_rows(const at::Tensor& rows, const at::Tensor& index) {
    const int64_t batch = rows.size(0), m = rows.size(1), c = rows.size(2);
    at::Tensor offset = at::arange(batch, index.options()).mul_(m);
    for (int64_t d = 1; d < index.dim(); ++d) offset = offset.unsqueeze(-1);
    std::vector<int64_t> shape = index.sizes().vec();
    shape.push_back(c);
    return rows.reshape({batch * m, c}).index_select(0, (index + offset).reshape(-1)).view(shape);
}

// From the squared distances sq [B,S,M] of every seed to every point, per seed the first
// `count` points closer than sqrt(sq_radius) in index order, the first one repeated where
// fewer are found: int64 [B,S,count]. A seed is a point of the cloud, so it always finds
// itself.
at::Tensor ball_query(const at::Tensor& sq, double sq_radius, int64_t count) {
    const int64_t m = sq.size(2);
    at::Tensor order = at::arange(m, sq.options().dtype(at::kLong));
    at::Tensor key = at::where(sq < sq_radius, order, order + m);
    at::Tensor first = std::get<0>(key.topk(count, -1, /*largest=*/false, /*sorted=*/true));
    return at::where(first < m, first, first.narrow(-1, 0, 1));
}

}  // namespace

UniformLossOptions pugan_uniform_options() { return UniformLossOptions{}; }

UniformLossOptions metapu_uniform_options() {
    UniformLossOptions options;
    options.percentages = {0.004, 0.008, 0.010, 0.012, 0.016};
    options.spacing = UniformSpacing::kHexagonal;
    return options;
}

at::Tensor uniform_loss(const at::Tensor& points, const UniformLossOptions& options) {
    check_batched_points(points, kWhat);
    check_options(options);
    const int64_t m = points.size(1);
    if (m < 2) throw_input_error(kWhat, "needs at least 2 points per cloud, found {}", m);
    const int64_t num_seeds =
        std::max<int64_t>(1, int64_t(std::floor(double(m) * options.seed_fraction + 1e-9)));
    at::Tensor seed_distances;  // [B,S,M], shared by every disk size
    {
        at::NoGradGuard no_grad;
        at::Tensor fixed = points.detach().contiguous();
        at::Tensor seeds = gather_rows(fixed, farthest_point_sampling_batched(fixed, num_seeds));
        seed_distances = (seeds.unsqueeze(2) - fixed.unsqueeze(1)).pow(2).sum(-1);
    }
    at::Tensor total;
    int64_t used = 0;
    for (double p : options.percentages) {
        // + 1e-9: ⌊M p⌋ of a product that should be an integer but rounds just below it.
        const int64_t count = int64_t(std::floor(double(m) * p + 1e-9));
        if (count < 2) continue;  // no nearest other member
        at::Tensor members, nearest;
        {
            at::NoGradGuard no_grad;
            members = ball_query(seed_distances, p, count);  // [B,S,count]
            at::Tensor at_members = gather_rows(points.detach(), members);
            at::Tensor sq = (at_members.unsqueeze(3) - at_members.unsqueeze(2)).pow(2).sum(-1);
            // Slots, not points: a padding copy of the first hit is another member at 0.
            sq.diagonal(0, 2, 3).fill_(INFINITY);
            nearest = members.gather(2, sq.argmin(-1));
        }
        at::Tensor d = (gather_rows(points, members) - gather_rows(points, nearest))
                           .pow(2)
                           .sum(-1)
                           .add(kDistanceEps)
                           .sqrt();
        const double area = kPi * p / double(count);
        const double expected = options.spacing == UniformSpacing::kSquare
                                    ? std::sqrt(area)
                                    : std::sqrt(2 * area / std::sqrt(3.0));
        at::Tensor term =
            (d - expected).pow(2).div(expected + kSpacingEps).mean() * std::pow(100 * p, 2);
        total = used == 0 ? term : total + term;
        ++used;
    }
    // Clouds too small for every disk size: nothing to measure, a zero that keeps the graph.
    if (used == 0) return points.sum() * 0;
    return total / double(used);
}

}  // namespace pumeta
