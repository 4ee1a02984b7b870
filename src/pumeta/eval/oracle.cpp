#include "pumeta/eval/oracle.h"

#include <ATen/ATen.h>

#include <algorithm>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/knn.h"

namespace pumeta {

UpsampleResult upsample_with_oracle(const Backbone& model, const at::Tensor& points,
                                    const at::Tensor& gt, const UpsampleOptions& options) {
    if (output_ratio(model, options.ratio) != model.ratio())
        throw_input_error("--tta-unit", "oracle adaptation needs a single pass (ratio {})",
                          model.ratio());
    check_points(gt, "oracle ground truth", 1);
    const int64_t r = model.ratio();
    auto pairs = [&](const at::Tensor& cloud, const Patches& patches,
                     const Normalization& frame) -> AdaptationPairs {
        const at::Tensor framed_gt = frame.apply(gt).contiguous();
        const int64_t m = std::min(patches.points.size(1) * r, framed_gt.size(0));
        at::Tensor seeds = cloud.index_select(0, patches.seeds);
        at::Tensor target =
            framed_gt.index_select(0, knn(framed_gt, seeds, m).indices.flatten()).view({-1, m, 3});
        target = (target - patches.centers.unsqueeze(1)) / patches.scales.view({-1, 1, 1});
        return {patches.points, target};
    };
    return upsample_cloud(model, points, options, pairs);
}

}  // namespace pumeta
