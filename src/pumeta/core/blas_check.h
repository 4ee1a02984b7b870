// LibTorch silently falls back to reference BLAS when no optimised BLAS is installed
// (Debian: libopenblas0-openmp), which makes training about 7x slower. Detect it.
#pragma once

namespace pumeta {

/// GFLOP/s of a float32 n x n matrix product (best of a few runs).
double measure_gemm_gflops(int n = 512);

/// Measures a 512x512 GEMM once per process and logs a loud warning below 10 GFLOP/s.
/// Returns the measured rate.
double check_blas_speed();

}  // namespace pumeta
