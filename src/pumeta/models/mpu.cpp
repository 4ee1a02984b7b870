#include "pumeta/models/mpu.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/config_fields.h"
#include "pumeta/models/downsample.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/dense_edge_conv.h"
#include "pumeta/nn/init.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "mpu config";
// The 1-D code of the two copies of a point: gen_1d_grid(2) = {−0.2, 0.2}.
constexpr double kCode = 0.2;
constexpr double kSkipFactor = 0.2;
// Σ(w + 1e-5) of the original's weight normalisation; ε keeps h = 0 (coincident points) finite.
constexpr double kWeightFloor = 1e-5;
constexpr double kBandwidthEps = 1e-12;
// The threshold before a level settles, and at 2×: large enough to keep every distance.
constexpr double kLooseThreshold = 100.0;
constexpr double kSettledBlend = 0.6;
// Test-time crops: floor(M / size · 5) seeds; outliers beyond 5 × the mean NN distance.
constexpr double kCropsPerPatch = 5.0;
constexpr double kOutlierFactor = 5.0;

// Sets every width from o.preset.
void apply_preset(MpuOptions& o) {
    if (o.preset == "paper") {
        o.levels = 4, o.k = 32, o.first_channels = 24, o.growth = 12, o.blocks = 4;
        o.up_channels = 128, o.head_channels = 64, o.skip_neighbors = 5;
    } else {
        throw_input_error(kContext, "unknown preset '{}' (expected paper)", o.preset);
    }
}

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("preset", o.preset, field::string);
    visit("levels", o.levels, field::positive_int);
    visit("ratio", o.ratio, field::positive_int);
    visit("k", o.k, field::positive_int);
    visit("first_channels", o.first_channels, field::positive_int);
    visit("growth", o.growth, field::positive_int);
    visit("blocks", o.blocks, field::positive_int);
    visit("up_channels", o.up_channels, field::positive_int);
    visit("head_channels", o.head_channels, field::positive_int);
    visit("skip_neighbors", o.skip_neighbors, field::positive_int);
    visit("patch_size", o.patch_size, field::positive_int);
    visit("downsampler", o.downsampler, field::downsampler);
    visit("fidelity_weight", o.fidelity_weight, field::positive_number);
    visit("cd_threshold", o.cd_threshold, field::positive_number);
    visit("stage_steps", o.stage_steps, field::positive_int);
    visit("combined_lr_factor", o.combined_lr_factor, field::positive_number);
    visit("gradient_clip", o.gradient_clip, field::non_negative_number);
    visit("seed", o.seed, field::seed);
}

// log2(ratio) when ratio is 2^l with 1 <= l <= levels, else 0.
int64_t levels_for_ratio(int64_t ratio, int64_t levels) {
    for (int64_t l = 1; l <= levels && l < 62; ++l)
        if (ratio == (int64_t(1) << l)) return l;
    return 0;
}

DenseEdgeConvShape feature_shape(const MpuOptions& o) {
    return DenseEdgeConvShape{o.first_channels, o.growth, o.blocks};
}

std::string level_prefix(int64_t level) { return "level" + std::to_string(level + 1); }

// x [B,R,C], idx int64 [B,M,k] into R -> [B,M,k,C]; differentiable twice w.r.t. x.
at::Tensor gather_rows(const at::Tensor& x, const at::Tensor& idx) {
    const int64_t batch = x.size(0), rows = x.size(1), channels = x.size(2);
    at::Tensor offsets = (at::arange(batch, idx.options()) * rows).view({batch, 1, 1});
    at::Tensor flat = x.reshape({batch * rows, channels}).index_select(0, (idx + offsets).view(-1));
    return flat.view({batch, idx.size(1), idx.size(2), channels});
}

uint64_t mix(uint64_t seed, int64_t step) {
    return seed ^ (static_cast<uint64_t>(step) + 1) * 0x9E3779B97F4A7C15ull;
}

}  // namespace

MpuOptions MpuOptions::from_json(const nlohmann::json& config) {
    MpuOptions options;
    read_backbone_config(
        config, "mpu", [&](auto&& visit) { visit_fields(options, visit); },
        [&] { apply_preset(options); });
    if (options.levels > 16)
        throw_input_error(kContext, "'levels' must be at most 16, found {}", options.levels);
    if (!config.contains("ratio")) options.ratio = int64_t(1) << options.levels;
    if (levels_for_ratio(options.ratio, options.levels) == 0)
        throw_input_error(kContext, "'ratio' must be 2^l with 1 <= l <= levels ({}), found {}",
                          options.levels, options.ratio);
    if (options.patch_size < 2)
        throw_input_error(kContext, "'patch_size' must be at least 2, found {}",
                          options.patch_size);
    return options;
}

nlohmann::json MpuOptions::to_json() const {
    return write_backbone_config("mpu", [&](auto&& visit) { visit_fields(*this, visit); });
}

bool mpu_combined_phase(int64_t step, int64_t stage_steps, int64_t max_levels) {
    if (stage_steps < 1 || max_levels < 1)
        throw_input_error("mpu_combined_phase", "stage_steps and max_levels must be >= 1");
    const int64_t s = stage_steps;
    step = std::max<int64_t>(step, 0);
    const int64_t newest = std::min(max_levels, 1 + (step + s) / (2 * s));
    return newest > 1 && step >= s * (2 * newest - 2);
}

MpuCurriculumStep mpu_curriculum(int64_t step, int64_t stage_steps, int64_t max_levels,
                                 double threshold, std::mt19937_64& rng) {
    if (stage_steps < 1 || max_levels < 1)
        throw_input_error("mpu_curriculum", "stage_steps and max_levels must be >= 1");
    const int64_t s = stage_steps;
    step = std::max<int64_t>(step, 0);
    const int64_t newest = std::min(max_levels, 1 + (step + s) / (2 * s));
    // How far level l is through its alone stage, which starts at S·(2l − 3): 0 ... 1.
    auto blend = [&](int64_t l) {
        if (l == 1) return 1.0;
        return std::clamp(double(step - s * (2 * l - 3)) / double(s), 0.0, 1.0);
    };
    MpuCurriculumStep out;
    if (newest > 1 && blend(newest) < 1) {
        out.levels = newest;
        out.frozen = newest - 1;
    } else {
        // P(i) ∝ i + 1 for i < newest: draw u in [0, Σ) and walk the cumulative weights.
        const double total = double(newest * (newest + 1) / 2);
        double u = uniform01(rng) * total;
        out.levels = newest;
        for (int64_t i = 0; i < newest; ++i) {
            u -= double(i + 1);
            if (u < 0) {
                out.levels = i + 1;
                break;
            }
        }
    }
    out.threshold =
        out.levels > 1 && blend(out.levels) > kSettledBlend ? threshold : kLooseThreshold;
    return out;
}

at::Tensor mpu_chamfer(const at::Tensor& pred, const at::Tensor& target, double threshold) {
    check_batched_points(pred, "mpu_chamfer prediction");
    check_batched_points(target, "mpu_chamfer target");
    // d² of each query to its nearest point, recomputed from the differences (exact and
    // differentiable twice); distances at or beyond threshold × their mean count zero.
    auto direction = [threshold](const at::Tensor& queries, const at::Tensor& points) {
        at::Tensor idx = nearest_point_indices(queries, points);
        at::Tensor nearest_points = gather_rows(points, idx.unsqueeze(-1)).squeeze(2);
        at::Tensor d = (queries - nearest_points).pow(2).sum(-1);  // [B,N]
        at::Tensor keep;
        {
            at::NoGradGuard no_grad;
            keep = d < threshold * d.mean(1, true);
        }
        return at::where(keep, d, at::zeros_like(d)).mean(1);
    };
    return (direction(target, pred) + direction(pred, target)).mean();
}

at::Tensor mpu_skip_weights(const at::Tensor& xyz, const at::Tensor& features,
                            const at::Tensor& neighbor_xyz, const at::Tensor& neighbor_features) {
    at::NoGradGuard no_grad;
    auto exponential = [](const at::Tensor& query, const at::Tensor& points) {
        at::Tensor d = (query.detach().unsqueeze(2) - points.detach()).pow(2).sum(-1);  // [B,M,k]
        at::Tensor h = std::get<0>(d.min(2, true)).mean(1, true);                       // [B,1,1]
        return at::exp(-d / (h / 2 + kBandwidthEps));
    };
    at::Tensor w = exponential(features, neighbor_features) * exponential(xyz, neighbor_xyz);
    return w / (w + kWeightFloor).sum(2, true);
}

at::Tensor mpu_test_crops(const at::Tensor& points, int64_t size) {
    check_points(points, "mpu_test_crops");
    const int64_t m = points.size(0);
    if (size < 1 || m <= size || m < 2)
        throw_input_error("mpu_test_crops", "needs more than {} points (and 2), found {}", size, m);
    at::NoGradGuard no_grad;
    at::Tensor p = points.detach().to(at::kFloat).contiguous();
    at::Tensor closest = knn(p, p, 2).sq_distances.select(1, 1);
    // <= rather than the original's <: points that all coincide with another (mean 0) stay.
    at::Tensor kept = at::nonzero(closest <= kOutlierFactor * closest.mean()).squeeze(1);
    at::Tensor inliers = p.index_select(0, kept);
    const int64_t n = inliers.size(0);
    const int64_t crops =
        std::clamp<int64_t>(int64_t(double(m) / double(size) * kCropsPerPatch), 1, n);
    at::Tensor seeds = inliers.index_select(0, farthest_point_sampling(inliers, crops));
    at::Tensor local = knn(inliers, seeds, std::min(size, n)).indices;  // [crops, size]
    return kept.index_select(0, local.reshape(-1)).view(local.sizes());
}

Mpu::Mpu(const MpuOptions& options) : options_(options) {
    std::mt19937_64 rng(options.seed);
    const MpuOptions& o = options_;
    for (int64_t level = 0; level < o.levels; ++level) {
        const std::string prefix = level_prefix(level);
        const int64_t channels =
            add_dense_edge_conv(params_, prefix + ".features", feature_shape(o), rng);
        // up_layer1 sees [features, code]; the code is one channel.
        add_linear(params_, prefix + ".up1", channels + 1, o.up_channels, true, rng);
        add_linear(params_, prefix + ".up2", o.up_channels, o.up_channels, true, rng);
        add_linear(params_, prefix + ".fc1", o.up_channels, o.head_channels, true, rng);
        add_linear(params_, prefix + ".fc2", o.head_channels, 3, true, rng);
    }
}

int64_t Mpu::active_levels() const { return levels_for_ratio(options_.ratio, options_.levels); }

nlohmann::json Mpu::config_for_ratio(int64_t ratio) const {
    if (levels_for_ratio(ratio, options_.levels) == 0) return nullptr;
    MpuOptions options = options_;
    options.ratio = ratio;
    return options.to_json();
}

void Mpu::check_input(const at::Tensor& x, const ParamMap& params, const char* what) const {
    check_batched_points(x, what);
    if (x.size(1) < 2) throw_input_error(what, "needs at least 2 points, found {}", x.size(1));
    const at::Tensor& first = param(params, "level1.features.layer0.weight");
    if (first.scalar_type() != x.scalar_type() || first.device() != x.device())
        throw_input_error(what, "points are {} on {}, parameters {} on {}",
                          std::string(c10::toString(x.scalar_type())), x.device().str(),
                          std::string(c10::toString(first.scalar_type())), first.device().str());
}

at::Tensor Mpu::skip_connection(const at::Tensor& xyz, const at::Tensor& features,
                                const SkipSource& previous) const {
    // The previous level's points may be one shared set for all of this level's crops
    // (batch 1, the test path): search them once for every crop's points.
    const int64_t batch = xyz.size(0), m = xyz.size(1);
    const bool shared = previous.xyz.size(0) == 1 && batch > 1;
    const int64_t k = std::min(options_.skip_neighbors, previous.xyz.size(1));
    at::Tensor queries = shared ? xyz.reshape({1, batch * m, 3}) : xyz;
    at::Tensor idx = knn_indices(previous.xyz, queries, k);
    auto gather = [&](const at::Tensor& source) {
        at::Tensor rows = gather_rows(source, idx);
        return shared ? rows.reshape({batch, m, k, source.size(2)}) : rows;
    };
    at::Tensor neighbor_features = gather(previous.features);
    if (k == 1) return features + kSkipFactor * neighbor_features.squeeze(2);
    at::Tensor w = mpu_skip_weights(xyz, features, gather(previous.xyz), neighbor_features);
    return features + kSkipFactor * (w.unsqueeze(-1) * neighbor_features).sum(2);
}

Mpu::LevelOutput Mpu::run_level(int64_t level, const at::Tensor& xyz, const SkipSource* previous,
                                const ParamMap& params) const {
    const std::string prefix = level_prefix(level);
    const int64_t batch = xyz.size(0), m = xyz.size(1);
    // Levels after the first see their input normalised to the unit sphere.
    at::Tensor centroid, radius, normalized = xyz;
    if (level > 0) {
        centroid = xyz.mean(1, true);
        // Floored: a crop of coincident points has radius 0.
        radius = (xyz - centroid).pow(2).sum(-1, true).amax(1, true).clamp_min(1e-24).sqrt();
        normalized = (xyz - centroid) / radius;
    }
    at::Tensor features = dense_edge_conv(normalized, params, prefix + ".features",
                                          feature_shape(options_), options_.k);
    if (previous) features = skip_connection(xyz, features, *previous);

    // up1 on [f_i, code_c] is W_f f_i + W_c code_c + b: per point and per copy, broadcast to
    // the 2M points in point-major order (copies of point i are rows 2i, 2i + 1).
    const int64_t c = features.size(2);
    const at::Tensor& w = param(params, prefix + ".up1.weight");
    at::Tensor per_point =
        conv1x1_weights(features, w.narrow(1, 0, c), param(params, prefix + ".up1.bias"));
    at::Tensor code = at::tensor({-kCode, kCode}, at::TensorOptions().dtype(at::kDouble))
                          .to(features.options())
                          .view({2, 1});
    at::Tensor per_copy = conv1x1_weights(code, w.narrow(1, c, 1), {});  // [2,U]
    at::Tensor h = at::relu(per_point.unsqueeze(2) + per_copy).reshape({batch, 2 * m, -1});
    h = at::relu(conv1x1(h, params, prefix + ".up2"));
    h = at::relu(conv1x1(h, params, prefix + ".fc1"));
    at::Tensor points = conv1x1(h, params, prefix + ".fc2") + normalized.repeat_interleave(2, 1);
    if (level > 0) points = points * radius + centroid;
    return {points, {xyz, features}};
}

std::pair<at::Tensor, at::Tensor> Mpu::run_training(const at::Tensor& input, const at::Tensor& gt,
                                                    int64_t levels, int64_t frozen,
                                                    std::mt19937_64& rng,
                                                    const ParamMap& params) const {
    const int64_t batch = input.size(0), size = options_.patch_size;
    at::Tensor xyz = input, target = gt;
    std::optional<SkipSource> previous;
    for (int64_t level = 0; level < levels; ++level) {
        const int64_t m = xyz.size(1);
        if (level > 0 && m > size) {
            // One random seed per sample; the input crop is its `size` nearest points, the GT
            // crop the same share of the GT around it (the original's gt_k).
            std::vector<int64_t> picks(batch);
            for (auto& pick : picks) pick = std::min(m - 1, int64_t(uniform01(rng) * double(m)));
            at::Tensor seed_idx = at::tensor(picks, at::kLong).to(xyz.device()).view({batch, 1, 1});
            at::Tensor seeds = gather_rows(xyz, seed_idx).squeeze(2).detach();  // [B,1,3]
            xyz = gather_rows(xyz, knn_indices(xyz, seeds, size)).squeeze(1);
            const int64_t gt_k =
                std::max<int64_t>(1, std::min(target.size(1), (target.size(1) * size + m / 2) / m));
            target = gather_rows(target, knn_indices(target, seeds, gt_k)).squeeze(1).detach();
        }
        std::optional<at::NoGradGuard> no_grad;
        if (level < frozen) no_grad.emplace();
        LevelOutput out = run_level(level, xyz, previous ? &*previous : nullptr, params);
        xyz = out.points;
        previous = out.skip;
    }
    return {xyz, target};
}

at::Tensor Mpu::upsample_one(const at::Tensor& x, const ParamMap& params) const {
    const int64_t size = options_.patch_size;
    at::Tensor xyz = x;
    std::optional<SkipSource> previous;
    for (int64_t level = 0; level < active_levels(); ++level) {
        const int64_t m = xyz.size(1);
        if (level == 0 || m <= size) {
            LevelOutput out = run_level(level, xyz, previous ? &*previous : nullptr, params);
            xyz = out.points;
            previous = out.skip;
            continue;
        }
        // Crops around FPS seeds, each run as one batch element; their outputs are merged
        // and FPS keeps 2M. The next level's skip source is every crop's points and features.
        at::Tensor crops = mpu_test_crops(xyz[0], size);
        at::Tensor crop_xyz =
            xyz[0].index_select(0, crops.reshape(-1)).view({-1, crops.size(1), 3});
        LevelOutput out = run_level(level, crop_xyz, previous ? &*previous : nullptr, params);
        at::Tensor merged = out.points.reshape({-1, 3});
        at::Tensor keep;
        {
            at::NoGradGuard no_grad;
            keep = farthest_point_sampling(merged.detach().to(at::kFloat).contiguous(),
                                           std::min(2 * m, merged.size(0)));
        }
        xyz = merged.index_select(0, keep).unsqueeze(0);
        previous = SkipSource{out.skip.xyz.reshape({1, -1, 3}),
                              out.skip.features.reshape({1, -1, out.skip.features.size(2)})};
    }
    return xyz;
}

at::Tensor Mpu::upsample(const at::Tensor& x, const ParamMap& params) const {
    check_input(x, params, "mpu input");
    // The original's test path takes one patch at a time (its crops form the batch).
    std::vector<at::Tensor> outputs;
    for (int64_t b = 0; b < x.size(0); ++b)
        outputs.push_back(upsample_one(x.slice(0, b, b + 1), params));
    return at::cat(outputs, 0);
}

double Mpu::level_weight(int64_t levels) const {
    // The original's 50·(log₂ R − i) for the ratio R the model trains at, i = levels − 1.
    return options_.fidelity_weight * double(active_levels() - levels + 1);
}

at::Tensor Mpu::loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                     int64_t step) const {
    check_input(input, params, "mpu input");
    check_batched_points(target, "mpu target");
    if (target.size(0) != input.size(0))
        throw_input_error("mpu target", "batch of {} for {} inputs", target.size(0), input.size(0));
    const int64_t n = input.size(1), t = target.size(1);
    const int64_t levels = t % n == 0 ? levels_for_ratio(t / n, options_.levels) : 0;
    if (levels == 0)
        throw_input_error("mpu target",
                          "{} points for {} inputs: the ratio must be 2^l with 1 <= l <= {}", t, n,
                          options_.levels);
    std::mt19937_64 rng(mix(options_.seed, step));
    auto [pred, gt] = run_training(input, target, levels, 0, rng, params);
    const double threshold = levels > 1 ? options_.cd_threshold : kLooseThreshold;
    return level_weight(levels) * mpu_chamfer(pred, gt, threshold);
}

LossTerms Mpu::training_terms(const at::Tensor& input, const at::Tensor& target,
                              const ParamMap& params, const ParamMap&, int64_t step) const {
    check_input(input, params, "mpu input");
    check_batched_points(target, "mpu target");
    const int64_t n = input.size(1);
    if (target.size(0) != input.size(0) || target.size(1) != n * options_.ratio)
        throw_input_error("mpu target", "[{}, {}] points for inputs [{}, {}] at ratio {}",
                          target.size(0), target.size(1), input.size(0), n, options_.ratio);
    std::mt19937_64 rng(mix(options_.seed, step));
    MpuCurriculumStep stage =
        mpu_curriculum(step, options_.stage_steps, active_levels(), options_.cd_threshold, rng);
    at::Tensor gt = target;
    const int64_t points = n << stage.levels;
    if (points < target.size(1)) {
        at::NoGradGuard no_grad;
        at::Tensor idx =
            farthest_point_sampling_batched(target.detach().to(at::kFloat).contiguous(), points)
                .to(target.device());
        gt = gather_rows(target.detach(), idx.unsqueeze(-1)).squeeze(2);
    }
    auto [pred, cropped] = run_training(input, gt, stage.levels, stage.frozen, rng, params);
    return {{"cd", level_weight(stage.levels) * mpu_chamfer(pred, cropped, stage.threshold)}};
}

OptimizerGroup Mpu::optimizer_group(const std::string& name) const {
    OptimizerGroup group;
    group.gradient_clip = options_.gradient_clip;
    return group;
}

double Mpu::learning_rate_factor(int64_t step) const {
    return mpu_combined_phase(step, options_.stage_steps, active_levels())
               ? options_.combined_lr_factor
               : 1.0;
}

at::Tensor Mpu::downsample(const at::Tensor& dense, uint64_t seed) const {
    check_batched_points(dense, "mpu downsample");
    return downsample_points(dense, std::max<int64_t>(1, dense.size(1) / options_.ratio),
                             options_.downsampler, seed);
}

int64_t mpu_level_parameters(const MpuOptions& o) {
    Mpu one_level([&] {
        MpuOptions single = o;
        single.levels = 1;
        single.ratio = 2;
        return single;
    }());
    return count_parameters(one_level.parameters());
}

std::unique_ptr<Backbone> make_mpu(const nlohmann::json& config) {
    return std::make_unique<Mpu>(MpuOptions::from_json(config));
}

nlohmann::json mpu_small_config() {
    // One skip neighbour: the exp weights of 5 carry no gradient (as the original's), so the
    // meta-gradient of the conformance suite would miss their slope (1.6 % measured) and not
    // match finite differences; tests/models/mpu.cpp checks the weighted skip itself.
    return {{"backbone", "mpu"},   {"levels", 2},         {"ratio", 4},       {"k", 4},
            {"first_channels", 4}, {"growth", 4},         {"blocks", 2},      {"up_channels", 8},
            {"head_channels", 4},  {"skip_neighbors", 1}, {"patch_size", 16}, {"seed", 3}};
}

}  // namespace pumeta
