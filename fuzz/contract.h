// The contract every fuzz target checks: any input is either read or refused with an
// InputError. A crash, a hang, a sanitizer report, any other exception or a read result that
// breaks the reader's promises is a defect.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "pumeta/core/error.h"

namespace pumeta::fuzz {

/// Stops the process with a message: a contract violation libFuzzer reports as a crash.
[[noreturn]] inline void violated(const std::string& what) {
    std::fprintf(stderr, "contract violated: %s\n", what.c_str());
    std::abort();
}

/// Runs `body` on the input; InputError is the accepted refusal.
template <class Body>
int run(const uint8_t* data, size_t size, Body&& body) {
    const std::string_view bytes(reinterpret_cast<const char*>(data), size);
    try {
        body(bytes);
    } catch (const InputError&) {
    }
    return 0;
}

/// Reads `bytes` as a file called `name` (the extension picks the reader) and checks what a
/// successful read promises: at least one finite point, attributes of the points' count,
/// face indices in range.
void read_geometry_contract(const std::string& name, std::string_view bytes);

}  // namespace pumeta::fuzz
