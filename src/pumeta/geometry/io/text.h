// Scanning of in-memory text files: lines with their numbers, tokens, and locale-independent
// number parsing (std::from_chars), which is several times faster than iostreams per token.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "pumeta/core/error.h"

namespace pumeta::io {

/// Iterates over the lines of a text buffer. Lines exclude their terminator ("\n" or "\r\n").
class LineReader {
  public:
    /// Starts at byte `offset` of `text`; `lines_before` lines precede that offset.
    explicit LineReader(std::string_view text, size_t offset = 0, int64_t lines_before = 0)
        : text_(text), offset_(offset), line_number_(lines_before) {}

    /// Stores the next line in `line`; false at the end of the text.
    bool next(std::string_view& line);

    /// Like next() but skips lines that are blank after removing a `comment` suffix.
    bool next_content(std::string_view& line, char comment = '\0');

    /// 1-based number of the line last returned (0 before the first).
    int64_t line_number() const { return line_number_; }

    /// Byte offset just past the terminator of the line last returned.
    size_t offset() const { return offset_; }

  private:
    std::string_view text_;
    size_t offset_;
    int64_t line_number_;
};

/// `text` without leading and trailing blanks (space, tab, CR, FF, VT).
std::string_view trim(std::string_view text);

/// Replaces `tokens` with the blank-separated tokens of `line` (commas separate too when
/// `comma_separates`). The vector is reused to avoid an allocation per line.
void split_tokens(std::string_view line, std::vector<std::string_view>& tokens,
                  bool comma_separates = false);

/// Parses the whole `token` (a leading '+' is allowed). False when it is not such a number or
/// when an integer does not fit. Floats that overflow become +-inf (rejected later as
/// non-finite), underflows become 0 or a subnormal.
bool parse_number(std::string_view token, float& value);
bool parse_number(std::string_view token, double& value);
bool parse_number(std::string_view token, int64_t& value);

/// `token` made safe for a one-line error message: at most 32 characters, non-printable
/// bytes as '?'.
std::string printable(std::string_view token);

/// Parses `token` or throws InputError "<path>: line <line>: expected <what>, found '<token>'".
template <typename T>
T parse_or_throw(std::string_view token, const std::string& path, int64_t line, const char* what) {
    T value;
    if (!parse_number(token, value))
        throw_input_error(path, "line {}: expected {}, found '{}'", line, what, printable(token));
    return value;
}

}  // namespace pumeta::io
