#include "pumeta/core/blas_check.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <dlfcn.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>

namespace pumeta {

namespace {

/// The library's kind from its canonical path.
std::string blas_name(const std::string& path) {
    if (path.empty()) return "unknown";
    const std::filesystem::path file(path);
    const std::string folder = file.parent_path().filename().string();
    if (path.find("openblas") != std::string::npos) return "OpenBLAS";
    if (path.find("blis") != std::string::npos) return "BLIS";
    if (path.find("mkl") != std::string::npos) return "MKL";
    // Debian's libblas3 installs netlib's implementation as <libdir>/blas/libblas.so.3.
    if (folder == "blas" && file.filename().string().rfind("libblas.so", 0) == 0)
        return "reference BLAS";
    return "unknown";
}

}  // namespace

std::string BlasLibrary::describe() const {
    std::string text = name;
    if (!config.empty()) text += " (" + config + ")";
    text += path.empty() ? ", linked in" : ", " + path;
    return text;
}

BlasLibrary loaded_blas() {
    BlasLibrary blas;
    // RTLD_DEFAULT searches the objects in the order the dynamic linker binds LibTorch's own
    // call to sgemm_, so this is the implementation its matrix products run on.
    void* sgemm = dlsym(RTLD_DEFAULT, "sgemm_");
    Dl_info info{};
    if (sgemm && dladdr(sgemm, &info) && info.dli_fname) {
        std::error_code error;
        const auto canonical = std::filesystem::canonical(info.dli_fname, error);
        blas.path = error ? std::string(info.dli_fname) : canonical.string();
    }
    blas.name = blas_name(blas.path);
    if (blas.name == "OpenBLAS") {
        using GetConfig = const char* (*)();
        if (auto get_config =
                reinterpret_cast<GetConfig>(dlsym(RTLD_DEFAULT, "openblas_get_config")))
            blas.config = get_config();
    }
    return blas;
}

double measure_gemm_gflops(int n) {
    // One thread: reference BLAS is single-threaded anyway, and a multi-threaded OpenMP GEMM
    // on a loaded machine can stall far below its real speed.
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

BlasLibrary check_blas() {
    static const BlasLibrary blas = [] {
        BlasLibrary loaded = loaded_blas();
        if (loaded.reference()) {
            spdlog::warn(
                "REFERENCE BLAS: matrix products run on {}, netlib's unoptimised BLAS; install "
                "libopenblas0-openmp (scripts/setup.sh does) or training will be about 7x "
                "slower",
                loaded.path);
            return loaded;
        }
        // Reference BLAS reaches about 6 GFLOP/s on the 2-core development machine and
        // OpenBLAS about 200: far below 10 with an optimised library means a busy machine.
        const double rate = measure_gemm_gflops(512);
        if (rate < 10.0)
            spdlog::warn(
                "slow matrix products: {:.1f} GFLOP/s on {}; the machine is slow or busy, so "
                "training will take longer",
                rate, loaded.describe());
        return loaded;
    }();
    return blas;
}

}  // namespace pumeta
