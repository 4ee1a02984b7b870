#include "pumeta/models/pugaussian.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <random>
#include <string_view>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/hash.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/config_fields.h"
#include "pumeta/models/downsample.h"
#include "pumeta/models/patch_frame.h"
#include "pumeta/nn/batch_norm.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/graph.h"
#include "pumeta/nn/init.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "pugaussian config";
// PyTorch's BatchNorm defaults, which the original keeps.
constexpr double kNormEps = 1e-5;
constexpr double kNormMomentum = 0.1;
// The scale head's Softplus(beta = 100) (PyTorch's threshold: linear above beta·x = 20).
constexpr double kSoftplusBeta = 100;
constexpr double kSoftplusThreshold = 20;
// The heads' LeakyReLU slope.
constexpr double kLeakySlope = 0.1;
// Patches through the network at once in the whole-cloud test (bounds memory: the refinement's
// attention holds about 25 MB per 256-point patch with the original's widths).
constexpr int64_t kPatchBatch = 8;
// Points per chunk of the point transformer's per-edge work at inference: 16 edges each, about
// 4 MB for the refinement's 256-channel attention layer, so that it stays in the cache.
constexpr int64_t kTransformerChunk = 256;

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("ratio", o.ratio, field::int_range(2, 64));
    visit("samples", o.samples, field::int_range(2, 64));
    visit("k", o.k, field::int_range(1, 1 << 10));
    visit("gaussian_channels", o.gaussian_channels, field::int_range(2, 1 << 12));
    visit("gaussian_attention", o.gaussian_attention, field::int_range(1, 1 << 12));
    visit("refine_channels", o.refine_channels, field::int_range(4, 1 << 12));
    visit("refine_attention", o.refine_attention, field::int_range(1, 1 << 12));
    visit("position_channels", o.position_channels, field::int_range(1, 1 << 12));
    visit("refine_passes", o.refine_passes, field::int_range(0, 16));
    visit("truncation", o.truncation, field::positive_number);
    visit("patch_size", o.patch_size, field::int_range(2, 1 << 20));
    visit("patch_rate", o.patch_rate, field::positive_int);
    visit("downsampler", o.downsampler, field::downsampler);
    visit("seed", o.seed, field::seed);
}

/// conv -> ReLU -> conv, the original's two-layer MLP_CONV (`prefix`.0, `prefix`.1).
at::Tensor mlp(const at::Tensor& x, const ParamMap& params, const std::string& prefix) {
    return conv1x1(at::relu(conv1x1(x, params, prefix + ".0")), params, prefix + ".1");
}

/// conv -> LeakyReLU(0.1) -> conv, the Gaussian heads.
at::Tensor head(const at::Tensor& x, const ParamMap& params, const std::string& prefix) {
    return conv1x1(at::leaky_relu(conv1x1(x, params, prefix + ".0"), kLeakySlope), params,
                   prefix + ".1");
}

/// A view of the bytes of a contiguous CPU tensor, for seeding from its values.
std::string_view bytes_of(const at::Tensor& t) {
    return {static_cast<const char*>(t.data_ptr()), static_cast<size_t>(t.nbytes())};
}

}  // namespace

PuGaussianOptions PuGaussianOptions::from_json(const nlohmann::json& config) {
    PuGaussianOptions options;
    read_backbone_config(config, "pugaussian", [&](auto&& visit) { visit_fields(options, visit); });
    if (options.ratio > options.samples)
        throw_input_error(kContext, "'ratio' {} exceeds the draws per point 'samples' {}",
                          options.ratio, options.samples);
    if (options.gaussian_channels % 2 != 0)
        throw_input_error(kContext, "'gaussian_channels' must be even, found {}",
                          options.gaussian_channels);
    if (options.refine_channels % 4 != 0)
        throw_input_error(kContext, "'refine_channels' must be a multiple of 4, found {}",
                          options.refine_channels);
    return options;
}

nlohmann::json PuGaussianOptions::to_json() const {
    return write_backbone_config("pugaussian", [&](auto&& visit) { visit_fields(*this, visit); });
}

PuGaussian::PuGaussian(const PuGaussianOptions& options) : options_(options) {
    std::mt19937_64 rng(options.seed);
    auto linear = [&](const std::string& prefix, int64_t in, int64_t out) {
        add_linear(params_, prefix, in, out, /*bias=*/true, rng);
    };
    auto two_layers = [&](const std::string& prefix, int64_t in, int64_t hidden, int64_t out) {
        linear(prefix + ".0", in, hidden);
        linear(prefix + ".1", hidden, out);
    };
    // The point transformer: in -> dim (start), query/key/value, a position encoding 3 ->
    // position_channels (batch norm, ReLU) -> dim, an attention MLP dim -> 4·dim (batch norm,
    // ReLU) -> dim, dim -> in (end), residual.
    auto transformer = [&](const std::string& prefix, int64_t in, int64_t dim) {
        const int64_t hidden = options.position_channels;
        linear(prefix + ".start", in, dim);
        for (const char* name : {".query", ".key", ".value"}) linear(prefix + name, dim, dim);
        linear(prefix + ".pos0", 3, hidden);
        add_batch_norm(params_, buffers_, prefix + ".pos0.bn", hidden);
        linear(prefix + ".pos1", hidden, dim);
        linear(prefix + ".attn0", dim, 4 * dim);
        add_batch_norm(params_, buffers_, prefix + ".attn0.bn", 4 * dim);
        linear(prefix + ".attn1", 4 * dim, dim);
        linear(prefix + ".end", dim, in);
    };
    const int64_t cg = options.gaussian_channels, cr = options.refine_channels;
    two_layers("gaussian.mlp1", 3, cg, cg);
    two_layers("gaussian.mlp2", 2 * cg, 2 * cg, cg);
    transformer("gaussian.transformer", cg, options.gaussian_attention);
    two_layers("gaussian.offset", cg, cg / 2, 3);
    two_layers("gaussian.scale", cg, cg / 2, 3);
    two_layers("gaussian.rotation", cg, cg / 2, 4);
    // The refinement reads its points (mlp1) beside the Gaussian features of the point each
    // was drawn from, and the global maximum of both (mlp2).
    two_layers("refine.mlp1", 3, cr / 2, cr);
    two_layers("refine.mlp2", 2 * (cr + cg), cr / 2, cr);
    transformer("refine.transformer", cr, options.refine_attention);
    two_layers("refine.up.mlp", cr, cr / 2, cr / 4);
    // The up unit's kernel-1 transposed convolution, stored as the original's [in, out].
    add_xavier_uniform(params_, "refine.up.deconv.weight", cr / 4, cr, rng);
    linear("refine.up.res.conv1", 2 * cr, cr);
    linear("refine.up.res.conv2", cr, cr);
    linear("refine.up.res.shortcut", 2 * cr, cr);
    two_layers("refine.regressor", cr, cr / 2, 3);
}

nlohmann::json PuGaussian::config_for_ratio(int64_t ratio) const {
    if (ratio < 2 || ratio > options_.samples) return nullptr;
    // A power of the weights' ratio runs as that ratio repeated, each pass renormalised (the
    // original's 16x: 4x twice).
    for (int64_t power = options_.ratio * options_.ratio; power <= ratio; power *= options_.ratio)
        if (power == ratio) return nullptr;
    PuGaussianOptions options = options_;
    options.ratio = ratio;
    return options.to_json();
}

namespace {

/// What one forward pass reads: the parameters, the buffers, which statistics its batch norms
/// use, and where the inputs of those batch norms go when asked (update_buffers).
struct Pass {
    const ParamMap& params;
    const ParamMap& buffers;
    bool batch_statistics;
    ParamMap* statistics;

    /// conv -> batch norm -> ReLU. With running statistics the batch norm is folded into the
    /// convolution (one product instead of a product and four element-wise passes).
    at::Tensor conv_norm_relu(const at::Tensor& x, const std::string& prefix) const {
        const std::string norm = prefix + ".bn";
        if (statistics || batch_statistics) {
            at::Tensor y = conv1x1(x, params, prefix);
            if (statistics) (*statistics)[norm] = y;
            return at::relu(batch_statistics
                                ? batch_norm_batch_stats(y, params, norm, kNormEps)
                                : batch_norm_running_stats(y, params, buffers, norm, kNormEps));
        }
        const FoldedConv folded =
            fold_batch_norm(params, buffers, prefix, norm, kNormEps, x.scalar_type());
        return at::relu(conv1x1_weights(x, folded.weight, folded.bias));
    }

    /// The point transformer on features x [B,N,C] at positions pos [B,N,3] with the
    /// neighbours idx [B,N,k]: attention weights per channel, softmax over the neighbours, of
    /// q_i − k_j + e_ij (e the encoding of p_i − p_j); the aggregated value v_i + e_ij; residual.
    at::Tensor transformer(const at::Tensor& x, const at::Tensor& pos, const at::Tensor& idx,
                           const std::string& prefix) const {
        if (!statistics && !batch_statistics && !at::GradMode::is_enabled())
            return transformer_inference(x, pos, idx, prefix);
        const at::Tensor h = conv1x1(x, params, prefix + ".start");
        const at::Tensor query = conv1x1(h, params, prefix + ".query");
        const at::Tensor key = conv1x1(h, params, prefix + ".key");
        const at::Tensor value = conv1x1(h, params, prefix + ".value");
        const at::Tensor offsets = pos.unsqueeze(2) - gather_neighbors(pos, idx);  // [B,N,k,3]
        const at::Tensor encoding =
            conv1x1(conv_norm_relu(offsets, prefix + ".pos0"), params, prefix + ".pos1");
        at::Tensor attention = conv_norm_relu(
            query.unsqueeze(2) - gather_neighbors(key, idx) + encoding, prefix + ".attn0");
        attention = conv1x1(attention, params, prefix + ".attn1").softmax(2);
        const at::Tensor aggregated = (attention * (value.unsqueeze(2) + encoding)).sum(2);
        return conv1x1(aggregated, params, prefix + ".end") + x;
    }

    /// transformer() without gradients, on running statistics, as the same arithmetic in
    /// another order: the per-edge work (position encoding, attention MLP, softmax) runs over
    /// chunks of points whose edge tensors stay in the cache, batch norm folded into the
    /// convolutions, and the value term uses that each channel's softmax weights sum to 1:
    /// Σ_j a_ij (v_i + e_ij) = v_i + Σ_j a_ij e_ij.
    at::Tensor transformer_inference(const at::Tensor& x, const at::Tensor& pos,
                                     const at::Tensor& idx, const std::string& prefix) const {
        const int64_t batch = x.size(0), n = x.size(1), k = idx.size(2);
        const at::Tensor h = conv1x1(x, params, prefix + ".start");
        const int64_t dim = h.size(-1);
        const at::Tensor query = conv1x1(h, params, prefix + ".query").reshape({batch * n, dim});
        const at::Tensor key = conv1x1(h, params, prefix + ".key").reshape({batch * n, dim});
        const at::Tensor value = conv1x1(h, params, prefix + ".value").reshape({batch * n, dim});
        const at::Tensor points = pos.reshape({batch * n, 3});
        const at::Tensor rows =
            (idx + (at::arange(batch, idx.options()) * n).view({batch, 1, 1})).reshape({-1, k});
        // The batch-normed layers folded, their weights laid out [in, out] for addmm.
        auto folded = [&](const std::string& layer) {
            const FoldedConv f =
                fold_batch_norm(params, buffers, layer, layer + ".bn", kNormEps, x.scalar_type());
            return std::make_pair(f.weight.t().contiguous(), f.bias);
        };
        const auto [pos0_w, pos0_b] = folded(prefix + ".pos0");
        const auto [attn0_w, attn0_b] = folded(prefix + ".attn0");
        const at::Tensor pos1_w = params.at(prefix + ".pos1.weight").t().contiguous();
        const at::Tensor pos1_b = params.at(prefix + ".pos1.bias");
        const at::Tensor attn1_w = params.at(prefix + ".attn1.weight").t().contiguous();
        const at::Tensor attn1_b = params.at(prefix + ".attn1.bias");
        at::Tensor aggregated = at::empty({batch * n, dim}, h.options());
        for (int64_t start = 0; start < batch * n; start += kTransformerChunk) {
            const int64_t end = std::min(batch * n, start + kTransformerChunk), c = end - start;
            const at::Tensor neighbours = rows.slice(0, start, end).reshape({-1});
            const at::Tensor offsets = (points.slice(0, start, end).unsqueeze(1) -
                                        points.index_select(0, neighbours).view({c, k, 3}))
                                           .view({c * k, 3});
            const at::Tensor encoding =
                at::addmm(pos1_b, at::addmm(pos0_b, offsets, pos0_w).relu_(), pos1_w);
            at::Tensor logits = (query.slice(0, start, end).unsqueeze(1) -
                                 key.index_select(0, neighbours).view({c, k, dim}))
                                    .add_(encoding.view({c, k, dim}));
            logits = at::addmm(
                attn1_b, at::addmm(attn0_b, logits.view({c * k, dim}), attn0_w).relu_(), attn1_w);
            const at::Tensor weights = logits.view({c, k, dim}).softmax(1);
            aggregated.slice(0, start, end)
                .copy_(
                    (weights * encoding.view({c, k, dim})).sum(1).add_(value.slice(0, start, end)));
        }
        return conv1x1(aggregated.view({batch, n, dim}), params, prefix + ".end") + x;
    }

    /// x [B,M,C] beside its maximum over the points, [B,M,2C].
    static at::Tensor with_global(const at::Tensor& x) {
        return at::cat({x, std::get<0>(x.max(1, /*keepdim=*/true)).expand_as(x)}, -1);
    }
};

}  // namespace

PuGaussian::Stages PuGaussian::forward(const at::Tensor& x, const at::Tensor& epsilon,
                                       const ParamMap& params, int64_t passes,
                                       bool batch_statistics) const {
    return forward_collecting(x, epsilon, params, passes, batch_statistics, nullptr);
}

PuGaussian::Stages PuGaussian::forward_collecting(const at::Tensor& x, const at::Tensor& epsilon,
                                                  const ParamMap& params, int64_t passes,
                                                  bool batch_statistics,
                                                  ParamMap* statistics) const {
    check_batched_points(x, "pugaussian input");
    const int64_t batch = x.size(0), n = x.size(1), samples = options_.samples;
    if (epsilon.sizes() != at::IntArrayRef({batch, n, samples, 3}))
        throw InternalError("pugaussian: draws of shape " + shape_string(epsilon) +
                            " for patches of shape " + shape_string(x));
    const Pass pass{params, buffers_, batch_statistics, statistics};
    Stages out;

    // The Gaussian module.
    at::Tensor features =
        mlp(Pass::with_global(mlp(x, params, "gaussian.mlp1")), params, "gaussian.mlp2");
    features = pass.transformer(features, x, knn_indices(x, x, std::min(options_.k, x.size(1))),
                                "gaussian.transformer");
    out.features = features;
    out.means = x + head(features, params, "gaussian.offset");
    const at::Tensor scale =
        at::softplus(head(features, params, "gaussian.scale"), kSoftplusBeta, kSoftplusThreshold);
    at::Tensor q = head(features, params, "gaussian.rotation");
    q = q / q.norm(2, -1, /*keepdim=*/true).clamp_min(1e-12);
    const at::Tensor w = q.select(-1, 0), a = q.select(-1, 1), b = q.select(-1, 2),
                     c = q.select(-1, 3);
    const at::Tensor rotation =
        at::stack({1 - 2 * (b * b + c * c), 2 * (a * b - w * c), 2 * (a * c + w * b),
                   2 * (a * b + w * c), 1 - 2 * (a * a + c * c), 2 * (b * c - w * a),
                   2 * (a * c - w * b), 2 * (b * c + w * a), 1 - 2 * (a * a + b * b)},
                  -1)
            .view({batch, n, 3, 3});
    // Σ = (R·diag(s))(R·diag(s))ᵀ; each draw is ε·Σ (Σ itself, not a square root of it: the
    // original's), clamped to [-1, 1], around the mean; point-major order.
    const at::Tensor spread = rotation * scale.unsqueeze(-2);
    out.covariances = spread.matmul(spread.transpose(-1, -2));
    out.coarse =
        (out.means.unsqueeze(2) + epsilon.to(x.scalar_type()).matmul(out.covariances).clamp(-1, 1))
            .reshape({batch, n * samples, 3});

    // The refinement, the same weights each pass; every point of the coarse patch reads the
    // Gaussian features of the point it was drawn from.
    const at::Tensor drawn_from = features.repeat_interleave(samples, 1);
    const bool inference = !statistics && !batch_statistics && !at::GradMode::is_enabled();
    const RefineProducts products =
        inference ? refine_products(features, params) : RefineProducts{};
    at::Tensor p = out.coarse;
    for (int64_t i = 0; i < passes; ++i) {
        const at::Tensor own = mlp(p, params, "refine.mlp1");
        at::Tensor h;
        if (inference) {
            // mlp2's first layer, by the parts of its input: the point's own features, the
            // Gaussian features (the same for the `samples` points of a Gaussian, so one product
            // per Gaussian) and the global maximum (one per patch).
            const at::Tensor global =
                std::get<0>(at::cat({own, drawn_from}, -1).max(1, /*keepdim=*/true));
            h = conv1x1_weights(own, products.own, {}) + products.drawn +
                conv1x1_weights(global, products.global, params.at("refine.mlp2.0.bias"));
            h = conv1x1(at::relu(h), params, "refine.mlp2.1");
        } else {
            h = mlp(Pass::with_global(at::cat({own, drawn_from}, -1)), params, "refine.mlp2");
        }
        h = pass.transformer(h, p, knn_indices(p, p, std::min(options_.k, p.size(1))),
                             "refine.transformer");
        // The ratio-1 up unit: a transposed convolution of a reduction beside the features, a
        // residual MLP, ReLU.
        const at::Tensor reduced = mlp(h, params, "refine.up.mlp");
        at::Tensor up;
        if (inference) {
            // conv1 and the shortcut in one product over [reduction, features], the transposed
            // convolution folded into their weights.
            const at::Tensor both =
                conv1x1_weights(at::cat({reduced, h}, -1), products.up, products.up_bias);
            const int64_t width = h.size(-1);
            up = at::relu(
                conv1x1(at::relu(both.narrow(-1, 0, width)), params, "refine.up.res.conv2") +
                both.narrow(-1, width, width));
        } else {
            const at::Tensor joined =
                at::cat({reduced.matmul(params.at("refine.up.deconv.weight")), h}, -1);
            up = at::relu(conv1x1(at::relu(conv1x1(joined, params, "refine.up.res.conv1")), params,
                                  "refine.up.res.conv2") +
                          conv1x1(joined, params, "refine.up.res.shortcut"));
        }
        p = p + at::tanh(mlp(up, params, "refine.regressor"));
    }
    out.refined = p;
    return out;
}

PuGaussian::RefineProducts PuGaussian::refine_products(const at::Tensor& features,
                                                       const ParamMap& params) const {
    const int64_t cr = options_.refine_channels, cg = options_.gaussian_channels;
    RefineProducts out;
    const at::Tensor first = params.at("refine.mlp2.0.weight");  // [cr/2, 2(cr + cg)]
    out.own = first.narrow(1, 0, cr);
    out.global = first.narrow(1, cr + cg, cr + cg);
    out.drawn = conv1x1_weights(features, first.narrow(1, cr, cg), {})
                    .repeat_interleave(options_.samples, 1);
    // [conv1; shortcut] (2cr x 2cr) on [deconv(reduction), h] = [reduction, h] with the
    // transposed convolution D [cr/4, cr] folded in: [W_a Dᵀ, W_b].
    const at::Tensor stacked = at::cat(
        {params.at("refine.up.res.conv1.weight"), params.at("refine.up.res.shortcut.weight")});
    const at::Tensor deconv = params.at("refine.up.deconv.weight");
    out.up = at::cat({stacked.narrow(1, 0, cr).matmul(deconv.t()), stacked.narrow(1, cr, cr)}, 1);
    out.up_bias =
        at::cat({params.at("refine.up.res.conv1.bias"), params.at("refine.up.res.shortcut.bias")});
    return out;
}

at::Tensor PuGaussian::draw_epsilon(const at::Tensor& x, uint64_t seed) const {
    check_batched_points(x, "pugaussian input");
    const at::Tensor values = x.detach().to(at::kCPU).contiguous();
    std::vector<at::Tensor> draws;
    for (int64_t b = 0; b < x.size(0); ++b) {
        const at::Tensor patch = values[b].contiguous();
        at::Generator generator =
            at::detail::createCPUGenerator(derive_seed(seed, bytes_of(patch)));
        at::Tensor epsilon = at::randn({x.size(1), options_.samples, 3}, generator, at::kFloat);
        // Truncation as the original's: every component beyond it drawn again until none is.
        for (;;) {
            const at::Tensor beyond = epsilon.abs() > options_.truncation;
            const int64_t count = beyond.sum().item<int64_t>();
            if (count == 0) break;
            epsilon.masked_scatter_(beyond, at::randn({count}, generator, at::kFloat));
        }
        draws.push_back(epsilon);
    }
    return at::stack(draws).to(x.options().requires_grad(false));
}

at::Tensor PuGaussian::upsample_seeded(const at::Tensor& x, const ParamMap& params,
                                       uint64_t seed) const {
    check_batched_points(x, "pugaussian input");
    if (x.size(1) < 2)
        throw_input_error("pugaussian input", "needs at least 2 points per patch, found {}",
                          x.size(1));
    at::NoGradGuard no_grad;
    const PatchFrame frame(x);
    const at::Tensor local = frame.apply(x);
    const at::Tensor refined =
        forward(local, draw_epsilon(local, seed), params, options_.refine_passes, false).refined;
    const at::Tensor picks = farthest_point_sampling_batched(refined.to(at::kFloat).contiguous(),
                                                             options_.ratio * x.size(1));
    return frame.invert(at::gather(refined, 1, picks.unsqueeze(-1).expand({-1, -1, 3})));
}

at::Tensor PuGaussian::upsample(const at::Tensor& x, const ParamMap& params) const {
    return upsample_seeded(x, params, options_.seed);
}

at::Tensor PuGaussian::cloud_candidates(const at::Tensor& cloud, const ParamMap& params,
                                        uint64_t seed) const {
    check_points(cloud, "pugaussian input", 2);
    at::NoGradGuard no_grad;
    const PatchFrame frame(cloud.unsqueeze(0));
    const at::Tensor unit = frame.apply(cloud.unsqueeze(0))[0].to(at::kFloat).contiguous();
    const int64_t n = unit.size(0);
    const int64_t patch_points = std::min(options_.patch_size, n);
    const int64_t count =
        std::max<int64_t>(1, static_cast<int64_t>(double(n) / double(options_.patch_size) *
                                                  double(options_.patch_rate)));
    const at::Tensor seeds = unit.index_select(0, farthest_point_sampling(unit, count));
    const at::Tensor members = knn(unit, seeds, patch_points).indices;  // [P, patch_points]
    const at::Tensor patches = unit.index_select(0, members.flatten()).view({count, -1, 3});
    std::vector<at::Tensor> outputs;
    for (int64_t start = 0; start < count; start += kPatchBatch)
        outputs.push_back(upsample_seeded(
            patches.slice(0, start, std::min(count, start + kPatchBatch)), params, seed));
    return frame.invert(at::cat(outputs).reshape({1, -1, 3}))[0].to(cloud.scalar_type());
}

LossTerms PuGaussian::loss_terms(const at::Tensor& input, const at::Tensor& target,
                                 const ParamMap& params, int64_t step) const {
    check_batched_points(input, "pugaussian loss input");
    check_batched_points(target, "pugaussian loss target");
    const at::Tensor x = input.detach();
    const Stages stages =
        forward(x, draw_epsilon(x, derive_seed(options_.seed, "loss/" + std::to_string(step))),
                params, /*passes=*/1, /*batch_statistics=*/true);
    return {{"coarse", chamfer_loss(stages.coarse, target)},
            {"refined", chamfer_loss(stages.refined, target)}};
}

at::Tensor PuGaussian::loss(const at::Tensor& input, const at::Tensor& target,
                            const ParamMap& params, int64_t step) const {
    return sum_of(loss_terms(input, target, params, step));
}

at::Tensor PuGaussian::downsample(const at::Tensor& dense, uint64_t seed) const {
    check_batched_points(dense, "pugaussian downsample");
    return downsample_points(dense, std::max<int64_t>(2, dense.size(1) / options_.ratio),
                             options_.downsampler, seed);
}

void PuGaussian::update_buffers(const at::Tensor& input, const ParamMap& params) {
    at::NoGradGuard no_grad;
    check_batched_points(input, "pugaussian update_buffers");
    ParamMap statistics;
    forward_collecting(input, draw_epsilon(input, options_.seed), params, /*passes=*/1,
                       /*batch_statistics=*/true, &statistics);
    for (const auto& [prefix, x] : statistics)
        update_running_stats(x, buffers_, prefix, kNormMomentum);
}

std::unique_ptr<Backbone> make_pugaussian(const nlohmann::json& config) {
    return std::make_unique<PuGaussian>(PuGaussianOptions::from_json(config));
}

nlohmann::json pugaussian_small_config() {
    return {{"backbone", "pugaussian"},
            {"ratio", 4},
            {"samples", 6},
            {"k", 4},
            {"gaussian_channels", 8},
            {"gaussian_attention", 4},
            {"refine_channels", 8},
            {"refine_attention", 4},
            {"position_channels", 4},
            {"patch_size", 16},
            {"downsampler", "random"},
            {"seed", 3}};
}

}  // namespace pumeta
