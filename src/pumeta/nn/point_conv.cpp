#include "pumeta/nn/point_conv.h"

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/nn/graph.h"

namespace pumeta {

namespace {

/// Batch norm's per-channel scale gamma / sqrt(var + eps) and its beta, in `type`.
std::pair<at::Tensor, at::Tensor> norm_scale(const ParamMap& params, const std::string& norm,
                                             const at::Tensor& var, double eps) {
    const at::Tensor gamma = param(params, norm + ".gamma").to(var.scalar_type());
    const at::Tensor beta = param(params, norm + ".beta").to(var.scalar_type());
    return {gamma * (var + eps).rsqrt(), beta};
}

/// Variance of each output channel of weight [Cout,Cin] applied to rows with covariance
/// [Cin,Cin]: diag(W Σ Wᵀ), clamped at 0 against the rounding of Σ.
at::Tensor projected_variance(const at::Tensor& weight, const at::Tensor& covariance) {
    return (weight.mm(covariance) * weight).sum(1).clamp_min(0);
}

}  // namespace

PointConvGraph point_conv_graph(const at::Tensor& points, const at::Tensor& idx) {
    check_batched_points(points, "point_conv_graph points");
    if (idx.dim() != 3 || idx.size(0) != points.size(0) || idx.size(1) != points.size(1) ||
        idx.scalar_type() != at::kLong)
        throw_input_error("point_conv_graph", "indices {} do not fit points {}", shape_string(idx),
                          shape_string(points));
    const int64_t batch = points.size(0), n = points.size(1), edges = idx.numel();
    PointConvGraph graph;
    graph.idx = idx;
    const at::Tensor offsets =
        (gather_neighbors(points, idx) - points.unsqueeze(2)).reshape({-1, 3});
    graph.offset_mean = offsets.mean(0);
    graph.centred_offsets = offsets - graph.offset_mean;
    graph.offset_covariance = graph.centred_offsets.t().mm(graph.centred_offsets) / double(edges);
    const at::Tensor flat =
        (idx + (at::arange(batch, idx.options()) * n).view({batch, 1, 1})).flatten();
    graph.edge_share =
        at::zeros({batch * n}, points.options().requires_grad(false))
            .index_add_(0, flat, at::ones({edges}, points.options().requires_grad(false)))
            .div_(double(edges))
            .view({batch, n, 1});
    return graph;
}

at::Tensor point_conv_batch_stats(const at::Tensor& features, const PointConvGraph& graph,
                                  const ParamMap& params, const std::string& prefix, double eps,
                                  BatchMomentsMap* moments) {
    if (features.dim() != 3 || features.size(0) != graph.idx.size(0) ||
        features.size(1) != graph.idx.size(1))
        throw_input_error(prefix, "features {} do not fit a graph of indices {}",
                          shape_string(features), shape_string(graph.idx));
    const int64_t batch = features.size(0), n = features.size(1), k = graph.idx.size(2);
    const int64_t channels = features.size(2);
    const at::ScalarType type = features.scalar_type();

    // BN_feats per point, statistics weighted by in-degree; then the gather.
    const at::Tensor feats_mean = (graph.edge_share * features).sum(at::IntArrayRef{0, 1});
    const at::Tensor feats_var =
        (graph.edge_share * (features - feats_mean).pow(2)).sum(at::IntArrayRef{0, 1});
    auto [feats_scale, feats_beta] = norm_scale(params, prefix + ".feats.bn", feats_var, eps);
    const at::Tensor neighbours = gather_neighbors(
        at::relu(at::addcmul(feats_beta - feats_mean * feats_scale, features, feats_scale)),
        graph.idx);  // [B,M,k,C]

    // BN_delta from the offsets' covariance, folded into W_delta.
    const at::Tensor delta_weight = param(params, prefix + ".delta.weight").to(type);
    if (delta_weight.dim() != 2 || delta_weight.size(0) != channels || delta_weight.size(1) != 3)
        throw_input_error(prefix + ".delta.weight", "has shape {}, expected [{}, 3]",
                          shape_string(delta_weight), channels);
    const at::Tensor delta_var = projected_variance(delta_weight, graph.offset_covariance.to(type));
    auto [delta_scale, delta_beta] = norm_scale(params, prefix + ".delta.bn", delta_var, eps);
    const at::Tensor geometric = at::relu(at::addmm(delta_beta, graph.centred_offsets.to(type),
                                                    (delta_weight * delta_scale.unsqueeze(1)).t()));

    // BN_post from the products' mean and second moment, folded into W_post.
    const at::Tensor product = geometric * neighbours.reshape({-1, channels});  // [E,C]
    const int64_t edges = product.size(0);
    const at::Tensor post_weight = param(params, prefix + ".post.weight").to(type);
    if (post_weight.dim() != 2 || post_weight.size(1) != channels)
        throw_input_error(prefix + ".post.weight", "has shape {}, expected [*, {}]",
                          shape_string(post_weight), channels);
    const at::Tensor product_mean = product.mean(0);
    const at::Tensor covariance =
        product.t().mm(product) / double(edges) - at::outer(product_mean, product_mean);
    const at::Tensor post_var = projected_variance(post_weight, covariance);
    auto [post_scale, post_beta] = norm_scale(params, prefix + ".post.bn", post_var, eps);
    if (moments) {
        auto bias = [&](const char* conv) {
            return param(params, prefix + conv + ".bias").to(type);
        };
        (*moments)[prefix + ".feats.bn"] = {feats_mean, feats_var, edges};
        (*moments)[prefix + ".delta.bn"] = {
            delta_weight.mv(graph.offset_mean.to(type)) + bias(".delta"), delta_var, edges};
        (*moments)[prefix + ".post.bn"] = {post_weight.mv(product_mean) + bias(".post"), post_var,
                                           edges};
    }
    const at::Tensor folded = post_weight * post_scale.unsqueeze(1);
    const at::Tensor out =
        at::relu(at::addmm(post_beta - folded.mv(product_mean), product, folded.t()));
    return out.view({batch, n, k, -1}).sum(2);
}

}  // namespace pumeta
