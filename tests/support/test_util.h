// Helpers shared by the tests: temporary directories, running the CLI, synthetic patches, tiny
// models. Random clouds come from the library (uniform_random_points in geometry/sampling.h).
#pragma once

#include <ATen/core/Tensor.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/models/backbone.h"

namespace pumeta::test {

/// Success when `action` throws InputError whose one-line message contains every fragment.
template <typename Action>
::testing::AssertionResult throws_input_error(Action&& action,
                                              const std::vector<std::string>& fragments) {
    try {
        action();
    } catch (const InputError& error) {
        const std::string message = error.what();
        if (message.find('\n') != std::string::npos)
            return ::testing::AssertionFailure() << "message spans lines: " << message;
        for (const std::string& fragment : fragments)
            if (message.find(fragment) == std::string::npos)
                return ::testing::AssertionFailure()
                       << "message '" << message << "' lacks '" << fragment << "'";
        return ::testing::AssertionSuccess() << message;
    } catch (const std::exception& error) {
        return ::testing::AssertionFailure() << "threw a non-InputError: " << error.what();
    }
    return ::testing::AssertionFailure() << "did not throw";
}

/// A fresh directory under the system temp dir, removed with its contents on destruction.
class TempDir {
  public:
    TempDir();
    ~TempDir();
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;

    const std::filesystem::path& path() const { return path_; }
    std::string file(const std::string& name) const { return (path_ / name).string(); }

  private:
    std::filesystem::path path_;
};

struct CommandResult {
    int exit_code = -1;
    std::string out;
    std::string err;
};

/// Runs `program` with `args` (quoted for the shell here), capturing stdout and stderr.
CommandResult run_command(const std::string& program, const std::vector<std::string>& args);

/// The path of the built `pumeta` binary.
std::string cli_path();

/// Runs the built `pumeta` binary with `args`.
CommandResult run_cli(const std::vector<std::string>& args);

/// Success when a command exited with 2 and the last line of its stderr is
/// "pumeta: error: ..." containing every fragment.
::testing::AssertionResult one_line_error(const CommandResult& r,
                                          const std::vector<std::string>& fragments);

/// A CSV file as rows of comma-separated fields, the header first (a trailing comma ends in an
/// empty field).
std::vector<std::vector<std::string>> read_csv(const std::string& path);

/// A program built beside the `pumeta` binary (e.g. "pumeta-ear"), or "" when it is not built.
std::string built_program(const std::string& name);

/// The first executable called `name` on $PATH, or "" when there is none.
std::string find_program(const std::string& name);

/// Writes `text` to `path` (binary, exactly these bytes).
void write_file(const std::string& path, const std::string& text);

/// Reads a whole file.
std::string read_file(const std::string& path);

/// The records of a run's log.jsonl (one JSON object per line) that hold `key`, in order:
/// "loss" for supervised steps, "outer_loss" for meta-training steps, "val_cd" and
/// "val_cd_after" for validations. A last line without its newline is left out: a run may be
/// writing it while a test polls.
std::vector<nlohmann::json> log_records(const std::string& log_file, const std::string& key);

/// A small surface patch: n points per element on a gently curved sheet over [-1,1]²,
/// [B,n,3], from a seeded generator.
at::Tensor sheet(int64_t batch, int64_t n, uint64_t seed, at::ScalarType type = at::kFloat);

/// Root of the source tree (for fixtures under tests/data).
std::string source_dir();

/// The public PU-GAN test meshes beside the source tree (../shared/benchmarks/pugan-test), and
/// whether they are there (tests that need them skip otherwise).
std::filesystem::path pugan_benchmark_dir();
bool have_pugan_benchmark();

/// A folder under `dir` in the published layout (input_2048/, gt_8192/, original_meshes/)
/// holding symbolic links to `meshes` of pugan_benchmark_dir() only.
std::filesystem::path pugan_benchmark_subset(const TempDir& dir,
                                             const std::vector<std::string>& meshes);

/// A raw-data tree shaped like get-data.sh's under `raw`: a furniture catalogue with a chair,
/// a table, a lamp and a human figure, CGAL CAD parts, a scanned statue and an aerial scan
/// (all meshes procedural, so the tree is made in milliseconds).
void make_raw_tree(const std::filesystem::path& raw);

/// A miniature reproduction under `dir`: make_raw_tree + a 4× dataset of 128-point inputs in
/// dir/data and two tiny untrained PU-GCN checkpoints, dir/models/pugcn-x4.pt and
/// pugcn-x4-meta.pt (meta options: N = 2, α = 0.01). Returns a `pumeta reproduce` config for
/// it (main ratio 4, sets test-indist and test-scans, a "quick" budget of 2 cases, external
/// baselines "copy" = `cp {input} {output}` and "absent" = a program that does not exist).
nlohmann::json make_tiny_reproduction(const std::filesystem::path& dir);

/// PU-GCN's registered small config (width 4 on 16-point patches, k 4, dilation 2, random
/// X↓) at `ratio` and `seed`: a model small enough for finite differences and in-process
/// training runs.
nlohmann::json tiny_pugcn_config(int64_t ratio, uint64_t seed);

/// Dis-PU's registered small config (width 4–8 on 16-point patches, seed 3) at `ratio`, for
/// the same uses.
nlohmann::json tiny_dispu_config(int64_t ratio = 4);

/// Overwrites `path` with another tiny meta-trained PU-GCN (weights from `seed`).
void save_tiny_meta_model(const std::string& path, uint64_t seed);

/// Overwrites `path` with another tiny plain PU-GCN (weights from `seed`).
void save_tiny_model(const std::string& path, uint64_t seed);

/// A PU-GCN of width 8 on 64-point patches (k 8, seed 1): large enough for the patch pipeline
/// on a few hundred points, small enough to adapt in milliseconds.
std::unique_ptr<Backbone> small_pugcn(int64_t ratio);

/// n points on the unit sphere (a surface, so that patches are meaningful), from `seed`.
at::Tensor sphere_points(int64_t n, uint64_t seed);

}  // namespace pumeta::test
