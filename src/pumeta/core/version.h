// What this build of pumeta is: its version, the commit it was built from, the LibTorch it
// was compiled against and the BLAS the process runs on.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace pumeta {

/// The project version (CMake's project(VERSION)), e.g. "0.1.0".
std::string version();

/// The git commit of the source tree at build time (12 hex digits, "-dirty" with uncommitted
/// changes), or "unknown" when built outside a git checkout.
std::string git_commit();

/// The LibTorch version the library was compiled against, e.g. "1.13.0".
std::string torch_version();

/// {"version", "commit", "libtorch", "blas": {"name", "path", "config"}}.
nlohmann::json build_info();

/// One line per item of build_info(), as `pumeta --version` prints it.
std::string build_info_text();

}  // namespace pumeta
