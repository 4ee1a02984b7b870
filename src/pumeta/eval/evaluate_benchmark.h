// Scoring a method on a public benchmark's test folder (PU-GAN's and PU1K's layout) with the
// protocol of their published tables (eval/benchmark_protocol.h): `pumeta eval --benchmark`.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pumeta/eval/evaluate_cases.h"

namespace pumeta {

/// One test object: its files, matched by stem.
struct BenchmarkObject {
    std::string name;   ///< the file stem
    std::string input;  ///< input_<N>/<name>.xyz
    std::string gt;     ///< gt_<rN>/<name>.xyz
    std::string mesh;   ///< <name>.off, or empty when the folder has none
};

/// A test folder as find_benchmark_layout() found it.
struct BenchmarkLayout {
    std::string benchmark = "pugan";  ///< its name, recorded in the summary
    std::string data_dir;
    std::string input_dir;  ///< the folder holding the inputs
    std::string gt_dir;     ///< the folder holding the ground truths
    int64_t input_points = 0;
    int64_t ratio = 0;
    std::vector<BenchmarkObject> objects;  ///< by name
};

/// The test objects under data_dir: inputs in input_<N>/*.xyz, ground truths in
/// gt_<ratio·N>/<stem>.xyz, meshes as <stem>.off in original_meshes/ or data_dir itself. A
/// folder that holds no .xyz file but a folder of its own name is looked into (PU1K's
/// input_2048/input_2048/). `input_points` picks input_<N> (0: the only one, or input_2048
/// when there are several); `ratio` picks gt_<ratio·N> (0: the only gt_<k·N>, k >= 2).
/// InputError "<folder>: ..." on one line when a folder is missing or ambiguous, holds no
/// inputs, or an input has no ground truth.
BenchmarkLayout find_benchmark_layout(const std::string& data_dir, int64_t input_points = 0,
                                      int64_t ratio = 0);

/// Upsamples every input with options.method (predict_with_method(); every method but "floor")
/// and scores it against its ground truth and mesh with score_benchmark_object(). Writes
/// out_dir/cases.csv (one row per object: object, n_in, n_out, n_gt, cd_1e3, hd_1e3,
/// hd_legacy_1e3, p2f_1e3, p2f_std_1e3 (the object's own mean and std), seconds; empty P2F
/// fields without a mesh) and out_dir/summary.json, which it returns: cd_1e3, hd_1e3,
/// hd_legacy_1e3 (means over objects), p2f_1e3 and p2f_std_1e3 (pooled over the points of the
/// objects with a mesh; null when none has one), the counts, the protocol's description and,
/// when some objects have no mesh, a note naming how many. With options.save_predictions each
/// prediction is written as out_dir/pred/<name>.xyz. model may be null unless the method needs
/// one; it must serve layout.ratio.
nlohmann::json evaluate_benchmark(const BenchmarkLayout& layout, const Backbone* model,
                                  const EvalOptions& options, const std::string& out_dir);

}  // namespace pumeta
