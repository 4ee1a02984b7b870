#include "pumeta/geometry/patches.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <utility>
#include <vector>

#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/kdtree_partition.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"

namespace pumeta {

namespace {

/// `count` seeds of cloud [N,3]: FPS over the whole cloud, or, above part_points, over each
/// k-d tree part with the count split by part size (largest remainders get the rest).
at::Tensor choose_seeds(const at::Tensor& cloud, int64_t count, int64_t part_points) {
    const int64_t n_points = cloud.size(0);
    if (n_points <= part_points) return farthest_point_sampling(cloud, count, 0);
    std::vector<at::Tensor> parts = kdtree_partition(cloud, part_points);
    std::vector<int64_t> counts(parts.size());
    std::vector<std::pair<double, size_t>> remainders;
    int64_t assigned = 0;
    for (size_t i = 0; i < parts.size(); ++i) {
        double share = static_cast<double>(count) * parts[i].numel() / n_points;
        counts[i] = std::min<int64_t>(static_cast<int64_t>(share), parts[i].numel());
        assigned += counts[i];
        remainders.emplace_back(share - counts[i], i);
    }
    std::sort(remainders.begin(), remainders.end(), std::greater<>());
    for (size_t k = 0; assigned < count; k = (k + 1) % remainders.size()) {
        size_t i = remainders[k].second;
        if (counts[i] < parts[i].numel()) ++counts[i], ++assigned;
    }
    std::vector<at::Tensor> seeds;
    for (size_t i = 0; i < parts.size(); ++i) {
        if (counts[i] == 0) continue;
        at::Tensor local = farthest_point_sampling(cloud.index_select(0, parts[i]), counts[i], 0);
        seeds.push_back(parts[i].index_select(0, local));
    }
    return at::cat(seeds);
}

}  // namespace

Patches extract_patches(const at::Tensor& cloud, const PatchOptions& options) {
    check_points(cloud, "extract_patches", 1);
    int64_t n_points = cloud.size(0);
    int64_t n = std::min(options.patch_size, n_points);
    auto num_seeds = static_cast<int64_t>(
        std::ceil(static_cast<double>(n_points) / options.patch_size * options.coverage));
    num_seeds = std::clamp<int64_t>(num_seeds, 1, n_points);
    Patches patches;
    patches.seeds = choose_seeds(cloud, num_seeds, options.fps_part_points);
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
