#include "pumeta/data/patch_set.h"

#include <ATen/ATen.h>
#include <torch/serialize.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <optional>

#include "pumeta/core/error.h"
#include "pumeta/data/hdf5_patches.h"
#include "pumeta/geometry/sampling.h"

namespace pumeta {

namespace {

constexpr int64_t kPatchSetVersion = 1;

}  // namespace

at::Tensor PatchSet::gt_patch(int64_t s) const {
    int64_t mesh = seeds[s][0].item<int64_t>();
    int64_t index = seeds[s][1].item<int64_t>();
    int64_t begin = offsets[mesh].item<int64_t>(), end = offsets[mesh + 1].item<int64_t>();
    at::Tensor cloud = points.slice(0, begin, end);
    int64_t k = std::min(patch_points * ratio, end - begin);
    at::Tensor d = (cloud - cloud[index]).pow(2).sum(1);
    at::Tensor nearest = std::get<1>(d.topk(k, 0, /*largest=*/false, /*sorted=*/true));
    return cloud.index_select(0, nearest);
}

void save_patch_set(const std::string& path, const PatchSet& set) {
    nlohmann::json meta = {{"version", kPatchSetVersion},
                           {"ratio", set.ratio},
                           {"patch_points", set.patch_points},
                           {"ids", set.ids}};
    torch::serialize::OutputArchive archive;
    archive.write("meta", c10::IValue(meta.dump()));
    archive.write("points", set.points);
    archive.write("offsets", set.offsets);
    archive.write("seeds", set.seeds);
    std::string tmp = path + ".tmp";
    archive.save_to(tmp);
    std::filesystem::rename(tmp, path);
}

bool is_hdf5_patch_path(const std::string& path) {
    std::string extension = std::filesystem::path(path).extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    return extension == ".h5" || extension == ".hdf5";
}

PatchSet load_patch_set(const std::string& path, const Hdf5PatchKeys& keys) {
    if (is_hdf5_patch_path(path)) return read_hdf5_patches(path, keys);
    if (!std::filesystem::exists(path)) throw_input_error(path, "file not found");
    torch::serialize::InputArchive archive;
    try {
        archive.load_from(path);
    } catch (const std::exception& e) {
        throw_input_error(path, "not a readable patch set ({})",
                          std::string(e.what()).substr(0, std::string(e.what()).find('\n')));
    }
    c10::IValue meta_value;
    PatchSet set;
    if (!archive.try_read("meta", meta_value) || !meta_value.isString())
        throw_input_error(path, "patch set has no metadata");
    auto meta = nlohmann::json::parse(meta_value.toStringRef());
    if (meta.value("version", 0) != kPatchSetVersion)
        throw_input_error(path, "patch set version {} (expected {})", meta.value("version", 0),
                          kPatchSetVersion);
    set.ratio = meta.at("ratio");
    set.patch_points = meta.at("patch_points");
    set.ids = meta.at("ids").get<std::vector<std::string>>();
    archive.read("points", set.points);
    archive.read("offsets", set.offsets);
    archive.read("seeds", set.seeds);
    if (set.num_meshes() != static_cast<int64_t>(set.ids.size()))
        throw_input_error(path, "patch set lists {} ids for {} meshes", set.ids.size(),
                          set.num_meshes());
    return set;
}

PatchSet load_patch_set_for_ratio(const std::string& path, int64_t ratio,
                                  const Hdf5PatchKeys& keys) {
    if (is_hdf5_patch_path(path)) return read_hdf5_patches(path, keys, ratio);
    PatchSet set = load_patch_set(path);
    if (set.ratio != ratio)
        throw_input_error(path, "patch set has ratio {} but the model has ratio {}", set.ratio,
                          ratio);
    return set;
}

InputSampler parse_input_sampler(const std::string& name) {
    if (name == "fps") return InputSampler::kFps;
    if (name == "random") return InputSampler::kRandom;
    if (name == "nonuniform") return InputSampler::kNonuniform;
    throw_input_error("", "unknown input sampler '{}' (expected fps, random or nonuniform)", name);
}

std::string to_string(InputSampler sampler) {
    switch (sampler) {
        case InputSampler::kFps:
            return "fps";
        case InputSampler::kRandom:
            return "random";
        case InputSampler::kNonuniform:
            return "nonuniform";
    }
    return "?";
}

namespace {

/// The random choices of one training pair, drawn before any geometry is built so that a
/// sharded loader can pass over the other shards' patches leaving the generator exactly where
/// building them would have.
struct PairDraw {
    int64_t fps_start = 0;     ///< kFps: first point of the farthest point sampling
    uint64_t subset_seed = 0;  ///< kRandom, kNonuniform: seed of the subset
};

/// `gt_points` is the GT patch's point count (the range of the FPS start).
PairDraw draw_pair(int64_t gt_points, InputSampler sampler, std::mt19937_64& rng) {
    PairDraw draw;
    if (sampler == InputSampler::kFps)
        draw.fps_start = std::uniform_int_distribution<int64_t>(0, gt_points - 1)(rng);
    else
        draw.subset_seed = rng();
    return draw;
}

Batch build_pair(const at::Tensor& gt_patch, int64_t input_points, InputSampler sampler,
                 const PairDraw& draw) {
    int64_t n = gt_patch.size(0);
    at::Tensor indices;
    switch (sampler) {
        case InputSampler::kFps:
            indices = farthest_point_sampling(gt_patch, input_points, draw.fps_start);
            break;
        case InputSampler::kRandom:
            indices = random_subset(n, input_points, draw.subset_seed);
            break;
        case InputSampler::kNonuniform:
            // gt_patch rows are sorted by distance to the seed, as the sampler expects.
            indices = nonuniform_subset(n, input_points, draw.subset_seed);
            break;
    }
    at::Tensor input = gt_patch.index_select(0, indices);
    at::Tensor centroid = gt_patch.mean(0, /*keepdim=*/true);
    at::Tensor gt = gt_patch - centroid;
    double radius = gt.norm(2, 1).max().item<double>();
    double scale = radius > 0 ? 1.0 / radius : 1.0;
    return {(input - centroid) * scale, gt * scale};
}

/// The augmentation of one pair: random rotation, scale in [0.8, 1.2], clipped jitter.
struct Augmentation {
    at::Tensor rotation;  ///< float32 [3,3], applied as points · rotation
    float scale = 1;
    at::Tensor jitter;  ///< float32 [input_points, 3], added to the input only
};

/// `normal` carries state between calls (it caches every second value), so one is shared by
/// the whole batch.
Augmentation draw_augmentation(int64_t input_points, std::mt19937_64& rng,
                               std::normal_distribution<float>& normal) {
    Augmentation a;
    a.rotation = random_rotation(rng).t();
    a.scale = std::uniform_real_distribution<float>(0.8f, 1.2f)(rng);
    a.jitter = at::empty({input_points, 3}, at::kFloat);
    float* j = a.jitter.data_ptr<float>();
    for (int64_t i = 0; i < a.jitter.numel(); ++i)
        j[i] = std::clamp(0.01f * normal(rng), -0.03f, 0.03f);
    return a;
}

/// Points in GT patch s without cutting it (see PatchSet::gt_patch).
int64_t gt_patch_points(const PatchSet& set, int64_t s) {
    int64_t mesh = set.seeds[s][0].item<int64_t>();
    int64_t mesh_points = (set.offsets[mesh + 1] - set.offsets[mesh]).item<int64_t>();
    return std::min(set.patch_points * set.ratio, mesh_points);
}

}  // namespace

Batch make_pair(const at::Tensor& gt_patch, int64_t input_points, InputSampler sampler,
                std::mt19937_64& rng) {
    return build_pair(gt_patch, input_points, sampler, draw_pair(gt_patch.size(0), sampler, rng));
}

PatchLoader::PatchLoader(const PatchSet& set, LoaderOptions options)
    : set_(set), options_(options) {
    if (set.num_patches() < options.batch_size)
        throw_input_error("", "patch set has {} patches, fewer than the batch size {}",
                          set.num_patches(), options.batch_size);
    if (options.shard_count < 1 || options.shard_index < 0 ||
        options.shard_index >= options.shard_count)
        throw_input_error("", "shard {} of {} does not exist", options.shard_index,
                          options.shard_count);
    if (options.batch_size % options.shard_count != 0)
        throw_input_error("", "batch size {} does not split into {} equal shards",
                          options.batch_size, options.shard_count);
    start_epoch(0);
}

int64_t PatchLoader::batches_per_epoch() const { return set_.num_patches() / options_.batch_size; }

void PatchLoader::start_epoch(int64_t epoch) {
    order_.resize(set_.num_patches());
    std::iota(order_.begin(), order_.end(), 0);
    std::mt19937_64 rng(options_.seed * 1000003 + epoch);
    std::shuffle(order_.begin(), order_.end(), rng);
}

void PatchLoader::seek(int64_t batches) {
    position_ = batches;
    start_epoch(position_ / batches_per_epoch());
}

Batch PatchLoader::next() {
    int64_t per_epoch = batches_per_epoch();
    int64_t in_epoch = position_ % per_epoch;
    if (in_epoch == 0 && position_ > 0) start_epoch(position_ / per_epoch);
    // Each batch has its own generator: resuming at a position reproduces it exactly.
    std::mt19937_64 rng(options_.seed ^ (0x9e3779b97f4a7c15ull * (position_ + 1)));
    std::normal_distribution<float> normal(0.f, 1.f);
    int64_t shard_size = options_.batch_size / options_.shard_count;
    int64_t first = options_.shard_index * shard_size;
    std::vector<at::Tensor> inputs, gts;
    inputs.reserve(shard_size);
    gts.reserve(shard_size);
    for (int64_t b = 0; b < options_.batch_size; ++b) {
        int64_t s = order_[in_epoch * options_.batch_size + b];
        PairDraw draw = draw_pair(gt_patch_points(set_, s), options_.sampler, rng);
        std::optional<Augmentation> augmentation;
        if (options_.augment) augmentation = draw_augmentation(set_.patch_points, rng, normal);
        if (b < first || b >= first + shard_size) continue;  // another shard's patch
        Batch pair = build_pair(set_.gt_patch(s), set_.patch_points, options_.sampler, draw);
        if (augmentation) {
            pair.input = pair.input.matmul(augmentation->rotation) * augmentation->scale +
                         augmentation->jitter;
            pair.gt = pair.gt.matmul(augmentation->rotation) * augmentation->scale;
        }
        inputs.push_back(pair.input);
        gts.push_back(pair.gt);
    }
    ++position_;
    return {at::stack(inputs), at::stack(gts)};
}

}  // namespace pumeta
