// The active sites of a sparse tensor: integer coordinates (batch, x, y, z) at a tensor
// stride, with their hash map and the kernel maps and coarser / generated sets derived from
// them. Every derived object is built once and cached here, so all layers on the same sites
// share one kernel map (MinkowskiEngine's coordinate manager, one per set).
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>

#include "pumeta/nn/sparse/coordinate_hash.h"
#include "pumeta/nn/sparse/kernel_map.h"

namespace pumeta {

class CoordinateSet;
using CoordinateSetPtr = std::shared_ptr<const CoordinateSet>;

class CoordinateSet {
  public:
    /// coords: integer [M,4] (batch, x, y, z), unique rows, batch in [0, kMaxBatch], x, y, z
    /// multiples of `stride` within [kMinCoordinate, kMaxCoordinate]. InputError otherwise.
    static CoordinateSetPtr create(const at::Tensor& coords, int64_t stride);

    /// int32 [M,4], contiguous, on the CPU.
    const at::Tensor& coords() const { return coords_; }
    /// int64 [M]: the batch column.
    const at::Tensor& batch_index() const { return batch_index_; }
    int64_t size() const { return coords_.size(0); }
    int64_t stride() const { return stride_; }
    /// 1 + the largest batch index (0 for an empty set).
    int64_t batch_size() const { return batch_size_; }

    /// Row of (batch, x, y, z), or -1.
    int64_t find(int64_t batch, int64_t x, int64_t y, int64_t z) const;
    /// Rows of query coordinates, integer [Q,4] -> int64 [Q] (-1 where absent).
    at::Tensor lookup(const at::Tensor& coords) const;

    /// The set at stride·factor: each site floored to a multiple of stride·factor, in order of
    /// first occurrence. Cached.
    CoordinateSetPtr coarser(int64_t factor) const;
    /// Stride-1 kernel map of this set onto itself. Cached per (kernel_size, dilation).
    std::shared_ptr<const KernelMap> conv_map(int64_t kernel_size, int64_t dilation) const;
    /// Map from this set to coarser(factor). Cached per (kernel_size, factor).
    std::shared_ptr<const KernelMap> down_map(int64_t kernel_size, int64_t factor) const;
    /// The sites generated from this set at stride / factor, and the map onto them. Cached per
    /// (kernel_size, factor). InputError unless factor divides the stride.
    struct Generated {
        CoordinateSetPtr set;
        std::shared_ptr<const KernelMap> map;
    };
    Generated generated(int64_t kernel_size, int64_t factor) const;

    /// How many kernel maps this set has built (cache hits build none).
    int64_t kernel_maps_built() const;

  private:
    /// `hash` maps each row of `coords` (int32 [M,4], validated) to its index.
    CoordinateSet(at::Tensor coords, int64_t stride, CoordinateHash hash);

    at::Tensor coords_;
    at::Tensor batch_index_;
    int64_t stride_;
    int64_t batch_size_ = 0;
    CoordinateHash hash_;

    // Derived objects, built on first request under the lock.
    mutable std::mutex mutex_;
    mutable std::map<int64_t, CoordinateSetPtr> coarser_;
    mutable std::map<std::tuple<char, int64_t, int64_t>, std::shared_ptr<const KernelMap>> maps_;
    mutable std::map<std::tuple<int64_t, int64_t>, Generated> generated_;
    mutable int64_t maps_built_ = 0;
};

/// Floor division of a by b > 0 (rounds towards minus infinity, unlike C++ integer division).
inline int64_t floor_div(int64_t a, int64_t b) {
    int64_t q = a / b;
    return (a % b != 0 && a < 0) ? q - 1 : q;
}

}  // namespace pumeta
