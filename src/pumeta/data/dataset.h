// The dataset builder: turns meshes and scans into training clouds (patches are cut at load
// time) and test cases, for every ratio. Layout of a dataset directory:
//   manifest.json                      config, splits, sources with SHA-256, counts
//   train-x<r>.tensors, val-x<r>.tensors
//                                      PatchSet (patch_set.h): per mesh a Poisson-disk cloud of
//                                      input_points·r points and the seed indices of its patches
//   cases/<set>/meshes/<case>.ply      normalised mesh (sets with meshes)
//   cases/<set>/x<r>/<case>/input.ply  test input (input_points Poisson-disk points, or a
//                                      random 1/r subset of a real scan)
//                      .../gt.ply      ground truth (input_points·r points)
//                      .../gt_alt.ply  a second, independently seeded GT sample (the sampling
//                                      floor; sets with meshes only)
//                      .../input_rel<p>.ply, input_abs<s>.ply   noisy inputs
//   cases/<set>/x<r>/cases.json        the list of cases with their files
// Simulated scan splits (scan_splits; scan_simulation.h) write cases like the real scans'
// (GT = the whole simulated sweep, input = a random 1/r subset) plus the scene mesh, in the
// same normalised frame, under cases/<set>/meshes/.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta {

/// A split of simulated scans: scan_scenes scenes swept by one sensor.
struct ScanSplitConfig {
    /// The split's name, e.g. "test-lidar16" (a directory under cases/).
    std::string split;
    /// A sensor of scan_sensor(): "lidar16", "lidar32", "lidar64" or "terrestrial".
    std::string sensor;
    /// Where the scenes' objects come from. "test": half from the meshes of test-indist,
    /// test-scans and test-humans, half newly generated shapes; "train": from the train
    /// split's meshes (real and generated) only, for anything that tunes or trains.
    std::string meshes = "test";

    static ScanSplitConfig from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

struct DatasetConfig {
    /// Where scripts/get-data.sh put the raw data; empty = no real data (generator only).
    std::string raw_dir = "data/raw";
    std::vector<int64_t> ratios = {4, 8, 16};
    /// Test inputs have this many points; a training mesh's cloud has input_points·r, so a
    /// training patch covers the same share of the surface as a test patch (docs/design.md,
    /// "Data": patch scale matches the test protocol).
    int64_t input_points = 2048;
    /// Input points per patch (the GT patch has patch_points·r).
    int64_t patch_points = 256;
    int64_t patches_per_mesh = 200;
    /// Procedural shapes added to train (and a share of them to val).
    int64_t generated_shapes = 400;
    uint64_t generator_seed = 1;
    /// Shares of the non-human furniture going to test-indist and val (by a hash of the id).
    double test_fraction = 0.15;
    double val_fraction = 0.05;
    /// Seed of every sampling step (each mesh and case derives its own from it).
    uint64_t seed = 2023;
    /// The inputs of the mesh cases (test and val): "poisson", a Poisson-disk sample of
    /// input_points of the mesh (the paper's protocol), or "gt_subset", a random 1/r of each
    /// ratio's ground truth (the protocol of the real and simulated scans, docs/data.md).
    std::string case_inputs = "poisson";
    /// Noise variants of each test input: relative (percent) and absolute (sigma) protocols.
    std::vector<double> relative_noise = {0.5, 1.0, 2.0};
    std::vector<double> absolute_noise = {0.01, 0.02};
    /// Limit on real models per split (0 = all): for quick datasets and tests.
    int64_t max_models_per_split = 0;
    /// Build only these splits (empty = all). Every file is seeded per mesh, split and ratio,
    /// so a partial build writes exactly the files a full build would; its manifest goes to
    /// manifest-<splits>-x<ratios>.json instead of manifest.json.
    std::vector<std::string> splits;
    /// Simulated scan splits (docs/data.md, "Simulated scans"); none by default.
    std::vector<ScanSplitConfig> scan_splits;
    /// Scenes per simulated split, objects per scene, and the seed of every choice, layout,
    /// noise and dropout of the simulation.
    int64_t scan_scenes = 4;
    int64_t scan_objects = 16;
    uint64_t scan_seed = 1;

    static DatasetConfig from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

/// The mesh without its zero-area faces, moved and scaled so that its area-weighted surface
/// centroid is at 0 and its farthest used vertex at radius 1. InputError (naming `what`) when
/// no face has positive area.
TriangleMesh normalize_to_unit_sphere(TriangleMesh mesh, const std::string& what);

/// Builds the whole dataset into out_dir (created; existing files are overwritten).
/// Returns the manifest (also written to out_dir/manifest.json). Logs progress.
nlohmann::json make_dataset(const DatasetConfig& config, const std::string& out_dir);

/// Checks a manifest's "splits": no model id in two splits, no file (by SHA-256) in two
/// splits, human figures only in test-humans. make_dataset runs it before writing the patch sets
/// and the manifest; InternalError naming the model otherwise.
void check_split_integrity(const nlohmann::json& manifest);

}  // namespace pumeta
