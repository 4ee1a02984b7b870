#include "pumeta/eval/grid_floor.h"

#include <ATen/ATen.h>

#include <algorithm>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/normalize.h"
#include "pumeta/geometry/patches.h"
#include "pumeta/geometry/sampling.h"

namespace pumeta {

at::Tensor grid_floor_output(const Backbone& model, const at::Tensor& points, const at::Tensor& gt,
                             int64_t ratio) {
    const double h = model.output_grid();
    if (!(h > 0))
        throw_input_error("--method grid-floor", "backbone {} has continuous outputs, no grid",
                          model.name());
    check_points(points, "grid-floor input", 1);
    check_points(gt, "grid-floor ground truth", 1);
    const Normalization frame = unit_sphere_normalization(points);
    const at::Tensor cloud = frame.apply(points).contiguous();
    const at::Tensor truth = frame.apply(gt).contiguous();
    PatchOptions options;
    options.patch_size = model.patch_size() * model.ratio() / ratio;  // as config_for_ratio
    const Patches patches = extract_patches(cloud, options);
    const int64_t n = patches.points.size(1);
    const int64_t m = std::min(n * ratio, truth.size(0));
    const at::Tensor seeds = cloud.index_select(0, patches.seeds);
    const at::Tensor near = knn(truth, seeds, m).indices;  // [P,m]
    std::vector<at::Tensor> outputs;
    for (int64_t p = 0; p < near.size(0); ++p) {
        const at::Tensor local =
            (truth.index_select(0, near[p]) - patches.centers[p]) / patches.scales[p];
        const auto [cells, inverse, counts] =
            at::unique_dim(at::floor(local / h).to(at::kLong), 0, true, false, true);
        const at::Tensor ranked = cells.index_select(0, std::get<1>(counts.sort(0, true)));
        const at::Tensor cycled =
            ranked.index_select(0, at::arange(n * ratio, at::kLong).remainder(ranked.size(0)));
        outputs.push_back((cycled.to(at::kFloat) + 0.5) * h * patches.scales[p] +
                          patches.centers[p]);
    }
    const at::Tensor candidates = at::cat(outputs).contiguous();
    const int64_t target = ratio * cloud.size(0);
    const at::Tensor picked =
        candidates.size(0) > target
            ? candidates.index_select(0, farthest_point_sampling(candidates, target, 0))
            : candidates;
    return frame.invert(picked);
}

}  // namespace pumeta
