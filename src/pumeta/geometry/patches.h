// Cutting a cloud into overlapping local patches (seed + k nearest neighbours), each
// normalised to the unit sphere on its own, and mapping results back (docs/design.md,
// "Inference": the patch pipeline).
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

struct Patches {
    at::Tensor points;   ///< float32 [P,n,3], each patch centred and scaled to radius 1
    at::Tensor indices;  ///< int64 [P,n], rows of the source cloud
    at::Tensor centers;  ///< float32 [P,3], patch centroids in the cloud's frame
    at::Tensor scales;   ///< float32 [P], patch radii (points = (p - center) / scale)
    at::Tensor seeds;    ///< int64 [P], the seed point of each patch
};

struct PatchOptions {
    /// Points per patch n (clamped to the cloud size).
    int64_t patch_size = 256;
    /// Seeds = ceil(N / n · coverage): each point lies in about `coverage` patches.
    double coverage = 3.0;
    /// Clouds of more points pick their seeds part by part (kdtree_partition into parts of at
    /// most this many points, seeds in proportion to each part's size): FPS over the whole
    /// cloud costs N · seeds, quadratic in N (about 25 s for 1 M points, hours for 10 M).
    int64_t fps_part_points = 70000;
};

/// Patches of a cloud [N,3]: seeds by farthest point sampling (from point 0; per k-d tree part
/// above fps_part_points), each patch the seed's n nearest neighbours in the whole cloud;
/// then, while some points lie in no patch (dense regions of a cloud whose density varies),
/// more seeds by FPS among those points, one per n of them. Every point is in a patch.
/// Deterministic.
Patches extract_patches(const at::Tensor& cloud, const PatchOptions& options = {});

/// Maps per-patch results [P,m,3] in the patches' normalised frames back to the cloud frame.
at::Tensor denormalize_patches(const Patches& patches, const at::Tensor& results);

}  // namespace pumeta
