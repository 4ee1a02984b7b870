#include "pumeta/nn/sparse/narrow_product.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <cstring>
#include <string>
#include <type_traits>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

// Rows per chunk of the weight gradient: each chunk sums into its own [K, Cin, Cout] (7 KiB at
// 8 -> 8, in L1), and the chunks are added in order afterwards. The chunking depends on the
// row count only, so the sum does not depend on the thread count.
constexpr int64_t kChunkRows = 4096;

// The kernels twice: for the baseline instruction set, and for AVX2 with FMA (taken when the
// CPU has them; the library itself is built for any x86-64). OpenBLAS picks its kernels at run
// time the same way, so without this the GEMM baseline would run 8-wide FMAs against 4-wide
// multiplies and adds here.
namespace baseline {
#include "pumeta/nn/sparse/narrow_product_kernels.inc"
}  // namespace baseline

#if defined(__x86_64__) && defined(__GNUC__)
#pragma GCC push_options
#pragma GCC target("avx2,fma")
namespace avx2 {
#include "pumeta/nn/sparse/narrow_product_kernels.inc"
}  // namespace avx2
#pragma GCC pop_options

bool has_avx2() {
    static const bool supported = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    return supported;
}
#endif

template <int Cout>
void product_rows(const float* x, int64_t cin, const float* w, const int32_t* table, int64_t volume,
                  int64_t begin, int64_t end, float* out) {
#if defined(__x86_64__) && defined(__GNUC__)
    if (has_avx2()) return avx2::product_rows<Cout>(x, cin, w, table, volume, begin, end, out);
#endif
    baseline::product_rows<Cout>(x, cin, w, table, volume, begin, end, out);
}

template <int Cout>
void gradient_rows(const float* x, int64_t cin, const float* g, const int32_t* table,
                   int64_t volume, int64_t begin, int64_t end, float* sum) {
#if defined(__x86_64__) && defined(__GNUC__)
    if (has_avx2()) return avx2::gradient_rows<Cout>(x, cin, g, table, volume, begin, end, sum);
#endif
    baseline::gradient_rows<Cout>(x, cin, g, table, volume, begin, end, sum);
}

template <int Cout>
at::Tensor product(const at::Tensor& x, const at::Tensor& weight, const at::Tensor& table) {
    const int64_t rows = table.size(0), volume = table.size(1), cin = x.size(1);
    at::Tensor out = at::empty({rows, Cout}, x.options());
    const float* xd = x.data_ptr<float>();
    const float* wd = weight.data_ptr<float>();
    const int32_t* td = table.data_ptr<int32_t>();
    float* od = out.data_ptr<float>();
    at::parallel_for(0, rows, 1024, [&](int64_t begin, int64_t end) {
        product_rows<Cout>(xd, cin, wd, td, volume, begin, end, od);
    });
    return out;
}

template <int Cout>
at::Tensor weight_gradient(const at::Tensor& x, const at::Tensor& grad_out,
                           const at::Tensor& table) {
    const int64_t rows = table.size(0), volume = table.size(1), cin = x.size(1);
    const int64_t chunks = std::max<int64_t>(1, (rows + kChunkRows - 1) / kChunkRows);
    const int64_t slice = volume * cin * Cout;
    at::Tensor partial = at::zeros({chunks, slice}, x.options());
    const float* xd = x.data_ptr<float>();
    const float* gd = grad_out.data_ptr<float>();
    const int32_t* td = table.data_ptr<int32_t>();
    float* pd = partial.data_ptr<float>();
    at::parallel_for(0, chunks, 1, [&](int64_t begin, int64_t end) {
        for (int64_t chunk = begin; chunk < end; ++chunk)
            gradient_rows<Cout>(xd, cin, gd, td, volume, chunk * kChunkRows,
                                std::min(rows, (chunk + 1) * kChunkRows), pd + chunk * slice);
    });
    at::Tensor sum = partial[0];
    for (int64_t chunk = 1; chunk < chunks; ++chunk) sum.add_(partial[chunk]);
    return sum.view({volume, cin, Cout});
}

/// f(std::integral_constant<int, W>()) for the output width W, one of the widths with kernels.
template <class F>
at::Tensor with_width(int64_t width, F&& f) {
    switch (width) {
        case 4:
            return f(std::integral_constant<int, 4>());
        case 8:
            return f(std::integral_constant<int, 8>());
        case 16:
            return f(std::integral_constant<int, 16>());
    }
    throw InternalError("narrow sparse product: no kernel for " + std::to_string(width) +
                        " output channels");
}

}  // namespace

bool narrow_kernels_serve(int64_t in_channels, int64_t out_channels, at::ScalarType type) {
    // Wider inputs go to the GEMM: at 32 -> 8 and 64 -> 16 it beat these kernels by 10-20 %
    // (bench_nn_sparse_conv), its K·Cin columns being wide enough for BLAS.
    return type == at::kFloat && in_channels >= 1 && in_channels <= 16 &&
           (out_channels == 4 || out_channels == 8 || out_channels == 16);
}

at::Tensor narrow_table_product(const at::Tensor& x, const at::Tensor& weight,
                                const at::Tensor& table) {
    at::Tensor xc = x.contiguous(), wc = weight.contiguous(), tc = table.contiguous();
    return with_width(weight.size(2),
                      [&](auto width) { return product<decltype(width)::value>(xc, wc, tc); });
}

at::Tensor narrow_table_weight_gradient(const at::Tensor& x, const at::Tensor& grad_out,
                                        const at::Tensor& table) {
    at::Tensor xc = x.contiguous(), gc = grad_out.contiguous(), tc = table.contiguous();
    return with_width(grad_out.size(1), [&](auto width) {
        return weight_gradient<decltype(width)::value>(xc, gc, tc);
    });
}

}  // namespace pumeta
