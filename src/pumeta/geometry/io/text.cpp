#include "pumeta/geometry/io/text.h"

#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <cstring>
#include <string>

namespace pumeta::io {

namespace {

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

// from_chars rejects a leading '+', which some writers emit ("+1.5").
std::string_view without_plus(std::string_view token) {
    if (token.size() > 1 && token[0] == '+' && token[1] != '-' && token[1] != '+')
        token.remove_prefix(1);
    return token;
}

float strto(const char* text, float) { return std::strtof(text, nullptr); }
double strto(const char* text, double) { return std::strtod(text, nullptr); }

template <typename Float>
bool parse_float(std::string_view token, Float& value) {
    token = without_plus(token);
    if (token.empty()) return false;
    auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (end != token.data() + token.size()) return false;
    if (error == std::errc::result_out_of_range) {
        // from_chars leaves the value unset on overflow/underflow; strto* gives +-inf or 0.
        std::string copy(token);
        value = strto(copy.c_str(), Float{});
        return true;
    }
    return error == std::errc();
}

}  // namespace

bool LineReader::next(std::string_view& line) {
    if (offset_ >= text_.size()) return false;
    const char* begin = text_.data() + offset_;
    const void* newline = std::memchr(begin, '\n', text_.size() - offset_);
    size_t length = newline ? static_cast<const char*>(newline) - begin : text_.size() - offset_;
    offset_ += length + (newline ? 1 : 0);
    if (length > 0 && begin[length - 1] == '\r') --length;
    line = std::string_view(begin, length);
    ++line_number_;
    return true;
}

bool LineReader::next_content(std::string_view& line, char comment) {
    while (next(line)) {
        if (comment) line = line.substr(0, std::min(line.find(comment), line.size()));
        line = trim(line);
        if (!line.empty()) return true;
    }
    return false;
}

std::string_view trim(std::string_view text) {
    size_t begin = 0, end = text.size();
    while (begin < end && is_blank(text[begin])) ++begin;
    while (end > begin && is_blank(text[end - 1])) --end;
    return text.substr(begin, end - begin);
}

void split_tokens(std::string_view line, std::vector<std::string_view>& tokens,
                  bool comma_separates) {
    tokens.clear();
    auto separates = [comma_separates](char c) {
        return is_blank(c) || (comma_separates && c == ',');
    };
    size_t i = 0;
    const size_t n = line.size();
    while (i < n) {
        while (i < n && separates(line[i])) ++i;
        size_t start = i;
        while (i < n && !separates(line[i])) ++i;
        if (i > start) tokens.push_back(line.substr(start, i - start));
    }
}

bool parse_number(std::string_view token, float& value) { return parse_float(token, value); }

bool parse_number(std::string_view token, double& value) { return parse_float(token, value); }

bool parse_number(std::string_view token, int64_t& value) {
    token = without_plus(token);
    if (token.empty()) return false;
    auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    return error == std::errc() && end == token.data() + token.size();
}

std::string printable(std::string_view token) {
    constexpr size_t kMaxLength = 32;
    std::string text;
    for (size_t i = 0; i < token.size() && i < kMaxLength; ++i) {
        unsigned char c = static_cast<unsigned char>(token[i]);
        text += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
    }
    if (token.size() > kMaxLength) text += "...";
    return text;
}

}  // namespace pumeta::io
