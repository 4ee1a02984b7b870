#include "pumeta/core/version.h"

#include <fmt/format.h>
#include <torch/version.h>

#include "pumeta/core/blas_check.h"
#include "pumeta_commit.h"

namespace pumeta {

std::string version() { return PUMETA_VERSION; }

std::string git_commit() { return PUMETA_GIT_COMMIT; }

std::string torch_version() { return TORCH_VERSION; }

nlohmann::json build_info() {
    const BlasLibrary blas = loaded_blas();
    return {{"version", version()},
            {"commit", git_commit()},
            {"libtorch", torch_version()},
            {"blas", {{"name", blas.name}, {"path", blas.path}, {"config", blas.config}}}};
}

std::string build_info_text() {
    return fmt::format("pumeta {}\ncommit {}\nLibTorch {}\nBLAS {}\n", version(), git_commit(),
                       torch_version(), loaded_blas().describe());
}

}  // namespace pumeta
