// Helpers shared by the geometry I/O tests.
#pragma once

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/geometry/point_cloud.h"
#include "support/test_util.h"

namespace pumeta::test {

/// Appends `value` with its bytes in big-endian (or little-endian) order.
template <typename T>
void put_bytes(std::string& out, T value, bool big_endian = false) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    for (size_t i = 0; i < sizeof(T); ++i) out += bytes[big_endian ? sizeof(T) - 1 - i : i];
}

/// float32 [n,3] tensor from row-major values.
inline at::Tensor float_rows(const std::vector<float>& values) {
    return at::tensor(values, at::kFloat).view({-1, 3});
}

/// int64 [n,3] tensor from row-major values.
inline at::Tensor index_rows(const std::vector<int64_t>& values) {
    return at::tensor(values, at::kLong).view({-1, 3});
}

/// Fixture files written by hand for these tests.
inline std::string io_fixture(const std::string& name) {
    return std::string(PUMETA_SOURCE_DIR) + "/tests/fixtures/io/" + name;
}

/// Folder of Debian's assimp-testmodels files: installed by scripts/setup.sh, or extracted
/// into data/raw/assimp by scripts/get-data.sh; empty when neither exists.
inline std::string assimp_dir() {
    for (const std::string& dir : {std::string("/usr/share/assimp/models"),
                                   std::string(PUMETA_SOURCE_DIR) + "/data/raw/assimp"})
        if (std::filesystem::is_directory(dir)) return dir;
    return "";
}

inline std::string assimp_model(const std::string& name) { return assimp_dir() + "/" + name; }

}  // namespace pumeta::test
