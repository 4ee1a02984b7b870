#include "pumeta/core/blas_check.h"

#include <gtest/gtest.h>

namespace pumeta {

// Guards the set-up, not a speed target: reference BLAS reaches about 6 GFLOP/s here and
// OpenBLAS about 200 (measured on the 2-core dev machine), so 10 separates them widely.
TEST(BlasCheck, MatrixProductIsNotRunningOnReferenceBlas) {
    double gflops = measure_gemm_gflops(512);
    EXPECT_GE(gflops, 10.0) << "install libopenblas0-openmp (scripts/setup.sh)";
}

}  // namespace pumeta
