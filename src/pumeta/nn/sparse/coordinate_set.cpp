#include "pumeta/nn/sparse/coordinate_set.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "sparse coordinates";

}  // namespace

CoordinateSet::CoordinateSet(at::Tensor coords, int64_t stride, CoordinateHash hash)
    : coords_(std::move(coords)), stride_(stride), hash_(std::move(hash)) {
    batch_index_ = coords_.select(1, 0).to(at::kLong);
    batch_size_ = size() == 0 ? 0 : batch_index_.max().item<int64_t>() + 1;
}

CoordinateSetPtr CoordinateSet::create(const at::Tensor& coords, int64_t stride) {
    if (!coords.defined() || coords.dim() != 2 || coords.size(1) != 4)
        throw_input_error(kContext, "expected coordinates of shape [M,4], found {}",
                          shape_string(coords));
    if (coords.scalar_type() != at::kInt && coords.scalar_type() != at::kLong)
        throw_input_error(kContext, "expected int32 or int64 coordinates, found {}",
                          std::string(c10::toString(coords.scalar_type())));
    if (stride < 1) throw_input_error(kContext, "tensor stride must be >= 1, found {}", stride);
    at::Tensor wide = coords.to(at::kCPU, at::kLong).contiguous();
    const int64_t* c = wide.data_ptr<int64_t>();
    const int64_t m = wide.size(0);
    CoordinateHash hash(m);
    for (int64_t i = 0; i < m; ++i) {
        const int64_t* row = c + 4 * i;
        if (!packable(row[0], row[1], row[2], row[3]))
            throw_input_error(kContext,
                              "row {} = ({}, {}, {}, {}) is outside batch [0, {}] or coordinates "
                              "[{}, {}]",
                              i, row[0], row[1], row[2], row[3], kMaxBatch, kMinCoordinate,
                              kMaxCoordinate);
        if (row[1] % stride || row[2] % stride || row[3] % stride)
            throw_input_error(kContext, "row {} = ({}, {}, {}) is not a multiple of stride {}", i,
                              row[1], row[2], row[3], stride);
        int64_t first = hash.insert(pack_coordinate(row[0], row[1], row[2], row[3]), i);
        if (first != i) throw_input_error(kContext, "rows {} and {} are the same site", first, i);
    }
    return CoordinateSetPtr(new CoordinateSet(wide.to(at::kInt), stride, std::move(hash)));
}

int64_t CoordinateSet::find(int64_t batch, int64_t x, int64_t y, int64_t z) const {
    if (!packable(batch, x, y, z)) return -1;
    return hash_.find(pack_coordinate(batch, x, y, z));
}

at::Tensor CoordinateSet::lookup(const at::Tensor& coords) const {
    if (!coords.defined() || coords.dim() != 2 || coords.size(1) != 4)
        throw_input_error(kContext, "lookup expects coordinates of shape [Q,4], found {}",
                          shape_string(coords));
    at::Tensor wide = coords.to(at::kCPU, at::kLong).contiguous();
    const int64_t* c = wide.data_ptr<int64_t>();
    at::Tensor rows = at::empty({wide.size(0)}, at::kLong);
    int64_t* r = rows.data_ptr<int64_t>();
    at::parallel_for(0, wide.size(0), 4096, [&](int64_t begin, int64_t end) {
        for (int64_t i = begin; i < end; ++i) {
            const int64_t* q = c + 4 * i;
            r[i] = find(q[0], q[1], q[2], q[3]);
        }
    });
    return rows;
}

CoordinateSetPtr CoordinateSet::coarser(int64_t factor) const {
    if (factor < 1) throw_input_error(kContext, "stride factor must be >= 1, found {}", factor);
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = coarser_.find(factor);
    if (it != coarser_.end()) return it->second;
    const int64_t step = stride_ * factor;
    const int32_t* c = coords_.data_ptr<int32_t>();
    std::vector<int32_t> kept;
    CoordinateHash hash(size() / 2);
    for (int64_t i = 0; i < size(); ++i) {
        const int32_t* row = c + 4 * i;
        int64_t x = floor_div(row[1], step) * step, y = floor_div(row[2], step) * step,
                z = floor_div(row[3], step) * step;
        if (!packable(row[0], x, y, z))
            throw_input_error(kContext, "site ({}, {}, {}) at stride {} leaves the range", x, y, z,
                              step);
        int64_t next = int64_t(kept.size() / 4);
        if (hash.insert(pack_coordinate(row[0], x, y, z), next) == next)
            kept.insert(kept.end(), {row[0], int32_t(x), int32_t(y), int32_t(z)});
    }
    at::Tensor coords = at::empty({int64_t(kept.size() / 4), 4}, at::kInt);
    std::copy(kept.begin(), kept.end(), coords.data_ptr<int32_t>());
    CoordinateSetPtr set(new CoordinateSet(coords, step, std::move(hash)));
    coarser_[factor] = set;
    return set;
}

std::shared_ptr<const KernelMap> CoordinateSet::conv_map(int64_t kernel_size,
                                                         int64_t dilation) const {
    check_kernel_size(kernel_size, kContext);
    if (dilation < 1) throw_input_error(kContext, "dilation must be >= 1, found {}", dilation);
    std::lock_guard<std::mutex> lock(mutex_);
    auto& slot = maps_[{'c', kernel_size, dilation}];
    if (!slot) {
        slot = std::make_shared<const KernelMap>(build_conv_map(*this, kernel_size, dilation));
        ++maps_built_;
    }
    return slot;
}

std::shared_ptr<const KernelMap> CoordinateSet::down_map(int64_t kernel_size,
                                                         int64_t factor) const {
    check_kernel_size(kernel_size, kContext);
    CoordinateSetPtr coarse = coarser(factor);
    std::lock_guard<std::mutex> lock(mutex_);
    auto& slot = maps_[{'d', kernel_size, factor}];
    if (!slot) {
        slot = std::make_shared<const KernelMap>(build_down_map(*this, *coarse, kernel_size));
        ++maps_built_;
    }
    return slot;
}

CoordinateSet::Generated CoordinateSet::generated(int64_t kernel_size, int64_t factor) const {
    check_kernel_size(kernel_size, kContext);
    if (factor < 1 || stride_ % factor != 0)
        throw_input_error(kContext, "cannot generate stride {} / {}: not an integer stride",
                          stride_, factor);
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = generated_.find({kernel_size, factor});
    if (it != generated_.end()) return it->second;
    GeneratedCoordinates made = generate_coordinates(*this, kernel_size, factor);
    Generated result;
    result.set = CoordinateSetPtr(
        new CoordinateSet(std::move(made.coords), stride_ / factor, std::move(made.hash)));
    result.map = std::make_shared<const KernelMap>(std::move(made.map));
    ++maps_built_;
    generated_[{kernel_size, factor}] = result;
    return result;
}

int64_t CoordinateSet::kernel_maps_built() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return maps_built_;
}

}  // namespace pumeta
