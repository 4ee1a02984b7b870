#include "pumeta/nn/init.h"

#include <ATen/ATen.h>

#include <cmath>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

void insert_new(ParamMap& params, const std::string& name, at::Tensor tensor) {
    tensor.requires_grad_(true);
    if (!params.emplace(name, std::move(tensor)).second)
        throw InternalError("parameter '" + name + "' initialised twice");
}

}  // namespace

void add_xavier_uniform(ParamMap& params, const std::string& name, int64_t fan_out, int64_t fan_in,
                        std::mt19937_64& rng) {
    double limit = std::sqrt(6.0 / double(fan_in + fan_out));
    reserve_parameter({fan_out, fan_in});
    at::Tensor weight = at::empty({fan_out, fan_in}, at::kFloat);
    float* data = weight.data_ptr<float>();
    for (int64_t i = 0; i < weight.numel(); ++i)
        data[i] = float((2.0 * uniform01(rng) - 1.0) * limit);
    insert_new(params, name, weight);
}

void add_zeros(ParamMap& params, const std::string& name, int64_t size) {
    reserve_parameter({size});
    insert_new(params, name, at::zeros({size}, at::kFloat));
}

void add_linear(ParamMap& params, const std::string& prefix, int64_t in, int64_t out, bool bias,
                std::mt19937_64& rng) {
    add_xavier_uniform(params, prefix + ".weight", out, in, rng);
    if (bias) add_zeros(params, prefix + ".bias", out);
}

}  // namespace pumeta
