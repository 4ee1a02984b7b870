#include "pumeta/models/pugcn.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <cmath>

#include "pumeta/core/error.h"
#include "pumeta/nn/chamfer_loss.h"
#include "support/test_util.h"

namespace pumeta {

namespace {

// Tiny network for tests that train or differentiate twice.
nlohmann::json tiny_config(int64_t ratio = 4) {
    return {{"backbone", "pugcn"},
            {"ratio", ratio},
            {"channels", 4},
            {"k", 4},
            {"dilation", 2},
            {"upsample_channels", 8},
            {"reconstruction_channels", 8},
            {"patch_size", 32},
            {"seed", 3}};
}

// Double-precision copy moved to a generic point: at initialisation the biases are zero, so
// zero-feature inputs put ReLUs exactly on their kink, where finite differences are one-sided.
ParamMap perturbed_double(const ParamMap& params, uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    ParamMap out;
    for (const auto& [name, tensor] : params) {
        at::Tensor noise = at::randn(tensor.sizes(), gen, at::TensorOptions().dtype(at::kDouble));
        out[name] = (tensor.detach().to(at::kDouble) + 0.1 * noise).requires_grad_(true);
    }
    return out;
}

std::vector<at::Tensor> values(const ParamMap& params) {
    std::vector<at::Tensor> out;
    for (const auto& [name, tensor] : params) out.push_back(tensor);
    return out;
}

}  // namespace

TEST(PuGcn, ParameterCountsMatchTheOfficialModel) {
    // Hand count with channels 32: head 2·3·32+32 = 224; block 1: reduction 32·32+32 and two
    // DenseGCN paths of 5216 (edge conv 2·32·32+32, l0 32·32+32, l1 64·32+32) = 11488;
    // block 2: reduction 193·32+32 + 10432 = 16640; NodeShuffle reduction 193·64+64 = 12416
    // and edge conv 2·64·64r + 64r; reconstruction 64·32+32 + 32·3+3 = 2179.
    // r = 4 gives 75,971, the count published for PU-GCN.
    for (auto [ratio, expected] :
         std::vector<std::pair<int64_t, int64_t>>{{4, 75971}, {8, 108995}, {16, 175043}}) {
        PuGcn model(PuGcnOptions::from_json({{"ratio", ratio}}));
        EXPECT_EQ(count_parameters(model.parameters()), expected) << "r = " << ratio;
    }
}

TEST(PuGcn, OutputShapesForEveryRatio) {
    at::Tensor x = test::sheet(2, 256, 1);
    for (int64_t ratio : {4, 8, 16}) {
        PuGcn model(PuGcnOptions::from_json({{"ratio", ratio}}));
        at::Tensor y = model.upsample(x);
        EXPECT_EQ(y.sizes(), (std::vector<int64_t>{2, 256 * ratio, 3})) << "r = " << ratio;
        EXPECT_TRUE(y.isfinite().all().item<bool>());
    }
}

TEST(PuGcn, OutputsAreOffsetsFromTheirInputPointInConsecutiveGroups) {
    PuGcn model(PuGcnOptions::from_json(tiny_config()));
    at::Tensor x = test::sheet(2, 32, 2);
    ParamMap params = model.parameters();
    params["out.fc2.weight"] = at::zeros_like(params["out.fc2.weight"]);
    params["out.fc2.bias"] = at::tensor({0.5f, -1.f, 2.f});
    at::Tensor y = model.upsample(x, params).view({2, 32, 4, 3});
    for (int64_t s = 0; s < 4; ++s)
        EXPECT_TRUE(at::allclose(y.select(2, s), x + at::tensor({0.5f, -1.f, 2.f})));
}

TEST(PuGcn, PermutingInputPointsPermutesTheirOutputGroups) {
    PuGcn model(PuGcnOptions::from_json({{"ratio", 4}, {"seed", 5}}));
    at::Tensor x = test::sheet(1, 256, 3);
    at::Generator gen = at::detail::createCPUGenerator(4);
    at::Tensor perm = at::randperm(256, gen, at::TensorOptions().dtype(at::kLong));
    at::NoGradGuard no_grad;
    at::Tensor y = model.upsample(x).view({1, 256, 4, 3});
    at::Tensor y_perm = model.upsample(x.index_select(1, perm)).view({1, 256, 4, 3});
    EXPECT_TRUE(at::allclose(y_perm, y.index_select(1, perm), 1e-4, 1e-5));
}

TEST(PuGcn, LossIsScaledChamferAndOverfitsOnePatch) {
    nlohmann::json config = tiny_config();
    config["loss_scale"] = 3.0;
    PuGcn model(PuGcnOptions::from_json(config));
    at::Tensor dense = test::sheet(1, 128, 5);
    at::Tensor input = dense.narrow(1, 0, 32);
    ParamMap& params = model.parameters();
    at::Tensor first = model.loss(input, dense, params);
    EXPECT_NEAR(first.item<double>(),
                3.0 * chamfer_loss(model.upsample(input), dense).item<double>(), 1e-6);

    // Adam, lr 1e-2, 50 steps, written out (β = 0.9, 0.999).
    std::map<std::string, std::pair<at::Tensor, at::Tensor>> moments;
    double last = 0;
    for (int step = 1; step <= 50; ++step) {
        at::Tensor loss = model.loss(input, dense, params);
        last = loss.item<double>();
        auto grads = torch::autograd::grad({loss}, values(params));
        at::NoGradGuard no_grad;
        size_t i = 0;
        for (auto& [name, p] : params) {
            auto& [m, v] = moments[name];
            if (!m.defined()) m = at::zeros_like(p), v = at::zeros_like(p);
            m.mul_(0.9).add_(grads[i], 0.1);
            v.mul_(0.999).addcmul_(grads[i], grads[i], 0.001);
            at::Tensor m_hat = m / (1 - std::pow(0.9, step));
            at::Tensor v_hat = v / (1 - std::pow(0.999, step));
            p.sub_(1e-2 * m_hat / (v_hat.sqrt() + 1e-8));
            ++i;
        }
    }
    EXPECT_LE(last, 0.5 * first.item<double>()) << "first " << first.item<double>();
}

TEST(PuGcn, LossIsTwiceDifferentiableAndMatchesFiniteDifferences) {
    // s(θ) = |∇L(θ)|²; autograd through create_graph gives ∇s = 2 H ∇L, checked against
    // central differences of s along a random direction, in double precision. The step is
    // small because kNN graphs, maxima and nearest neighbours switch discretely.
    PuGcn model(PuGcnOptions::from_json(tiny_config()));
    ParamMap theta = perturbed_double(model.parameters(), 9);
    at::Tensor dense = test::sheet(2, 128, 6, at::kDouble);
    at::Tensor input = test::sheet(2, 32, 7, at::kDouble);
    auto grad_norm = [&](const ParamMap& p, bool create_graph) {
        at::Tensor loss = model.loss(input, dense, p);
        auto grads = torch::autograd::grad({loss}, values(p), {}, create_graph, create_graph);
        at::Tensor s = at::zeros({}, at::kDouble);
        for (const auto& g : grads) s = s + g.pow(2).sum();
        return s;
    };
    at::Tensor s = grad_norm(theta, true);
    auto ds = torch::autograd::grad({s}, values(theta));

    at::Generator gen = at::detail::createCPUGenerator(8);
    ParamMap plus, minus;
    double directional = 0, norm = 0;
    const double eps = 1e-7;
    size_t i = 0;
    for (const auto& [name, p] : theta) {
        at::Tensor v = at::randn(p.sizes(), gen, p.options().requires_grad(false));
        directional += (ds[i++] * v).sum().item<double>();
        norm += v.pow(2).sum().item<double>();
        plus[name] = (p.detach() + eps * v).requires_grad_(true);
        minus[name] = (p.detach() - eps * v).requires_grad_(true);
    }
    double numeric =
        (grad_norm(plus, false).item<double>() - grad_norm(minus, false).item<double>()) /
        (2 * eps);
    EXPECT_GT(std::abs(directional), 1e-8 * std::sqrt(norm));
    EXPECT_NEAR(numeric, directional, 1e-6 * std::abs(directional));
}

TEST(PuGcn, ConfigRoundTripsAndRebuildsTheSameWeights) {
    PuGcn model(PuGcnOptions::from_json(tiny_config()));
    nlohmann::json config = model.config();
    EXPECT_EQ(config["backbone"], "pugcn");
    EXPECT_EQ(config["downsampler"], "fps");
    EXPECT_EQ(config["loss_scale"], 1.0);
    std::unique_ptr<Backbone> again = make_backbone(config);
    EXPECT_EQ(again->config(), config);
    for (const auto& [name, tensor] : model.parameters())
        EXPECT_TRUE(tensor.equal(again->parameters().at(name))) << name;
    nlohmann::json other = config;
    other["seed"] = 4;
    EXPECT_FALSE(make_backbone(other)
                     ->parameters()
                     .at("head.central.weight")
                     .equal(model.parameters().at("head.central.weight")));
}

TEST(PuGcn, InvalidConfigsAreInputErrorsNamingTheField) {
    auto message = [](const nlohmann::json& config) -> std::string {
        try {
            make_backbone(config);
        } catch (const InputError& e) {
            return e.what();
        }
        return "no error";
    };
    EXPECT_NE(message({{"backbone", "pugcn"}, {"chanels", 8}}).find("unknown field 'chanels'"),
              std::string::npos);
    EXPECT_NE(message({{"backbone", "pugcn"}, {"ratio", 0}}).find("'ratio'"), std::string::npos);
    EXPECT_NE(message({{"backbone", "pugcn"}, {"downsampler", "grid"}}).find("grid"),
              std::string::npos);
    EXPECT_NE(message({{"backbone", "pugcn"}, {"loss_scale", -1}}).find("loss_scale"),
              std::string::npos);
    EXPECT_NE(message({{"backbone", "pugcn"}, {"k", 200}}).find("k·dilation"), std::string::npos);
    EXPECT_NE(message({{"backbone", "nope"}}).find("unknown backbone 'nope' (known: "),
              std::string::npos);
    EXPECT_NE(message({{"ratio", 4}}).find("\"backbone\""), std::string::npos);
}

TEST(PuGcn, SmallPatchesUseFewerNeighboursButOnePointIsAnInputError) {
    PuGcn model(PuGcnOptions::from_json(tiny_config()));
    // Fewer points than k·dilation: the graphs shrink to the points present.
    at::Tensor small = model.upsample(test::sheet(1, 8, 1));
    EXPECT_EQ(small.size(1), 8 * model.ratio());
    EXPECT_TRUE(small.isfinite().all().item<bool>());
    EXPECT_THROW(model.upsample(test::sheet(1, 1, 1)), InputError);
    EXPECT_THROW(model.upsample(test::sheet(1, 32, 1, at::kDouble)), InputError);
    EXPECT_THROW(model.upsample(at::zeros({1, 32, 2})), InputError);
}

TEST(Registry, CustomBackbonesCanBeRegistered) {
    register_backbone("pugcn-alias", [](const nlohmann::json& config) {
        nlohmann::json copy = config;
        copy["backbone"] = "pugcn";
        return make_pugcn(copy);
    });
    nlohmann::json config = tiny_config();
    config["backbone"] = "pugcn-alias";
    EXPECT_EQ(make_backbone(config)->name(), "pugcn");
    EXPECT_THROW(register_backbone("pugcn-alias", make_pugcn), InternalError);
}

}  // namespace pumeta
