#pragma once
// Small text-scanning helpers shared by the controller-format readers (SINUMERIK trace, TwinCAT Scope, halscope).
// Private to src/io: not part of the public API.

#include <cstddef>
#include <string_view>
#include <system_error>

#include <fast_float/fast_float.h>

namespace feedid::scan {

inline std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r' || s.front() == '\n')) {
        s.remove_prefix(1);
    }
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r' || s.back() == '\n')) {
        s.remove_suffix(1);
    }
    return s;
}

/// 1-based line number of a byte offset (for error messages; only called on the error path).
inline std::size_t line_of(std::string_view text, std::size_t offset) {
    std::size_t line = 1;
    const std::size_t end = offset < text.size() ? offset : text.size();
    for (std::size_t k = 0; k < end; ++k) line += text[k] == '\n';
    return line;
}

/// Parses a whole cell as a number ("+1.5", "-3", "2,5" with decimal ','); false when the cell is not exactly a
/// number. Leading '+' is accepted (halscope writes "%+.14f"); surrounding blanks are not the caller's problem.
inline bool parse_number(std::string_view cell, double& value, char decimal_point = '.') {
    cell = trim(cell);
    if (!cell.empty() && cell.front() == '+') cell.remove_prefix(1);
    if (cell.empty()) return false;
    const fast_float::parse_options options{fast_float::chars_format::general, decimal_point};
    const auto result = fast_float::from_chars_advanced(cell.data(), cell.data() + cell.size(), value, options);
    return result.ec == std::errc() && result.ptr == cell.data() + cell.size();
}

/// Splits off the next line (without its '\n' and a trailing '\r'); advances `position` past it.
inline std::string_view next_line(std::string_view text, std::size_t& position) {
    const std::size_t start = position;
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) {
        end = text.size();
        position = text.size();
    } else {
        position = end + 1;
    }
    std::string_view line = text.substr(start, end - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    return line;
}

}  // namespace feedid::scan
