// Training data in memory: per mesh a dense Poisson-disk cloud and the seeds of its patches.
// Patches are cut when a batch is drawn (seed point + its patch_points·r nearest neighbours),
// which keeps a full training set small enough to load in a second.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

namespace pumeta {

struct PatchSet {
    int64_t ratio = 4;
    int64_t patch_points = 256;    ///< input points per patch; GT patches have patch_points·ratio
    at::Tensor points;             ///< float32 [P,3], all meshes' clouds concatenated
    at::Tensor offsets;            ///< int64 [M+1]: mesh m owns points[offsets[m]:offsets[m+1]]
    at::Tensor seeds;              ///< int64 [S,2]: (mesh, point index within the mesh) per patch
    std::vector<std::string> ids;  ///< mesh ids, [M]

    int64_t num_meshes() const { return offsets.defined() ? offsets.size(0) - 1 : 0; }
    int64_t num_patches() const { return seeds.defined() ? seeds.size(0) : 0; }

    /// GT patch of seed s: the patch_points·ratio nearest neighbours of the seed point in its
    /// mesh's cloud, float32 [patch_points·ratio, 3], in the mesh's (unit-sphere) frame.
    at::Tensor gt_patch(int64_t s) const;
};

/// The datasets of an HDF5 patch file (PU-GAN's and PU1K's training data,
/// data/hdf5_patches.h) that hold the input and the GT patches.
struct Hdf5PatchKeys {
    std::string input = "poisson_256";
    std::string gt = "poisson_1024";
};

/// Whether `path` is read as an HDF5 patch file: its extension is .h5 or .hdf5 (any case).
bool is_hdf5_patch_path(const std::string& path);

void save_patch_set(const std::string& path, const PatchSet& set);
/// A patch set written by save_patch_set, or an HDF5 patch file (is_hdf5_patch_path) read with
/// `keys` (read_hdf5_patches).
PatchSet load_patch_set(const std::string& path, const Hdf5PatchKeys& keys = {});
/// load_patch_set for a model of ratio `ratio`: InputError "<path>: patch set has ratio A but
/// the model has ratio B" when the set's ratio differs (for an HDF5 file: when its GT patches
/// do not hold `ratio` times the points of its input patches).
PatchSet load_patch_set_for_ratio(const std::string& path, int64_t ratio,
                                  const Hdf5PatchKeys& keys = {});

/// How training inputs are drawn from a GT patch (recorded in every checkpoint's config).
enum class InputSampler {
    kFps,         ///< farthest point sampling from a random start: blue noise, like Poisson-disk
    kRandom,      ///< uniform random subset: like random subsets of real scans
    kNonuniform,  ///< PU-GAN's non-uniform sampler (points ordered by distance to the seed)
};
InputSampler parse_input_sampler(const std::string& name);
std::string to_string(InputSampler sampler);

struct LoaderOptions {
    int64_t batch_size = 64;
    InputSampler sampler = InputSampler::kFps;
    /// Random rotation, scale in [0.8, 1.2], jitter sigma 0.01 clipped to 0.03 (on the input).
    bool augment = true;
    uint64_t seed = 0;
    /// Distributed sampling: the loader yields only the shard_index-th of shard_count equal,
    /// contiguous parts of every batch (batch_size must divide evenly), each patch exactly as
    /// the unsharded loader draws it, so the shards of all ranks together are the full batch.
    int64_t shard_index = 0;
    int64_t shard_count = 1;
};

/// A training batch, each patch normalised by its GT patch's centroid and radius.
///   input: float32 [B, patch_points, 3];  gt: float32 [B, patch_points·ratio, 3]
/// (B = batch_size / shard_count for a sharded loader).
struct Batch {
    at::Tensor input;
    at::Tensor gt;
};

/// Shuffled epochs over all patches of a PatchSet, batch by batch. Deterministic given the
/// seed; position() / seek() let training resume at the same batch.
class PatchLoader {
  public:
    PatchLoader(const PatchSet& set, LoaderOptions options);

    Batch next();
    int64_t batches_per_epoch() const;
    /// Batches drawn so far; seek(n) continues as if n batches had been drawn.
    int64_t position() const { return position_; }
    void seek(int64_t batches);

  private:
    void start_epoch(int64_t epoch);

    const PatchSet& set_;
    LoaderOptions options_;
    std::vector<int64_t> order_;
    int64_t position_ = 0;
};

/// One training pair from a GT patch (exposed for tests): draws the input with `sampler`,
/// normalises both by the GT patch's centroid and radius. gt_patch [R·n, 3] -> {[n,3], [R·n,3]}.
Batch make_pair(const at::Tensor& gt_patch, int64_t input_points, InputSampler sampler,
                std::mt19937_64& rng);

}  // namespace pumeta
