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
    KdTree tree(cloud);
    patches.indices = tree.query(cloud.index_select(0, patches.seeds), n).indices;  // [P,n]
    // Where density varies (scans: centimetres near the sensor, metres far away), seeds
    // spread evenly in space leave dense regions out of every patch. Cover them: seeds by
    // FPS among the points no patch holds, one per n of them, until every point is in a
    // patch. A seed is marked covered even if exact duplicates crowd it out of its own patch.
    at::Tensor covered = at::zeros({n_points}, at::kBool);
    covered.index_fill_(0, patches.indices.flatten(), true);
    std::vector<at::Tensor> seeds = {patches.seeds}, indices = {patches.indices};
    for (at::Tensor open = (~covered).nonzero().view(-1); open.numel() > 0;
         open = (~covered).nonzero().view(-1)) {
        const int64_t extra = (open.numel() + n - 1) / n;
        at::Tensor local =
            choose_seeds(cloud.index_select(0, open), extra, options.fps_part_points);
        at::Tensor added = open.index_select(0, local);
        at::Tensor rows = tree.query(cloud.index_select(0, added), n).indices;
        covered.index_fill_(0, rows.flatten(), true);
        covered.index_fill_(0, added, true);
        seeds.push_back(added);
        indices.push_back(rows);
    }
    patches.seeds = at::cat(seeds);
    patches.indices = at::cat(indices);
    num_seeds = patches.seeds.numel();
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
