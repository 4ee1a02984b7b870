// Whole-cloud upsampling with a trained backbone: normalise to the unit sphere, cut into
// overlapping patches of the network's size, upsample them in batches, merge their outputs
// and pick exactly ratio·N points (docs/design.md, "Inference"), with optional test-time
// adaptation (paper Algorithm 2) before predicting.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>

#include "pumeta/geometry/normalize.h"
#include "pumeta/geometry/patches.h"
#include "pumeta/inference/adaptation.h"
#include "pumeta/models/backbone.h"

namespace pumeta {

/// The pipeline's version: raised whenever the same model, input and options give other
/// points, so that cached results (eval/cell_cache.cpp) are recomputed. 2: every point in a
/// patch; whole-cloud inference for PU-Dense. 3: measured returns keep their input points.
/// 4: irregularly spaced inputs pick their outputs by FPS at any size. 5: noise-free
/// irregularly spaced inputs keep their input points.
inline constexpr int64_t kPipelineVersion = 5;

/// How a pass picks its exactly r·N output points from the patches' candidates.
enum class Selection {
    kFps,        ///< farthest point sampling over all candidates: an even output
    kOwnership,  ///< each input point's patch keeps the candidates nearest to it (about r·N,
                 ///< the few extra or missing at random): the output follows the input's density
};

struct UpsampleOptions {
    /// Output ratio; 0 = the model's. A power of the model's ratio (16 = 4 twice) applies the
    /// model repeatedly (output_ratio()).
    int64_t ratio = 0;
    /// Patches per forward pass (bounds memory); 0 = the backbone's inference_batch_patches().
    int64_t batch_patches = 0;
    /// Each input point lies in about this many patches.
    double coverage = 3.0;
    /// Seed of the test-time downsampler (the only randomness of the pipeline).
    uint64_t seed = 0;
    /// Test-time adaptation before predicting (none by default).
    Adaptation adaptation;
    /// The final selection. Unset: FPS up to kFpsMaxCandidates for irregularly spaced inputs
    /// that are not scans (kMeasuredSpacingSpread < spacing_spread() <= kScanSpacingSpread:
    /// measured returns, random subsets); for the others FPS when (candidates × output
    /// points) is at most fps_budget, else ownership. 2,048 -> 8,192 (2e8), 2,048 -> 16,384
    /// (8e8) and the second 4× pass of 16× (3.2e9) take FPS; 10k inputs at 4× (4.8e9)
    /// ownership, which on large scans keeps the near field's density (docs/design.md,
    /// "Large clouds").
    std::optional<Selection> selection;
    double fps_budget = 4e9;
    /// Density-aware bound (0 = off): each output point is pulled towards its nearest input
    /// point p until it lies within spacing_bound × (the distance from p to p's nearest other
    /// input point), so that no network spreads children farther than the input's own spacing
    /// there (sparse far-range scan returns; docs/design.md, "Scans").
    double spacing_bound = 0;
    /// Line projection (0 = off): where an input point's 8 nearest input points lie on a line
    /// (linearity (λ1 − λ2)/λ1 of their covariance above this), output points whose nearest
    /// input point it is move onto that line through it (scan lines of sparse sweeps).
    /// Unset: kScanLineLinearity for scans (InputKind::kScan), else off.
    std::optional<double> line_projection;
    /// Whole-cloud inference (PU-Dense's own protocol) instead of patches: the cloud, scaled
    /// so that its median point spacing equals that of the patches the pipeline would cut,
    /// runs through the network in one piece, or in k-d tree parts of at most this many
    /// points (adaptation, if any, still adapts on the patches). 0 = patches; unset = the
    /// backbone's choice (Backbone::inference_whole_cloud_points; docs/design.md,
    /// "Where PU-Dense's error comes from").
    std::optional<int64_t> whole_cloud_points;
    /// Keep the input points among the outputs (r·N = the N inputs + (r−1)·N network
    /// points). Unset: for scans and measured returns (classify_input(): InputKind::kScan,
    /// kMeasured); docs/design.md, "Scans".
    std::optional<bool> keep_input;
    /// A progress bar over the patch batches on a terminal (`pumeta upsample`; off inside
    /// `pumeta eval`, which has its own).
    bool show_progress = false;
};

struct UpsampleResult {
    at::Tensor points;  ///< float32 [ratio·N, 3], in the input's frame
    int64_t n_in = 0;
    int64_t patches = 0;     ///< patches upsampled (all passes)
    double seconds = 0;      ///< total wall time
    double tta_seconds = 0;  ///< of which adaptation
    /// The inner loss before and after adaptation: self-supervised L(F(X↓), X), or the loss
    /// on a PairSource's pairs (NaN without adaptation).
    double loss_before = std::numeric_limits<double>::quiet_NaN();
    double loss_after = std::numeric_limits<double>::quiet_NaN();
};

/// The 90th over the 10th percentile of the distances from the points of cloud [N,3] to their
/// nearest other point (1 for N < 3 or coincident points): about 1.3–1.8 for Poisson-disk
/// samples of surfaces (with noise up to 3.3), 2.0–3.9 for random subsets of simulated aerial
/// line scans, about 4.7 for uniformly random points on a surface, 9–11 for simulated 32-beam
/// sweeps.
double spacing_spread(const at::Tensor& cloud);
/// The shape of the surface the points of cloud [N,3] lie on, against their spacing, from
/// each point's 16 nearest neighbours (one k-NN and one eigen-decomposition for both).
struct SurfaceShape {
    /// How thin: the median over points of the standard deviation along the least direction
    /// of their neighbours (sqrt of the least eigenvalue of the neighbourhood covariance),
    /// over the median nearest-neighbour distance. About 0.04–0.08 for simulated aerial scans
    /// (roofs and ground, planar at their spacing), 0.03–0.7 for the 2,048-point samples of
    /// meshes (median 0.5: curved at that spacing), 0.3–0.8 with noise of the order of the
    /// spacing.
    double thickness = 0;
    /// How far off a smooth surface: the 10th percentile over points of the RMS residual of a
    /// quadric height field fitted to their neighbours (over the neighbourhood's principal
    /// plane), over the median nearest-neighbour distance; at most 50,000 evenly strided
    /// points are fitted. A quadric follows a surface's curvature, so noise-free samples score
    /// near 0 however curved at their spacing (a tenth of the points on smooth parts is
    /// enough): 0.000–0.016 for 17 of 24 random 25,000- and 12,500-point subsets of `val`
    /// objects (the other 7, with fine detail at their spacing, 0.15–0.55), against 0.05–0.6
    /// for the same with noise of 0.5–2 % (docs/design.md, "Scans").
    double roughness = 0;
};
/// Both 0 for N < 16 or coincident points.
SurfaceShape surface_shape(const at::Tensor& cloud);
/// surface_shape(cloud).thickness.
double surface_thickness(const at::Tensor& cloud);
/// surface_shape(cloud).roughness.
double surface_roughness(const at::Tensor& cloud);

/// What the pipeline takes an input for (docs/design.md, "Scans").
enum class InputKind {
    kSampled,   ///< an even sample of surfaces (the meshes' Poisson-disk inputs) or a thick one
    kMeasured,  ///< points on their surface, irregularly spaced but evenly dense:
                ///< spacing_spread() > kMeasuredSpacingSpread and either returns on thin
                ///< surfaces (aerial LiDAR; surface_thickness() < kMeasuredThickness) or
                ///< noise-free points (a random subset of a denser cloud; surface_roughness()
                ///< < kExactRoughness); keeps the input points
    kScan,      ///< density varying with range (spinning and terrestrial sweeps):
                ///< spacing_spread() > kScanSpacingSpread; keeps the input points and projects
                ///< outputs onto scan lines
};
InputKind classify_input(const at::Tensor& cloud);
/// The same with the cloud's spacing_spread() already computed (its surface_shape() is then
/// computed only where the spread leaves the kind open).
InputKind classify_input(const at::Tensor& cloud, double spread);
/// The same from the cloud's spacing_spread() and surface_shape().
InputKind classify_input(double spread, const SurfaceShape& shape);
/// "sampled", "measured" or "scan".
const char* input_kind_name(InputKind kind);

/// Above this spacing_spread() a pass treats its input as a scan.
inline constexpr double kScanSpacingSpread = 6.0;
/// Above this spacing_spread() and below kMeasuredThickness, as measured returns.
inline constexpr double kMeasuredSpacingSpread = 1.9;
inline constexpr double kMeasuredThickness = 0.15;
/// Or above that spread and below this surface_roughness() (noise-free points).
inline constexpr double kExactRoughness = 0.03;
/// The most candidates the default selection gives to FPS (the pruned one: 200,000 -> 50,000
/// in about 0.1 s).
inline constexpr int64_t kFpsMaxCandidates = 4'000'000;
/// The line projection's linearity threshold for scans.
inline constexpr double kScanLineLinearity = 0.3;

/// The output ratio of `model` for a requested one: the model's own for 0, else `requested`,
/// which must be a power of the model's ratio (InputError naming both otherwise).
int64_t output_ratio(const Backbone& model, int64_t requested);

/// Pairs that one θ' adapts on: input float32 [P,n,3] -> target [P,m,3], in patch frames.
struct AdaptationPairs {
    at::Tensor input;
    at::Tensor target;
};

/// Supplies the adaptation pairs of a pass in place of the unit's, from the pass's cloud
/// float32 [N,3] in the unit-sphere frame `frame` of the input, and its patches. An evaluation
/// tool (eval/oracle.h: pairs from the ground truth), never the default path.
using PairSource = std::function<AdaptationPairs(const at::Tensor& cloud, const Patches& patches,
                                                 const Normalization& frame)>;

/// Upsamples a cloud float32 [N,3] (N >= 1) to exactly ratio·N points, adapting first when
/// options.adaptation is enabled (on `pairs`' pairs when given: one θ' per pass, the unit
/// ignored). The model is never modified. Same inputs and seed, same output.
UpsampleResult upsample_cloud(const Backbone& model, const at::Tensor& points,
                              const UpsampleOptions& options, const PairSource& pairs = nullptr);

/// The non-learned baseline, as the published one: the midpoints from each point to its 2r
/// nearest neighbours, the point itself included (k nearest others when k > 0), then exactly
/// ratio·N distinct ones: farthest point sampling while its cost (candidates × output points)
/// is within `fps_budget` (the network's, so every test set keeps FPS), else weighted sample
/// elimination with the Poisson-disk radius of ratio·N points on the area the input covers,
/// which is O(M log M). A multiple of 4 above 4 is 4x, then the rest (k = 0). No position
/// repeats unless the
/// input repeats it (fewer than ratio·N distinct midpoints are joined by more).
at::Tensor midpoint_upsample(const at::Tensor& points, int64_t ratio, int64_t k = 0,
                             double fps_budget = UpsampleOptions().fps_budget);

}  // namespace pumeta
