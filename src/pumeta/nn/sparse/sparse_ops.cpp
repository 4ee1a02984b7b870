#include "pumeta/nn/sparse/sparse_ops.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

at::Tensor on_device(const at::Tensor& index, const at::Tensor& like) {
    return index.device() == like.device() ? index : index.to(like.device());
}

}  // namespace

SparseTensor sparse_cat(const SparseTensor& a, const SparseTensor& b) {
    if (a.coords() != b.coords())
        throw_input_error("sparse cat", "tensors on different coordinate sets");
    return a.with_features(at::cat({a.features(), b.features()}, 1));
}

SparseTensor add_onto(const SparseTensor& a, const SparseTensor& b) {
    if (a.channels() != b.channels())
        throw_input_error("sparse add", "{} vs {} channels", a.channels(), b.channels());
    if (a.coords() == b.coords()) return a.with_features(a.features() + b.features());
    if (a.stride() != b.stride())
        throw_input_error("sparse add", "strides {} and {} differ", a.stride(), b.stride());
    at::Tensor rows = a.coords()->lookup(b.coords()->coords());
    if (rows.numel() > 0 && rows.min().item<int64_t>() < 0)
        throw_input_error("sparse add", "the second tensor has sites the first lacks");
    return a.with_features(a.features().index_add(0, on_device(rows, a.features()), b.features()));
}

SparseTensor prune(const SparseTensor& x, const at::Tensor& keep) {
    if (!keep.defined() || keep.dim() != 1 || keep.size(0) != x.size() ||
        keep.scalar_type() != at::kBool)
        throw_input_error("sparse prune", "expected a bool mask [{}], found {}", x.size(),
                          shape_string(keep));
    at::Tensor rows = keep.to(at::kCPU).nonzero().view(-1);
    CoordinateSetPtr kept =
        CoordinateSet::create(x.coords()->coords().index_select(0, rows), x.stride());
    return SparseTensor(kept, x.features().index_select(0, on_device(rows, x.features())));
}

at::Tensor global_average_pool(const SparseTensor& x) {
    const int64_t batch = x.coords()->batch_size();
    at::Tensor index = on_device(x.coords()->batch_index(), x.features());
    at::Tensor sums =
        at::zeros({batch, x.channels()}, x.features().options()).index_add(0, index, x.features());
    at::Tensor counts =
        at::bincount(x.coords()->batch_index(), {}, batch).to(x.features().options()).clamp_min(1);
    return sums / counts.unsqueeze(1);
}

SparseTensor broadcast_to_sites(const at::Tensor& per_batch, const CoordinateSetPtr& sites) {
    if (per_batch.dim() != 2 || per_batch.size(0) < sites->batch_size())
        throw_input_error("sparse broadcast", "expected [>= {}, C] rows, found {}",
                          sites->batch_size(), shape_string(per_batch));
    return SparseTensor(sites,
                        per_batch.index_select(0, on_device(sites->batch_index(), per_batch)));
}

}  // namespace pumeta
