#include "pumeta/core/blas_check.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <spdlog/spdlog.h>

#include <chrono>

namespace pumeta {

double measure_gemm_gflops(int n) {
    // One thread: reference BLAS is single-threaded anyway, and a multi-threaded OpenMP GEMM
    // on a loaded machine can stall far below its real speed (a false alarm).
    int threads = at::get_num_threads();
    at::set_num_threads(1);
    at::NoGradGuard no_grad;
    at::Tensor a = at::rand({n, n});
    at::Tensor b = at::rand({n, n});
    at::Tensor c = at::mm(a, b);  // warm-up: thread pool and BLAS initialisation
    double best = 1e30;
    for (int run = 0; run < 5; ++run) {
        auto start = std::chrono::steady_clock::now();
        at::mm_out(c, a, b);
        double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        best = std::min(best, seconds);
    }
    at::set_num_threads(threads);
    return 2.0 * n * n * n / best / 1e9;
}

double check_blas_speed() {
    static const double gflops = [] {
        double rate = measure_gemm_gflops(512);
        if (rate < 10.0)
            spdlog::warn(
                "SLOW BLAS: a 512x512 matrix product runs at {:.1f} GFLOP/s (< 10). LibTorch "
                "is probably using reference BLAS; install libopenblas0-openmp "
                "(scripts/setup.sh does) or training will be about 7x slower.",
                rate);
        return rate;
    }();
    return gflops;
}

}  // namespace pumeta
