// Exceptions carrying context. Only main() turns them into a message and an exit code.
#pragma once

#include <fmt/format.h>

#include <stdexcept>
#include <string>

namespace pumeta {

/// Bad user input (unreadable file, malformed data, invalid option): exit code 2.
/// The message names the file (when there is one) and what is wrong, on one line.
class InputError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

/// Internal failure (a bug, an exhausted resource): exit code 1.
class InternalError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

/// Throws InputError("<file>: <formatted message>").
template <typename... Args>
[[noreturn]] void throw_input_error(const std::string& file, fmt::format_string<Args...> format,
                                    Args&&... args) {
    std::string message = fmt::format(format, std::forward<Args>(args)...);
    throw InputError(file.empty() ? message : file + ": " + message);
}

}  // namespace pumeta
