// The process's peak resident set, as the benchmarks report it.
#include "pumeta/core/allocator.h"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>

namespace pumeta {
namespace {

TEST(PeakResident, GrowsByWhatTheProcessTouches) {
    const double before = peak_resident_mib();
    EXPECT_GT(before, 1.0);  // the test binary with LibTorch loaded
    constexpr size_t kBytes = size_t(96) << 20;
    std::unique_ptr<char[]> block(new char[kBytes]);
    std::memset(block.get(), 1, kBytes);  // resident only once written
    volatile char sink = block[kBytes - 1];
    (void)sink;
    const double after = peak_resident_mib();
    // The peak cannot fall, and 96 MiB written must raise it unless it was already higher.
    EXPECT_GE(after, before);
    EXPECT_GE(after, 96.0);
}

}  // namespace
}  // namespace pumeta
