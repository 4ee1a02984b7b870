#include "pumeta/nn/sparse/sparse_tensor.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

SparseTensor::SparseTensor(CoordinateSetPtr coords, at::Tensor features)
    : coords_(std::move(coords)), features_(std::move(features)) {
    if (!coords_) throw_input_error("sparse tensor", "coordinates are missing");
    if (!features_.defined() || features_.dim() != 2 || !features_.is_floating_point())
        throw_input_error("sparse tensor", "expected floating-point features [M,C], found {}",
                          shape_string(features_));
    if (features_.size(0) != coords_->size())
        throw_input_error("sparse tensor", "{} feature rows for {} sites", features_.size(0),
                          coords_->size());
}

}  // namespace pumeta
