// The unit-sphere frame of each cloud of a batch, as the released upsamplers normalise their
// patches (Grad-PU's and PU-Gaussian's normalize_point_cloud): centroid and furthest distance.
#pragma once

#include <ATen/ATen.h>

namespace pumeta {

/// Each cloud of x [B,M,3] on its unit sphere: centroid [B,1,3] and furthest distance [B,1,1]
/// from it (1 for a cloud of coincident points).
struct PatchFrame {
    at::Tensor centroid, radius;
    explicit PatchFrame(const at::Tensor& x) {
        centroid = x.mean(1, /*keepdim=*/true);
        radius = (x - centroid).norm(2, -1, /*keepdim=*/true).amax(1, /*keepdim=*/true);
        radius = at::where(radius > 0, radius, at::ones_like(radius));
    }
    at::Tensor apply(const at::Tensor& x) const { return (x - centroid) / radius; }
    at::Tensor invert(const at::Tensor& x) const { return x * radius + centroid; }
};

}  // namespace pumeta
