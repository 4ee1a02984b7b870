// MPU, the patch-based progressive upsampler of Wang et al. ("3PU", CVPR 2019): a cascade of
// ×2 levels with their own weights, each a dense EdgeConv feature extractor, an inter-level
// skip connection, duplicate-up with a 1-D code and a residual coordinate head; levels beyond
// the first crop their input to patch_size points around seeds. Layer shapes, skip weights,
// patch extraction, loss and curriculum follow the official TensorFlow code
// (code/dense_interlevelplus.py, model_utils.py, main_curriculum_interleave.py): the 4-level
// 16× model has 76,027 parameters per level, 304,108 in all. One set of weights serves every
// ratio 2^l, l = 1 ... levels, by running the first l levels (config_for_ratio).
#pragma once

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "pumeta/models/backbone.h"

namespace pumeta {

/// MPU's configuration: the JSON fields of {"backbone": "mpu", ...}. "preset" ("paper", the
/// default) sets every width first; fields given explicitly override it. Unknown fields are
/// rejected.
struct MpuOptions {
    /// Width preset the fields below started from: "paper" (the official 16× model).
    std::string preset = "paper";
    /// ×2 levels whose weights the model holds (the official model: 4, i.e. up to 16×).
    int64_t levels = 4;
    /// Upsampling ratio: 2^l for 1 <= l <= levels; the first l levels run. Default 2^levels.
    int64_t ratio = 16;
    /// Neighbours of the dynamic EdgeConv graphs (official flag 32; fewer points: N − 1).
    int64_t k = 32;
    /// Dense EdgeConv widths per level: first layer, growth, blocks (264 features at 24/12/4).
    int64_t first_channels = 24;
    int64_t growth = 12;
    int64_t blocks = 4;
    /// Widths of the two up convolutions and of the hidden coordinate layer.
    int64_t up_channels = 128;
    int64_t head_channels = 64;
    /// Previous-level points averaged by the skip connection (official fm_knn 5; with 1 the
    /// nearest one's features are added without weights, the original's fm_knn = 1 branch).
    int64_t skip_neighbors = 5;
    /// Points per input patch; a level whose input has more points runs on crops of this size
    /// (the original's min(patch points, 312)).
    int64_t patch_size = 256;
    /// Training-pair / X↓ downsampler: fps, random or nonuniform (see downsample_points).
    std::string downsampler = "fps";
    /// Loss factor of the Chamfer term: fidelity_weight · (levels − i) at ratio 2^(i+1).
    double fidelity_weight = 50.0;
    /// Chamfer outlier threshold τ (distances ≥ τ × their direction's mean count 0) once a
    /// level is past 60 % of its alone stage; 100 before that and always at 2×.
    double cd_threshold = 2.0;
    /// Curriculum stage length S in training steps (the original: 15,000).
    int64_t stage_steps = 15000;
    /// Supervised training as the original's: the learning rate times this in the combined
    /// phases (mpu_combined_phase), every gradient value clipped to ±gradient_clip.
    double combined_lr_factor = 0.5;
    double gradient_clip = 1.0;
    /// Seed of the parameter initialisation and of the training crops and ratio draws.
    uint64_t seed = 0;

    /// InputError "mpu config: ..." for unknown fields, wrong types or invalid values.
    static MpuOptions from_json(const nlohmann::json& config);
    /// Every field, with "backbone": "mpu".
    nlohmann::json to_json() const;
};

/// What one supervised training step of the curriculum trains (mpu_curriculum).
struct MpuCurriculumStep {
    /// Levels that run (the batch's ratio is 2^levels).
    int64_t levels = 1;
    /// Levels below this one are frozen (run without gradient): the newest level alone.
    int64_t frozen = 0;
    /// The Chamfer outlier threshold τ of the step.
    double threshold = 100;
};

/// The original's curriculum over `max_levels` levels with stage length S = stage_steps: the
/// newest level is 1 for steps [0, S), l >= 2 from S·(2l − 3); it trains alone (earlier levels
/// frozen, ratio 2^l) for S steps, then "combined": each step draws its level count i + 1 with
/// probability ∝ i + 1 (i < newest) from `rng` and trains every level up to it. τ is
/// `threshold` once the step's level is past 0.6·S of its alone stage (never at one level),
/// else 100.
MpuCurriculumStep mpu_curriculum(int64_t step, int64_t stage_steps, int64_t max_levels,
                                 double threshold, std::mt19937_64& rng);

/// Whether `step` lies in a "combined" phase of the curriculum: a newest level l >= 2 past its
/// alone stage, steps [S·(2l − 2), S·(2l − 1)), and every step from S·(2L − 2) on.
bool mpu_combined_phase(int64_t step, int64_t stage_steps, int64_t max_levels);

/// The original's Chamfer loss with outlier threshold: per sample and direction, squared
/// nearest-neighbour distances ≥ threshold × their mean count 0; mean fwd + mean bwd, averaged
/// over the batch. pred [B,N,3], target [B,M,3]; differentiable twice w.r.t. pred.
at::Tensor mpu_chamfer(const at::Tensor& pred, const at::Tensor& target, double threshold);

/// The skip connection's weights for current points `xyz` [B,M,3] with features [B,M,C] and
/// their k nearest previous-level points (positions [B,M,k,3], features [B,M,k,C]):
/// w = exp(−d_f / (h_f/2 + ε)) · exp(−d_s / (h_s/2 + ε)) with d squared distances and h the
/// per-sample mean over points of the minimum over the k; normalised by Σ_k (w + 1e-5).
/// [B,M,k], without gradient.
at::Tensor mpu_skip_weights(const at::Tensor& xyz, const at::Tensor& features,
                            const at::Tensor& neighbor_xyz, const at::Tensor& neighbor_features);

/// Indices of a level's test-time crops of `points` [M,3] (M > size): points whose nearest
/// other point is at squared distance ≥ 5 × the mean are dropped, seeds = FPS (from the
/// first kept point) of floor(M / size · 5) kept points, each crop the min(size, kept) kept
/// points nearest its seed. int64 [crops, min(size, kept)] into `points`.
at::Tensor mpu_test_crops(const at::Tensor& points, int64_t size);

class Mpu : public Backbone {
  public:
    explicit Mpu(const MpuOptions& options);

    std::string name() const override { return "mpu"; }
    nlohmann::json config() const override { return options_.to_json(); }
    int64_t ratio() const override { return options_.ratio; }
    int64_t patch_size() const override { return options_.patch_size; }
    const MpuOptions& options() const { return options_; }
    /// Levels that run at ratio(): log2(ratio()).
    int64_t active_levels() const;

    /// The same weights at ratio 2^l (1 <= l <= levels); null for any other ratio.
    nlohmann::json config_for_ratio(int64_t ratio) const override;

    /// The original's test path, each patch on its own: x float [B,N,3] (N >= 2) -> [B,rN,3].
    /// Level l > 1 on an input of M > patch_size points runs on mpu_test_crops, and FPS of
    /// the crops' outputs keeps 2M points. Level 1's copies of point i are rows 2i, 2i + 1.
    at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const override;
    using Backbone::upsample;

    /// The original's loss for a pair at ratio R = target / input points (2^l, l <= levels;
    /// else InputError): the first l levels on the training path (one random crop per sample
    /// at every level whose input exceeds patch_size, the GT cropped to match, the crop seeds
    /// drawn from seed and `step`), then fidelity_weight · (levels − l + 1) · mpu_chamfer with
    /// τ = cd_threshold (100 at l = 1). Used by meta-learning and test-time adaptation.
    at::Tensor loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                    int64_t step = 0) const override;

    /// Supervised training with the curriculum (mpu_curriculum at `step`, over the active
    /// levels): target holds ratio()·N points; a step at ratio 2^l < ratio() compares with its
    /// FPS subset of 2^l·N points (a uniform subset, as the original's sparser GT sampling).
    /// One term, "cd".
    LossTerms training_terms(const at::Tensor& input, const at::Tensor& target,
                             const ParamMap& params, const ParamMap& auxiliary,
                             int64_t step) const override;

    /// downsample_points(dense, M / ratio(), options().downsampler, seed).
    at::Tensor downsample(const at::Tensor& dense, uint64_t seed) const override;
    /// Every tensor with its gradient clipped to ±gradient_clip.
    OptimizerGroup optimizer_group(const std::string& name) const override;
    /// combined_lr_factor in the combined phases, else 1.
    double learning_rate_factor(int64_t step) const override;

  private:
    /// What a level leaves to the next one's skip connection: its input points (in level 1's
    /// frame) and final features.
    struct SkipSource {
        at::Tensor xyz;       ///< [B,M,3]
        at::Tensor features;  ///< [B,M,C]
    };
    struct LevelOutput {
        at::Tensor points;  ///< [B,2M,3] in the input's frame
        SkipSource skip;
    };
    LevelOutput run_level(int64_t level, const at::Tensor& xyz, const SkipSource* previous,
                          const ParamMap& params) const;
    at::Tensor skip_connection(const at::Tensor& xyz, const at::Tensor& features,
                               const SkipSource& previous) const;
    /// The training path of the first `levels` levels; levels below `frozen` without
    /// gradient. Returns the output and the GT cropped alongside it.
    std::pair<at::Tensor, at::Tensor> run_training(const at::Tensor& input, const at::Tensor& gt,
                                                   int64_t levels, int64_t frozen,
                                                   std::mt19937_64& rng,
                                                   const ParamMap& params) const;
    at::Tensor upsample_one(const at::Tensor& x, const ParamMap& params) const;
    double level_weight(int64_t levels) const;
    void check_input(const at::Tensor& x, const ParamMap& params, const char* what) const;

    MpuOptions options_;
};

/// Parameters of one level: 76,027 at the paper's widths.
int64_t mpu_level_parameters(const MpuOptions& options);

/// The registry's factory: Mpu(MpuOptions::from_json(config)).
std::unique_ptr<Backbone> make_mpu(const nlohmann::json& config);

/// MPU's smallest useful config (2 levels, widths 4-8, k 4, 16-point patches, x4, one skip
/// neighbour), registered with the kind for the backbone conformance suite.
nlohmann::json mpu_small_config();

}  // namespace pumeta
