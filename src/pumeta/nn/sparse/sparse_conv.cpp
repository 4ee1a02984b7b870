#include "pumeta/nn/sparse/sparse_conv.h"

#include <ATen/ATen.h>
#include <ATen/Dispatch.h>
#include <ATen/Parallel.h>
#include <torch/csrc/autograd/custom_function.h>

#include <algorithm>
#include <cmath>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/nn/init.h"
#include "pumeta/nn/sparse/narrow_product.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "sparse convolution";

at::Tensor uniform_tensor(at::IntArrayRef shape, double limit, std::mt19937_64& rng) {
    reserve_parameter(shape);
    at::Tensor t = at::empty(shape, at::kFloat);
    float* data = t.data_ptr<float>();
    for (int64_t i = 0; i < t.numel(); ++i) data[i] = float((2.0 * uniform01(rng) - 1.0) * limit);
    return t.requires_grad_(true);
}

void insert_new(ParamMap& params, const std::string& name, at::Tensor tensor) {
    if (!params.emplace(name, std::move(tensor)).second)
        throw InternalError("parameter '" + name + "' initialised twice");
}

at::Tensor optional_param(const ParamMap& params, const std::string& name) {
    auto it = params.find(name);
    return it == params.end() ? at::Tensor() : it->second;
}

const at::Tensor& checked_weight(const ParamMap& params, const std::string& prefix,
                                 int64_t kernel_size, int64_t in_channels) {
    const at::Tensor& w = param(params, prefix + ".weight");
    const int64_t volume = kernel_size * kernel_size * kernel_size;
    if (w.dim() != 3 || w.size(0) != volume || w.size(1) != in_channels)
        throw_input_error(kContext, "'{}.weight' is {}, expected [{}, {}, Cout]", prefix,
                          shape_string(w), volume, in_channels);
    return w;
}

/// An index tensor on the device of the features it indexes (kernel maps live on the CPU).
at::Tensor on_device(const at::Tensor& index, const at::Tensor& like) {
    return index.device() == like.device() ? index : index.to(like.device());
}

// Below this many channels, rows move element-wise (gather / scatter_add_): index_add_ costs
// about 100 ns per row on the CPU whatever its width, which dominates narrow layers, and
// index_select's backward is an index_add_.
constexpr int64_t kNarrowChannels = 16;

// Floats of gathered features (and of products) per block of a batched convolution: 1 MiB, so
// they stay in cache between gather, GEMM and scatter. A 3³ convolution 64 -> 64 on 99k sites
// (bench_nn_sparse_conv): 1,958 ms unblocked, 526 ms blocked.
constexpr int64_t kBlockFloats = int64_t(1) << 18;

at::Tensor expanded(const at::Tensor& index, int64_t channels) {
    return index.unsqueeze(1).expand({index.size(0), channels});
}

/// x[index] for x [M,C], index int64 [P] -> [P,C].
at::Tensor gather_rows(const at::Tensor& x, const at::Tensor& index) {
    at::Tensor i = on_device(index, x);
    if (x.size(1) >= kNarrowChannels) return x.index_select(0, i);
    return x.gather(0, expanded(i, x.size(1)));
}

/// out[index[p]] += rows[p], in place. In place because neither backward needs `out`, and a
/// fresh tensor per kernel offset would copy the whole output each time.
void scatter_add_rows(at::Tensor& out, const at::Tensor& index, const at::Tensor& rows) {
    at::Tensor i = on_device(index, out);
    if (out.size(1) >= kNarrowChannels)
        out.index_add_(0, i, rows);
    else
        out.scatter_add_(0, expanded(i, out.size(1)), rows);
}

/// Whether autograd records an op on a and b.
bool recorded(const at::Tensor& a, const at::Tensor& b) {
    return at::GradMode::is_enabled() && (a.requires_grad() || b.requires_grad());
}

/// Rows per block for gathered features of `width` channels over `offsets` kernel offsets:
/// all of them while autograd records (each block's gather would have its own backward, an
/// index_add_ into a zero tensor the size of the whole input), else a cache-sized block.
int64_t block_rows(bool recording, int64_t rows, int64_t offsets, int64_t width) {
    if (recording) return rows;
    return std::max<int64_t>(64, kBlockFloats / (offsets * width));
}

/// Pairs [start, start + n) of every offset of a batched map, flattened: rows2d is the map's
/// batched_in or batched_out viewed as [offsets, rows].
at::Tensor block_pairs(const at::Tensor& rows2d, int64_t start, int64_t n) {
    return n == rows2d.size(1) ? rows2d.reshape(-1) : rows2d.narrow(1, start, n).reshape(-1);
}

/// x with one zero row appended: the row that the batched maps' padding pairs read.
at::Tensor with_zero_row(const at::Tensor& x) { return at::cat({x, x.new_zeros({1, x.size(1)})}); }

/// Whether the output-major tables serve a product on `features` (they index host memory).
bool table_path(const KernelMap& map, const at::Tensor& features) {
    return map.gather_table.defined() && features.device().is_cpu() &&
           (features.scalar_type() == at::kFloat || features.scalar_type() == at::kDouble);
}

/// Rows [start, start + n) of the output-major gather into `slots` [n, K·C]: row r, columns
/// [k·C, (k+1)·C) hold x[table[start + r, k]], or zeros where the entry is -1.
/// x [M, C] contiguous.
template <class T>
void gather_slots(const at::Tensor& x, const at::Tensor& table, int64_t start, int64_t n,
                  at::Tensor& slots) {
    const int64_t channels = x.size(1), volume = table.size(1);
    const T* source = x.data_ptr<T>();
    const int32_t* rows = table.data_ptr<int32_t>() + start * volume;
    T* target = slots.data_ptr<T>();
    at::parallel_for(0, n, 256, [&](int64_t begin, int64_t end) {
        for (int64_t r = begin; r < end; ++r)
            for (int64_t k = 0; k < volume; ++k) {
                T* slot = target + (r * volume + k) * channels;
                const int32_t i = rows[r * volume + k];
                if (i < 0)
                    std::fill(slot, slot + channels, T(0));
                else
                    std::copy(source + i * channels, source + (i + 1) * channels, slot);
            }
    });
}

/// Rows per block of the output-major path: gathered slots of about kBlockFloats floats.
int64_t table_block_rows(int64_t volume, int64_t channels) {
    return std::max<int64_t>(16, kBlockFloats / (volume * channels));
}

/// kernel_map_product through the gather table: per block of output rows, one gather of
/// every (row, offset) slot and one GEMM with the weight as [K·Cin, Cout]. No scatter. Narrow
/// outputs take the direct kernels instead (narrow_product.h).
at::Tensor table_product(const at::Tensor& features, const at::Tensor& weight,
                         const at::Tensor& table) {
    if (narrow_kernels_serve(features.size(1), weight.size(2), features.scalar_type()))
        return narrow_table_product(features, weight, table);
    at::Tensor x = features.contiguous();
    const int64_t rows = table.size(0), volume = table.size(1), channels = x.size(1);
    at::Tensor w = weight.contiguous().view({volume * channels, weight.size(2)});
    at::Tensor out = at::empty({rows, weight.size(2)}, x.options());
    const int64_t block = table_block_rows(volume, channels);
    at::Tensor slots = at::empty({std::min(block, rows), volume * channels}, x.options());
    for (int64_t start = 0; start < rows; start += block) {
        const int64_t n = std::min(block, rows - start);
        at::Tensor part = slots.narrow(0, 0, n);
        AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "gather_slots",
                                   [&] { gather_slots<scalar_t>(x, table, start, n, part); });
        at::Tensor rows_out = out.narrow(0, start, n);
        at::mm_out(rows_out, part, w);
    }
    return out;
}

/// kernel_map_weight_gradient through the gather table: Σ over blocks of
/// slots(features)ᵀ · grad_out, as [K, Cin, Cout].
at::Tensor table_weight_gradient(const at::Tensor& features, const at::Tensor& grad_out,
                                 const at::Tensor& table) {
    if (narrow_kernels_serve(features.size(1), grad_out.size(1), features.scalar_type()))
        return narrow_table_weight_gradient(features, grad_out, table);
    at::Tensor x = features.contiguous(), g = grad_out.contiguous();
    const int64_t rows = table.size(0), volume = table.size(1), channels = x.size(1);
    at::Tensor sum = at::zeros({volume * channels, g.size(1)}, x.options());
    const int64_t block = table_block_rows(volume, channels);
    at::Tensor slots = at::empty({std::min(block, rows), volume * channels}, x.options());
    for (int64_t start = 0; start < rows; start += block) {
        const int64_t n = std::min(block, rows - start);
        at::Tensor part = slots.narrow(0, 0, n);
        AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "gather_slots",
                                   [&] { gather_slots<scalar_t>(x, table, start, n, part); });
        sum.addmm_(part.t(), g.narrow(0, start, n));
    }
    return sum.view({volume, channels, g.size(1)});
}

/// Σ_k scatter(map.out[k], gather(map.in[k], features) · weight[k]), without the bias. Never
/// recorded by autograd (KernelMapProduct carries its gradient), so always in row blocks.
at::Tensor kernel_map_product(const at::Tensor& features, const at::Tensor& weight,
                              const KernelMap& map) {
    if (table_path(map, features)) return table_product(features, weight, map.gather_table);
    // Start from the centre tap where it maps every site to itself: no gather, no scatter.
    at::Tensor out;
    if (map.identity_offset >= 0)
        out = features.mm(weight[map.identity_offset]);
    else
        out = at::zeros({map.output_size, weight.size(2)}, features.options());
    if (!map.batched_offsets.defined()) {
        for (int64_t k = 0; k < map.kernel_volume(); ++k) {
            if (k == map.identity_offset || map.in[k].numel() == 0) continue;
            scatter_add_rows(out, map.out[k], gather_rows(features, map.in[k]).mm(weight[k]));
        }
        return out;
    }
    // All other offsets at once: gather from the features plus a zero row, one batched GEMM,
    // scatter into the output plus a dropped row; in blocks of rows whose gathered features and
    // products stay in cache.
    const int64_t offsets = map.batched_offsets.numel();
    const int64_t rows = map.batched_in.numel() / offsets;
    const int64_t block =
        block_rows(/*recording=*/false, rows, offsets, std::max(features.size(1), weight.size(2)));
    at::Tensor padded_in = with_zero_row(features);
    at::Tensor weights = weight.index_select(0, on_device(map.batched_offsets, features));
    at::Tensor padded_out = with_zero_row(out);
    at::Tensor in_rows = map.batched_in.view({offsets, rows});
    at::Tensor out_rows = map.batched_out.view({offsets, rows});
    for (int64_t start = 0; start < rows; start += block) {
        const int64_t n = std::min(block, rows - start);
        at::Tensor gathered = gather_rows(padded_in, block_pairs(in_rows, start, n))
                                  .view({offsets, n, features.size(1)});
        scatter_add_rows(padded_out, block_pairs(out_rows, start, n),
                         at::bmm(gathered, weights).view({-1, out.size(1)}));
    }
    return padded_out.narrow(0, 0, map.output_size);
}

/// The gradient of <grad_out, kernel_map_product(features, W, map)> with respect to W:
/// [K, Cin, Cout] whose row k is gather(map.in[k], features)ᵀ · gather(map.out[k], grad_out).
at::Tensor kernel_map_weight_gradient(const at::Tensor& features, const at::Tensor& grad_out,
                                      const KernelMap& map) {
    if (!recorded(features, grad_out) && table_path(map, features))
        return table_weight_gradient(features, grad_out, map.gather_table);
    std::vector<at::Tensor> per_offset(size_t(map.kernel_volume()));
    if (map.identity_offset >= 0)
        per_offset[size_t(map.identity_offset)] = features.t().mm(grad_out);
    if (map.batched_offsets.defined()) {
        const int64_t offsets = map.batched_offsets.numel();
        const int64_t rows = map.batched_in.numel() / offsets;
        const int64_t block = block_rows(recorded(features, grad_out), rows, offsets,
                                         std::max(features.size(1), grad_out.size(1)));
        at::Tensor padded_in = with_zero_row(features), padded_grad = with_zero_row(grad_out);
        at::Tensor in_rows = map.batched_in.view({offsets, rows});
        at::Tensor out_rows = map.batched_out.view({offsets, rows});
        at::Tensor sum;
        for (int64_t start = 0; start < rows; start += block) {
            const int64_t n = std::min(block, rows - start);
            at::Tensor x = gather_rows(padded_in, block_pairs(in_rows, start, n))
                               .view({offsets, n, features.size(1)});
            at::Tensor g = gather_rows(padded_grad, block_pairs(out_rows, start, n))
                               .view({offsets, n, grad_out.size(1)});
            if (sum.defined())
                sum.baddbmm_(x.transpose(1, 2), g);  // only without autograd: one block else
            else
                sum = at::bmm(x.transpose(1, 2), g);
        }
        auto k = map.batched_offsets.accessor<int64_t, 1>();
        for (int64_t i = 0; i < offsets; ++i) per_offset[size_t(k[i])] = sum[i];
    } else {
        for (int64_t k = 0; k < map.kernel_volume(); ++k) {
            if (k == map.identity_offset || map.in[k].numel() == 0) continue;
            per_offset[size_t(k)] =
                gather_rows(features, map.in[k]).t().mm(gather_rows(grad_out, map.out[k]));
        }
    }
    for (at::Tensor& w : per_offset)
        if (!w.defined()) w = features.new_zeros({features.size(1), grad_out.size(1)});
    return at::stack(per_offset);
}

/// A kernel map carried through autograd's saved data.
struct SavedKernelMap : torch::CustomClassHolder {
    explicit SavedKernelMap(KernelMap m) : map(std::move(m)) {}
    KernelMap map;
};

/// kernel_map_product with its own backward, so that the backward runs in row blocks too
/// (autograd's own backward of the blocked ops would allocate a whole-input gradient per
/// block) and saves the features and weights rather than every gathered row. The backward is
/// built from the same differentiable pieces, so a graph-recording backward (MAML's inner
/// loop) differentiates again: the feature gradient is this product on the transposed map.
class KernelMapProduct : public torch::autograd::Function<KernelMapProduct> {
  public:
    static at::Tensor forward(torch::autograd::AutogradContext* ctx, const at::Tensor& features,
                              const at::Tensor& weight, const KernelMap& map) {
        ctx->save_for_backward({features, weight});
        ctx->saved_data["map"] =
            c10::IValue::make_capsule(c10::make_intrusive<SavedKernelMap>(map));
        return kernel_map_product(features, weight, map);
    }

    static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                   torch::autograd::variable_list grads) {
        torch::autograd::variable_list saved = ctx->get_saved_variables();
        const at::Tensor& features = saved[0];
        const at::Tensor& weight = saved[1];
        c10::intrusive_ptr<torch::CustomClassHolder> holder = ctx->saved_data["map"].toCapsule();
        const KernelMap& map = static_cast<const SavedKernelMap*>(holder.get())->map;
        const at::Tensor& grad_out = grads[0];
        at::Tensor grad_features, grad_weight;
        if (features.requires_grad()) {
            KernelMap transposed = map.transposed();
            at::Tensor weight_t = weight.transpose(1, 2);
            grad_features = recorded(grad_out, weight_t)
                                ? KernelMapProduct::apply(grad_out, weight_t, transposed)
                                : kernel_map_product(grad_out, weight_t, transposed);
        }
        if (weight.requires_grad())
            grad_weight = kernel_map_weight_gradient(features, grad_out, map);
        return {grad_features, grad_weight, at::Tensor()};
    }
};

}  // namespace

void add_sparse_conv(ParamMap& params, const std::string& prefix, int64_t in, int64_t out,
                     int64_t kernel_size, bool bias, std::mt19937_64& rng, bool transposed) {
    check_kernel_size(kernel_size, kContext);
    const int64_t volume = kernel_size * kernel_size * kernel_size;
    const double limit = 1.0 / std::sqrt(double((transposed ? out : in) * volume));
    insert_new(params, prefix + ".weight", uniform_tensor({volume, in, out}, limit, rng));
    if (bias) insert_new(params, prefix + ".bias", uniform_tensor({out}, limit, rng));
}

at::Tensor apply_kernel_map(const at::Tensor& features, const at::Tensor& weight,
                            const at::Tensor& bias, const KernelMap& map) {
    if (features.dim() != 2 || features.size(0) != map.input_size)
        throw_input_error(kContext, "features {} do not match a kernel map from {} sites",
                          shape_string(features), map.input_size);
    if (weight.dim() != 3 || weight.size(0) != map.kernel_volume() ||
        weight.size(1) != features.size(1))
        throw_input_error(kContext, "weight {} does not match {} offsets and {} channels",
                          shape_string(weight), map.kernel_volume(), features.size(1));
    at::Tensor out = recorded(features, weight) ? KernelMapProduct::apply(features, weight, map)
                                                : kernel_map_product(features, weight, map);
    return bias.defined() ? out + bias : out;
}

SparseTensor sparse_conv(const SparseTensor& x, const ParamMap& params, const std::string& prefix,
                         const SparseConvOptions& options) {
    const at::Tensor& weight = checked_weight(params, prefix, options.kernel_size, x.channels());
    at::Tensor bias = optional_param(params, prefix + ".bias");
    if (options.stride < 1)
        throw_input_error(kContext, "stride must be >= 1, found {}", options.stride);
    if (options.stride > 1 && options.dilation != 1)
        throw_input_error(kContext, "dilation {} with stride {} is not supported", options.dilation,
                          options.stride);
    if (options.stride == 1) {
        if (options.kernel_size == 1) {
            at::Tensor out = x.features().mm(weight[0]);
            return x.with_features(bias.defined() ? out + bias : out);
        }
        auto map = x.coords()->conv_map(options.kernel_size, options.dilation);
        return x.with_features(apply_kernel_map(x.features(), weight, bias, *map));
    }
    auto map = x.coords()->down_map(options.kernel_size, options.stride);
    return SparseTensor(x.coords()->coarser(options.stride),
                        apply_kernel_map(x.features(), weight, bias, *map));
}

SparseTensor sparse_conv_transpose(const SparseTensor& x, const CoordinateSetPtr& target,
                                   const ParamMap& params, const std::string& prefix,
                                   int64_t kernel_size, int64_t factor) {
    const at::Tensor& weight = checked_weight(params, prefix, kernel_size, x.channels());
    if (!target || target->coarser(factor) != x.coords())
        throw_input_error(kContext,
                          "transposed convolution '{}': the target is not the set its input "
                          "was strided down from",
                          prefix);
    KernelMap map = target->down_map(kernel_size, factor)->transposed();
    return SparseTensor(target, apply_kernel_map(x.features(), weight,
                                                 optional_param(params, prefix + ".bias"), map));
}

SparseTensor sparse_conv_generative(const SparseTensor& x, const ParamMap& params,
                                    const std::string& prefix, int64_t kernel_size,
                                    int64_t factor) {
    const at::Tensor& weight = checked_weight(params, prefix, kernel_size, x.channels());
    CoordinateSet::Generated generated = x.coords()->generated(kernel_size, factor);
    return SparseTensor(generated.set,
                        apply_kernel_map(x.features(), weight,
                                         optional_param(params, prefix + ".bias"), *generated.map));
}

}  // namespace pumeta
