#include "pumeta/models/pudense.h"

#include <ATen/ATen.h>

#include <limits>
#include <random>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/models/config_fields.h"
#include "pumeta/models/downsample.h"
#include "pumeta/nn/batch_norm.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/sparse/sparse_conv.h"
#include "pumeta/nn/sparse/sparse_ops.h"
#include "pumeta/nn/sparse/voxelize.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "pudense config";
// Two inputs: MAML alternates between X↓ (inner loop) and X (outer loss), pretraining between
// update_buffers and loss on one batch. Each entry holds its kernel maps.
constexpr size_t kVoxelCacheSize = 2;

std::vector<int64_t> preset_channels(const std::string& preset) {
    if (preset == "paper") return {32, 32, 64, 128, 256};
    if (preset == "compact") return {16, 16, 32, 64, 64};
    throw_input_error(kContext, "unknown preset '{}' (expected paper, compact)", preset);
}

// Batch-norm momentum: a number in (0, 1].
double momentum(const nlohmann::json& value, const std::string& key, const std::string& context) {
    const double m = field::positive_number(value, key, context);
    if (m > 1) throw_input_error(context, "'{}' must be in (0, 1], found {}", key, value.dump());
    return m;
}

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("ratio", o.ratio, field::positive_int);
    visit("preset", o.preset, field::string);
    visit("channels", o.channels, field::positive_ints(5));
    visit("last_kernel_size", o.last_kernel_size, field::positive_int);
    visit("resolution", o.resolution, field::positive_number);
    visit("patch_size", o.patch_size, field::positive_int);
    visit("downsampler", o.downsampler, field::downsampler);
    visit("loss_scale", o.loss_scale, field::positive_number);
    visit("bn_momentum", o.bn_momentum, momentum);
    visit("batch_stats_at_inference", o.batch_stats_at_inference, field::boolean);
    visit("refine", o.refine, field::boolean);
    visit("refine_weight", o.refine_weight, field::positive_number);
    visit("refine_range", o.refine_range, field::positive_number);
    visit("seed", o.seed, field::seed);
}

std::string level(const char* name, int64_t index, const char* suffix = "") {
    return name + std::to_string(index) + suffix;
}

/// The layers below run from `params` with one batch-norm context.
struct Layers {
    const ParamMap& params;
    const BatchNormContext& norm;

    SparseTensor conv(const SparseTensor& x, const std::string& name, int64_t kernel_size,
                      int64_t dilation = 1) const {
        return sparse_conv(x, params, name, {kernel_size, 1, dilation});
    }
    SparseTensor bn(const SparseTensor& x, const std::string& name) const {
        return sparse_batch_norm(x, params, name, norm);
    }
    SparseTensor relu(const SparseTensor& x) const {
        return x.with_features(at::relu(x.features()));
    }
    /// conv → batch norm → ReLU, the unit of both blocks.
    SparseTensor unit(const SparseTensor& x, const std::string& conv_name,
                      const std::string& bn_name, int64_t kernel_size, int64_t dilation = 1) const {
        return relu(bn(conv(x, conv_name, kernel_size, dilation), bn_name));
    }

    /// Inception: [1³ C→C/4, 3³ C/4→C/4, 1³ C/4→C/2] ++ [3³ C→C/4, 3³ C/4→C/2], plus x.
    SparseTensor inception(const SparseTensor& x, const std::string& p) const {
        SparseTensor a = unit(x, p + ".conv1", p + ".norm1", 1);
        a = unit(a, p + ".conv2", p + ".norm2", 3);
        a = unit(a, p + ".conv3", p + ".norm3", 1);
        SparseTensor b = unit(x, p + ".conv4", p + ".norm4", 3);
        b = unit(b, p + ".conv5", p + ".norm5", 3);
        return x.with_features(at::cat({a.features(), b.features()}, 1) + x.features());
    }

    /// Pyramid: 1³, 3³ at dilations 6, 12, 18, and the global average broadcast through 1³,
    /// each C→C/4; concatenated 5C/4 → 1³ → C, plus x.
    SparseTensor pyramid(const SparseTensor& x, const std::string& p) const {
        SparseTensor pooled = broadcast_to_sites(global_average_pool(x), x.coords());
        at::Tensor branches = at::cat({unit(x, p + ".aspp1", p + ".aspp1_bn", 1).features(),
                                       unit(x, p + ".aspp2", p + ".aspp2_bn", 3, 6).features(),
                                       unit(x, p + ".aspp3", p + ".aspp3_bn", 3, 12).features(),
                                       unit(x, p + ".aspp4", p + ".aspp4_bn", 3, 18).features(),
                                       unit(pooled, p + ".aspp5", p + ".aspp5_bn", 1).features()},
                                      1);
        SparseTensor fused = unit(x.with_features(branches), p + ".conv2", p + ".bn2", 1);
        return x.with_features(fused.features() + x.features());
    }

    /// Inception, Pyramid, Inception.
    SparseTensor block(const SparseTensor& x, const std::string& p) const {
        return inception(pyramid(inception(x, p + ".0"), p + ".1"), p + ".2");
    }
};

void add_inception(ParamMap& params, ParamMap& buffers, const std::string& p, int64_t c,
                   std::mt19937_64& rng) {
    const int64_t q = c / 4, h = c / 2;
    const struct {
        const char* conv;
        const char* norm;
        int64_t in, out, kernel;
    } units[] = {{".conv1", ".norm1", c, q, 1},
                 {".conv2", ".norm2", q, q, 3},
                 {".conv3", ".norm3", q, h, 1},
                 {".conv4", ".norm4", c, q, 3},
                 {".conv5", ".norm5", q, h, 3}};
    for (const auto& u : units) {
        add_sparse_conv(params, p + u.conv, u.in, u.out, u.kernel, /*bias=*/true, rng);
        add_batch_norm(params, buffers, p + u.norm, u.out);
    }
}

void add_pyramid(ParamMap& params, ParamMap& buffers, const std::string& p, int64_t c,
                 std::mt19937_64& rng) {
    const int64_t q = c / 4;
    const int64_t kernels[] = {1, 3, 3, 3, 1};
    for (int64_t i = 0; i < 5; ++i) {
        std::string name = p + ".aspp" + std::to_string(i + 1);
        add_sparse_conv(params, name, c, q, kernels[i], /*bias=*/true, rng);
        add_batch_norm(params, buffers, name + "_bn", q);
    }
    add_sparse_conv(params, p + ".conv2", 5 * q, c, 1, /*bias=*/true, rng);
    add_batch_norm(params, buffers, p + ".bn2", c);
}

void add_block(ParamMap& params, ParamMap& buffers, const std::string& p, int64_t c,
               std::mt19937_64& rng) {
    add_inception(params, buffers, p + ".0", c, rng);
    add_pyramid(params, buffers, p + ".1", c, rng);
    add_inception(params, buffers, p + ".2", c, rng);
}

}  // namespace

PuDenseOptions PuDenseOptions::from_json(const nlohmann::json& config) {
    PuDenseOptions options;
    read_backbone_config(
        config, "pudense", [&](auto&& visit) { visit_fields(options, visit); },
        [&] { options.channels = preset_channels(options.preset); });
    for (int64_t c : options.channels)
        if (c % 4 != 0) throw_input_error(kContext, "channels must be multiples of 4, found {}", c);
    if (options.channels[0] != options.channels[1])
        throw_input_error(kContext, "channels[0] = {} must equal channels[1] = {}",
                          options.channels[0], options.channels[1]);
    if (options.last_kernel_size < 3 || options.last_kernel_size % 2 == 0)
        throw_input_error(kContext, "'last_kernel_size' must be odd and >= 3, found {}",
                          options.last_kernel_size);
    return options;
}

nlohmann::json PuDenseOptions::to_json() const {
    return write_backbone_config("pudense", [&](auto&& visit) { visit_fields(*this, visit); });
}

PuDense::PuDense(const PuDenseOptions& options) : options_(options) {
    std::mt19937_64 rng(options.seed);
    const std::vector<int64_t>& c = options.channels;
    // Encoder: level 1 at stride 1 (kernel 5), levels 2-5 by stride-2 3³ convolutions.
    add_sparse_conv(params_, "conv1", 1, c[0], 5, /*bias=*/false, rng);
    add_batch_norm(params_, buffers_, "norm1", c[0]);
    add_block(params_, buffers_, "block1", c[0], rng);
    for (int64_t l = 2; l <= 5; ++l) {
        add_sparse_conv(params_, level("conv", l), c[l - 2], c[l - 1], 3, /*bias=*/false, rng);
        add_batch_norm(params_, buffers_, level("norm", l), c[l - 1]);
        add_block(params_, buffers_, level("block", l), c[l - 1], rng);
    }
    // Decoder: transposed convolutions back to levels 4, 3, 2 on the concatenated skips, then
    // the generative one to new stride-1 sites.
    for (int64_t l = 5; l >= 2; --l) {
        const int64_t in = l == 5 ? c[4] : c[l - 1] + c[l];
        const int64_t kernel = l == 2 ? options.last_kernel_size : 3;
        add_sparse_conv(params_, level("conv", l, "_tr"), in, c[l - 1], kernel, /*bias=*/false, rng,
                        /*transposed=*/true);
        add_batch_norm(params_, buffers_, level("norm", l, "_tr"), c[l - 1]);
        add_block(params_, buffers_, level("block", l, "_tr"), c[l - 1], rng);
    }
    add_sparse_conv(params_, "conv1_tr", c[1], c[0], 3, /*bias=*/false, rng);
    add_sparse_conv(params_, "final", c[0], 1, 1, /*bias=*/true, rng);
    if (options.refine) {
        // Drawn after the faithful network, which the same seed therefore reproduces.
        add_sparse_conv(params_, "refine.hidden", c[0], c[0], 1, /*bias=*/true, rng);
        add_sparse_conv(params_, "refine.offset", c[0], 3, 1, /*bias=*/true, rng);
        at::NoGradGuard no_grad;
        params_.at("refine.offset.weight").zero_();
        params_.at("refine.offset.bias").zero_();
    }
}

Occupancy PuDense::occupancy(const CoordinateSetPtr& voxels, const ParamMap& params,
                             const BatchNormContext& norm) const {
    const Layers layers{params, norm};
    const at::Tensor& first = param(params, "conv1.weight");
    SparseTensor x(voxels, at::ones({voxels->size(), 1}, first.options().requires_grad(false)));

    // Encoder; skip[l] is level l's block output before its ReLU.
    std::vector<SparseTensor> skip;
    SparseTensor out = layers.block(layers.bn(layers.conv(x, "conv1", 5), "norm1"), "block1");
    skip.push_back(out);
    for (int64_t l = 2; l <= 5; ++l) {
        SparseTensor down = sparse_conv(layers.relu(out), params, level("conv", l), {3, 2, 1});
        out = layers.block(layers.bn(down, level("norm", l)), level("block", l));
        skip.push_back(out);
    }
    out = layers.relu(out);

    // Decoder: back to the encoder's sites, concatenating its features.
    for (int64_t l = 5; l >= 3; --l) {
        const CoordinateSetPtr& target = skip[l - 2].coords();
        SparseTensor up = sparse_conv_transpose(out, target, params, level("conv", l, "_tr"), 3);
        up = layers.relu(
            layers.block(layers.bn(up, level("norm", l, "_tr")), level("block", l, "_tr")));
        out = sparse_cat(up, skip[l - 2]);
    }
    SparseTensor generated =
        sparse_conv_generative(out, params, "conv2_tr", options_.last_kernel_size);
    generated = layers.relu(layers.block(layers.bn(generated, "norm2_tr"), "block2_tr"));
    // The stride-1 input sites are among the generated ones (the kernel covers each fine
    // voxel's offset from its stride-2 parent), so the sum lives on the generated sites.
    out = layers.relu(layers.conv(add_onto(generated, skip[0]), "conv1_tr", 3));
    Occupancy occ{out.coords(), layers.conv(out, "final", 1).features().squeeze(1), {}};
    if (options_.refine) {
        at::Tensor raw =
            layers.conv(layers.relu(layers.conv(out, "refine.hidden", 1)), "refine.offset", 1)
                .features();
        occ.offsets = at::tanh(raw) * (options_.refine_range * voxel_size());
    }
    return occ;
}

std::vector<at::Tensor> PuDense::selected(const Occupancy& occ, int64_t batch,
                                          int64_t wanted) const {
    at::Tensor logits = occ.logits.detach().to(at::kCPU);
    at::Tensor batch_index = occ.sites->batch_index();
    std::vector<at::Tensor> rows_of;
    for (int64_t b = 0; b < batch; ++b) {
        at::Tensor rows = (batch_index == b).nonzero().view(-1);
        at::Tensor ranked =
            std::get<1>(logits.index_select(0, rows).topk(std::min(wanted, rows.numel())));
        // Too few candidates: repeat the ranking so that the count stays exactly `wanted`.
        at::Tensor order = at::arange(wanted, at::kLong).remainder(ranked.numel());
        rows_of.push_back(rows.index_select(0, ranked.index_select(0, order)));
    }
    return rows_of;
}

at::Tensor PuDense::output_points(const Occupancy& occ, int64_t batch, int64_t wanted) const {
    at::Tensor points = voxel_centres(occ.sites->coords(), voxel_size());
    if (occ.offsets.defined()) points = points.to(occ.offsets.options()) + occ.offsets;
    std::vector<at::Tensor> outputs;
    for (const at::Tensor& rows : selected(occ, batch, wanted))
        outputs.push_back(points.index_select(0, rows.to(points.device())));
    return at::stack(outputs);
}

void PuDense::check_input(const at::Tensor& x, const ParamMap& params, const char* what) const {
    check_batched_points(x, what);
    if (x.size(1) < 1) throw_input_error(what, "needs at least one point per element");
    const at::Tensor& first = param(params, "conv1.weight");
    if (first.scalar_type() != x.scalar_type())
        throw_input_error(what, "points are {}, parameters {}",
                          std::string(c10::toString(x.scalar_type())),
                          std::string(c10::toString(first.scalar_type())));
}

CoordinateSetPtr PuDense::voxels(const at::Tensor& x) const {
    at::Tensor key = x.detach();
    std::lock_guard<std::mutex> lock(cache_mutex_);
    for (const CachedVoxels& cached : cache_)
        if (cached.points.sizes() == key.sizes() &&
            cached.points.scalar_type() == key.scalar_type() &&
            cached.points.device() == key.device() && cached.points.equal(key))
            return cached.voxels;
    CachedVoxels entry{key.clone(), voxelize(key, voxel_size())};
    cache_.push_front(entry);
    if (cache_.size() > kVoxelCacheSize) cache_.pop_back();
    return entry.voxels;
}

at::Tensor PuDense::upsample(const at::Tensor& x, const ParamMap& params) const {
    check_input(x, params, "pudense input");
    at::NoGradGuard no_grad;
    BatchNormContext norm;
    norm.batch_statistics = options_.batch_stats_at_inference;
    norm.running = &buffers_;
    Occupancy occ = occupancy(voxels(x), params, norm);

    return output_points(occ, x.size(0), options_.ratio * x.size(1)).to(x.options());
}

at::Tensor PuDense::loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                         int64_t step) const {
    return sum_of(loss_terms(input, target, params, step));
}

LossTerms PuDense::loss_terms(const at::Tensor& input, const at::Tensor& target,
                              const ParamMap& params, int64_t step) const {
    check_input(input, params, "pudense input");
    check_batched_points(target, "pudense target");
    if (target.size(0) != input.size(0))
        throw_input_error("pudense target", "batch of {} for {} inputs", target.size(0),
                          input.size(0));
    BatchNormContext norm;
    Occupancy occ = occupancy(voxels(input), params, norm);
    CoordinateSetPtr truth = voxelize(target, voxel_size());
    at::Tensor labels = (truth->lookup(occ.sites->coords()) >= 0).to(occ.logits.options());
    // BCE with logits, log(1 + e^z) − y·z: softplus is differentiable twice.
    at::Tensor bce = (at::softplus(occ.logits) - labels * occ.logits).mean();
    LossTerms terms = {{"bce", options_.loss_scale * bce}};
    if (options_.refine) {
        at::Tensor moved = output_points(occ, input.size(0), target.size(1));
        terms.emplace_back(
            "refine_cd", options_.refine_weight * chamfer_loss(moved, target.to(moved.options())));
    }
    return terms;
}

nlohmann::json PuDense::config_for_ratio(int64_t ratio) const {
    if (ratio < 1) throw_input_error("pudense ratio", "{} is not a ratio >= 1", ratio);
    PuDenseOptions options = options_;
    options.ratio = ratio;
    // Round to nearest, at least one point per patch.
    options.patch_size =
        std::max<int64_t>(1, (options_.patch_size * options_.ratio + ratio / 2) / ratio);
    return options.to_json();
}

at::Tensor PuDense::downsample(const at::Tensor& dense, uint64_t seed) const {
    check_batched_points(dense, "pudense downsample");
    return downsample_points(dense, std::max<int64_t>(1, dense.size(1) / options_.ratio),
                             options_.downsampler, seed);
}

nlohmann::json PuDense::diagnose(const at::Tensor& input, const at::Tensor& target) const {
    check_input(input, params_, "pudense input");
    check_batched_points(target, "pudense target");
    at::NoGradGuard no_grad;
    BatchNormContext norm;
    norm.batch_statistics = options_.batch_stats_at_inference;
    norm.running = &buffers_;
    const Occupancy occ = occupancy(voxels(input), params_, norm);
    const CoordinateSetPtr truth = voxelize(target, voxel_size());
    const at::Tensor logits = occ.logits.to(at::kCPU).to(at::kDouble);
    const at::Tensor is_truth = truth->lookup(occ.sites->coords()) >= 0;
    const at::Tensor centres = voxel_centres(occ.sites->coords(), voxel_size());
    const int64_t wanted = target.size(1);
    // Ranked points cycled to `wanted`, as upsample() fills a short ranking.
    auto cycled = [&](const at::Tensor& points) {
        return points.index_select(0, at::arange(wanted, at::kLong).remainder(points.size(0)));
    };
    auto cd = [](const at::Tensor& a, const at::Tensor& b) {
        return 2.0 * chamfer_loss(a.unsqueeze(0).to(at::kFloat), b.unsqueeze(0).to(at::kFloat))
                         .item<double>();
    };
    nlohmann::json floor_cd, candidates_cd, recall, precision;
    for (int64_t b = 0; b < target.size(0); ++b) {
        const at::Tensor gt = target[b].to(at::kCPU);
        // The target's voxels, most occupied first.
        const auto [voxels, inverse, counts] =
            at::unique_dim(voxel_coordinates(gt.unsqueeze(0), voxel_size()), 0, true, false, true);
        const at::Tensor by_count = std::get<1>(counts.sort(0, /*descending=*/true));
        floor_cd.push_back(
            cd(cycled(voxel_centres(voxels.index_select(0, by_count), voxel_size())), gt));
        const at::Tensor rows = (occ.sites->batch_index() == b).nonzero().view(-1);
        const at::Tensor hit = is_truth.index_select(0, rows);
        recall.push_back(hit.sum().item<double>() / static_cast<double>(voxels.size(0)));
        if (rows.numel() == 0) {  // nothing generated: nothing selected
            precision.push_back(0.0);
            candidates_cd.push_back(std::numeric_limits<double>::quiet_NaN());
            continue;
        }
        const at::Tensor own = logits.index_select(0, rows);
        const int64_t keep = std::min(wanted, rows.numel());
        const at::Tensor selected = std::get<1>(own.topk(keep));
        precision.push_back(hit.index_select(0, selected).to(at::kDouble).mean().item<double>());
        // Target voxels among the candidates first, then the network's ranking.
        const at::Tensor ideal =
            std::get<1>((own + hit.to(at::kDouble) * (own.abs().max() * 2 + 1)).topk(keep));
        candidates_cd.push_back(
            cd(cycled(centres.index_select(0, rows.index_select(0, ideal))), gt));
    }
    return {{"floor_cd", floor_cd},
            {"candidates_cd", candidates_cd},
            {"candidate_recall", recall},
            {"precision", precision}};
}

void PuDense::update_buffers(const at::Tensor& input, const ParamMap& params) {
    check_input(input, params, "pudense input");
    at::NoGradGuard no_grad;
    BatchNormContext norm;
    norm.update = &buffers_;
    norm.momentum = options_.bn_momentum;
    occupancy(voxels(input), params, norm);
}

std::unique_ptr<Backbone> make_pudense(const nlohmann::json& config) {
    return std::make_unique<PuDense>(PuDenseOptions::from_json(config));
}

nlohmann::json pudense_small_config() {
    return {{"backbone", "pudense"}, {"ratio", 4},       {"channels", {4, 4, 8, 8, 8}},
            {"resolution", 16},      {"patch_size", 64}, {"seed", 3}};
}

}  // namespace pumeta
