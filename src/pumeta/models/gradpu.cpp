#include "pumeta/models/gradpu.h"

#include <ATen/ATen.h>
#include <torch/csrc/autograd/autograd.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/core/threads.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/inference/upsample.h"
#include "pumeta/models/config_fields.h"
#include "pumeta/models/downsample.h"
#include "pumeta/models/patch_frame.h"
#include "pumeta/nn/batch_norm.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/init.h"
#include "pumeta/nn/point_conv.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "gradpu config";
// PyTorch's BatchNorm defaults, which the original keeps.
constexpr double kNormEps = 1e-5;
constexpr double kNormMomentum = 0.1;
// Refinement patches upsampled per batch (bounds memory: about 25 MB per patch of 1,024).
constexpr int64_t kRefineBatch = 8;

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("ratio", o.ratio, field::int_range(2, 64));
    visit("k", o.k, field::int_range(2, 1 << 10));
    visit("blocks", o.blocks, field::positive_int);
    visit("layers", o.layers, field::positive_int);
    visit("channels", o.channels, field::int_range(2, 1 << 12));
    visit("growth", o.growth, field::positive_int);
    visit("patch_size", o.patch_size, field::int_range(3, 1 << 20));
    visit("refine_patch_size", o.refine_patch_size, field::int_range(3, 1 << 20));
    visit("patch_rate", o.patch_rate, field::positive_int);
    visit("steps", o.steps, field::int_range(0, 1000));
    visit("step_size", o.step_size, field::non_negative_number);
    visit("max_distance", o.max_distance, field::positive_number);
    visit("step_rule", o.step_rule, field::one_of({"cloud_mean", "per_point"}));
    visit("query_sigma", o.query_sigma, field::non_negative_number);
    visit("downsampler", o.downsampler, field::downsampler);
    visit("seed", o.seed, field::seed);
}

std::string layer_prefix(int64_t block, int64_t layer) {
    return "extractor.block" + std::to_string(block) + ".layer" + std::to_string(layer);
}
std::string transition_prefix(int64_t block) {
    return "extractor.block" + std::to_string(block) + ".transition";
}
std::string mlp_prefix(int64_t i) { return "regressor.mlp" + std::to_string(i); }

/// out[b,q,j] = x[b, idx[b,q,j]]: x [B,N,C], idx int64 [B,Q,k] -> [B,Q,k,C]; differentiable
/// (twice) with respect to x.
at::Tensor gather_rows(const at::Tensor& x, const at::Tensor& idx) {
    const int64_t batch = x.size(0), n = x.size(1), channels = x.size(2);
    at::Tensor offsets = (at::arange(batch, idx.options()) * n).view({batch, 1, 1});
    at::Tensor rows = x.reshape({batch * n, channels});
    return rows.index_select(0, (idx + offsets).flatten())
        .view({batch, idx.size(1), idx.size(2), channels});
}

}  // namespace

GradPuOptions GradPuOptions::from_json(const nlohmann::json& config) {
    GradPuOptions options;
    read_backbone_config(config, "gradpu", [&](auto&& visit) { visit_fields(options, visit); });
    if (options.channels / 2 < 1)
        throw_input_error(kContext, "'channels' must be at least 2, found {}", options.channels);
    return options;
}

nlohmann::json GradPuOptions::to_json() const {
    return write_backbone_config("gradpu", [&](auto&& visit) { visit_fields(*this, visit); });
}

struct GradPu::Features {
    at::Tensor points;              ///< [B,M,3], the patch the features describe
    std::vector<at::Tensor> local;  ///< blocks + 1 maps [B,M,C]
    at::Tensor global;              ///< [B,C]
};

GradPu::GradPu(const GradPuOptions& options) : options_(options) {
    std::mt19937_64 rng(options.seed);
    const int64_t c = options.channels, g = options.growth;
    // Every convolution has a bias and, in the extractor, a batch norm after it.
    auto conv_bn = [&](const std::string& prefix, int64_t in, int64_t out) {
        add_linear(params_, prefix, in, out, /*bias=*/true, rng);
        add_batch_norm(params_, buffers_, prefix + ".bn", out);
    };
    conv_bn("extractor.init", 3, c);
    for (int64_t b = 0; b < options.blocks; ++b) {
        for (int64_t l = 0; l < options.layers; ++l) {
            const std::string prefix = layer_prefix(b, l);
            conv_bn(prefix + ".bottle", c + l * g, g);
            conv_bn(prefix + ".delta", 3, g);
            conv_bn(prefix + ".feats", g, g);
            conv_bn(prefix + ".post", g, g);
        }
        conv_bn(transition_prefix(b), c + options.layers * g, c);
    }
    const std::vector<int64_t> widths = {3 + c * (options.blocks + 2), 2 * c, c, c / 2, 1};
    for (size_t i = 0; i + 1 < widths.size(); ++i)
        add_linear(params_, mlp_prefix(static_cast<int64_t>(i)), widths[i], widths[i + 1],
                   /*bias=*/true, rng);
    // The last layer starts with non-negative weights on its (ReLU, so non-negative) inputs:
    // the predicted distance then starts positive wherever any unit before it is live. With
    // PyTorch's signed initialisation the final ReLU is often dead for every query at small
    // widths, and neither training nor adaptation can start (imported weights replace this).
    const std::string last = mlp_prefix(static_cast<int64_t>(widths.size()) - 2);
    params_.at(last + ".weight") = params_.at(last + ".weight").detach().abs().requires_grad_(true);
    params_.at(last + ".bias") = params_.at(last + ".bias").detach().abs().requires_grad_(true);
}

nlohmann::json GradPu::config_for_ratio(int64_t ratio) const {
    if (ratio < 2 || ratio > 64) return nullptr;
    // A power of the weights' ratio runs as that ratio repeated, each pass renormalised (the
    // original's default, --double_4X: 16x as 4x twice).
    for (int64_t power = options_.ratio * options_.ratio; power <= ratio; power *= options_.ratio)
        if (power == ratio) return nullptr;
    GradPuOptions options = options_;
    options.ratio = ratio;
    return options.to_json();
}

GradPu::Features GradPu::extract(const at::Tensor& p, const ParamMap& params, bool batch_statistics,
                                 BatchMomentsMap* statistics) const {
    // conv -> batch norm -> ReLU; the input of each batch norm is kept in `statistics` when
    // asked for (update_buffers).
    auto unit = [&](const at::Tensor& x, const std::string& prefix) {
        at::Tensor y = conv1x1(x, params, prefix);
        if (statistics) (*statistics)[prefix + ".bn"] = batch_moments(y);
        y = batch_statistics
                ? batch_norm_batch_stats(y, params, prefix + ".bn", kNormEps)
                : batch_norm_running_stats(y, params, buffers_, prefix + ".bn", kNormEps);
        return at::relu(y);
    };
    Features out;
    out.points = p;
    const at::Tensor idx = knn_indices(p, p, std::min(options_.k, p.size(1)));  // [B,M,k]
    // Train mode and the running statistics' update run each Point3DConv from small moments
    // of its edges (nn/point_conv.h); with running statistics the edges are composed directly.
    PointConvGraph graph;
    at::Tensor delta;
    if (batch_statistics)
        graph = point_conv_graph(p, idx);
    else
        delta = gather_rows(p, idx) - p.unsqueeze(2);  // [B,M,k,3]
    at::Tensor features = unit(p, "extractor.init");
    out.local.push_back(features);
    for (int64_t b = 0; b < options_.blocks; ++b) {
        at::Tensor dense = features;
        for (int64_t l = 0; l < options_.layers; ++l) {
            const std::string prefix = layer_prefix(b, l);
            // Point3DConv: the 1x1 convolution of the neighbours' features runs per point
            // before the gather (it is linear).
            const at::Tensor feats =
                conv1x1(unit(dense, prefix + ".bottle"), params, prefix + ".feats");
            at::Tensor edges;
            if (batch_statistics) {
                edges = point_conv_batch_stats(feats, graph, params, prefix, kNormEps, statistics);
            } else {
                // With running statistics its batch norm is one affine map per channel: it
                // and the ReLU run per point too.
                const at::Tensor neighbours =
                    gather_rows(at::relu(batch_norm_running_stats(feats, params, buffers_,
                                                                  prefix + ".feats.bn", kNormEps)),
                                idx);
                edges = unit(unit(delta, prefix + ".delta") * neighbours, prefix + ".post").sum(2);
            }
            dense = at::cat({dense, edges}, -1);
        }
        features = unit(dense, transition_prefix(b));
        out.local.push_back(features);
    }
    out.global = std::get<0>(features.max(1));
    return out;
}

at::Tensor GradPu::regress(const Features& features, const at::Tensor& q,
                           const ParamMap& params) const {
    const at::Tensor& p = features.points;
    const int64_t batch = q.size(0), queries = q.size(1);
    // Inverse-distance weights of the 3 nearest patch points; the norm's gradient is 0 where
    // a query sits on a patch point (the queries start there), as PyTorch's.
    const at::Tensor idx = knn_indices(p, q, std::min<int64_t>(3, p.size(1)));  // [B,Q,3]
    at::Tensor distance = at::linalg_vector_norm(gather_rows(p, idx) - q.unsqueeze(2), 2, {-1});
    at::Tensor weights = (distance + 1e-8).reciprocal();
    weights = (weights / weights.sum(-1, /*keepdim=*/true)).unsqueeze(-1);  // [B,Q,3,1]
    std::vector<at::Tensor> channels = {q};
    for (const at::Tensor& map : features.local)
        channels.push_back((gather_rows(map, idx) * weights).sum(2));
    channels.push_back(features.global.unsqueeze(1).expand({batch, queries, -1}));
    at::Tensor h = at::cat(channels, -1);
    for (int64_t i = 0; i < 4; ++i) h = at::relu(conv1x1(h, params, mlp_prefix(i)));
    return h.squeeze(-1);
}

at::Tensor GradPu::distance(const at::Tensor& p, const at::Tensor& q, const ParamMap& params,
                            bool batch_statistics) const {
    check_batched_points(p, "gradpu patch");
    check_batched_points(q, "gradpu queries");
    return regress(extract(p, params, batch_statistics), q, params);
}

at::Tensor GradPu::refine(const at::Tensor& p, const ParamMap& params, double point_step) const {
    // The weights are constants here: only the points move.
    ParamMap frozen;
    for (const auto& [name, tensor] : params) frozen.emplace(name, tensor.detach());
    Features features;
    {
        at::NoGradGuard no_grad;
        features = extract(p, frozen, /*batch_statistics=*/false);
    }
    at::Tensor x = p.detach().clone();
    for (int64_t step = 0; step < options_.steps; ++step) {
        at::AutoGradMode grad_mode(true);
        at::Tensor query = x.detach().requires_grad_(true);
        at::Tensor d = regress(features, query, frozen).clamp_max(options_.max_distance);
        at::Tensor gradient = torch::autograd::grad({d.sum()}, {query})[0];
        x = query.detach() - point_step * gradient;
    }
    return x;
}

at::Tensor midpoint_interpolate(const at::Tensor& x, int64_t ratio) {
    check_batched_points(x, "midpoint_interpolate input");
    at::NoGradGuard no_grad;
    const int64_t batch = x.size(0), n = x.size(1);
    const int64_t k = std::min(2 * ratio, n);
    const at::Tensor idx = knn_indices(x, x, k);
    at::Tensor mids = ((gather_rows(x, idx) + x.unsqueeze(2)) / 2).reshape({batch, n * k, 3});
    // Fewer midpoints than outputs only for patches of fewer than `ratio` points: FPS then
    // repeats some.
    if (n * k < ratio * n) mids = mids.repeat({1, (ratio + k - 1) / k, 1});
    const at::Tensor picks = farthest_point_sampling_batched(mids.contiguous(), ratio * n);
    return at::gather(mids, 1, picks.unsqueeze(-1).expand({-1, -1, 3}));
}

at::Tensor GradPu::upsample(const at::Tensor& x, const ParamMap& params) const {
    check_batched_points(x, "gradpu input");
    if (x.size(1) < 2)
        throw_input_error("gradpu input", "needs at least 2 points per patch, found {}", x.size(1));
    const int64_t m = options_.ratio * x.size(1);
    if (m > options_.refine_patch_size) {
        // A patch larger than a refinement patch is a cloud: the whole pipeline per patch.
        std::vector<at::Tensor> outputs;
        for (int64_t b = 0; b < x.size(0); ++b) {
            at::Tensor candidates = cloud_candidates(x[b], params, options_.seed);
            outputs.push_back(candidates.index_select(0, farthest_point_sampling(candidates, m)));
        }
        return at::stack(outputs, 0);
    }
    const at::Tensor interpolated = midpoint_interpolate(x, options_.ratio);
    const PatchFrame frame(interpolated);
    const double point_step =
        options_.step_rule == "cloud_mean" ? options_.step_size / double(m) : options_.step_size;
    return frame.invert(refine(frame.apply(interpolated), params, point_step));
}

at::Tensor GradPu::cloud_candidates(const at::Tensor& cloud, const ParamMap& params,
                                    uint64_t /*seed*/) const {
    check_points(cloud, "gradpu input", 2);
    at::NoGradGuard no_grad;
    const PatchFrame frame(cloud.unsqueeze(0));
    const at::Tensor unit = frame.apply(cloud.unsqueeze(0))[0].contiguous();
    at::Tensor interpolated =
        midpoint_upsample(unit.to(at::kFloat), options_.ratio).to(cloud.scalar_type());
    const int64_t m = interpolated.size(0);
    const int64_t patch_points = std::min(options_.refine_patch_size, m);
    const int64_t count =
        std::max<int64_t>(1, static_cast<int64_t>(double(m) / double(options_.refine_patch_size) *
                                                  double(options_.patch_rate)));
    const at::Tensor search = interpolated.to(at::kFloat).contiguous();
    const at::Tensor seeds = search.index_select(0, farthest_point_sampling(search, count));
    const at::Tensor members = knn(search, seeds, patch_points).indices;  // [P, patch_points]
    at::Tensor patches = interpolated.index_select(0, members.flatten()).view({count, -1, 3});
    const double point_step = options_.step_rule == "cloud_mean"
                                  ? options_.step_size / double(count * patch_points)
                                  : options_.step_size;
    // Each patch's displacements, brought back to the cloud's frame and added to its points
    // there: a point that no patch moves stays bit-identical (so the final selection sees one
    // position, not the normalisation round trips' rounding of it).
    std::vector<at::Tensor> displacements;
    for (int64_t start = 0; start < count; start += kRefineBatch) {
        const at::Tensor batch = patches.slice(0, start, std::min(count, start + kRefineBatch));
        const PatchFrame patch_frame(batch);
        const at::Tensor local = patch_frame.apply(batch);
        displacements.push_back((refine(local, params, point_step) - local) * patch_frame.radius);
    }
    const at::Tensor origins =
        frame.invert(interpolated.unsqueeze(0))[0].index_select(0, members.flatten());
    return origins + at::cat(displacements).reshape({-1, 3}) * frame.radius[0];
}

at::Tensor GradPu::loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                        int64_t step) const {
    check_batched_points(input, "gradpu loss input");
    check_batched_points(target, "gradpu loss target");
    const at::Tensor interpolated = midpoint_interpolate(input.detach(), options_.ratio);
    at::Generator generator = at::detail::createCPUGenerator(options_.seed * 0x9E3779B97F4A7C15ull +
                                                             static_cast<uint64_t>(step));
    at::Tensor noise = at::randn(interpolated.sizes(), generator,
                                 at::TensorOptions().dtype(interpolated.scalar_type()));
    const at::Tensor queries =
        interpolated + options_.query_sigma * noise.to(interpolated.device());
    // The true distance: to the nearest target point.
    const at::Tensor closest = gather_rows(target.detach(), knn_indices(target, queries, 1));
    const at::Tensor truth = at::linalg_vector_norm(closest.squeeze(2) - queries, 2, {-1});
    const at::Tensor predicted = distance(interpolated, queries, params, /*batch_statistics=*/true);
    return (predicted - truth).abs().sum(1).mean();
}

at::Tensor GradPu::downsample(const at::Tensor& dense, uint64_t seed) const {
    check_batched_points(dense, "gradpu downsample");
    return downsample_points(dense, std::max<int64_t>(2, dense.size(1) / options_.ratio),
                             options_.downsampler, seed);
}

void GradPu::update_buffers(const at::Tensor& input, const ParamMap& params) {
    at::NoGradGuard no_grad;
    check_batched_points(input, "gradpu update_buffers");
    BatchMomentsMap statistics;
    extract(midpoint_interpolate(input, options_.ratio), params, /*batch_statistics=*/true,
            &statistics);
    for (const auto& [prefix, moments] : statistics)
        update_running_stats(moments, buffers_, prefix, kNormMomentum);
}

std::unique_ptr<Backbone> make_gradpu(const nlohmann::json& config) {
    return std::make_unique<GradPu>(GradPuOptions::from_json(config));
}

nlohmann::json gradpu_small_config() {
    return {{"backbone", "gradpu"},
            {"ratio", 4},
            {"k", 4},
            {"blocks", 1},
            {"layers", 2},
            {"channels", 4},
            {"growth", 4},
            {"patch_size", 16},
            {"refine_patch_size", 64},
            {"steps", 3},
            {"step_size", 0.05},
            {"step_rule", "per_point"},
            {"downsampler", "random"},
            {"seed", 3}};
}

}  // namespace pumeta
