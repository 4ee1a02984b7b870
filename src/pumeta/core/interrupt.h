// Ctrl-C and SIGTERM as a request to stop long work cleanly (training checkpoints first).
#pragma once

namespace pumeta {

/// From now on the first SIGINT or SIGTERM only sets a flag that long loops poll; the
/// second one ends the process as usual. `pumeta train` and `pumeta meta-train` call it.
void catch_interrupts();

/// Whether a caught signal asks the process to stop.
bool interrupt_requested();

/// Forgets a pending request and catches the next signal again (tests).
void reset_interrupts();

}  // namespace pumeta
