#include "pumeta/models/metapu.h"

#include <ATen/ATen.h>

#include <cmath>
#include <random>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/config_fields.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/graph.h"
#include "pumeta/nn/init.h"
#include "pumeta/nn/repulsion_loss.h"
#include "pumeta/nn/sinkhorn_loss.h"
#include "pumeta/nn/uniform_loss.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "metapu config";
constexpr double kLeakySlope = 0.2;
// Training scales and scale codes live on the grid 1.1, 1.2, ..., max ratio.
constexpr int64_t kGridFirst = 11;  // tenths
constexpr int64_t kRepulsionNeighbors = 4;
// The generators' initial weights: truncated normal (±2σ), as the original's fc_init_.
constexpr double kGeneratorStd = 0.01;

int64_t max_ratio(const MetaPuOptions& o) { return o.candidates * o.candidates; }

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("ratio", o.ratio, field::positive_int);
    visit("channels", o.channels, field::positive_int);
    visit("stage1_blocks", o.stage1_blocks, field::positive_int);
    visit("stage2_blocks", o.stage2_blocks, field::positive_int);
    visit("k", o.k, field::positive_int);
    visit("generator_hidden", o.generator_hidden, field::positive_int);
    visit("candidates", o.candidates, field::positive_int);
    visit("patch_size", o.patch_size, field::positive_int);
    visit("reconstruction", o.reconstruction, field::one_of({"sinkhorn", "chamfer"}));
    visit("blur", o.blur, field::positive_number);
    visit("reach", o.reach, field::positive_number);
    visit("sinkhorn_scaling", o.sinkhorn_scaling, field::positive_number);
    visit("sinkhorn_gradient", o.sinkhorn_gradient, field::one_of({"envelope", "unrolled"}));
    visit("scale_weights_penalty", o.scale_weights_penalty, field::non_negative_number);
    visit("uniform_weight", o.uniform_weight, field::non_negative_number);
    visit("repulsion_weight", o.repulsion_weight, field::non_negative_number);
    visit("generator_lr_scale", o.generator_lr_scale, field::positive_number);
    visit("weight_decay", o.weight_decay, field::non_negative_number);
    visit("seed", o.seed, field::seed);
}

// Grid entries: 1.1 + 0.1·i for i in [0, count).
int64_t grid_count(int64_t max_ratio) { return 10 * max_ratio - kGridFirst + 1; }

void add_truncated_normal(ParamMap& params, const std::string& name, int64_t rows, int64_t cols,
                          std::mt19937_64& rng) {
    if (params.count(name)) throw InternalError("parameter '" + name + "' added twice");
    reserve_parameter({rows, cols});
    at::Tensor t = at::empty({rows, cols}, at::kFloat);
    float* data = t.data_ptr<float>();
    for (int64_t i = 0; i < rows * cols; ++i) {
        double z;
        do {  // Box-Muller from portable uniforms, redrawn beyond 2σ
            const double u = 1.0 - uniform01(rng), v = uniform01(rng);
            z = std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * M_PI * v);
        } while (std::abs(z) > 2.0);
        data[i] = float(kGeneratorStd * z);
    }
    params[name] = t.requires_grad_(true);
}

// A generator 1 → hidden → C² with a linear skip 1 → C² (the original's ResLinear).
void add_generator(ParamMap& params, const std::string& prefix, int64_t hidden, int64_t channels,
                   std::mt19937_64& rng) {
    add_truncated_normal(params, prefix + ".fc11.weight", hidden, 1, rng);
    add_zeros(params, prefix + ".fc11.bias", hidden);
    add_truncated_normal(params, prefix + ".fc12.weight", channels * channels, hidden, rng);
    add_zeros(params, prefix + ".fc12.bias", channels * channels);
    add_truncated_normal(params, prefix + ".fcskip.weight", channels * channels, 1, rng);
    add_zeros(params, prefix + ".fcskip.bias", channels * channels);
}

// The C×C matrix (out, in) a generator makes from the scale code.
at::Tensor generate(const ParamMap& params, const std::string& prefix, double code,
                    int64_t channels) {
    const at::Tensor& first = param(params, prefix + ".fc11.weight");
    at::Tensor s = at::full({1, 1}, code, first.options().requires_grad(false));
    at::Tensor h = at::leaky_relu(conv1x1(s, params, prefix + ".fc11"), kLeakySlope);
    at::Tensor w = conv1x1(h, params, prefix + ".fc12") + conv1x1(s, params, prefix + ".fcskip");
    return w.view({channels, channels});
}

// A center/neighbour pair of bias-free 1×1 convolutions: `prefix.{center,neighbor}.weight`.
void add_pair(ParamMap& params, const std::string& prefix, int64_t in, int64_t out,
              std::mt19937_64& rng) {
    add_linear(params, prefix + ".center", in, out, /*bias=*/false, rng);
    add_linear(params, prefix + ".neighbor", in, out, /*bias=*/false, rng);
}

// The graph convolution of an RGC block on activated features h [B,N,C]: the mean over the
// k + 1 terms W_c h_i and W_n h_j (j among the k neighbours idx [B,N,k]).
at::Tensor graph_mean(const at::Tensor& h, const at::Tensor& idx, const at::Tensor& w_center,
                      const at::Tensor& w_neighbor) {
    at::Tensor neighbors = gather_neighbors(conv1x1_weights(h, w_neighbor, {}), idx).sum(2);
    return (conv1x1_weights(h, w_center, {}) + neighbors) / double(idx.size(2) + 1);
}

at::Tensor graph_mean(const at::Tensor& h, const at::Tensor& idx, const ParamMap& params,
                      const std::string& prefix) {
    return graph_mean(h, idx, param(params, prefix + ".center.weight"),
                      param(params, prefix + ".neighbor.weight"));
}

// The k nearest other points of every point (kd-trees on a float32 copy): int64 [B,N,k].
at::Tensor xyz_graph(const at::Tensor& xyz, int64_t k) {
    at::NoGradGuard no_grad;
    at::Tensor query = xyz.detach().to(at::kFloat).contiguous();
    // The point itself comes first (with exact duplicates a copy of it may, same distances).
    return knn(query, query, k + 1).indices.narrow(2, 1, k);
}

at::Tensor gather_points(const at::Tensor& points, const at::Tensor& idx) {
    return points.gather(1, idx.unsqueeze(-1).expand({-1, -1, points.size(2)}));
}

// Rows of x [B,N,C] at idx int64 [B,Q,k] (any Q): [B,Q,k,C]. Differentiable twice in x.
at::Tensor gather_rows(const at::Tensor& x, const at::Tensor& idx) {
    const int64_t batch = x.size(0), n = x.size(1);
    at::Tensor offset = at::arange(batch, idx.options()).mul(n).view({batch, 1, 1});
    return x.reshape({batch * n, x.size(2)})
        .index_select(0, (idx + offset).flatten())
        .view({batch, idx.size(1), idx.size(2), x.size(2)});
}

/// The original's input-only augmentation, per cloud: with probability ½ jitter σ 0.025
/// clipped to ±0.05 per coordinate, and with probability ½ a small rotation (angles about x,
/// y and z with σ 0.03 rad clipped to ±0.09). The loader's perturbations of the input do not
/// reach Meta-PU, whose training_terms draws its own input from the ground truth.
at::Tensor perturb_input(const at::Tensor& input, uint64_t seed) {
    at::NoGradGuard no_grad;
    at::Generator gen = at::detail::createCPUGenerator(seed);
    const int64_t batch = input.size(0);
    const at::TensorOptions cpu = at::TensorOptions().dtype(at::kFloat);
    at::Tensor coin = at::rand({batch, 2}, gen, cpu);
    at::Tensor jitter = at::clamp(at::randn(input.sizes(), gen, cpu) * 0.025, -0.05, 0.05);
    jitter = jitter * (coin.select(1, 0) < 0.5).to(at::kFloat).view({batch, 1, 1});
    at::Tensor angles = at::clamp(at::randn({batch, 3}, gen, cpu) * 0.03, -0.09, 0.09);
    angles = angles * (coin.select(1, 1) < 0.5).to(at::kFloat).view({batch, 1});
    angles = angles.contiguous();
    const float* a = angles.data_ptr<float>();
    std::vector<at::Tensor> rotated;
    for (int64_t b = 0; b < batch; ++b, a += 3) {
        const double cx = std::cos(a[0]), sx = std::sin(a[0]), cy = std::cos(a[1]);
        const double sy = std::sin(a[1]), cz = std::cos(a[2]), sz = std::sin(a[2]);
        at::Tensor rx = at::tensor(std::vector<double>{1, 0, 0, 0, cx, -sx, 0, sx, cx});
        at::Tensor ry = at::tensor(std::vector<double>{cy, 0, sy, 0, 1, 0, -sy, 0, cy});
        at::Tensor rz = at::tensor(std::vector<double>{cz, -sz, 0, sz, cz, 0, 0, 0, 1});
        at::Tensor r = rz.view({3, 3}).matmul(ry.view({3, 3})).matmul(rx.view({3, 3}));
        rotated.push_back(input[b].matmul(r.t().to(input.options())));
    }
    return at::stack(rotated) + jitter.to(input.options());
}

uint64_t splitmix64(uint64_t x) {
    x += 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

// The training scale of a step as tenths: 11 .. 10·max_ratio.
int64_t training_tenths(int64_t step, int64_t max_ratio) {
    return kGridFirst + int64_t(splitmix64(uint64_t(step)) % uint64_t(grid_count(max_ratio)));
}

SinkhornOptions sinkhorn_options(const MetaPuOptions& o) {
    SinkhornOptions s;
    s.blur = o.blur;
    s.reach = o.reach;
    s.scaling = o.sinkhorn_scaling;
    s.gradient = o.sinkhorn_gradient == "unrolled" ? SinkhornGradient::kUnrolled
                                                   : SinkhornGradient::kEnvelope;
    return s;
}

}  // namespace

MetaPuOptions MetaPuOptions::from_json(const nlohmann::json& config) {
    MetaPuOptions o;
    read_backbone_config(config, "metapu", [&](auto&& visit) { visit_fields(o, visit); });
    if (o.candidates < 2)
        throw_input_error(kContext, "'candidates' must be at least 2, found {}", o.candidates);
    if (o.ratio < 2 || o.ratio > max_ratio(o))
        throw_input_error(kContext, "'ratio' {} is outside 2..{}", o.ratio, max_ratio(o));
    if (o.patch_size < 2)
        throw_input_error(kContext, "'patch_size' must be at least 2, found {}", o.patch_size);
    if (o.sinkhorn_scaling >= 1)
        throw_input_error(kContext, "'sinkhorn_scaling' must be below 1, found {}",
                          o.sinkhorn_scaling);
    return o;
}

nlohmann::json MetaPuOptions::to_json() const {
    return write_backbone_config("metapu", [&](auto&& visit) { visit_fields(*this, visit); });
}

double metapu_scale_code(double stage_scale, int64_t candidates) {
    const int64_t count = grid_count(candidates * candidates);
    const double position = (stage_scale * stage_scale - 0.1 * kGridFirst) / 0.1;
    const int64_t index = std::clamp<int64_t>(std::llround(position), 0, count - 1);
    return std::sqrt(double(kGridFirst + index) / 10.0) / double(candidates);
}

double metapu_training_scale(int64_t step, int64_t max_ratio) {
    return double(training_tenths(step, max_ratio)) / 10.0;
}

at::Tensor metapu_sparse_input(const at::Tensor& dense, int64_t m, uint64_t seed) {
    check_batched_points(dense, "metapu_sparse_input");
    const int64_t count = dense.size(1);
    if (m < 1 || m > count)
        throw_input_error("metapu_sparse_input", "cannot keep {} of {} points", m, count);
    at::NoGradGuard no_grad;
    const bool complement = m > count / 2;
    std::mt19937_64 rng(seed);
    std::vector<at::Tensor> rows;
    for (int64_t b = 0; b < dense.size(0); ++b) {
        const uint64_t element_seed = rng();
        at::Tensor points = dense[b].detach().to(at::kCPU);
        const int64_t centre = int64_t(rng() % uint64_t(count));
        at::Tensor by_distance = (points - points[centre]).pow(2).sum(-1).argsort();
        at::Tensor drawn = by_distance.index_select(
            0, nonuniform_subset(count, complement ? count - m : m, element_seed));
        if (!complement) {
            rows.push_back(drawn);
            continue;
        }
        at::Tensor keep = at::ones({count}, at::kBool);
        keep.index_fill_(0, drawn, false);
        rows.push_back(keep.nonzero().flatten());
    }
    return gather_points(dense, at::stack(rows).to(dense.device()));
}

bool metapu_generator_parameter(const std::string& name) {
    for (const char* part : {".fc11.", ".fc12.", ".fcskip."})
        if (name.find(part) != std::string::npos) return true;
    return false;
}

OptimizerGroup MetaPu::optimizer_group(const std::string& name) const {
    OptimizerGroup group;
    group.lr_scale = metapu_generator_parameter(name) ? options_.generator_lr_scale : 1.0;
    group.weight_decay = options_.weight_decay;
    return group;
}

MetaPu::MetaPu(const MetaPuOptions& options) : options_(options) {
    std::mt19937_64 rng(options.seed);
    const int64_t c = options.channels;
    add_linear(params_, "points.conv1", 3, c, /*bias=*/false, rng);
    add_linear(params_, "points.conv2", c, c, /*bias=*/false, rng);
    add_linear(params_, "points.conv3", c, c, /*bias=*/false, rng);
    for (auto [prefix, blocks] : {std::pair{std::string("stage1"), options.stage1_blocks},
                                  std::pair{std::string("stage2"), options.stage2_blocks}}) {
        add_pair(params_, prefix + ".head", c, c, rng);
        add_generator(params_, prefix + ".scale_weights.center", options.generator_hidden, c, rng);
        add_generator(params_, prefix + ".scale_weights.neighbor", options.generator_hidden, c,
                      rng);
        for (int64_t b = 0; b < blocks; ++b)
            add_pair(params_, prefix + ".block" + std::to_string(b), c, c, rng);
        add_pair(params_, prefix + ".offset", c, 3 * options.candidates, rng);
    }
}

nlohmann::json MetaPu::config_for_ratio(int64_t ratio) const {
    if (ratio < 2 || ratio > max_ratio(options_)) return nullptr;
    MetaPuOptions options = options_;
    options.ratio = ratio;
    options.patch_size =
        std::max<int64_t>(2, (options_.patch_size * options_.ratio + ratio / 2) / ratio);
    return options.to_json();
}

at::Tensor MetaPu::point_head(const at::Tensor& x, const ParamMap& params) const {
    at::Tensor idx = xyz_graph(x, std::min(options_.k, x.size(1) - 1));
    at::Tensor relative = gather_neighbors(x, idx) - x.unsqueeze(2);  // [B,N,k,3]
    at::Tensor h = at::relu(conv1x1(relative, params, "points.conv1"));
    h = at::relu(conv1x1(h, params, "points.conv2"));
    return max_over_neighbors(conv1x1(h, params, "points.conv3"));
}

// One RGC-up stage. Each block computes h = act(x), then graph_mean(h) + h: the original's
// in-place activation rewrites the tensor its skip connection holds, so the residual it adds
// is the activated input (docs/design.md, "Meta-PU").
MetaPu::Stage MetaPu::stage(const std::string& prefix, int64_t blocks, bool offsets_after_blocks,
                            const at::Tensor& xyz, const at::Tensor& features, double scale,
                            int64_t n_out, const ParamMap& params) const {
    const int64_t batch = xyz.size(0), n = xyz.size(1), c = options_.channels;
    at::Tensor idx = xyz_graph(xyz, std::min(options_.k, n - 1));
    at::Tensor skip = at::relu(features);
    at::Tensor x = graph_mean(skip, idx, params, prefix + ".head") + skip;

    const double code = metapu_scale_code(scale, options_.candidates);
    at::Tensor w_center = generate(params, prefix + ".scale_weights.center", code, c);
    at::Tensor w_neighbor = generate(params, prefix + ".scale_weights.neighbor", code, c);
    at::Tensor h = at::leaky_relu(x, kLeakySlope);
    x = graph_mean(h, idx, w_center, w_neighbor) + h;

    at::Tensor offset_input;
    for (int64_t b = 0; b < blocks; ++b) {
        h = at::relu(x);
        if (!offsets_after_blocks && b == blocks - 1) offset_input = h;
        x = graph_mean(h, idx, params, prefix + ".block" + std::to_string(b)) + h;
    }
    if (!offset_input.defined()) offset_input = at::relu(x);

    // candidates offsets per point, point-major: candidate j of point i is row i·c + j.
    const int64_t m = options_.candidates;
    at::Tensor offsets = graph_mean(offset_input, idx, params, prefix + ".offset");
    at::Tensor candidates =
        (offsets.view({batch, n, m, 3}) + xyz.unsqueeze(2)).reshape({batch, n * m, 3});
    at::Tensor chosen;
    {
        at::NoGradGuard no_grad;
        at::Tensor fixed = candidates.detach();
        if (fixed.scalar_type() != at::kFloat && fixed.device().is_cpu())
            fixed = fixed.to(at::kFloat);
        chosen = farthest_point_sampling_batched(fixed, n_out).to(xyz.device());
    }
    at::Tensor norm = 0.5 * (w_center.pow(2).sum() + w_neighbor.pow(2).sum());
    return {gather_points(candidates, chosen), x + skip, norm};
}

MetaPuOutput MetaPu::forward(const at::Tensor& x, const ParamMap& params, double scale,
                             int64_t n_out) const {
    check_batched_points(x, "metapu input");
    const int64_t n = x.size(1);
    if (n < 2) throw_input_error("metapu input", "needs at least 2 points, found {}", n);
    const at::Tensor& first = param(params, "points.conv1.weight");
    if (first.scalar_type() != x.scalar_type() || first.device() != x.device())
        throw_input_error("metapu input", "points are {} on {}, parameters {} on {}",
                          std::string(c10::toString(x.scalar_type())), x.device().str(),
                          std::string(c10::toString(first.scalar_type())), first.device().str());
    if (!(scale > 1) || scale > double(max_ratio(options_)) + 1e-9)
        throw_input_error("metapu input", "scale {} is outside (1, {}]", scale,
                          max_ratio(options_));
    // Stage 1 to ⌊N·round(√R, 3)⌋ points (the original's rounding), but at least
    // ⌈n_out / candidates⌉ so that stage 2 has enough candidates (tiny inputs just below the
    // largest ratio: 16 points at 15.9), stage 2 to n_out.
    if (n_out < 1 || n_out > max_ratio(options_) * n)
        throw_input_error("metapu input", "cannot make {} points from {} (at most {})", n_out, n,
                          max_ratio(options_) * n);
    const double root = std::round(std::sqrt(scale) * 1000.0) / 1000.0;
    const int64_t n1 = std::min(options_.candidates * n,
                                std::max(int64_t(std::floor(n * root + 1e-9)),
                                         (n_out + options_.candidates - 1) / options_.candidates));

    at::Tensor f0 = point_head(x, params);
    Stage first_stage =
        stage("stage1", options_.stage1_blocks, false, x, f0, std::sqrt(scale), n1, params);
    // Feature transfer: each new point takes the mean of the stage-1 features of its k
    // nearest input points.
    const at::Tensor nearest = knn_indices(x, first_stage.points, std::min(options_.k, n));
    at::Tensor transferred = gather_rows(first_stage.features, nearest).mean(2);
    Stage second_stage = stage("stage2", options_.stage2_blocks, true, first_stage.points,
                               transferred, double(n_out) / double(n1), n_out, params);
    return {second_stage.points, first_stage.scale_weights_norm + second_stage.scale_weights_norm};
}

at::Tensor MetaPu::upsample(const at::Tensor& x, const ParamMap& params) const {
    check_batched_points(x, "metapu input");
    return forward(x, params, double(options_.ratio), options_.ratio * x.size(1)).points;
}

LossTerms MetaPu::loss_terms(const at::Tensor& input, const at::Tensor& target,
                             const ParamMap& params, int64_t step) const {
    check_batched_points(input, "metapu input");
    check_batched_points(target, "metapu target");
    if (target.size(0) != input.size(0))
        throw_input_error("metapu target", "batch of {} for {} inputs", target.size(0),
                          input.size(0));
    const int64_t m = target.size(1);
    MetaPuOutput out = forward(input, params, double(m) / double(input.size(1)), m);
    LossTerms terms;
    if (options_.reconstruction == "chamfer")
        terms.emplace_back("chamfer", chamfer_loss(out.points, target));
    else
        terms.emplace_back("sinkhorn",
                           sinkhorn_divergence(out.points, target, sinkhorn_options(options_)));
    if (options_.scale_weights_penalty > 0)
        terms.emplace_back("scale_weights",
                           options_.scale_weights_penalty * out.scale_weights_norm);
    if (options_.uniform_weight > 0)
        terms.emplace_back("uniform", options_.uniform_weight *
                                          uniform_loss(out.points, metapu_uniform_options()));
    if (options_.repulsion_weight > 0 && m > 1)
        terms.emplace_back("repulsion", options_.repulsion_weight *
                                            punet_repulsion_loss(
                                                out.points, std::min(kRepulsionNeighbors, m - 1)));
    return terms;
}

at::Tensor MetaPu::loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                        int64_t step) const {
    return sum_of(loss_terms(input, target, params, step));
}

LossTerms MetaPu::training_terms(const at::Tensor& input, const at::Tensor& target,
                                 const ParamMap& params, const ParamMap& auxiliary,
                                 int64_t step) const {
    check_batched_points(target, "metapu target");
    const int64_t m = target.size(1);
    // R = tenths / 10 in integers: no rounding in ⌊M/R⌋ and ⌊⌊M/R⌋·R⌋.
    const int64_t tenths = training_tenths(step, max_ratio(options_));
    const int64_t n = std::max<int64_t>(2, 10 * m / tenths);
    const int64_t truth = std::min(m, n * tenths / 10);
    at::Tensor sparse = metapu_sparse_input(target, n, splitmix64(uint64_t(step) ^ 0x5eedULL));
    sparse = perturb_input(sparse, splitmix64(uint64_t(step) ^ 0x7e57ULL));
    return loss_terms(sparse, target.narrow(1, 0, truth), params, step);
}

at::Tensor MetaPu::downsample(const at::Tensor& dense, uint64_t seed) const {
    check_batched_points(dense, "metapu downsample");
    return metapu_sparse_input(dense, std::max<int64_t>(2, dense.size(1) / options_.ratio), seed);
}

std::unique_ptr<Backbone> make_metapu(const nlohmann::json& config) {
    return std::make_unique<MetaPu>(MetaPuOptions::from_json(config));
}

nlohmann::json metapu_small_config() {
    return {{"backbone", "metapu"},
            {"ratio", 4},
            {"channels", 4},
            {"stage1_blocks", 1},
            {"stage2_blocks", 1},
            {"k", 4},
            {"generator_hidden", 4},
            {"patch_size", 16},
            {"sinkhorn_gradient", "unrolled"},
            {"seed", 3}};
}

}  // namespace pumeta
