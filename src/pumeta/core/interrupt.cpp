#include "pumeta/core/interrupt.h"

#include <csignal>

namespace pumeta {

namespace {

volatile std::sig_atomic_t requested = 0;

void on_signal(int) { requested = 1; }

}  // namespace

void catch_interrupts() {
    struct sigaction action = {};
    action.sa_handler = on_signal;
    sigemptyset(&action.sa_mask);
    // One-shot: the handler is reset to the default, so a second signal ends the process.
    action.sa_flags = SA_RESETHAND;
    sigaction(SIGINT, &action, nullptr);
    sigaction(SIGTERM, &action, nullptr);
}

bool interrupt_requested() { return requested != 0; }

void reset_interrupts() {
    requested = 0;
    catch_interrupts();
}

}  // namespace pumeta
