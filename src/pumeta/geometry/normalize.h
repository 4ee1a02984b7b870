// Similarity transforms that bring clouds to a canonical frame, and their inverses.
#pragma once

#include <ATen/core/Tensor.h>

namespace pumeta {

/// p' = (p - center) * scale. center: float32 [3].
struct Normalization {
    at::Tensor center;
    double scale = 1.0;

    /// points: floating [...,3] ([N,3], or [B,N,3] with the same transform for every batch
    /// element; per-patch transforms are in patches.h). An undefined center counts as 0.
    at::Tensor apply(const at::Tensor& points) const;
    /// The inverse, p = p' / scale + center.
    at::Tensor invert(const at::Tensor& points) const;
};

enum class CenterMode {
    kCentroid,     ///< mean of the points (PU-GAN's mesh normalisation)
    kBoundingBox,  ///< centre of the axis-aligned bounding box (the evaluation frame)
};

/// The transform mapping `points` [N,3] to center 0 and largest point radius 1.
/// A cloud of one point (or all points equal) gets scale 1.
Normalization unit_sphere_normalization(const at::Tensor& points,
                                        CenterMode mode = CenterMode::kCentroid);

}  // namespace pumeta
