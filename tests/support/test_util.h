// Helpers shared by the tests: temporary directories, running the CLI, random clouds.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace pumeta::test {

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

/// Runs the built `pumeta` binary with `args` (no shell quoting needed for plain arguments).
CommandResult run_cli(const std::vector<std::string>& args);

/// Writes `text` to `path` (binary, exactly these bytes).
void write_file(const std::string& path, const std::string& text);

/// Reads a whole file.
std::string read_file(const std::string& path);

/// float32 [n,3] points uniform in [-1,1]^3 from a seeded generator.
at::Tensor random_points(int64_t n, uint64_t seed);

/// Root of the source tree (for fixtures under tests/data).
std::string source_dir();

/// A raw-data tree shaped like get-data.sh's under `raw`: a furniture catalogue with a chair,
/// a table, a lamp and a human figure, CGAL CAD parts, a scanned statue and an aerial scan
/// (all meshes procedural, so the tree is made in milliseconds).
void make_raw_tree(const std::filesystem::path& raw);

}  // namespace pumeta::test
