#include "pumeta/geometry/patches.h"

#include <ATen/ATen.h>

#include <cmath>

#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"

namespace pumeta {

Patches extract_patches(const at::Tensor& cloud, const PatchOptions& options) {
    check_points(cloud, "extract_patches", 1);
    int64_t n_points = cloud.size(0);
    int64_t n = std::min(options.patch_size, n_points);
    auto num_seeds = static_cast<int64_t>(
        std::ceil(static_cast<double>(n_points) / options.patch_size * options.coverage));
    num_seeds = std::clamp<int64_t>(num_seeds, 1, n_points);
    Patches patches;
    patches.seeds = farthest_point_sampling(cloud, num_seeds, 0);
    at::Tensor seed_points = cloud.index_select(0, patches.seeds);
    patches.indices = knn(cloud, seed_points, n).indices;  // [P,n]
    at::Tensor points = cloud.index_select(0, patches.indices.flatten()).view({num_seeds, n, 3});
    patches.centers = points.mean(1);
    at::Tensor centred = points - patches.centers.unsqueeze(1);
    patches.scales = centred.norm(2, 2).amax(1).clamp_min(1e-12);
    patches.points = centred / patches.scales.view({-1, 1, 1});
    return patches;
}

at::Tensor denormalize_patches(const Patches& patches, const at::Tensor& results) {
    return results * patches.scales.view({-1, 1, 1}) + patches.centers.unsqueeze(1);
}

}  // namespace pumeta
