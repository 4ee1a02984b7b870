// The first SIGINT or SIGTERM is a request that long loops poll; the second ends the process.
#include "pumeta/core/interrupt.h"

#include <gtest/gtest.h>

#include <csignal>

namespace pumeta {
namespace {

void restore_default_handlers() {
    reset_interrupts();
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
}

TEST(Interrupts, TheFirstSignalIsARequestThatResetForgets) {
    catch_interrupts();
    EXPECT_FALSE(interrupt_requested());
    std::raise(SIGINT);
    EXPECT_TRUE(interrupt_requested());
    reset_interrupts();
    EXPECT_FALSE(interrupt_requested());
    std::raise(SIGTERM);
    EXPECT_TRUE(interrupt_requested());
    restore_default_handlers();
}

TEST(InterruptsDeathTest, TheSecondSignalEndsTheProcess) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    EXPECT_EXIT(
        {
            catch_interrupts();
            std::raise(SIGTERM);
            std::raise(SIGTERM);
        },
        testing::KilledBySignal(SIGTERM), "");
}

}  // namespace
}  // namespace pumeta
