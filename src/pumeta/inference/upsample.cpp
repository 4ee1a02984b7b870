#include "pumeta/inference/upsample.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <mutex>
#include <optional>
#include <random>

#include "pumeta/core/error.h"
#include "pumeta/core/progress.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/core/threads.h"
#include "pumeta/geometry/kdtree_partition.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/patches.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/downsample.h"

namespace pumeta {

namespace {

using Clock = std::chrono::steady_clock;

// Patches are split into at least this many batches where there are as many patches, so that
// up to this many threads have work: a function of the patch count, never of the threads.
constexpr int64_t kMinBatches = 8;

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

/// Whether (candidates × output points) is within the FPS budget (UpsampleOptions).
bool fps_affordable(int64_t candidates, int64_t count, double budget) {
    return static_cast<double>(candidates) * static_cast<double>(count) <= budget;
}

/// The distinct points of float32 [N,3] `points` and of the midpoints from each to its k
/// nearest others, none equal to a point of `exclude`: the candidates of the midpoint baseline
/// (the midpoint of a point with itself is the point).
at::Tensor midpoint_candidates(const at::Tensor& points, int64_t k, const at::Tensor& exclude) {
    k = std::min(k, points.size(0) - 1);
    at::Tensor candidates = points;
    if (k > 0) {
        at::Tensor neighbours = knn(points, points, k + 1).indices.slice(1, 1);
        at::Tensor mids =
            (points.unsqueeze(1) +
             points.index_select(0, neighbours.flatten()).view({points.size(0), k, 3})) *
            0.5f;
        candidates = at::cat({points, mids.reshape({-1, 3})}).contiguous();
    }
    return candidates.index_select(0, distinct_points(candidates, exclude));
}

/// At least `count` distinct points, none in `exclude`: those of `base` (distinct points) and,
/// where they are too few, the midpoints between them over more neighbours each round. Fewer
/// only when `base` is too small to make enough.
at::Tensor with_midpoints(const at::Tensor& base, int64_t count, const at::Tensor& exclude) {
    at::Tensor grown =
        exclude.defined() ? base.index_select(0, distinct_points(base, exclude)) : base;
    for (int64_t k = 1; grown.size(0) < count && k < base.size(0); k *= 2)
        grown = midpoint_candidates(base, k, exclude);
    return grown;
}

/// Exactly `count` points out of candidates, none twice and none equal to a point of `exclude`
/// (the input points an output keeps): FPS when `fps`, else a random subset. Candidates with
/// fewer such points than `count` are first joined by midpoints between them; only candidates
/// that cannot make enough (nearly all in one place) repeat some.
at::Tensor select_exactly(const at::Tensor& candidates, int64_t count, bool fps, uint64_t seed,
                          const at::Tensor& exclude = {}) {
    if (candidates.size(0) == 0)
        throw InternalError("upsample: no candidate points to select from");
    at::Tensor base = candidates.index_select(0, distinct_points(candidates));
    at::Tensor pool = with_midpoints(base, count, exclude);
    int64_t m = pool.size(0);
    if (m == count) return pool;
    if (m > count && fps)
        return pool.index_select(0, farthest_point_sampling_pruned(pool, count, 0));
    if (m > count) return pool.index_select(0, random_subset(m, count, seed));
    if (m == 0) {  // every candidate is a kept input point
        pool = base;
        m = pool.size(0);
    }
    spdlog::warn(
        "upsample: the candidates make {} distinct positions for {} output points; some repeat", m,
        count);
    const int64_t copies = count / m;
    at::Tensor repeated = pool.repeat({copies, 1});
    if (count == copies * m) return repeated;
    at::Tensor extra = pool.index_select(0, random_subset(m, count - copies * m, seed));
    return at::cat({repeated, extra});
}

/// Each point's neighbours q − q̄, centred on their mean: cloud [N,3], indices int64 [N,k]
/// into it -> float64 [N,k,3].
at::Tensor centred_neighbours(const at::Tensor& cloud, const at::Tensor& indices) {
    at::Tensor neighbours = cloud.index_select(0, indices.flatten()).view({-1, indices.size(1), 3});
    return (neighbours - neighbours.mean(1, /*keepdim=*/true)).to(at::kDouble);
}

/// The scatter matrix Σ (q − q̄)(q − q̄)ᵀ of centred neighbours [N,k,3] -> [N,3,3].
at::Tensor scatter(const at::Tensor& centred) { return centred.transpose(1, 2).matmul(centred); }

/// The scatter matrix over each point's neighbours: cloud [N,3], indices [N,k] -> [N,3,3].
at::Tensor neighbourhood_scatter(const at::Tensor& cloud, const at::Tensor& indices) {
    return scatter(centred_neighbours(cloud, indices));
}

/// Pulls every output point q towards its nearest input point p until
/// |q − p| <= bound · (distance from p to its nearest other input point).
/// cloud [N,3], outputs [..., 3] (same frame) -> outputs' shape.
at::Tensor project_onto_lines(const at::Tensor& cloud, const at::Tensor& outputs,
                              double threshold) {
    const int64_t k = std::min<int64_t>(8, cloud.size(0));
    if (k < 3) return outputs;
    KdTree tree(cloud);
    auto [values, vectors] =
        at::linalg_eigh(neighbourhood_scatter(cloud, tree.query(cloud, k).indices));
    at::Tensor largest = values.select(1, 2);
    at::Tensor linear = (largest - values.select(1, 1)) > threshold * largest.clamp_min(1e-300);
    at::Tensor axis = vectors.select(2, 2).to(cloud.scalar_type());  // [N,3]
    at::Tensor flat = outputs.reshape({-1, 3}).contiguous();
    at::Tensor parent = tree.query(flat, 1).indices.squeeze(1);
    at::Tensor source = cloud.index_select(0, parent);
    at::Tensor direction = axis.index_select(0, parent);
    at::Tensor along = source + ((flat - source) * direction).sum(1, true) * direction;
    return at::where(linear.index_select(0, parent).unsqueeze(1), along, flat)
        .view(outputs.sizes());
}

at::Tensor bound_to_spacing(const at::Tensor& cloud, const at::Tensor& outputs, double bound) {
    if (cloud.size(0) < 2) return outputs;
    at::Tensor flat = outputs.reshape({-1, 3}).contiguous();
    KdTree tree(cloud);
    at::Tensor spacing = tree.query(cloud, 2).sq_distances.select(1, 1).sqrt();  // [N]
    KnnResult nearest = tree.query(flat, 1);
    at::Tensor parent = nearest.indices.squeeze(1);
    at::Tensor radius = spacing.index_select(0, parent) * bound;
    at::Tensor source = cloud.index_select(0, parent);
    at::Tensor offset = flat - source;
    at::Tensor length = offset.norm(2, 1);
    at::Tensor shrink =
        at::where(length > radius, radius / length.clamp_min(1e-30), at::ones_like(length));
    return (source + offset * shrink.unsqueeze(1)).view(outputs.sizes());
}

/// Marks the outputs of each patch that fall in the region the patch "owns": an output point
/// survives when the nearest input point to it has the patch's seed as its nearest seed.
/// Each input point thus contributes through one patch only, giving about ratio·N points.
/// Returns bool [P·m] over the outputs in patch order.
at::Tensor merge_by_ownership(const at::Tensor& cloud, const Patches& patches,
                              const at::Tensor& outputs /*[P,m,3]*/) {
    at::Tensor seed_points = cloud.index_select(0, patches.seeds);
    at::Tensor owner = knn(seed_points, cloud, 1).indices.squeeze(1);  // [N] patch id
    int64_t p = outputs.size(0), m = outputs.size(1);
    at::Tensor flat = outputs.reshape({p * m, 3}).contiguous();
    at::Tensor nearest_input = knn(cloud, flat, 1).indices.squeeze(1);  // [P·m]
    at::Tensor patch_of_output = at::arange(p, at::kLong).repeat_interleave(m);
    return owner.index_select(0, nearest_input) == patch_of_output;
}

/// X↓ of dense [B,M,3]: the adaptation's sampler's M/r points, else the backbone's own.
at::Tensor downsample_for_adaptation(const Backbone& model, const at::Tensor& dense,
                                     const Adaptation& adaptation, uint64_t seed) {
    if (!adaptation.downsampler) return model.downsample(dense, seed);
    return downsample_points(dense, std::max<int64_t>(1, dense.size(1) / model.ratio()),
                             to_string(*adaptation.downsampler), seed);
}

/// The self-supervised pairs of the "cloud" unit: X↓ = the downsampler on the whole cloud
/// (N/r points), cut into patches of the network's size; each is paired with the
/// patch_size·r points of X nearest to its seed, both normalised by that target's centroid
/// and radius (as training pairs are). The network thus adapts on inputs of its usual size
/// and density relative to the patch, one scale coarser, where the "object" unit feeds it
/// patch_size/r-point downsamples of its 256-point patches.
AdaptationPairs cloud_scale_pairs(const Backbone& model, const at::Tensor& cloud,
                                  const PatchOptions& patch_options, const Adaptation& adaptation,
                                  uint64_t seed) {
    const int64_t r = model.ratio();
    if (cloud.size(0) / r < 2)
        throw_input_error("--tta-unit cloud", "{} points are too few to downsample by {}",
                          cloud.size(0), r);
    at::Tensor down = downsample_for_adaptation(model, cloud.unsqueeze(0), adaptation, seed)
                          .squeeze(0)
                          .contiguous();
    Patches patches = extract_patches(down, patch_options);
    const int64_t n = patches.points.size(1);
    const int64_t m = std::min(n * r, cloud.size(0));
    at::Tensor seeds = down.index_select(0, patches.seeds);
    at::Tensor target =
        cloud.index_select(0, knn(cloud, seeds, m).indices.flatten()).view({-1, m, 3});
    at::Tensor input = down.index_select(0, patches.indices.flatten()).view({-1, n, 3});
    at::Tensor center = target.mean(1, /*keepdim=*/true);
    at::Tensor scale = (target - center).norm(2, 2).amax(1).clamp_min(1e-12).view({-1, 1, 1});
    return {(input - center) / scale, (target - center) / scale};
}

/// How a pass treats its input: as a scan or not (UpsampleOptions::keep_input,
/// line_projection).
struct ScanHandling {
    bool keep_input = false;
    double line_projection = 0;
    std::optional<Selection> selection;
    bool irregular = false;  ///< spaced irregularly but evenly dense: measured returns, subsets
    double fps_budget = 0;

    ScanHandling(const at::Tensor& cloud, const UpsampleOptions& options)
        : selection(options.selection), fps_budget(options.fps_budget) {
        if (options.keep_input && options.line_projection && options.selection) {
            keep_input = *options.keep_input;
            line_projection = *options.line_projection;
            return;
        }
        const double spread = spacing_spread(cloud);
        const InputKind kind = classify_input(cloud, spread);
        const bool scan = kind == InputKind::kScan;
        irregular = !scan && spread > kMeasuredSpacingSpread;
        keep_input = options.keep_input.value_or(kind != InputKind::kSampled);
        line_projection = options.line_projection.value_or(scan ? kScanLineLinearity : 0.0);
    }

    /// Whether FPS picks `count` of `candidates` points (else ownership, or at random where
    /// there is none).
    bool fps(int64_t candidates, int64_t count) const {
        if (selection) return *selection == Selection::kFps;
        if (irregular) return candidates <= kFpsMaxCandidates;
        return fps_affordable(candidates, count, fps_budget);
    }

    /// The candidates [..., 3] after the line projection.
    at::Tensor place(const at::Tensor& cloud, const at::Tensor& candidates) const {
        return line_projection > 0 ? project_onto_lines(cloud, candidates, line_projection)
                                   : candidates;
    }

    /// Exactly r·N points: the input points and (r−1)·N candidates when it keeps them, else
    /// r·N candidates. `select(count, exclude)` picks a count of points, none equal to one of
    /// `exclude` (the kept input, else none).
    at::Tensor output(const at::Tensor& cloud, int64_t r,
                      const std::function<at::Tensor(int64_t, const at::Tensor&)>& select) const {
        if (!keep_input) return select(r * cloud.size(0), at::Tensor());
        return at::cat({cloud, select((r - 1) * cloud.size(0), cloud)});
    }
};

/// Median over the points of clouds [B,n,3] of the distance to their nearest other point.
double median_spacing(const at::Tensor& clouds) {
    at::Tensor sq = knn(clouds, clouds, 2).sq_distances.select(-1, 1);
    return sq.flatten().median().sqrt().item<double>();
}

/// Whole-cloud inference (UpsampleOptions::whole_cloud_points): the cloud, scaled to the
/// median point spacing of its patches, through the network with `params`, in k-d tree parts
/// of at most `part_points`; exactly r·N points.
at::Tensor upsample_whole(const Backbone& model, const ParamMap& params, const at::Tensor& cloud,
                          const Patches& patches, int64_t part_points,
                          const UpsampleOptions& options, UpsampleResult& result) {
    const double scale = cloud.size(0) < 2 || patches.points.size(1) < 2
                             ? 1.0
                             : median_spacing(patches.points) / median_spacing(cloud);
    std::vector<at::Tensor> parts =
        cloud.size(0) <= part_points ? std::vector<at::Tensor>{at::arange(cloud.size(0), at::kLong)}
                                     : kdtree_partition(cloud, part_points);
    // The parts run concurrently, each on one thread (core/threads.h): the same bits whatever
    // the thread count.
    std::vector<at::Tensor> outputs(parts.size());
    at::NoGradGuard no_grad;
    for_each_concurrently(static_cast<int64_t>(parts.size()), [&](int64_t i) {
        at::Tensor points = cloud.index_select(0, parts[i]);
        at::Tensor centre = points.mean(0, /*keepdim=*/true);
        at::Tensor x = ((points - centre) * scale).unsqueeze(0);
        outputs[i] = model.upsample(x, params).squeeze(0) / scale + centre;
    });
    result.patches += static_cast<int64_t>(parts.size());
    const ScanHandling scan(cloud, options);
    at::Tensor candidates = scan.place(cloud, at::cat(outputs)).contiguous();
    return scan.output(cloud, model.ratio(), [&](int64_t count, const at::Tensor& exclude) {
        return select_exactly(candidates, count, scan.fps(candidates.size(0), count), options.seed,
                              exclude);
    });
}

/// The backbone's own whole-cloud pipeline (Backbone::cloud_candidates) with `params`, then
/// the same selection of exactly r·N points as the patches' (FPS over distinct candidates,
/// scans keeping their input points).
at::Tensor upsample_own(const Backbone& model, const ParamMap& params, const at::Tensor& cloud,
                        const UpsampleOptions& options, UpsampleResult& result) {
    at::Tensor candidates;
    {
        ThreadCountGuard one_thread(1);
        candidates = model.cloud_candidates(cloud, params, options.seed);
    }
    result.patches += 1;
    const ScanHandling scan(cloud, options);
    candidates = scan.place(cloud, candidates).contiguous();
    return scan.output(cloud, model.ratio(), [&](int64_t count, const at::Tensor& exclude) {
        return select_exactly(candidates, count, scan.fps(candidates.size(0), count), options.seed,
                              exclude);
    });
}

at::Tensor upsample_once(const Backbone& model, const at::Tensor& cloud,
                         const UpsampleOptions& options, const Normalization& frame,
                         const PairSource& pair_source, UpsampleResult& result) {
    int64_t r = model.ratio();
    PatchOptions patch_options;
    patch_options.patch_size = model.patch_size();
    patch_options.coverage = options.coverage;
    Patches patches = extract_patches(cloud, patch_options);
    int64_t num_patches = patches.points.size(0);

    // Test-time adaptation (Algorithm 2): θ' from N steps on L(F_θ(X↓), X).
    const Adaptation& adaptation = options.adaptation;
    ParamMap object_params = model.parameters();
    auto tta_start = Clock::now();
    // Adaptation runs on one thread (core/threads.h): its gradients then have the same bits
    // whatever the thread count.
    auto adapt_pairs = [&](const at::Tensor& input, const at::Tensor& target) {
        ThreadCountGuard one_thread(1);
        std::vector<double> losses;
        ParamMap adapted = adapt(model, model.parameters(), input, target, adaptation.inner,
                                 adaptation.step_sizes, /*create_graph=*/false, &losses);
        // A diverged adaptation (as meta-training drops, kDivergedInnerLoss) would return
        // garbage: keep θ and say so.
        if (inner_loop_diverged(losses)) {
            spdlog::warn(
                "test-time adaptation diverged (self-supervised loss {} -> {}); using "
                "the unadapted model; try a smaller --tta-lr",
                losses.front(), losses.back());
            adapted = model.parameters();
            losses.back() = losses.front();
        }
        return std::make_pair(adapted, losses);
    };
    auto adapt_on = [&](const at::Tensor& x, uint64_t seed) {
        return adapt_pairs(downsample_for_adaptation(model, x, adaptation, seed), x);
    };
    // The one-θ' units adapt on at most max_patches pairs (a seeded subset).
    auto subset = [&](int64_t rows) {
        return rows <= adaptation.max_patches
                   ? at::arange(rows, at::kLong)
                   : random_subset(rows, adaptation.max_patches, options.seed);
    };
    const bool per_patch = adaptation.unit == AdaptationUnit::kPatch && !pair_source;
    const int64_t whole_cloud = options.whole_cloud_points ? *options.whole_cloud_points
                                                           : model.inference_whole_cloud_points();
    if (whole_cloud > 0 && adaptation.enabled() && per_patch)
        throw_input_error("--tta-unit",
                          "patch adapts each patch, but whole-cloud inference "
                          "(--whole-cloud) runs none; use object or cloud");
    const bool own_pipeline = model.has_cloud_pipeline() && whole_cloud <= 0;
    if (own_pipeline && adaptation.enabled() && per_patch)
        throw_input_error("--tta-unit",
                          "patch adapts each patch, but {} upsamples the whole cloud by its "
                          "own pipeline; use object or cloud",
                          model.name());
    if (adaptation.enabled() && !per_patch) {
        std::pair<ParamMap, std::vector<double>> adapted;
        if (adaptation.unit == AdaptationUnit::kObject && !pair_source) {
            adapted = adapt_on(patches.points.index_select(0, subset(num_patches)), options.seed);
        } else {
            AdaptationPairs pairs = pair_source ? pair_source(cloud, patches, frame)
                                                : cloud_scale_pairs(model, cloud, patch_options,
                                                                    adaptation, options.seed);
            at::Tensor rows = subset(pairs.input.size(0));
            adapted =
                adapt_pairs(pairs.input.index_select(0, rows), pairs.target.index_select(0, rows));
        }
        object_params = std::move(adapted.first);
        result.loss_before = adapted.second.front();
        result.loss_after = adapted.second.back();
    }
    result.tta_seconds += seconds_since(tta_start);
    if (own_pipeline) return upsample_own(model, object_params, cloud, options, result);
    if (whole_cloud > 0)
        return upsample_whole(model, object_params, cloud, patches, whole_cloud, options, result);
    result.patches += num_patches;

    // The patches go through the network in batches of a fixed composition (the model's batch
    // size, never the thread count), batches run concurrently, each on one thread
    // (core/threads.h), so that the outputs have the same bits whatever the thread count; with
    // per-patch adaptation each patch is such a unit. The geometry around it (patches, kNN,
    // FPS) is parallel inside, as its results do not depend on the thread count.
    const int64_t batch =
        adaptation.enabled() && per_patch
            ? 1
            : std::min(options.batch_patches > 0 ? options.batch_patches
                                                 : model.inference_batch_patches(),
                       std::max<int64_t>(1, (num_patches + kMinBatches - 1) / kMinBatches));
    const int64_t num_batches = (num_patches + batch - 1) / batch;
    std::vector<at::Tensor> outputs(num_batches);
    std::vector<double> before(num_batches, 0), after(num_batches, 0),
        adapt_seconds(num_batches, 0);
    std::optional<ProgressBar> progress;
    if (options.show_progress) progress.emplace(num_patches, fmt::format("upsample x{}", r));
    std::mutex progress_mutex;
    int64_t patches_done = 0;
    for_each_concurrently(num_batches, [&](int64_t b) {
        const int64_t start = b * batch, end = std::min(num_patches, start + batch);
        at::Tensor chunk = patches.points.slice(0, start, end);
        if (adaptation.enabled() && per_patch) {
            auto t0 = Clock::now();
            auto [adapted, losses] = adapt_on(chunk, options.seed + start);
            adapt_seconds[b] = seconds_since(t0);
            before[b] = losses.front();
            after[b] = losses.back();
            at::NoGradGuard no_grad;
            outputs[b] = model.upsample(chunk, adapted);
        } else {
            at::NoGradGuard no_grad;
            outputs[b] = model.upsample(chunk, object_params);
        }
        if (progress) {
            std::lock_guard<std::mutex> lock(progress_mutex);
            patches_done += end - start;
            progress->update(patches_done, fmt::format("{} patches", num_patches));
        }
    });
    if (progress) progress->finish();
    if (adaptation.enabled() && per_patch) {
        double before_sum = 0, after_sum = 0;
        for (int64_t b = 0; b < num_batches; ++b) {
            before_sum += before[b];
            after_sum += after[b];
            result.tta_seconds += adapt_seconds[b];
        }
        result.loss_before = before_sum / num_patches;
        result.loss_after = after_sum / num_patches;
    }
    at::Tensor upsampled = denormalize_patches(patches, at::cat(outputs));  // [P, m, 3]
    if (options.spacing_bound > 0)
        upsampled = bound_to_spacing(cloud, upsampled, options.spacing_bound);
    const ScanHandling scan(cloud, options);
    upsampled = scan.place(cloud, upsampled);
    return scan.output(cloud, r, [&](int64_t target, const at::Tensor& exclude) {
        at::Tensor candidates = upsampled.reshape({-1, 3}).contiguous();
        if (scan.fps(candidates.size(0), target))
            return select_exactly(candidates, target, /*fps=*/true, options.seed, exclude);
        // The merge leaves about r·N points: the few extra go at random (an FPS over all of
        // them to drop a few hundred would cost as much as the network), the few missing are
        // drawn from the outputs it dropped.
        at::Tensor owned = merge_by_ownership(cloud, patches, upsampled);
        at::Tensor kept = candidates.index({owned});
        kept = kept.index_select(0, distinct_points(kept, exclude));
        if (kept.size(0) >= target) return select_exactly(kept, target, false, options.seed);
        at::Tensor taken = exclude.defined() ? at::cat({exclude, kept}) : kept;
        at::Tensor dropped = candidates.index({owned.logical_not()});
        at::Tensor fill = select_exactly(dropped.size(0) ? dropped : kept, target - kept.size(0),
                                         false, options.seed, taken);
        return at::cat({kept, fill});
    });
}

}  // namespace

double spacing_spread(const at::Tensor& cloud) {
    check_points(cloud, "spacing_spread", 1);
    if (cloud.size(0) < 3) return 1.0;
    at::Tensor spacing = knn(cloud, cloud, 2).sq_distances.select(1, 1).sqrt().to(at::kDouble);
    at::Tensor q = at::quantile(spacing, at::tensor({0.1, 0.9}, spacing.options()));
    const double low = q[0].item<double>(), high = q[1].item<double>();
    return low > 0 ? high / low : (high > 0 ? std::numeric_limits<double>::infinity() : 1.0);
}

SurfaceShape surface_shape(const at::Tensor& cloud) {
    check_points(cloud, "surface_shape", 1);
    constexpr int64_t kNeighbours = 16;
    constexpr int64_t kMaxFits = 50'000;
    const int64_t n = cloud.size(0);
    if (n < kNeighbours) return {};
    KnnResult nn = knn(cloud, cloud, kNeighbours);
    at::Tensor nearest = nn.sq_distances.select(1, 1).sqrt().to(at::kDouble);
    const double spacing = nearest.median().item<double>();
    if (!(spacing > 0)) return {};
    at::Tensor centred = centred_neighbours(cloud, nn.indices);
    auto [values, axes] = at::linalg_eigh(scatter(centred) / kNeighbours);
    SurfaceShape shape;
    shape.thickness = values.select(1, 0).clamp_min(0).sqrt().median().item<double>() / spacing;

    // The quadric fits on at most kMaxFits evenly strided points: the 10th percentile of a few
    // tens of thousands is as good as all of them. In the frame of each neighbourhood's
    // principal axes (eigh's ascending order: the normal first): height h over (u, v).
    const int64_t stride = (n + kMaxFits - 1) / kMaxFits;
    at::Tensor rows = at::arange(0, n, stride, at::kLong);
    const double fit_spacing = nearest.index_select(0, rows).median().item<double>();
    if (!(fit_spacing > 0)) return shape;
    at::Tensor local =
        centred.index_select(0, rows).matmul(axes.index_select(0, rows)) / fit_spacing;
    at::Tensor h = local.select(2, 0), v = local.select(2, 1), u = local.select(2, 2);
    at::Tensor design = at::stack({u * u, u * v, v * v, u, v, at::ones_like(u)}, 2);
    at::Tensor fit = std::get<0>(at::linalg_lstsq(design, h.unsqueeze(2)));
    at::Tensor residual = (h - design.matmul(fit).squeeze(2)).square().mean(1).sqrt();
    shape.roughness = at::quantile(residual, 0.1).item<double>();
    return shape;
}

double surface_thickness(const at::Tensor& cloud) { return surface_shape(cloud).thickness; }

double surface_roughness(const at::Tensor& cloud) { return surface_shape(cloud).roughness; }

InputKind classify_input(const at::Tensor& cloud) {
    return classify_input(cloud, spacing_spread(cloud));
}

InputKind classify_input(const at::Tensor& cloud, double spread) {
    if (spread > kScanSpacingSpread || spread <= kMeasuredSpacingSpread)
        return classify_input(spread, SurfaceShape{});
    return classify_input(spread, surface_shape(cloud));
}

InputKind classify_input(double spread, const SurfaceShape& shape) {
    if (spread > kScanSpacingSpread) return InputKind::kScan;
    if (spread > kMeasuredSpacingSpread &&
        (shape.thickness < kMeasuredThickness || shape.roughness < kExactRoughness))
        return InputKind::kMeasured;
    return InputKind::kSampled;
}

const char* input_kind_name(InputKind kind) {
    switch (kind) {
        case InputKind::kScan:
            return "scan";
        case InputKind::kMeasured:
            return "measured";
        case InputKind::kSampled:
            break;
    }
    return "sampled";
}

namespace {

/// The ratios up to 256 that the model's weights serve directly (config_for_ratio), written
/// as ranges: "2-16", "2, 4, 8, 16"; empty when it serves only its own.
std::string direct_ratios(const Backbone& model) {
    std::vector<std::pair<int64_t, int64_t>> runs;
    for (int64_t r = 2; r <= 256; ++r) {
        if (r != model.ratio() && model.config_for_ratio(r).is_null()) continue;
        if (!runs.empty() && runs.back().second == r - 1)
            runs.back().second = r;
        else
            runs.emplace_back(r, r);
    }
    if (runs.size() == 1 && runs[0].first == runs[0].second) return "";
    std::string text;
    for (const auto& [first, last] : runs) {
        if (!text.empty()) text += ", ";
        text += first == last ? std::to_string(first)
                              : std::to_string(first) + "-" + std::to_string(last);
    }
    return text;
}

}  // namespace

int64_t output_ratio(const Backbone& model, int64_t requested) {
    const int64_t ratio = requested == 0 ? model.ratio() : requested;
    int64_t power = 1;
    while (power < ratio) power *= model.ratio();
    if (power != ratio) {
        const std::string direct = direct_ratios(model);
        if (direct.empty())
            throw_input_error("--ratio", "ratio {} is not a power of the model's ratio {}", ratio,
                              model.ratio());
        throw_input_error("--ratio",
                          "ratio {} is neither one this model serves ({}) nor a power of its "
                          "ratio {}",
                          ratio, direct, model.ratio());
    }
    return ratio;
}

UpsampleResult upsample_cloud(const Backbone& model, const at::Tensor& points,
                              const UpsampleOptions& options, const PairSource& pairs) {
    check_points(points, "upsample input", 1);
    auto start = Clock::now();
    const int64_t ratio = output_ratio(model, options.ratio);
    UpsampleResult result;
    result.n_in = points.size(0);
    Normalization frame = unit_sphere_normalization(points);
    at::Tensor cloud = frame.apply(points).contiguous();
    int64_t pass = 0;
    for (int64_t done = 1; done < ratio; done *= model.ratio(), ++pass) {
        UpsampleOptions pass_options = options;
        pass_options.seed = options.seed + 7919 * pass;
        cloud = upsample_once(model, cloud, pass_options, frame, pairs, result).contiguous();
    }
    result.points = frame.invert(cloud);
    result.seconds = seconds_since(start);
    return result;
}

at::Tensor midpoint_upsample(const at::Tensor& points, int64_t ratio, int64_t k,
                             double fps_budget) {
    check_points(points, "midpoint input", 2);
    if (ratio < 1) throw_input_error("--ratio", "ratio {} is below 1", ratio);
    if (k <= 0 && ratio > 4 && ratio % 4 == 0)  // 16x as 4x twice, as the published baseline
        return midpoint_upsample(midpoint_upsample(points, 4, 0, fps_budget), ratio / 4, 0,
                                 fps_budget);
    // The 2r nearest neighbours, the point itself included.
    if (k <= 0) k = 2 * ratio - 1;
    const int64_t target = ratio * points.size(0);
    const at::Tensor base = points.index_select(0, distinct_points(points));
    at::Tensor candidates = midpoint_candidates(base, k, {});
    if (candidates.size(0) < target) candidates = with_midpoints(base, target, {});
    if (candidates.size(0) <= target || fps_affordable(candidates.size(0), target, fps_budget))
        return select_exactly(candidates, target, /*fps=*/true, 0);
    // The area the input covers, each point owning the hexagon of its nearest-neighbour
    // spacing d (area sqrt(3)/2 d^2), and the Poisson-disk radius of `target` points on it.
    const double spacing =
        knn(base, base, 2).sq_distances.select(1, 1).sqrt().mean().item<double>();
    const double area = static_cast<double>(base.size(0)) * std::sqrt(3.0) / 2 * spacing * spacing;
    const double r_max =
        2.0 * std::sqrt(area / static_cast<double>(target) / (2.0 * std::sqrt(3.0)));
    return candidates.index_select(0, eliminate_samples(candidates, target, r_max));
}

}  // namespace pumeta
