// Whole-file reads and atomic writes, with errors as InputError naming the file.
#pragma once

#include <string>
#include <string_view>

namespace pumeta::io {

/// The bytes of `path`. InputError when it is missing, not a regular file, unreadable or empty.
std::string read_whole_file(const std::string& path);

/// Writes `bytes` to "<path>.tmp-<pid>" beside `path`, then renames it over `path`, so that
/// readers never see a partial file. On any failure the temporary file is removed and
/// InputError is thrown.
void write_atomically(const std::string& path, std::string_view bytes);

}  // namespace pumeta::io
