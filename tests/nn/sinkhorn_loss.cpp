// The Sinkhorn divergence against a plain dense log-domain Sinkhorn in double (alternating,
// not symmetric, updates at a fixed ε iterated to convergence, and the primal-dual value
// instead of the symmetrised one), finite differences for its gradients, and invariances.
#include "pumeta/nn/sinkhorn_loss.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <cmath>

#include "pumeta/core/error.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

at::Tensor cloud(int64_t n, uint64_t seed, double scale = 0.3) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    return scale * at::randn({1, n, 3}, gen, at::TensorOptions().dtype(at::kDouble));
}

// OT_ε,ρ(a, b) for uniform weights by alternating damped log-domain updates at ε until they
// stop moving; value ρ⟨a, 1 − e^{−f/ρ}⟩ + ρ⟨b, 1 − e^{−g/ρ}⟩ − ε(⟨π, 1⟩ − ⟨a ⊗ b, 1⟩).
double reference_ot(const at::Tensor& x, const at::Tensor& y, double eps, double rho) {
    const int64_t n = x.size(0), m = y.size(0);
    at::Tensor c = 0.5 * (x.unsqueeze(1) - y.unsqueeze(0)).pow(2).sum(-1);
    at::Tensor a_log = at::full({n}, -std::log(double(n)), at::kDouble);
    at::Tensor b_log = at::full({m}, -std::log(double(m)), at::kDouble);
    at::Tensor f = at::zeros({n}, at::kDouble), g = at::zeros({m}, at::kDouble);
    const double d = 1.0 / (1.0 + eps / rho);
    for (int i = 0; i < 100000; ++i) {
        at::Tensor f_next =
            -d * eps * at::logsumexp(b_log.unsqueeze(0) + (g.unsqueeze(0) - c) / eps, 1);
        at::Tensor g_next =
            -d * eps * at::logsumexp(a_log.unsqueeze(1) + (f_next.unsqueeze(1) - c) / eps, 0);
        const double change = std::max((f_next - f).abs().max().item<double>(),
                                       (g_next - g).abs().max().item<double>());
        f = f_next, g = g_next;
        if (change < 1e-15) break;
    }
    at::Tensor plan =
        (a_log.unsqueeze(1) + b_log.unsqueeze(0) + (f.unsqueeze(1) + g.unsqueeze(0) - c) / eps)
            .exp();
    return (rho * (1 - (-f / rho).exp()).mean() + rho * (1 - (-g / rho).exp()).mean() -
            eps * (plan.sum() - 1))
        .item<double>();
}

double reference_divergence(const at::Tensor& x, const at::Tensor& y, double eps, double rho) {
    return reference_ot(x, y, eps, rho) - 0.5 * reference_ot(x, x, eps, rho) -
           0.5 * reference_ot(y, y, eps, rho);
}

SinkhornOptions converged(SinkhornGradient gradient) {
    SinkhornOptions o;
    o.blur = 0.2;
    o.reach = 0.5;
    o.extra_iterations = 5000;
    o.tolerance = 1e-15;
    o.gradient = gradient;
    return o;
}

TEST(SinkhornDivergence, MatchesADenseSinkhornIteratedToConvergence) {
    at::Tensor x = cloud(7, 1), y = cloud(9, 2) + 0.1;
    const double expected = reference_divergence(x[0], y[0], 0.04, 0.25);
    for (SinkhornGradient mode : {SinkhornGradient::kEnvelope, SinkhornGradient::kUnrolled}) {
        const double value = sinkhorn_divergence(x, y, converged(mode)).item<double>();
        EXPECT_NEAR(value, expected, 1e-10 * std::abs(expected) + 1e-14);
    }
    EXPECT_GT(expected, 1e-4);
}

TEST(SinkhornDivergence, DefaultScheduleIsCloseToConvergedAtMetaPuSettings) {
    // Meta-PU's blur 0.001 and reach 0.2 on clouds with spacing far above the blur: the
    // ε-scaling schedule alone lands within 1 % of the converged value.
    at::Tensor x = cloud(12, 3), y = cloud(12, 4);
    SinkhornOptions fast;
    SinkhornOptions slow = fast;
    slow.extra_iterations = 2000;
    slow.tolerance = 1e-14;
    const double a = sinkhorn_divergence(x, y, fast).item<double>();
    const double b = sinkhorn_divergence(x, y, slow).item<double>();
    EXPECT_NEAR(a, b, 0.01 * b);
}

TEST(SinkhornDivergence, IdenticalCloudsGiveZeroAndTranslationIncreasesIt) {
    at::Tensor x = cloud(20, 5);
    EXPECT_NEAR(sinkhorn_divergence(x, x.clone()).item<double>(), 0.0, 1e-12);
    double previous = 0;
    for (double t : {0.02, 0.05, 0.1, 0.2}) {
        at::Tensor shifted = x + at::tensor({t, 0.0, 0.0}, at::kDouble);
        const double value = sinkhorn_divergence(x, shifted).item<double>();
        EXPECT_GT(value, previous) << "t = " << t;
        previous = value;
    }
    // Float32 clouds too, at the default blur.
    at::Tensor xf = x.to(at::kFloat);
    EXPECT_NEAR(sinkhorn_divergence(xf, xf.clone()).item<double>(), 0.0, 1e-6);
}

TEST(SinkhornDivergence, BatchIsTheMeanOfItsElements) {
    at::Tensor x = at::cat({cloud(6, 6), cloud(6, 7)}), y = at::cat({cloud(8, 8), cloud(8, 9)});
    const double both = sinkhorn_divergence(x, y).item<double>();
    const double first = sinkhorn_divergence(x.slice(0, 0, 1), y.slice(0, 0, 1)).item<double>();
    const double second = sinkhorn_divergence(x.slice(0, 1, 2), y.slice(0, 1, 2)).item<double>();
    EXPECT_NEAR(both, 0.5 * (first + second), 1e-12);
}

// Central differences of the value along `direction` at `x` (y fixed).
double numeric_slope(const at::Tensor& x, const at::Tensor& y, const at::Tensor& direction,
                     const SinkhornOptions& o) {
    const double h = 1e-6;
    return (sinkhorn_divergence(x + h * direction, y, o).item<double>() -
            sinkhorn_divergence(x - h * direction, y, o).item<double>()) /
           (2 * h);
}

TEST(SinkhornDivergence, GradientsMatchFiniteDifferencesAtConvergence) {
    at::Tensor x0 = cloud(6, 10), y = cloud(7, 11) + 0.05;
    at::Tensor direction = cloud(6, 12, 1.0);
    for (SinkhornGradient mode : {SinkhornGradient::kEnvelope, SinkhornGradient::kUnrolled}) {
        SinkhornOptions o = converged(mode);
        at::Tensor x = x0.clone().requires_grad_(true);
        at::Tensor grad = torch::autograd::grad({sinkhorn_divergence(x, y, o)}, {x})[0];
        const double analytic = (grad * direction).sum().item<double>();
        const double numeric = numeric_slope(x0, y, direction, o);
        EXPECT_NEAR(analytic, numeric, 1e-6 * std::abs(numeric)) << int(mode);
        // Both clouds receive gradients (the target side too).
        at::Tensor yg = y.clone().requires_grad_(true);
        at::Tensor gy = torch::autograd::grad({sinkhorn_divergence(x0, yg, o)}, {yg})[0];
        EXPECT_GT(gy.abs().max().item<double>(), 0);
    }
}

// H·v by autograd (double backward) and by central differences of the gradient.
std::pair<double, double> hessian_along(const at::Tensor& x0, const at::Tensor& y,
                                        const at::Tensor& v, const SinkhornOptions& o) {
    at::Tensor x = x0.clone().requires_grad_(true);
    at::Tensor grad = torch::autograd::grad({sinkhorn_divergence(x, y, o)}, {x}, {}, true, true)[0];
    at::Tensor hv = torch::autograd::grad({(grad * v).sum()}, {x})[0];
    auto gradient_at = [&](const at::Tensor& at_x) {
        at::Tensor p = at_x.clone().requires_grad_(true);
        return torch::autograd::grad({sinkhorn_divergence(p, y, o)}, {p})[0];
    };
    const double h = 1e-6;
    at::Tensor numeric = (gradient_at(x0 + h * v) - gradient_at(x0 - h * v)) / (2 * h);
    return {(hv * v).sum().item<double>(), (numeric * v).sum().item<double>()};
}

TEST(SinkhornDivergence, UnrolledSecondOrderIsExact) {
    SinkhornOptions o;  // the schedule alone: exact derivatives of what is computed
    o.blur = 0.1;
    o.gradient = SinkhornGradient::kUnrolled;
    auto [analytic, numeric] = hessian_along(cloud(5, 13), cloud(6, 14), cloud(5, 15, 1.0), o);
    EXPECT_NEAR(analytic, numeric, 1e-5 * std::abs(numeric));
    EXPECT_GT(std::abs(numeric), 1e-4);
}

TEST(SinkhornDivergence, EnvelopeSecondOrderIsFiniteAndPositiveAlongATranslation) {
    // Moving every output point the same way away from the target costs more and more:
    // the explicit second derivative the envelope mode keeps sees that curvature.
    at::Tensor x = cloud(8, 16), y = x + 0.05;
    at::Tensor v = at::ones({1, 8, 3}, at::kDouble);
    auto [analytic, numeric] = hessian_along(x, y, v, SinkhornOptions{});
    EXPECT_TRUE(std::isfinite(analytic));
    EXPECT_GT(analytic, 0);
    EXPECT_GT(numeric, 0);
}

TEST(SinkhornDivergence, RejectsBadInput) {
    at::Tensor x = cloud(4, 17);
    EXPECT_TRUE(test::throws_input_error([&] { sinkhorn_divergence(x, x[0]); }, {"[B,N,3]"}));
    EXPECT_TRUE(test::throws_input_error(
        [&] {
            sinkhorn_divergence(x, at::cat({x, x}));
        },
        {"batches of 1 and 2"}));
    EXPECT_TRUE(test::throws_input_error([&] { sinkhorn_divergence(x, x.to(at::kFloat)); },
                                         {"share a floating type"}));
    SinkhornOptions bad;
    bad.scaling = 1;
    EXPECT_TRUE(test::throws_input_error([&] { sinkhorn_divergence(x, x, bad); }, {"scaling"}));
}

}  // namespace
}  // namespace pumeta
