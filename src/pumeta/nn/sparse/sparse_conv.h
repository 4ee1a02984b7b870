// Sparse 3-D convolutions on SparseTensors, running from an explicit ParamMap (MAML's fast
// weights) and built from row gathers (index_select / gather), GEMMs (mm / bmm) and scatter-adds
// (index_add_ / scatter_add_) in cache-sized row blocks. Their backward is written out (the same
// blocked pieces on the transposed map) and is itself differentiable, so MAML's second-order
// meta-gradient flows through them. Semantics follow
// MinkowskiEngine: kernels are centred on the output site, offsets are in units of the input stride
// (of the output stride for transposed convolutions), weights are [K³, Cin, Cout].
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <random>
#include <string>

#include "pumeta/nn/parameters.h"
#include "pumeta/nn/sparse/sparse_tensor.h"

namespace pumeta {

/// Adds `prefix.weight` float32 [K³, in, out] and, with `bias`, `prefix.bias` [out], both
/// uniform in ±1/sqrt(fan) with fan = in·K³ (out·K³ when `transposed`), MinkowskiEngine's
/// initialisation.
void add_sparse_conv(ParamMap& params, const std::string& prefix, int64_t in, int64_t out,
                     int64_t kernel_size, bool bias, std::mt19937_64& rng, bool transposed = false);

/// Σ_k scatter(map.out[k], gather(map.in[k], features) · weight[k]) (+ bias):
/// features [map.input_size, Cin], weight [K, Cin, Cout] with K = map.kernel_volume(), bias
/// [Cout] or undefined -> [map.output_size, Cout].
at::Tensor apply_kernel_map(const at::Tensor& features, const at::Tensor& weight,
                            const at::Tensor& bias, const KernelMap& map);

struct SparseConvOptions {
    /// Odd kernel size K (1 is a per-site linear map).
    int64_t kernel_size = 3;
    /// 1, or the factor by which the output's tensor stride grows (outputs at the sites of
    /// x.coords()->coarser(stride)).
    int64_t stride = 1;
    /// Spacing of the kernel taps in input strides (stride 1 only).
    int64_t dilation = 1;
};

/// Convolution with `prefix.weight` [K³, Cin, Cout] (and `prefix.bias` when present).
SparseTensor sparse_conv(const SparseTensor& x, const ParamMap& params, const std::string& prefix,
                         const SparseConvOptions& options);

/// Transposed convolution from x (stride S) back to `target`, a finer set with
/// target->coarser(factor) == x.coords() (the set x was strided down from). Weights
/// [K³, Cin, Cout]: out[u + k·S/factor] += x[u] · W_k.
SparseTensor sparse_conv_transpose(const SparseTensor& x, const CoordinateSetPtr& target,
                                   const ParamMap& params, const std::string& prefix,
                                   int64_t kernel_size, int64_t factor = 2);

/// Generative transposed convolution: like sparse_conv_transpose, but the output sites are all
/// sites the kernel reaches (x.coords()->generated(kernel_size, factor)).
SparseTensor sparse_conv_generative(const SparseTensor& x, const ParamMap& params,
                                    const std::string& prefix, int64_t kernel_size,
                                    int64_t factor = 2);

}  // namespace pumeta
