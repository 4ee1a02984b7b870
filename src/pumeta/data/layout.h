// Where things are in a make-dataset directory (the layout drawn in data/dataset.h): the one
// place that spells out its paths, for the writer (make_dataset) and every reader (eval,
// reproduce, report, contact-sheet).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

namespace pumeta::layout {

/// The test sets (splits with cases only; "val" has cases too, for tuning).
inline constexpr const char* kTestIndist = "test-indist";
inline constexpr const char* kTestScans = "test-scans";
inline constexpr const char* kTestAerial = "test-aerial";
inline constexpr const char* kTestHumans = "test-humans";
/// Every test set, in the order of the paper's tables.
inline constexpr std::array<const char*, 4> kTestSets = {kTestIndist, kTestScans, kTestAerial,
                                                         kTestHumans};

/// Files of one case directory (cases/<set>/x<r>/<case>/).
inline constexpr const char* kInputFile = "input.ply";
inline constexpr const char* kGtFile = "gt.ply";
inline constexpr const char* kGtAltFile = "gt_alt.ply";

/// "x<ratio>": the directory of a ratio's cases, and the key of its counts in the manifest.
std::string ratio_tag(int64_t ratio);

/// <dataset>/cases: every set's cases.
std::filesystem::path cases_root(const std::filesystem::path& dataset);

/// <dataset>/cases/<set>/x<ratio>: the cases of a set at a ratio (what `pumeta eval` takes).
std::filesystem::path cases_dir(const std::filesystem::path& dataset, const std::string& set,
                                int64_t ratio);

/// <cases_dir>/cases.json: the list of a cases directory's cases with their files.
std::filesystem::path case_index_path(const std::filesystem::path& cases_dir);

/// The index of a cases directory (its cases.json: {"set", "ratio", "cases": [...]});
/// InputError naming the file when it is missing or malformed.
nlohmann::json read_case_index(const std::filesystem::path& cases_dir);

/// <dataset>/cases/<set>/meshes/<case>.ply: a case's normalised mesh, shared by its ratios.
std::filesystem::path case_mesh_path(const std::filesystem::path& dataset, const std::string& set,
                                     const std::string& case_name);

/// case_mesh_path relative to the case's directory, as cases.json records it.
std::string case_mesh_entry(const std::string& case_name);

/// "<split>-x<ratio>.tensors": the PatchSet file of a training split (as the manifest records
/// it).
std::string patch_set_file(const std::string& split, int64_t ratio);

/// <dataset>/<split>-x<ratio>.tensors.
std::filesystem::path patch_set_path(const std::filesystem::path& dataset, const std::string& split,
                                     int64_t ratio);

}  // namespace pumeta::layout
