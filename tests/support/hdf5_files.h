// Writing small HDF5 files in tests (the public benchmarks' training-patch format,
// data/hdf5_patches.h), well-formed or deliberately not. The HDF5 headers stay in the .cpp.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <string>
#include <vector>

namespace pumeta::test {

/// One dataset of an HDF5 file.
struct Hdf5Dataset {
    /// A path below the root; groups on the way ("data/poisson_256") are created.
    std::string name;
    /// The data: float32, float64 or int32, any shape. Undefined: a chunked float32 dataset of
    /// shape `declared` whose data is never written.
    at::Tensor values;
    std::vector<int64_t> declared;
};

/// Writes a new HDF5 file at `path` holding `datasets` (std::runtime_error when the library
/// fails).
void write_hdf5(const std::string& path, const std::vector<Hdf5Dataset>& datasets);

}  // namespace pumeta::test
