#include "pumeta/models/pugaussian.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/nn/parameters.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

PuGaussian small_model() {
    return PuGaussian(PuGaussianOptions::from_json(pugaussian_small_config()));
}

TEST(PuGaussian, TheOriginalsSizeHas268109ParametersAndTheStatisticsOfFourBatchNorms) {
    PuGaussian model(PuGaussianOptions{});
    // The released file's 275,086 less the feature projection (4,864) and the confidence head
    // (2,113), which feed nothing.
    EXPECT_EQ(count_parameters(model.parameters()), 268109);
    EXPECT_EQ(model.buffers().size(), 8u);
    // Position encodings of 64 channels in both transformers, attention MLPs of 4 · 32 and 4 · 64.
    EXPECT_EQ(count_parameters(model.buffers()), 2 * (64 + 64 + 128 + 256));
}

TEST(PuGaussian, RatiosUpToTheDrawsPerPointAndNoMore) {
    nlohmann::json config = pugaussian_small_config();
    config["ratio"] = 7;
    EXPECT_THROW(PuGaussianOptions::from_json(config), InputError);
    const PuGaussian model = small_model();
    EXPECT_FALSE(model.config_for_ratio(6).is_null());
    EXPECT_FALSE(model.config_for_ratio(2).is_null());
    EXPECT_TRUE(model.config_for_ratio(7).is_null());
    EXPECT_TRUE(model.config_for_ratio(16).is_null());  // 4x twice
}

// Each component of the standard normal draws lies within the truncation; a patch's draws come
// from the seed and its own points, whatever else is in its batch.
TEST(PuGaussian, DrawsAreTruncatedAndSeededByEachPatch) {
    const PuGaussian model = small_model();
    const at::Tensor x = test::sheet(2, 16, 4);
    const at::Tensor both = model.draw_epsilon(x, 9);
    ASSERT_EQ(both.sizes(), (std::vector<int64_t>{2, 16, 6, 3}));
    EXPECT_LE(both.abs().max().item<double>(), 2.0);
    EXPECT_GT(both.abs().max().item<double>(), 1.5);  // still a normal draw, not a squeezed one
    EXPECT_TRUE(both[1].equal(model.draw_epsilon(x.slice(0, 1, 2), 9)[0]));
    EXPECT_FALSE(both[0].equal(both[1]));
    EXPECT_FALSE(both.equal(model.draw_epsilon(x, 10)));
}

// ---- An independent re-computation, point by point in double precision ----

using Vec = at::Tensor;  // one point's features, double [C]

struct Reference {
    ParamMap params, buffers;
    int64_t k, samples;

    Vec p(const std::string& name) const { return params.at(name); }
    Vec linear(const Vec& v, const std::string& prefix) const {
        return p(prefix + ".weight").mv(v) + p(prefix + ".bias");
    }
    Vec two_layers(const Vec& v, const std::string& prefix) const {
        return linear(at::relu(linear(v, prefix + ".0")), prefix + ".1");
    }
    // conv -> batch norm (running statistics, not folded) -> ReLU
    Vec norm_relu(const Vec& v, const std::string& prefix) const {
        const std::string bn = prefix + ".bn";
        const Vec y = linear(v, prefix);
        return at::relu((y - buffers.at(bn + ".running_mean")) /
                            at::sqrt(buffers.at(bn + ".running_var") + 1e-5) * p(bn + ".gamma") +
                        p(bn + ".beta"));
    }
    // The k nearest of each point, itself first, by sorting all distances.
    std::vector<std::vector<int64_t>> neighbours(const std::vector<Vec>& pos) const {
        std::vector<std::vector<int64_t>> out;
        for (const Vec& a : pos) {
            std::vector<double> d;
            for (const Vec& b : pos) d.push_back((a - b).pow(2).sum().item<double>());
            std::vector<int64_t> order(pos.size());
            std::iota(order.begin(), order.end(), 0);
            std::stable_sort(order.begin(), order.end(),
                             [&](int64_t i, int64_t j) { return d[i] < d[j]; });
            order.resize(std::min<size_t>(k, order.size()));
            out.push_back(order);
        }
        return out;
    }
    std::vector<Vec> transformer(const std::vector<Vec>& x, const std::vector<Vec>& pos,
                                 const std::string& prefix) const {
        const auto nbr = neighbours(pos);
        std::vector<Vec> q, key, v, out;
        for (const Vec& xi : x) {
            const Vec h = linear(xi, prefix + ".start");
            q.push_back(linear(h, prefix + ".query"));
            key.push_back(linear(h, prefix + ".key"));
            v.push_back(linear(h, prefix + ".value"));
        }
        for (size_t i = 0; i < x.size(); ++i) {
            std::vector<Vec> logits, values;
            for (int64_t j : nbr[i]) {
                const Vec e =
                    linear(norm_relu(pos[i] - pos[j], prefix + ".pos0"), prefix + ".pos1");
                logits.push_back(
                    linear(norm_relu(q[i] - key[j] + e, prefix + ".attn0"), prefix + ".attn1"));
                values.push_back(v[i] + e);
            }
            Vec top = logits[0];
            for (const Vec& l : logits) top = at::maximum(top, l);
            Vec total = at::zeros_like(top), agg = at::zeros_like(top);
            for (size_t j = 0; j < logits.size(); ++j) total = total + at::exp(logits[j] - top);
            for (size_t j = 0; j < logits.size(); ++j)
                agg = agg + at::exp(logits[j] - top) / total * values[j];
            out.push_back(linear(agg, prefix + ".end") + x[i]);
        }
        return out;
    }
    static Vec global_max(const std::vector<Vec>& f) {
        Vec m = f[0];
        for (const Vec& v : f) m = at::maximum(m, v);
        return m;
    }
    Vec head(const Vec& v, const std::string& prefix) const {
        return linear(at::leaky_relu(linear(v, prefix + ".0"), 0.1), prefix + ".1");
    }
};

// One patch through pumeta's network (batched, batch norm folded) and through the reference
// above (a loop over points and neighbours, batch norm as written, the rotation by Rodrigues'
// form of the quaternion): means, covariances, coarse draws and both refinement passes agree.
TEST(PuGaussian, EveryStageMatchesAnIndependentComputation) {
    PuGaussian model = small_model();
    // Running statistics away from their initial values, so that the folding is exercised.
    model.update_buffers(test::sheet(2, 16, 30), model.parameters());
    Reference ref;
    for (const auto& [name, t] : model.parameters()) ref.params[name] = t.detach().to(at::kDouble);
    for (const auto& [name, t] : model.buffers()) ref.buffers[name] = t.to(at::kDouble);
    ref.k = model.options().k;
    ref.samples = model.options().samples;

    const int64_t n = 16, s = ref.samples;
    const at::Tensor x = test::sheet(1, n, 31, at::kDouble);
    const at::Tensor epsilon = model.draw_epsilon(x, 32);

    std::vector<Vec> pos, f1;
    for (int64_t i = 0; i < n; ++i) pos.push_back(x[0][i]);
    for (const Vec& p : pos) f1.push_back(ref.two_layers(p, "gaussian.mlp1"));
    const Vec g1 = Reference::global_max(f1);
    std::vector<Vec> f2;
    for (const Vec& f : f1) f2.push_back(ref.two_layers(at::cat({f, g1}), "gaussian.mlp2"));
    const std::vector<Vec> features = ref.transformer(f2, pos, "gaussian.transformer");

    std::vector<Vec> means, covariances, coarse;
    for (int64_t i = 0; i < n; ++i) {
        const Vec mean = pos[i] + ref.head(features[i], "gaussian.offset");
        const Vec raw = ref.head(features[i], "gaussian.scale");
        std::vector<double> scale(3);
        for (int c = 0; c < 3; ++c) {
            const double t = 100 * raw[c].item<double>();
            scale[c] = t > 20 ? t / 100 : std::log1p(std::exp(t)) / 100;
        }
        Vec q = ref.head(features[i], "gaussian.rotation");
        q = q / q.norm();
        const double w = q[0].item<double>();
        const Vec u = q.slice(0, 1, 4);
        // R = I + 2w[u]x + 2[u]x², the rotation of a unit quaternion (w, u).
        Vec cross = at::zeros({3, 3}, at::kDouble);
        cross[0][1] = -u[2];
        cross[0][2] = u[1];
        cross[1][0] = u[2];
        cross[1][2] = -u[0];
        cross[2][0] = -u[1];
        cross[2][1] = u[0];
        const Vec rotation = at::eye(3, at::kDouble) + 2 * w * cross + 2 * cross.mm(cross);
        const Vec s2 = at::tensor({scale[0] * scale[0], scale[1] * scale[1], scale[2] * scale[2]},
                                  at::kDouble);
        const Vec covariance = rotation.mm(at::diag(s2)).mm(rotation.t());
        means.push_back(mean);
        covariances.push_back(covariance);
        for (int64_t j = 0; j < s; ++j)
            coarse.push_back(mean + epsilon[0][i][j].unsqueeze(0).mm(covariance)[0].clamp(-1, 1));
    }

    std::vector<Vec> points = coarse;
    for (int pass = 0; pass < 2; ++pass) {
        std::vector<Vec> h1;
        for (size_t m = 0; m < points.size(); ++m)
            h1.push_back(at::cat({ref.two_layers(points[m], "refine.mlp1"), features[m / s]}));
        const Vec g = Reference::global_max(h1);
        std::vector<Vec> h2;
        for (const Vec& h : h1) h2.push_back(ref.two_layers(at::cat({h, g}), "refine.mlp2"));
        const std::vector<Vec> h3 = ref.transformer(h2, points, "refine.transformer");
        std::vector<Vec> next;
        for (size_t m = 0; m < points.size(); ++m) {
            const Vec reduced = ref.two_layers(h3[m], "refine.up.mlp");
            const Vec joined = at::cat({ref.p("refine.up.deconv.weight").t().mv(reduced), h3[m]});
            const Vec up = at::relu(ref.linear(at::relu(ref.linear(joined, "refine.up.res.conv1")),
                                               "refine.up.res.conv2") +
                                    ref.linear(joined, "refine.up.res.shortcut"));
            next.push_back(points[m] + at::tanh(ref.two_layers(up, "refine.regressor")));
        }
        points = next;
    }
    // Both of pumeta's paths: the batched one (gradients on) and the chunked inference one.
    for (bool gradients : {true, false}) {
        at::AutoGradMode mode(gradients);
        const PuGaussian::Stages stages = model.forward(x, epsilon, ref.params, 2, false);
        const std::string path = gradients ? "batched: " : "inference: ";
        auto worst = [](const at::Tensor& ours, const std::vector<Vec>& theirs) {
            double d = 0;
            for (size_t i = 0; i < theirs.size(); ++i)
                d = std::max(d, (ours[int64_t(i)] - theirs[i]).abs().max().item<double>());
            return d;
        };
        EXPECT_LT(worst(stages.means[0], means), 1e-10) << path << "means";
        EXPECT_LT(worst(stages.covariances[0], covariances), 1e-10) << path << "covariances";
        EXPECT_LT(worst(stages.coarse[0], coarse), 1e-10) << path << "coarse";
        EXPECT_LT(worst(stages.refined[0], points), 1e-9) << path << "refined";
        // The refinement moved the points: the comparison is not of two untouched copies.
        EXPECT_GT((stages.refined - stages.coarse).abs().max().item<double>(), 1e-3);
    }
}

// The inference path cuts the points of a whole batch into chunks, across patch boundaries:
// 4 patches of 40 points make 960 refined points, several chunks, the same result as the
// batched path.
TEST(PuGaussian, TheInferencePathAgreesWithTheBatchedOneAcrossChunks) {
    PuGaussian model = small_model();
    model.update_buffers(test::sheet(2, 16, 40), model.parameters());
    ParamMap params;
    for (const auto& [name, t] : model.parameters()) params[name] = t.detach().to(at::kDouble);
    for (auto& [name, t] : model.buffers()) t = t.to(at::kDouble);
    const at::Tensor x = test::sheet(4, 40, 41, at::kDouble);
    const at::Tensor epsilon = model.draw_epsilon(x, 42);
    const at::Tensor batched = model.forward(x, epsilon, params, 2, false).refined;
    at::NoGradGuard no_grad;
    const at::Tensor chunked = model.forward(x, epsilon, params, 2, false).refined;
    ASSERT_EQ(chunked.sizes(), (std::vector<int64_t>{4, 240, 3}));
    EXPECT_LT((chunked - batched).abs().max().item<double>(), 1e-10);
}

}  // namespace
}  // namespace pumeta
