#include "pumeta/nn/sinkhorn_loss.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "sinkhorn_divergence";
// Cost entries per block outside the graph: 16 MB in float32.
constexpr int64_t kBlockPairs = int64_t(1) << 22;
// Entries per row of a cloud's plan with itself that carry the self terms' derivatives.
constexpr int64_t kSelfPlanEntries = 16;

// ½|p_i − q_j|² [N,M] from coordinate differences (exact, differentiable in both clouds).
at::Tensor half_sq_distances(const at::Tensor& p, const at::Tensor& q) {
    return 0.5 * (p.unsqueeze(1) - q.unsqueeze(0)).pow(2).sum(-1);
}

// The same through |p|² + |q|² − 2 p·q, for the blocks outside the graph (no [N,M,3]).
at::Tensor half_sq_distances_fast(const at::Tensor& p, const at::Tensor& q) {
    at::Tensor sq = p.pow(2).sum(-1, true) + q.pow(2).sum(-1).unsqueeze(0) - 2 * p.matmul(q.t());
    return 0.5 * sq.clamp_min(0);
}

// The soft minimum over the points q_j of C(p_i, q_j) − ε h_j: −ε log Σ_j exp(h_j − C_ij / ε),
// p [N,3], q [M,3], h [M] -> [N]. In the graph (all of C at once).
at::Tensor softmin(double eps, const at::Tensor& p, const at::Tensor& q, const at::Tensor& h) {
    return -eps * at::logsumexp(h.unsqueeze(0) - half_sq_distances(p, q) / eps, 1);
}

// softmin without a graph, in row blocks; with `mean_target`, also u_i = Σ_j P_ij q_j for
// the soft assignment P_ij = softmax_j(h_j − C_ij / ε), and with `largest` > 0 the indices and
// weights of the `largest` biggest P_ij of each row.
struct Softmin {
    at::Tensor value;          ///< [N]
    at::Tensor mean_target{};  ///< [N,3]
    at::Tensor top_index{};    ///< int64 [N,K]
    at::Tensor top_weight{};   ///< [N,K]
};
Softmin softmin_blocked(double eps, const at::Tensor& p, const at::Tensor& q, const at::Tensor& h,
                        bool mean_target, int64_t largest = 0) {
    at::NoGradGuard no_grad;
    const int64_t n = p.size(0), m = q.size(0);
    const int64_t rows = std::max<int64_t>(1, kBlockPairs / m);
    std::vector<at::Tensor> values, means, indices, weights;
    for (int64_t begin = 0; begin < n; begin += rows) {
        at::Tensor block = p.slice(0, begin, std::min(n, begin + rows));
        at::Tensor logits = h.unsqueeze(0) - half_sq_distances_fast(block, q) / eps;
        at::Tensor lse = at::logsumexp(logits, 1);
        values.push_back(-eps * lse);
        if (!mean_target && largest == 0) continue;
        at::Tensor plan = (logits - lse.unsqueeze(1)).exp_();
        if (mean_target) means.push_back(plan.matmul(q));
        if (largest > 0) {
            auto [weight, index] = plan.topk(std::min(largest, m), 1);
            indices.push_back(index);
            weights.push_back(weight);
        }
    }
    Softmin out{at::cat(values)};
    if (mean_target) out.mean_target = at::cat(means);
    if (largest > 0) out.top_index = at::cat(indices), out.top_weight = at::cat(weights);
    return out;
}

// The ε schedule of geomloss (p = 2) with the diameter rounded up to blur · scaling^−K:
// ε = (blur · scaling^−k)² for k = K, K, K − 1, ..., 0. The values stay put when the points
// move a little, so that unrolled derivatives are those of one function.
std::vector<double> epsilon_schedule(double diameter, const SinkhornOptions& o) {
    const int64_t steps = std::max<int64_t>(
        0, int64_t(std::ceil(std::log(diameter / o.blur) / -std::log(o.scaling))));
    std::vector<double> eps = {std::pow(o.blur * std::pow(o.scaling, -double(steps)), 2)};
    for (int64_t k = steps; k >= 0; --k)
        eps.push_back(std::pow(o.blur * std::pow(o.scaling, -double(k)), 2));
    return eps;
}

struct Potentials {
    at::Tensor f_xy, g_yx, f_xx, g_yy;
};

// The divergence of one pair of clouds x [N,3], y [M,3].
at::Tensor divergence(const at::Tensor& x, const at::Tensor& y, const SinkhornOptions& o) {
    const bool unrolled = o.gradient == SinkhornGradient::kUnrolled;
    const double rho = o.reach * o.reach;
    auto damping = [rho](double eps) { return 1.0 / (1.0 + eps / rho); };
    const at::TensorOptions like = x.options().requires_grad(false);
    const at::Tensor a_log = at::full({x.size(0)}, -std::log(double(x.size(0))), like);
    const at::Tensor b_log = at::full({y.size(0)}, -std::log(double(y.size(0))), like);
    double diameter;
    {
        at::NoGradGuard no_grad;
        at::Tensor both = at::cat({x, y}).detach();
        diameter = (std::get<0>(both.max(0)) - std::get<0>(both.min(0))).norm().item<double>();
    }
    const std::vector<double> schedule = epsilon_schedule(std::max(diameter, o.blur), o);

    auto soft = [&](double eps, const at::Tensor& p, const at::Tensor& q, const at::Tensor& h) {
        return unrolled ? softmin(eps, p, q, h) : softmin_blocked(eps, p, q, h, false).value;
    };
    auto update = [&](double eps, const Potentials& v) {
        const double d = damping(eps);
        return Potentials{
            d * soft(eps, x, y, b_log + v.g_yx / eps), d * soft(eps, y, x, a_log + v.f_xy / eps),
            d * soft(eps, x, x, a_log + v.f_xx / eps), d * soft(eps, y, y, b_log + v.g_yy / eps)};
    };
    // Symmetric iterations: the average of the old potentials and their update.
    auto average = [](const Potentials& old, const Potentials& next) {
        return Potentials{0.5 * (old.f_xy + next.f_xy), 0.5 * (old.g_yx + next.g_yx),
                          0.5 * (old.f_xx + next.f_xx), 0.5 * (old.g_yy + next.g_yy)};
    };

    Potentials v;
    {
        const double eps = schedule.front(), d = damping(eps);
        v = {d * soft(eps, x, y, b_log), d * soft(eps, y, x, a_log), d * soft(eps, x, x, a_log),
             d * soft(eps, y, y, b_log)};
    }
    for (double eps : schedule) v = average(v, update(eps, v));
    const double eps = schedule.back(), d = damping(eps);
    for (int64_t i = 0; i < o.extra_iterations; ++i) {
        Potentials next = average(v, update(eps, v));
        double change = 0;
        for (auto [a, b] : {std::pair{&next.f_xy, &v.f_xy}, std::pair{&next.g_yx, &v.g_yx},
                            std::pair{&next.f_xx, &v.f_xx}, std::pair{&next.g_yy, &v.g_yy}})
            change = std::max(change, (*a - *b).abs().max().item<double>());
        v = next;
        if (change <= o.tolerance) break;
    }

    // The final extrapolation: each potential once more at its points.
    Potentials last;
    if (unrolled) {
        last = update(eps, v);
    } else {
        // Cross terms: f_i = softmin_j(C(p_i, q̄_j) − ε h̄_j) with q and h detached (as
        // geomloss): its value from the blocks, and its derivative p_i − u_i, u = P q̄, carried
        // by ½|p|² − p·u minus its value. The factor ρ / (ρ + ε/2) (geomloss: d) makes
        // (ρ + ε/2)·∂e^{−f/ρ} the envelope gradient Σ_j π_ij (p_i − q_j).
        const double k = rho / (rho + eps / 2);
        auto cross = [&](const at::Tensor& p, const at::Tensor& q, const at::Tensor& h) {
            Softmin s = softmin_blocked(eps, p.detach(), q.detach(), h.detach(), true);
            at::Tensor value = d * s.value;
            if (!p.requires_grad()) return value;
            at::Tensor quadratic = 0.5 * p.pow(2).sum(-1) - (p * s.mean_target).sum(-1);
            return value + k * (quadratic - quadratic.detach());
        };
        // Self terms: the cloud sits on both sides, f_i = softmin_j(C(p_i, p_j) − ε h̄_j), so
        // both ends of each pair move: ½ Σ_j P_ij ½|p_i − p_j|² over the kSelfPlanEntries
        // largest P_ij of each row (all of them at Meta-PU's blur, where a point's plan is
        // itself) carries the derivative; a translation then leaves it unchanged to second
        // order, as it leaves OT(p, p).
        auto self = [&](const at::Tensor& p, const at::Tensor& h) {
            Softmin s =
                softmin_blocked(eps, p.detach(), p.detach(), h.detach(), false, kSelfPlanEntries);
            at::Tensor value = d * s.value;
            if (!p.requires_grad()) return value;
            const int64_t n = p.size(0), entries = s.top_index.size(1);
            at::Tensor partners = p.index_select(0, s.top_index.flatten()).view({n, entries, 3});
            at::Tensor spread =
                (s.top_weight * 0.25 * (p.unsqueeze(1) - partners).pow(2).sum(-1)).sum(1);
            return value + k * (spread - spread.detach());
        };
        last = {cross(x, y, b_log + v.g_yx / eps), cross(y, x, a_log + v.f_xy / eps),
                self(x, a_log + v.f_xx / eps), self(y, b_log + v.g_yy / eps)};
    }
    auto mass = [rho](const at::Tensor& f) { return (-f / rho).exp(); };
    return (rho + eps / 2) * ((mass(last.f_xx) - mass(last.f_xy)).mean() +
                              (mass(last.g_yy) - mass(last.g_yx)).mean());
}

}  // namespace

at::Tensor sinkhorn_divergence(const at::Tensor& x, const at::Tensor& y,
                               const SinkhornOptions& options) {
    check_batched_points(x, kContext);
    check_batched_points(y, kContext);
    if (x.size(0) != y.size(0))
        throw_input_error(kContext, "batches of {} and {} clouds", x.size(0), y.size(0));
    if (x.size(1) < 1 || y.size(1) < 1)
        throw_input_error(kContext, "empty cloud ({} and {} points)", x.size(1), y.size(1));
    if (x.scalar_type() != y.scalar_type() || !x.is_floating_point())
        throw_input_error(kContext, "points must share a floating type, found {} and {}",
                          std::string(c10::toString(x.scalar_type())),
                          std::string(c10::toString(y.scalar_type())));
    if (!(options.blur > 0) || !(options.reach > 0))
        throw_input_error(kContext, "blur and reach must be > 0, found {} and {}", options.blur,
                          options.reach);
    if (!(options.scaling > 0 && options.scaling < 1))
        throw_input_error(kContext, "scaling must lie in (0, 1), found {}", options.scaling);
    std::vector<at::Tensor> values;
    for (int64_t b = 0; b < x.size(0); ++b) values.push_back(divergence(x[b], y[b], options));
    return at::stack(values).mean();
}

}  // namespace pumeta
