#include "pumeta/nn/batch_norm.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

void insert_new(ParamMap& map, const std::string& name, at::Tensor tensor) {
    if (!map.emplace(name, std::move(tensor)).second)
        throw InternalError("tensor '" + name + "' initialised twice");
}

// x viewed as rows of channels: [R, C].
at::Tensor channel_rows(const at::Tensor& x, const std::string& prefix) {
    if (!x.defined() || x.dim() < 1 || !x.is_floating_point())
        throw_input_error(prefix, "expected floating-point features [..., C], found {}",
                          shape_string(x));
    return x.reshape({-1, x.size(-1)});
}

const at::Tensor& channel_vector(const ParamMap& map, const std::string& name, int64_t channels) {
    const at::Tensor& t = param(map, name);
    if (t.dim() != 1 || t.size(0) != channels)
        throw_input_error(name, "has shape {}, features have {} channels", shape_string(t),
                          channels);
    return t;
}

at::Tensor normalize(const at::Tensor& x, const at::Tensor& mean, const at::Tensor& var,
                     const ParamMap& params, const std::string& prefix, double eps) {
    const int64_t channels = x.size(-1);
    const at::Tensor& gamma = channel_vector(params, prefix + ".gamma", channels);
    const at::Tensor& beta = channel_vector(params, prefix + ".beta", channels);
    // One scale and shift per channel, then a single fused multiply-add over x.
    at::Tensor scale = gamma * (var + eps).rsqrt();
    return at::addcmul(beta - mean * scale, x, scale);
}

}  // namespace

void add_batch_norm(ParamMap& params, ParamMap& buffers, const std::string& prefix,
                    int64_t channels) {
    for (int i = 0; i < 4; ++i) reserve_parameter({channels});
    insert_new(params, prefix + ".gamma", at::ones({channels}, at::kFloat).requires_grad_(true));
    insert_new(params, prefix + ".beta", at::zeros({channels}, at::kFloat).requires_grad_(true));
    insert_new(buffers, prefix + ".running_mean", at::zeros({channels}, at::kFloat));
    insert_new(buffers, prefix + ".running_var", at::ones({channels}, at::kFloat));
}

at::Tensor batch_norm_batch_stats(const at::Tensor& x, const ParamMap& params,
                                  const std::string& prefix, double eps) {
    at::Tensor rows = channel_rows(x, prefix);
    at::Tensor mean = rows.mean(0);
    at::Tensor var = (rows - mean).pow(2).mean(0);
    return normalize(x, mean, var, params, prefix, eps);
}

at::Tensor batch_norm_running_stats(const at::Tensor& x, const ParamMap& params,
                                    const ParamMap& buffers, const std::string& prefix,
                                    double eps) {
    channel_rows(x, prefix);
    const int64_t channels = x.size(-1);
    at::Tensor mean = channel_vector(buffers, prefix + ".running_mean", channels).to(x.options());
    at::Tensor var = channel_vector(buffers, prefix + ".running_var", channels).to(x.options());
    return normalize(x, mean, var, params, prefix, eps);
}

FoldedConv fold_batch_norm(const ParamMap& params, const ParamMap& buffers, const std::string& conv,
                           const std::string& norm, double eps, at::ScalarType type) {
    const at::Tensor weight = params.at(conv + ".weight");
    const int64_t channels = weight.size(0);
    const at::Tensor mean = channel_vector(buffers, norm + ".running_mean", channels).to(type);
    const at::Tensor var = channel_vector(buffers, norm + ".running_var", channels).to(type);
    const at::Tensor scale = params.at(norm + ".gamma") * (var + eps).rsqrt();
    return {weight * scale.unsqueeze(1),
            (params.at(conv + ".bias") - mean) * scale + params.at(norm + ".beta")};
}

BatchMoments batch_moments(const at::Tensor& x) {
    at::NoGradGuard no_grad;
    at::Tensor rows = channel_rows(x, "batch_moments").detach();
    auto [var, mean] = at::var_mean(rows, 0, /*unbiased=*/false);
    return {mean, var, rows.size(0)};
}

void update_running_stats(const at::Tensor& x, ParamMap& buffers, const std::string& prefix,
                          double momentum) {
    channel_rows(x, prefix);
    update_running_stats(batch_moments(x), buffers, prefix, momentum);
}

void update_running_stats(const BatchMoments& batch, ParamMap& buffers, const std::string& prefix,
                          double momentum) {
    if (!(momentum >= 0 && momentum <= 1))
        throw_input_error(prefix, "batch-norm momentum must be in [0, 1], found {}", momentum);
    if (batch.rows < 2)
        throw_input_error(prefix, "running statistics need at least 2 rows, found {}", batch.rows);
    at::NoGradGuard no_grad;
    const int64_t channels = batch.mean.numel();
    channel_vector(buffers, prefix + ".running_mean", channels);  // named errors first
    channel_vector(buffers, prefix + ".running_var", channels);
    at::Tensor& mean = buffers.at(prefix + ".running_mean");
    at::Tensor& var = buffers.at(prefix + ".running_var");
    const double unbiased = double(batch.rows) / double(batch.rows - 1);
    // New tensors rather than in-place updates: copies of the map stay snapshots.
    mean = (1 - momentum) * mean + momentum * batch.mean.detach().to(mean.options());
    var = (1 - momentum) * var + momentum * (batch.var.detach() * unbiased).to(var.options());
}

}  // namespace pumeta
