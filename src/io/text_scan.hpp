#pragma once
// Small text-scanning helpers shared by the controller-format readers (SINUMERIK trace, TwinCAT Scope, halscope).
// Private to src/io: not part of the public API.

#include <cstddef>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <unordered_set>
#include <vector>

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

/// The lines of a text, one at a time, counted (1-based) for messages.
struct Lines {
    std::string_view text;
    std::size_t position{0};
    std::size_t number{0};  ///< of the line `next` gave last
    bool next(std::string_view& line) {
        if (position >= text.size()) return false;
        line = next_line(text, position);
        ++number;
        return true;
    }
};

/// Splits a delimited line into cells (blanks around each trimmed, one level of double quotes removed); a quoted
/// cell may hold the separator. `cells` is cleared first.
inline void split_cells(std::string_view line, char separator, std::vector<std::string_view>& cells) {
    cells.clear();
    std::size_t start = 0;
    bool quoted = false;
    for (std::size_t k = 0; k <= line.size(); ++k) {
        if (k < line.size() && line[k] == '"') quoted = !quoted;
        if (k == line.size() || (line[k] == separator && !quoted)) {
            std::string_view cell = trim(line.substr(start, k - start));
            if (cell.size() >= 2 && cell.front() == '"' && cell.back() == '"')
                cell = trim(cell.substr(1, cell.size() - 2));
            cells.push_back(cell);
            start = k + 1;
        }
    }
}

/// Equal ignoring ASCII case.
inline bool iequals(std::string_view a, std::string_view b) {
    if (a.size() != b.size()) return false;
    for (std::size_t k = 0; k < a.size(); ++k) {
        const auto x = static_cast<unsigned char>(a[k]);
        const auto y = static_cast<unsigned char>(b[k]);
        if ((x >= 'A' && x <= 'Z' ? x + 32 : x) != (y >= 'A' && y <= 'Z' ? y + 32 : y)) return false;
    }
    return true;
}

/// The text without a UTF-8 byte-order mark.
inline std::string_view without_bom(std::string_view text) {
    return text.starts_with("\xEF\xBB\xBF") ? text.substr(3) : text;
}

/// Makes repeated names unique by numbering the repeats in order ("x", "x#2", "x#3", skipping a number already taken
/// by another column); returns each name that repeated, once, in order of first repetition.
inline std::vector<std::string> number_repeated_names(std::vector<std::string>& names) {
    std::unordered_set<std::string> taken(names.begin(), names.end());
    std::unordered_map<std::string, int> seen;
    std::vector<std::string> repeated;
    for (auto& name : names) {
        int& count = seen[name];
        if (++count == 1) continue;
        if (count == 2) repeated.push_back(name);
        std::string candidate;
        do {
            candidate = name + "#" + std::to_string(count);
        } while (!taken.insert(candidate).second && ++count > 0);
        name = std::move(candidate);
    }
    return repeated;
}

}  // namespace feedid::scan
