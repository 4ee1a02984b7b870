// PU-GAN's uniformity loss (the code's get_uniform_loss, not the paper's formula; see
// docs/design.md), in the two variants the Table I backbones train with: PU-GAN's square
// lattice spacing and Meta-PU's hexagonal one.
#pragma once

#include <ATen/core/Tensor.h>

#include <vector>

namespace pumeta {

/// Expected nearest-neighbour spacing of n points spread evenly over a disk of area π·p.
enum class UniformSpacing {
    kSquare,     ///< d̂ = √(π p / n) (PU-GAN)
    kHexagonal,  ///< d̂ = √(2 π p / (√3 n)) (Meta-PU)
};

struct UniformLossOptions {
    /// Disk sizes p as fractions of the unit-radius patch area: each disk has radius √p and
    /// expects n_p = ⌊M p⌋ of the M points.
    std::vector<double> percentages = {0.004, 0.006, 0.008, 0.010, 0.012};
    /// Seeds (disk centres) per cloud: ⌊M · seed_fraction⌋ by farthest-point sampling.
    double seed_fraction = 0.05;
    UniformSpacing spacing = UniformSpacing::kSquare;
};

/// PU-GAN's settings (the defaults above).
UniformLossOptions pugan_uniform_options();
/// Meta-PU's: p ∈ {0.4, 0.8, 1.0, 1.2, 1.6} %, hexagonal spacing.
UniformLossOptions metapu_uniform_options();

/// For points [B,M,3] (float or double): for every p, in every disk around the FPS seeds take
/// the first n_p points within radius √p (index order; fewer found: padded by repeating the
/// first hit), each member's distance d to its nearest other member, and
/// (d − d̂)² / d̂ averaged over all disks and members, times (100 p)²; the loss is the mean
/// over the p values (a scalar). Distances are sqrt(|d|² + 1e-8) as in the original, so a
/// padding copy counts at 1e-4: the padding acts as the original's implicit penalty on disks
/// with too few points. A p with n_p < 2 (small clouds) has no nearest other member and is
/// left out of the mean; with none left the loss is 0. There are max(1, ⌊M · seed_fraction⌋)
/// seeds. Seeds, ball queries and nearest members are chosen without
/// gradient tracking; the distances are recomputed from coordinate differences, so the loss
/// is differentiable twice with respect to the points.
/// InputError for fewer than 2 points, percentages outside (0, 1] or seed_fraction outside
/// (0, 1].
at::Tensor uniform_loss(const at::Tensor& points, const UniformLossOptions& options = {});

}  // namespace pumeta
