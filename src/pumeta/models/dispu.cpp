#include "pumeta/models/dispu.h"

#include <ATen/ATen.h>

#include <cmath>
#include <random>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/models/config_fields.h"
#include "pumeta/models/downsample.h"
#include "pumeta/nn/attention.h"
#include "pumeta/nn/batch_norm.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/dense_edge_conv.h"
#include "pumeta/nn/graph.h"
#include "pumeta/nn/init.h"
#include "pumeta/nn/repulsion_loss.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "dispu config";
constexpr const char* kWeightNetNorm = "refine.weight_net.bn";
constexpr const char* kPretrainSteps = "schedule.pretrain_steps";
// TensorFlow batch_norm's epsilon; Dis-PU passes bn_decay 0.95.
constexpr double kNormEps = 1e-3;
constexpr double kNormMomentum = 0.05;
// Attention scores per block of the non-local branch: 64 MB in float32.
constexpr int64_t kMaxAttentionScores = int64_t(1) << 24;
constexpr double kGridRange = 0.2;
constexpr double kOffsetRange = 0.5;
constexpr int64_t kRepulsionNeighbors = 4;
constexpr double kRepulsionH = 1e-3;

// Sets every width from o.preset.
void apply_preset(DisPuOptions& o) {
    if (o.preset == "paper") {
        o.k = 16, o.growth = 24, o.blocks = 4;
        o.expand_channels = 256, o.feature_channels = 128;
        o.regressor_channels = 256, o.regressor_bottleneck = 64;
        o.refiner_channels = 128, o.refiner_out_channels = 256, o.attention_channels = 64;
    } else if (o.preset == "compact") {
        // For 2-core training: a quarter of the paper's parameters and a third of its
        // multiply-adds (the refiner's per-edge MLP and [1,C] convolution scale with its
        // width²). A step measured ~70 % of the paper's: kNN graphs, the per-point mixing
        // matmuls and the Chamfer searches cost the same at every width.
        o.k = 16, o.growth = 12, o.blocks = 4;
        o.expand_channels = 128, o.feature_channels = 64;
        o.regressor_channels = 128, o.regressor_bottleneck = 32;
        o.refiner_channels = 64, o.refiner_out_channels = 128, o.attention_channels = 32;
    } else {
        throw_input_error(kContext, "unknown preset '{}' (expected paper, compact)", o.preset);
    }
}

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("preset", o.preset, field::string);
    visit("ratio", o.ratio, field::positive_int);
    visit("k", o.k, field::positive_int);
    visit("growth", o.growth, field::positive_int);
    visit("blocks", o.blocks, field::positive_int);
    visit("expand_channels", o.expand_channels, field::positive_int);
    visit("feature_channels", o.feature_channels, field::positive_int);
    visit("regressor_channels", o.regressor_channels, field::positive_int);
    visit("regressor_bottleneck", o.regressor_bottleneck, field::positive_int);
    visit("refiner_channels", o.refiner_channels, field::positive_int);
    visit("refiner_out_channels", o.refiner_out_channels, field::positive_int);
    visit("attention_channels", o.attention_channels, field::positive_int);
    visit("patch_size", o.patch_size, field::positive_int);
    visit("downsampler", o.downsampler, field::downsampler);
    visit("repulsion_weight", o.repulsion_weight, field::non_negative_number);
    visit("coarse_residual", o.coarse_residual, field::boolean);
    visit("steps_per_epoch", o.steps_per_epoch, field::positive_int);
    visit("seed", o.seed, field::seed);
}

DenseEdgeConvShape feature_shape(const DisPuOptions& o) {
    return DenseEdgeConvShape{/*first=*/o.growth, o.growth, o.blocks};
}

// TensorFlow's Xavier limit for a kernel counts its window in both fans (a [1,W] kernel
// with Cin inputs and Cout outputs has fans W·Cin and W·Cout); an edge convolution is one
// kernel over [x_i, x_j − x_i]. Rescales a weight drawn by add_xavier_uniform (whose limit
// used fan sum `drawn`) to the limit of fan sum `original`.
void match_original_xavier(ParamMap& params, const std::string& name, int64_t drawn,
                           int64_t original) {
    at::NoGradGuard no_grad;
    params.at(name).mul_(std::sqrt(double(drawn) / double(original)));
}

void add_regressor(ParamMap& params, const std::string& prefix, int64_t in, const DisPuOptions& o,
                   std::mt19937_64& rng) {
    add_linear(params, prefix + ".fc0", in, o.regressor_channels, /*bias=*/true, rng);
    add_linear(params, prefix + ".fc1", o.regressor_channels, o.regressor_bottleneck, true, rng);
    add_linear(params, prefix + ".fc2", o.regressor_bottleneck, 3, true, rng);
}

// Two ReLU layers and a linear one to xyz.
at::Tensor regress(const at::Tensor& x, const ParamMap& params, const std::string& prefix) {
    at::Tensor h = at::relu(conv1x1(x, params, prefix + ".fc0"));
    h = at::relu(conv1x1(h, params, prefix + ".fc1"));
    return conv1x1(h, params, prefix + ".fc2");
}

struct Groups {
    at::Tensor index;     ///< int64 [B,M,k]: the k nearest points, the point itself included
    at::Tensor relative;  ///< [B,M,k,3]: their positions relative to the group's centre
};

// The refiner's groups on the coarse points (the original's knn_query: self included).
// Neighbours are searched with kd-trees on a float32 copy, never through a [M,M] matrix.
Groups group_points(const at::Tensor& xyz, int64_t k) {
    Groups groups;
    {
        at::NoGradGuard no_grad;
        at::Tensor query = xyz.detach().to(at::kFloat).contiguous();
        groups.index = knn(query, query, k).indices;
    }
    groups.relative = gather_neighbors(xyz, groups.index) - xyz.unsqueeze(2);
    return groups;
}

}  // namespace

DisPuOptions DisPuOptions::from_json(const nlohmann::json& config) {
    DisPuOptions options;
    read_backbone_config(
        config, "dispu", [&](auto&& visit) { visit_fields(options, visit); },
        [&] { apply_preset(options); });
    if (options.patch_size < 2)
        throw_input_error(kContext, "'patch_size' must be at least 2, found {}",
                          options.patch_size);
    return options;
}

nlohmann::json DisPuOptions::to_json() const {
    return write_backbone_config("dispu", [&](auto&& visit) { visit_fields(*this, visit); });
}

DisPu::DisPu(const DisPuOptions& options) : options_(options) {
    std::mt19937_64 rng(options.seed);
    const DisPuOptions& o = options_;

    // Feature extractor: PU-GAN's dense EdgeConv with the first layer as wide as the growth.
    const int64_t channels = add_dense_edge_conv(params_, "features", feature_shape(o), rng);

    // Duplicate-up on [features, grid code], then the coarse regressor.
    add_linear(params_, "up.conv1", channels + 2, o.expand_channels, true, rng);
    add_linear(params_, "up.conv2", o.expand_channels, o.feature_channels, true, rng);
    add_regressor(params_, "coarse", o.feature_channels, o, rng);

    // Spatial refiner.
    const int64_t f = o.feature_channels, width = o.refiner_channels;
    const int64_t out = o.refiner_out_channels, attention = o.attention_channels;
    add_linear(params_, "refine.local0", 6 + f, width, true, rng);
    add_linear(params_, "refine.local1", width, width, true, rng);
    add_linear(params_, "refine.weight_net.conv", 3, o.k, true, rng);
    add_batch_norm(params_, buffers_, kWeightNetNorm, o.k);
    add_linear(params_, "refine.after_conv", width * o.k, out, true, rng);
    match_original_xavier(params_, "refine.after_conv.weight", width * o.k + out,
                          width * (o.k + out));
    add_linear(params_, "refine.skip", 6 + f, out, true, rng);
    add_linear(params_, "refine.attention.kv", f, 2 * attention, true, rng);
    add_linear(params_, "refine.attention.query", f, attention, true, rng);
    add_linear(params_, "refine.attention.project", attention, out, true, rng);
    add_linear(params_, "refine.aggregation", out, out, true, rng);
    add_regressor(params_, "fine", out, o, rng);

    buffers_[kPretrainSteps] = at::zeros({}, at::kLong);
}

void DisPu::check_input(const at::Tensor& x, const ParamMap& params, const char* what) const {
    check_batched_points(x, what);
    if (x.size(1) < 2) throw_input_error(what, "needs at least 2 points, found {}", x.size(1));
    const at::Tensor& first = param(params, "features.layer0.weight");
    if (first.scalar_type() != x.scalar_type() || first.device() != x.device())
        throw_input_error(what, "points are {} on {}, parameters {} on {}",
                          std::string(c10::toString(x.scalar_type())), x.device().str(),
                          std::string(c10::toString(first.scalar_type())), first.device().str());
}

at::Tensor DisPu::extract_features(const at::Tensor& x, const ParamMap& params) const {
    return dense_edge_conv(x, params, "features", feature_shape(options_), options_.k);
}

at::Tensor DisPu::duplicate_up(const at::Tensor& features, const ParamMap& params) const {
    const int64_t batch = features.size(0), n = features.size(1), c = features.size(2);
    const int64_t r = options_.ratio;
    // conv1 on [f_i, grid_s] is W_f f_i + W_g grid_s + b: computed per point and per copy,
    // then broadcast to the r·N duplicated points.
    const at::Tensor& w = param(params, "up.conv1.weight");
    at::Tensor per_point =
        conv1x1_weights(features, w.narrow(1, 0, c), param(params, "up.conv1.bias"));
    at::Tensor per_copy =
        conv1x1_weights(dispu_grid(r).to(features.options()), w.narrow(1, c, 2), {});
    // [B,r,N,E]: copy s of point i becomes row s·N + i, the original's tile order.
    at::Tensor h = at::relu(per_point.unsqueeze(1) + per_copy.unsqueeze(1).unsqueeze(0));
    return at::relu(conv1x1(h.reshape({batch, r * n, -1}), params, "up.conv2"));
}

DisPu::Coarse DisPu::generate(const at::Tensor& x, const ParamMap& params) const {
    at::Tensor features = duplicate_up(extract_features(x, params), params);
    at::Tensor points = regress(features, params, "coarse");
    // Row s·N + i is copy s of point i: x repeated r times along the point axis.
    if (options_.coarse_residual) points = points + x.repeat({1, options_.ratio, 1});
    return {features, points};
}

at::Tensor DisPu::refine(const Coarse& coarse, const ParamMap& params,
                         NormStatistics statistics) const {
    const at::Tensor& xyz = coarse.points;
    const at::Tensor& features = coarse.features;
    const int64_t batch = xyz.size(0), m = xyz.size(1), f = features.size(2);
    Groups groups = group_points(xyz, std::min(options_.k, m));

    // Local branch. The first shared MLP sees [xyz_j − xyz_i, xyz_j, f_j] on every edge:
    // W_r (xyz_j − xyz_i) + W_x xyz_j + W_f f_j + b = P_j + C_i with P = (W_r + W_x) xyz +
    // W_f f and C = b − W_r xyz, so its matmuls run per point, not per edge.
    const at::Tensor& w0 = param(params, "refine.local0.weight");
    at::Tensor w_rel = w0.narrow(1, 0, 3);
    at::Tensor per_point = conv1x1_weights(xyz, w_rel + w0.narrow(1, 3, 3), {}) +
                           conv1x1_weights(features, w0.narrow(1, 6, f), {});
    at::Tensor centre = conv1x1_weights(xyz, -w_rel, param(params, "refine.local0.bias"));
    at::Tensor local = (gather_neighbors(per_point, groups.index) + centre.unsqueeze(2)).relu_();
    local = at::relu(conv1x1(local, params, "refine.local1"));  // [B,M,k,R]

    // The weight net on relative positions (Dis-PU's only batch norm) gives each group a
    // k × K mixing of its members; the [1,R] convolution of the original is then a linear
    // map of the mixed [K,R] block (column s·R + c for mixing s, channel c).
    at::Tensor mixing = conv1x1(groups.relative, params, "refine.weight_net.conv");
    mixing = statistics == NormStatistics::kBatch
                 ? batch_norm_batch_stats(mixing, params, kWeightNetNorm, kNormEps)
                 : batch_norm_running_stats(mixing, params, buffers_, kWeightNetNorm, kNormEps);
    at::Tensor mixed = at::matmul(at::relu(mixing).transpose(2, 3), local);  // [B,M,K,R]
    at::Tensor local_out =
        at::relu(conv1x1(mixed.reshape({batch, m, -1}), params, "refine.after_conv"));

    // Skip branch: channel-wise max over the group of [xyz_j − xyz_i, xyz_j, f_j].
    at::Tensor pooled = gather_max(at::cat({xyz, features}, -1), groups.index);
    at::Tensor skip = at::relu(
        conv1x1(at::cat({pooled.narrow(2, 0, 3) - xyz, pooled}, -1), params, "refine.skip"));

    // Non-local branch: every point attends to all M points of its patch.
    at::Tensor kv = conv1x1(features, params, "refine.attention.kv");
    at::Tensor query = conv1x1(features, params, "refine.attention.query");
    const int64_t a = query.size(-1);
    at::Tensor attended = blocked_attention(query, kv.narrow(2, 0, a), kv.narrow(2, a, a),
                                            1.0 / std::sqrt(double(a)), kMaxAttentionScores);
    at::Tensor non_local = at::relu(conv1x1(attended, params, "refine.attention.project"));

    return at::relu(conv1x1(local_out + skip + non_local, params, "refine.aggregation"));
}

DisPuOutput DisPu::forward(const at::Tensor& x, const ParamMap& params,
                           NormStatistics statistics) const {
    check_input(x, params, "dispu input");
    Coarse coarse = generate(x, params);
    at::Tensor raw = regress(refine(coarse, params, statistics), params, "fine");
    at::Tensor offset = 2 * kOffsetRange * at::sigmoid(raw) - kOffsetRange;
    return {coarse.points, coarse.points + offset};
}

at::Tensor DisPu::upsample(const at::Tensor& x, const ParamMap& params) const {
    return forward(x, params, NormStatistics::kRunning).fine;
}

at::Tensor DisPu::loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                       int64_t step) const {
    return sum_of(loss_terms(input, target, params, step));
}

LossTerms DisPu::loss_terms(const at::Tensor& input, const at::Tensor& target,
                            const ParamMap& params, int64_t step) const {
    DisPuOutput out = forward(input, params, NormStatistics::kBatch);
    const double w =
        dispu_fine_weight(std::max(step, pretrain_steps() - 1), options_.steps_per_epoch);
    // Dis-PU's Chamfer distance sums the two directions' means: 2 · chamfer_loss.
    LossTerms terms = {{"coarse", 2000.0 * chamfer_loss(out.coarse, target)},
                       {"fine", w * 2000.0 * chamfer_loss(out.fine, target)}};
    if (options_.repulsion_weight > 0) {
        int64_t neighbors = std::min(kRepulsionNeighbors, out.fine.size(1) - 1);
        terms.emplace_back("repulsion", options_.repulsion_weight *
                                            repulsion_loss(out.fine, neighbors, kRepulsionH));
    }
    return terms;
}

at::Tensor DisPu::downsample(const at::Tensor& dense, uint64_t seed) const {
    check_batched_points(dense, "dispu downsample");
    return downsample_points(dense, dense.size(1) / options_.ratio, options_.downsampler, seed);
}

void DisPu::update_buffers(const at::Tensor& input, const ParamMap& params) {
    at::NoGradGuard no_grad;
    check_input(input, params, "dispu update_buffers");
    at::Tensor xyz = generate(input, params).points;
    Groups groups = group_points(xyz, std::min(options_.k, xyz.size(1)));
    update_running_stats(conv1x1(groups.relative, params, "refine.weight_net.conv"), buffers_,
                         kWeightNetNorm, kNormMomentum);
    buffers_.at(kPretrainSteps) = buffers_.at(kPretrainSteps) + 1;
}

int64_t DisPu::pretrain_steps() const { return param(buffers_, kPretrainSteps).item<int64_t>(); }

double dispu_fine_weight(int64_t step, int64_t steps_per_epoch) {
    if (steps_per_epoch < 1)
        throw_input_error("dispu_fine_weight", "steps_per_epoch must be >= 1, found {}",
                          steps_per_epoch);
    const int64_t epoch = std::max<int64_t>(step, 0) / steps_per_epoch;
    if (epoch <= 10) return 0.01;
    if (epoch <= 20) return 0.1;
    if (epoch <= 30) return 0.5;
    return 1.0;
}

at::Tensor dispu_grid(int64_t ratio) {
    if (ratio < 1) throw_input_error("dispu_grid", "ratio must be >= 1, found {}", ratio);
    int64_t nx = 1;
    for (int64_t i = int64_t(std::sqrt(double(ratio))) + 1; i >= 1; --i) {
        if (ratio % i == 0) {
            nx = i;
            break;
        }
    }
    const int64_t ny = ratio / nx;
    at::Tensor xs = at::linspace(-kGridRange, kGridRange, nx, at::kFloat);
    at::Tensor ys = at::linspace(-kGridRange, kGridRange, ny, at::kFloat);
    return at::stack({xs.repeat({ny}), ys.repeat_interleave(nx)}, 1);
}

std::unique_ptr<Backbone> make_dispu(const nlohmann::json& config) {
    return std::make_unique<DisPu>(DisPuOptions::from_json(config));
}

nlohmann::json dispu_small_config() {
    return {{"backbone", "dispu"},
            {"ratio", 4},
            {"k", 4},
            {"growth", 4},
            {"blocks", 2},
            {"expand_channels", 8},
            {"feature_channels", 8},
            {"regressor_channels", 8},
            {"regressor_bottleneck", 4},
            {"refiner_channels", 4},
            {"refiner_out_channels", 8},
            {"attention_channels", 4},
            {"patch_size", 16},
            {"seed", 3}};
}

}  // namespace pumeta
