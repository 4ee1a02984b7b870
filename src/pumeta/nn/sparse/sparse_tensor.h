// A sparse voxel tensor: features at the active sites of a coordinate set.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

#include "pumeta/nn/sparse/coordinate_set.h"

namespace pumeta {

class SparseTensor {
  public:
    /// features: floating [M,C], row i at site coords->coords()[i]. InputError when the row
    /// counts differ or features are not a floating-point matrix.
    SparseTensor(CoordinateSetPtr coords, at::Tensor features);

    const CoordinateSetPtr& coords() const { return coords_; }
    const at::Tensor& features() const { return features_; }
    int64_t size() const { return features_.size(0); }
    int64_t channels() const { return features_.size(1); }
    int64_t stride() const { return coords_->stride(); }

    /// The same sites with other features [M,C'].
    SparseTensor with_features(at::Tensor features) const { return {coords_, std::move(features)}; }

  private:
    CoordinateSetPtr coords_;
    at::Tensor features_;
};

}  // namespace pumeta
