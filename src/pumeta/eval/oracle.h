// The ground-truth "oracle" adaptation: a diagnostic reference, never a result. θ' comes from N
// steps on supervised pairs (each patch of X as the network sees it, with the patch_size·r
// ground-truth points nearest to its seed in the same patch frame), i.e. what N steps could
// gain with a perfect training signal (`pumeta eval --tta-unit oracle`, docs/design.md).
#pragma once

#include <ATen/core/Tensor.h>

#include "pumeta/inference/upsample.h"

namespace pumeta {

/// Upsamples points float32 [N,3] as upsample_cloud() does with options.adaptation, θ'
/// adapted on the oracle pairs of gt float32 [M,3] (in the input's frame). InputError unless
/// the output ratio is the model's own (a single pass).
UpsampleResult upsample_with_oracle(const Backbone& model, const at::Tensor& points,
                                    const at::Tensor& gt, const UpsampleOptions& options);

}  // namespace pumeta
