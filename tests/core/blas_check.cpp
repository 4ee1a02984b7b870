// Which BLAS the process runs on, read from the process (not from a timing): right on an idle
// and on a busy machine, and wrong-footed by neither.
#include "pumeta/core/blas_check.h"

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <thread>
#include <vector>

#include "support/test_util.h"

namespace pumeta {
namespace {

/// Debian's reference BLAS (package libblas3), which LD_LIBRARY_PATH can force on a process.
const char* const kReferenceBlasDir = "/usr/lib/x86_64-linux-gnu/blas";

/// One spinning thread per core while alive: the machine as busy as a parallel build makes it.
class BusyMachine {
  public:
    BusyMachine() {
        const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
        for (unsigned i = 0; i < cores; ++i)
            threads_.emplace_back([this] {
                volatile double x = 1;
                while (!stop_) x = x * 1.0000001 + 1e-9;
            });
    }
    ~BusyMachine() {
        stop_ = true;
        for (auto& t : threads_) t.join();
    }

  private:
    std::atomic<bool> stop_{false};
    std::vector<std::thread> threads_;
};

/// The BLAS line of `pumeta --version`, with LD_LIBRARY_PATH set to `library_path` when given.
std::string blas_line(const std::string& library_path) {
    std::vector<std::string> args;
    if (!library_path.empty()) args.push_back("LD_LIBRARY_PATH=" + library_path);
    args.insert(args.end(), {test::cli_path(), "--version"});
    const test::CommandResult r = test::run_command("env", args);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    const size_t at = r.out.find("BLAS ");
    return at == std::string::npos ? "" : r.out.substr(at, r.out.find('\n', at) - at);
}

TEST(BlasCheck, ThisProcessRunsOnAnOptimisedBlas) {
    const BlasLibrary blas = loaded_blas();
    EXPECT_FALSE(blas.path.empty()) << "no loaded object exports sgemm_";
    EXPECT_FALSE(blas.reference())
        << blas.describe() << ": install libopenblas0-openmp (scripts/setup.sh)";
    if (blas.name == "OpenBLAS") EXPECT_NE(blas.config.find("OpenBLAS"), std::string::npos);
}

TEST(BlasCheck, ReferenceBlasForcedOnAProcessIsNamedIdleAndUnderLoad) {
    if (!std::filesystem::exists(std::string(kReferenceBlasDir) + "/libblas.so.3"))
        GTEST_SKIP() << "no reference BLAS in " << kReferenceBlasDir << " (package libblas3)";
    const BlasLibrary idle = loaded_blas();
    const std::string forced_idle = blas_line(kReferenceBlasDir);
    const std::string plain_idle = blas_line("");
    EXPECT_NE(forced_idle.find("reference BLAS"), std::string::npos) << forced_idle;
    EXPECT_NE(forced_idle.find(kReferenceBlasDir), std::string::npos) << forced_idle;
    EXPECT_EQ(plain_idle.find("reference BLAS"), std::string::npos) << plain_idle;
    EXPECT_NE(plain_idle.find(idle.name), std::string::npos) << plain_idle;
    BusyMachine busy;
    EXPECT_EQ(blas_line(kReferenceBlasDir), forced_idle);
    EXPECT_EQ(blas_line(""), plain_idle);
    const BlasLibrary loaded = loaded_blas();
    EXPECT_EQ(loaded.path, idle.path);
    EXPECT_FALSE(loaded.reference());
}

}  // namespace
}  // namespace pumeta
