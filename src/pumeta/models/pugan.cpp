#include "pumeta/models/pugan.h"

#include <ATen/ATen.h>

#include <cmath>
#include <random>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/config_fields.h"
#include "pumeta/models/dispu.h"
#include "pumeta/models/downsample.h"
#include "pumeta/nn/attention.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/dense_edge_conv.h"
#include "pumeta/nn/emd_loss.h"
#include "pumeta/nn/init.h"
#include "pumeta/nn/repulsion_loss.h"
#include "pumeta/nn/uniform_loss.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "pugan config";
// Attention scores per block without gradients: 64 MB in float32.
constexpr int64_t kMaxAttentionScores = int64_t(1) << 24;
constexpr int64_t kRepulsionNeighbors = 4;
constexpr double kRepulsionH = 1e-3;
// The last layer (fc_layer2) has weight decay 0 in the original.
constexpr const char* kLastLayer = "fc2.";
constexpr const char* kGamma = ".gamma";

// Sets every width from o.preset.
void apply_preset(PuGanOptions& o) {
    if (o.preset == "paper") {
        o.k = 16, o.first = 24, o.growth = 24, o.blocks = 4;
        o.feature_channels = 128, o.up_channels = 256, o.down_channels = 256;
        o.head_channels = 64, o.discriminator_channels = 32;
    } else if (o.preset == "compact") {
        // For quick 2-core runs: half of every width (a quarter of the parameters); the
        // attention over r'N points, most of the cost, shrinks with the feature width.
        o.k = 16, o.first = 12, o.growth = 12, o.blocks = 4;
        o.feature_channels = 64, o.up_channels = 128, o.down_channels = 128;
        o.head_channels = 32, o.discriminator_channels = 16;
    } else {
        throw_input_error(kContext, "unknown preset '{}' (expected paper, compact)", o.preset);
    }
}

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("preset", o.preset, field::string);
    visit("ratio", o.ratio, field::positive_int);
    visit("extra_copies", o.extra_copies, field::int_range(0, 64));
    visit("k", o.k, field::positive_int);
    visit("first", o.first, field::positive_int);
    visit("growth", o.growth, field::positive_int);
    visit("blocks", o.blocks, field::positive_int);
    visit("feature_channels", o.feature_channels, field::positive_int);
    visit("up_channels", o.up_channels, field::positive_int);
    visit("down_channels", o.down_channels, field::positive_int);
    visit("head_channels", o.head_channels, field::positive_int);
    visit("discriminator_channels", o.discriminator_channels, field::positive_int);
    visit("patch_size", o.patch_size, field::positive_int);
    visit("downsampler", o.downsampler, field::downsampler);
    visit("emd_weight", o.emd_weight, field::non_negative_number);
    visit("uniform_weight", o.uniform_weight, field::non_negative_number);
    visit("repulsion_weight", o.repulsion_weight, field::non_negative_number);
    visit("regularization", o.regularization, field::non_negative_number);
    visit("adversarial_weight", o.adversarial_weight, field::non_negative_number);
    visit("discriminator_lr", o.discriminator_lr, field::positive_number);
    visit("emd_matching", o.emd_matching, field::one_of({"auction", "approximate"}));
    visit("seed", o.seed, field::seed);
}

DenseEdgeConvShape feature_shape(const PuGanOptions& o) {
    return DenseEdgeConvShape{o.first, o.growth, o.blocks};
}

EmdOptions emd_options(const PuGanOptions& o) {
    EmdOptions options;
    options.matching =
        o.emd_matching == "auction" ? EmdMatching::kAuction : EmdMatching::kApproximate;
    return options;
}

// PU-GAN's attention_unit on x [B,M,C]: f, g = ReLU(conv C -> C/4), h = ReLU(conv C -> C),
// out = γ · softmax_j(g_i · f_j) h + x, γ a learned scalar that starts at 0.
void add_attention(ParamMap& params, const std::string& prefix, int64_t channels,
                   std::mt19937_64& rng) {
    add_linear(params, prefix + ".f", channels, channels / 4, true, rng);
    add_linear(params, prefix + ".g", channels, channels / 4, true, rng);
    add_linear(params, prefix + ".h", channels, channels, true, rng);
    add_zeros(params, prefix + kGamma, 1);
}

at::Tensor attention(const at::Tensor& x, const ParamMap& params, const std::string& prefix) {
    at::Tensor f = at::relu(conv1x1(x, params, prefix + ".f"));
    at::Tensor g = at::relu(conv1x1(x, params, prefix + ".g"));
    at::Tensor h = at::relu(conv1x1(x, params, prefix + ".h"));
    at::Tensor attended = blocked_attention(g, f, h, 1.0, kMaxAttentionScores);
    return param(params, prefix + kGamma) * attended + x;
}

void add_up_block(ParamMap& params, const std::string& prefix, const PuGanOptions& o,
                  std::mt19937_64& rng) {
    add_attention(params, prefix + ".attention", o.feature_channels + 2, rng);
    add_linear(params, prefix + ".conv1", o.feature_channels + 2, o.up_channels, true, rng);
    add_linear(params, prefix + ".conv2", o.up_channels, o.feature_channels, true, rng);
}

}  // namespace

PuGanOptions PuGanOptions::from_json(const nlohmann::json& config) {
    PuGanOptions options;
    read_backbone_config(
        config, "pugan", [&](auto&& visit) { visit_fields(options, visit); },
        [&] { apply_preset(options); });
    if (options.patch_size < 2)
        throw_input_error(kContext, "'patch_size' must be at least 2, found {}",
                          options.patch_size);
    if (options.feature_channels + 2 < 4)
        throw_input_error(kContext, "'feature_channels' must be at least 2, found {}",
                          options.feature_channels);
    return options;
}

nlohmann::json PuGanOptions::to_json() const {
    return write_backbone_config("pugan", [&](auto&& visit) { visit_fields(*this, visit); });
}

PuGan::PuGan(const PuGanOptions& options) : options_(options) {
    std::mt19937_64 rng(options.seed);
    const PuGanOptions& o = options_;
    const int64_t features = add_dense_edge_conv(params_, "features", feature_shape(o), rng);
    add_linear(params_, "conv0", features, o.feature_channels, true, rng);
    add_up_block(params_, "up0", o, rng);
    // The down block's first layer is a [1, r'] convolution over the r' copies of a point:
    // one linear map of their features side by side (column c·C + channel).
    const int64_t side_by_side = o.copies() * o.feature_channels;
    add_linear(params_, "down0.conv1", side_by_side, o.down_channels, true, rng);
    {
        // TensorFlow's Xavier limit counts the window in both fans: sqrt(6 / (r'·C + r'·D)),
        // where add_linear drew with sqrt(6 / (r'·C + D)).
        at::NoGradGuard no_grad;
        params_.at("down0.conv1.weight")
            .mul_(std::sqrt(double(side_by_side + o.down_channels) /
                            double(side_by_side + o.copies() * o.down_channels)));
    }
    add_linear(params_, "down0.conv2", o.down_channels, o.feature_channels, true, rng);
    add_up_block(params_, "up1", o, rng);
    add_linear(params_, "fc1", o.feature_channels, o.head_channels, true, rng);
    add_linear(params_, "fc2", o.head_channels, 3, true, rng);
}

void PuGan::check_input(const at::Tensor& x, const ParamMap& params, const char* what) const {
    check_batched_points(x, what);
    if (x.size(1) < 2) throw_input_error(what, "needs at least 2 points, found {}", x.size(1));
    const at::Tensor& first = param(params, "features.layer0.weight");
    if (first.scalar_type() != x.scalar_type() || first.device() != x.device())
        throw_input_error(what, "points are {} on {}, parameters {} on {}",
                          std::string(c10::toString(x.scalar_type())), x.device().str(),
                          std::string(c10::toString(first.scalar_type())), first.device().str());
}

at::Tensor pugan_tile_with_grid(const at::Tensor& features, int64_t copies) {
    if (features.dim() != 3 || copies < 1)
        throw_input_error("pugan_tile_with_grid",
                          "expected features [B,N,C] and copies >= 1, "
                          "found {} and {}",
                          shape_string(features), copies);
    const int64_t batch = features.size(0), n = features.size(1);
    at::Tensor grid = dispu_grid(copies).to(features.options()).repeat_interleave(n, 0);
    return at::cat({features.repeat({1, copies, 1}), grid.unsqueeze(0).expand({batch, -1, 2})}, -1);
}

// up_block: [B,N,C] -> [B,r'N,C], copy-major.
at::Tensor PuGan::expand(const at::Tensor& features, const ParamMap& params,
                         const std::string& prefix) const {
    at::Tensor h =
        attention(pugan_tile_with_grid(features, options_.copies()), params, prefix + ".attention");
    h = at::relu(conv1x1(h, params, prefix + ".conv1"));
    return at::relu(conv1x1(h, params, prefix + ".conv2"));
}

// down_block: [B,r'N,C] -> [B,N,C], the r' copies of each point side by side.
at::Tensor PuGan::contract(const at::Tensor& features, const ParamMap& params,
                           const std::string& prefix) const {
    const int64_t batch = features.size(0), copies = options_.copies();
    const int64_t n = features.size(1) / copies, c = features.size(2);
    at::Tensor grouped =
        features.reshape({batch, copies, n, c}).transpose(1, 2).reshape({batch, n, copies * c});
    at::Tensor h = at::relu(conv1x1(grouped, params, prefix + ".conv1"));
    return at::relu(conv1x1(h, params, prefix + ".conv2"));
}

at::Tensor PuGan::generate(const at::Tensor& x, const ParamMap& params) const {
    check_input(x, params, "pugan input");
    at::Tensor features =
        dense_edge_conv(x, params, "features", feature_shape(options_), options_.k);
    // up_projection_unit: H2 = H0 + up(down(H0) − L).
    at::Tensor low = at::relu(conv1x1(features, params, "conv0"));
    at::Tensor high = expand(low, params, "up0");
    at::Tensor error = contract(high, params, "down0") - low;
    high = high + expand(error, params, "up1");
    return conv1x1(at::relu(conv1x1(high, params, "fc1")), params, "fc2");
}

at::Tensor PuGan::upsample(const at::Tensor& x, const ParamMap& params) const {
    at::Tensor dense = generate(x, params);
    const int64_t batch = dense.size(0), m = options_.ratio * x.size(1);
    at::Tensor picked;
    {
        at::NoGradGuard no_grad;
        picked = farthest_point_sampling_batched(dense.detach().contiguous(), m);
    }
    return dense.gather(1, picked.unsqueeze(2).expand({batch, m, 3}));
}

LossTerms PuGan::reconstruction_terms(const at::Tensor& pred, const at::Tensor& target) const {
    if (pred.sizes() != target.sizes())
        throw_input_error("pugan loss", "target {} must have the shape of the output {}",
                          shape_string(target), shape_string(pred));
    LossTerms terms = {{"emd", options_.emd_weight * emd_loss(pred, target, emd_options(options_))},
                       {"uniform", options_.uniform_weight * uniform_loss(pred)}};
    const int64_t neighbors = std::min(kRepulsionNeighbors, pred.size(1) - 1);
    terms.emplace_back("repulsion",
                       options_.repulsion_weight * repulsion_loss(pred, neighbors, kRepulsionH));
    return terms;
}

at::Tensor PuGan::loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                       int64_t step) const {
    return sum_of(loss_terms(input, target, params, step));
}

LossTerms PuGan::loss_terms(const at::Tensor& input, const at::Tensor& target,
                            const ParamMap& params, int64_t) const {
    return reconstruction_terms(upsample(input, params), target);
}

at::Tensor PuGan::downsample(const at::Tensor& dense, uint64_t seed) const {
    check_batched_points(dense, "pugan downsample");
    return downsample_points(dense, dense.size(1) / options_.ratio, options_.downsampler, seed);
}

ParamMap PuGan::make_auxiliary(uint64_t seed) const {
    // Without the adversarial term no discriminator is trained (reconstruction-only runs).
    if (options_.adversarial_weight == 0) return {};
    std::mt19937_64 rng(seed);
    const int64_t s = options_.discriminator_channels;
    ParamMap d;
    add_linear(d, "d.conv0", 3, s, true, rng);
    add_linear(d, "d.conv1", s, 2 * s, true, rng);
    add_attention(d, "d.attention", 4 * s, rng);
    add_linear(d, "d.conv2", 4 * s, 4 * s, true, rng);
    add_linear(d, "d.conv3", 4 * s, 8 * s, true, rng);
    add_linear(d, "d.fc0", 8 * s, 8 * s, true, rng);
    add_linear(d, "d.fc1", 8 * s, 1, true, rng);
    return d;
}

at::Tensor pugan_discriminate(const at::Tensor& cloud, const ParamMap& d) {
    check_batched_points(cloud, "pugan discriminator input");
    at::Tensor h = conv1x1(at::relu(conv1x1(cloud, d, "d.conv0")), d, "d.conv1");
    at::Tensor global = std::get<0>(h.max(1, /*keepdim=*/true)).expand_as(h);
    h = attention(at::cat({h, global}, -1), d, "d.attention");
    h = conv1x1(at::relu(conv1x1(h, d, "d.conv2")), d, "d.conv3");
    at::Tensor pooled = std::get<0>(h.max(1));
    return conv1x1(at::relu(conv1x1(pooled, d, "d.fc0")), d, "d.fc1").squeeze(-1);
}

LossTerms PuGan::training_terms(const at::Tensor& input, const at::Tensor& target,
                                const ParamMap& params, const ParamMap& auxiliary, int64_t) const {
    at::Tensor pred = upsample(input, params);
    // Without the adversarial term there is no discriminator to feed (make_auxiliary).
    const bool adversarial = options_.adversarial_weight > 0;
    if (adversarial) {
        // The first output on this batch is kept: after several generator updates on it the
        // discriminator still sees the output from before them all.
        std::lock_guard<std::mutex> lock(last_mutex_);
        if (!last_input_.defined() || !last_input_.is_same(input)) {
            last_input_ = input;
            last_output_ = pred.detach();
        }
    }
    LossTerms terms = reconstruction_terms(pred, target);
    at::Tensor squares;
    for (const auto& [name, p] : params) {
        if (name.rfind(kLastLayer, 0) == 0 || name.find(kGamma) != std::string::npos) continue;
        at::Tensor sq = p.pow(2).sum();
        squares = squares.defined() ? squares + sq : sq;
    }
    terms.emplace_back("regularization", 0.5 * options_.regularization * squares);
    if (adversarial)
        terms.emplace_back(
            "adversarial",
            options_.adversarial_weight * (pugan_discriminate(pred, auxiliary) - 1).pow(2).mean());
    return terms;
}

at::Tensor PuGan::auxiliary_loss(const at::Tensor& input, const at::Tensor& target,
                                 const ParamMap& params, const ParamMap& auxiliary, int64_t) const {
    at::Tensor fake;
    {
        std::lock_guard<std::mutex> lock(last_mutex_);
        if (last_input_.defined() && last_input_.is_same(input)) fake = last_output_;
        last_input_ = last_output_ = at::Tensor();
    }
    if (!fake.defined()) {
        at::NoGradGuard no_grad;
        fake = upsample(input, params);
    }
    return (pugan_discriminate(target, auxiliary) - 1).pow(2).mean() +
           pugan_discriminate(fake, auxiliary).pow(2).mean();
}

std::unique_ptr<Backbone> make_pugan(const nlohmann::json& config) {
    return std::make_unique<PuGan>(PuGanOptions::from_json(config));
}

nlohmann::json pugan_small_config() {
    return {{"backbone", "pugan"},
            {"ratio", 4},
            {"k", 4},
            {"first", 4},
            {"growth", 4},
            {"blocks", 2},
            {"feature_channels", 6},
            {"up_channels", 8},
            {"down_channels", 8},
            {"head_channels", 4},
            {"discriminator_channels", 4},
            {"patch_size", 16},
            {"seed", 3}};
}

}  // namespace pumeta
