// LibTorch silently falls back to reference BLAS when no optimised BLAS is installed
// (Debian: libopenblas0-openmp), which makes training about 7x slower. Which BLAS the process
// loaded is read from the process itself, not guessed from a timing: a busy machine is slow
// with any BLAS.
#pragma once

#include <string>

namespace pumeta {

/// The BLAS library this process calls for matrix products.
struct BlasLibrary {
    /// Canonical path of the shared object that provides `sgemm_` (symbolic links such as
    /// Debian's alternatives resolved); empty when no loaded object exports it (a LibTorch
    /// with its BLAS linked in statically).
    std::string path;
    /// "OpenBLAS", "BLIS", "MKL", "reference BLAS" or "unknown", from the path.
    std::string name;
    /// OpenBLAS's own description (openblas_get_config(): version, kernel, threading) where
    /// the process has OpenBLAS; empty otherwise.
    std::string config;

    /// Debian's reference implementation (netlib, in the `blas/` folder of libblas3).
    bool reference() const { return name == "reference BLAS"; }
    /// One line: name, config and path.
    std::string describe() const;
};

/// The BLAS of this process (dladdr of `sgemm_` as the dynamic linker resolves it).
BlasLibrary loaded_blas();

/// GFLOP/s of a float32 n x n matrix product (best of a few runs).
double measure_gemm_gflops(int n = 512);

/// Once per process: a loud warning naming the package to install when the process runs on
/// reference BLAS. A speed measurement is a second signal only: a slow one says the machine
/// is slow or busy, and names no package. Returns the loaded library.
BlasLibrary check_blas();

}  // namespace pumeta
