// The floor a gridded backbone's outputs cannot go below on whole objects: the ground truth
// itself pushed through the patch pipeline on that grid.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

#include "pumeta/models/backbone.h"

namespace pumeta {

/// What `model`'s pipeline would output for input float32 [N,3] if its network chose ideally:
/// each patch of the input (the pipeline's patches) gets the patch_size·r ground-truth points
/// nearest its seed, snapped to the model's output grid in the patch frame
/// (Backbone::output_grid), most occupied cells first, repeated cyclically to patch_size·r
/// (as PU-Dense fills its ranking); the patches' outputs are merged and r·N of them picked by
/// farthest point sampling, as upsample_cloud() does for clouds of this size. gt float32
/// [M,3] in the input's frame. InputError for a backbone whose outputs are continuous.
at::Tensor grid_floor_output(const Backbone& model, const at::Tensor& points, const at::Tensor& gt,
                             int64_t ratio);

}  // namespace pumeta
