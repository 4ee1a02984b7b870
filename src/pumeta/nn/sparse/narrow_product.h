// Direct kernels for narrow sparse convolutions through a kernel map's output-major table
// (KernelMap::gather_table): each output row accumulates x[table[o, k]] · W_k straight from
// the input rows, with the output width a compile-time constant so that the accumulation is a
// few vector registers.
//
// Why: the general table path gathers every (output, offset) slot into [rows, K·Cin] and runs
// one GEMM with Cout columns. For Cout ≤ 16 BLAS runs that GEMM far below its peak and the
// gather copies every row, empty slots included (39 % of them on a voxelised surface), so a
// 3³ convolution 8 -> 8 cost 2.6x three dense GEMMs of its useful FLOPs. The direct kernels
// skip empty slots and never materialise the gathered rows (docs/design.md, "CPU performance").
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

/// Whether the direct kernels serve a product with weights [K, in_channels, out_channels] of
/// this scalar type: float32, at most 16 input channels and out_channels one of 4, 8, 16 (the
/// kernels compute any in_channels; this is where they beat the gathered GEMM).
bool narrow_kernels_serve(int64_t in_channels, int64_t out_channels, at::ScalarType type);

/// out [rows, Cout], out[o] = Σ_k x[table[o, k]] · weight[k] over the entries ≥ 0.
/// x [M, Cin] float, weight [K, Cin, Cout] float, table int32 [rows, K] with entries in
/// [-1, M). The caller checks narrow_kernels_serve first.
at::Tensor narrow_table_product(const at::Tensor& x, const at::Tensor& weight,
                                const at::Tensor& table);

/// The gradient of <grad_out, narrow_table_product(x, W, table)> with respect to W:
/// [K, Cin, Cout] whose slice k is Σ_o x[table[o, k]]ᵀ · grad_out[o] over the entries ≥ 0.
/// grad_out [rows, Cout] float. Summed per chunk of rows, then over chunks in a fixed order, so
/// the result depends on the thread count only through that order.
at::Tensor narrow_table_weight_gradient(const at::Tensor& x, const at::Tensor& grad_out,
                                        const at::Tensor& table);

}  // namespace pumeta
