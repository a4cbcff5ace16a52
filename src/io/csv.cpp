#include "feedid/io/csv.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <fast_float/fast_float.h>
#include <fmt/core.h>
#include <fmt/format.h>

#include "feedid/error.hpp"

namespace feedid {

namespace {

constexpr double missing = std::numeric_limits<double>::quiet_NaN();

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
    return s;
}

std::string_view unquote(std::string_view s) {
    s = trim(s);
    if (s.size() >= 2 && s.front() == '"' && s.back() == '"') s = s.substr(1, s.size() - 2);
    return trim(s);
}

// Splits a header line on the separator, honouring double quotes (a quoted header may contain the separator).
std::vector<std::string> split_header(std::string_view line, char separator) {
    std::vector<std::string> cells;
    std::string cell;
    bool quoted = false;
    for (const char c : line) {
        if (c == '"') {
            quoted = !quoted;
            cell += c;
        } else if (c == separator && !quoted) {
            cells.emplace_back(unquote(cell));
            cell.clear();
        } else {
            cell += c;
        }
    }
    cells.emplace_back(unquote(cell));
    return cells;
}

char detect_separator(std::string_view header) {
    // The separator is the candidate that occurs most often outside quotes; a single column has none.
    std::size_t best_count = 0;
    char best = ',';
    for (const char candidate : {'\t', ';', ','}) {
        std::size_t count = 0;
        bool quoted = false;
        for (const char c : header) {
            if (c == '"') quoted = !quoted;
            else if (c == candidate && !quoted) ++count;
        }
        if (count > best_count) {
            best_count = count;
            best = candidate;
        }
    }
    return best;
}

bool is_comment_or_blank(std::string_view line) {
    line = trim(line);
    return line.empty() || line.front() == '#';
}

// A comment line `# name = number` carries a scalar constant (a drive constant, say) along with the trace.
void read_constant(std::string_view line, std::map<std::string, double>& constants) {
    line = trim(line);
    if (line.empty() || line.front() != '#') return;
    line.remove_prefix(1);
    const auto equals = line.find('=');
    if (equals == std::string_view::npos) return;
    const auto name = trim(line.substr(0, equals));
    auto value_text = trim(line.substr(equals + 1));
    if (name.empty() || name.find_first_of(" \t") != std::string_view::npos) return;
    if (!value_text.empty() && value_text.front() == '+') value_text.remove_prefix(1);
    double value = 0.0;
    const auto parsed = fast_float::from_chars(value_text.data(), value_text.data() + value_text.size(), value);
    if (parsed.ec == std::errc() && parsed.ptr == value_text.data() + value_text.size()) {
        constants[std::string(name)] = value;
    }
}

}  // namespace

std::pair<std::string, std::string> split_name_unit(std::string_view cell) {
    cell = unquote(cell);
    if (!cell.empty() && (cell.back() == ']' || cell.back() == ')')) {
        const char open = cell.back() == ']' ? '[' : '(';
        if (const auto pos = cell.rfind(open); pos != std::string_view::npos && pos > 0) {
            return {std::string(trim(cell.substr(0, pos))),
                    std::string(trim(cell.substr(pos + 1, cell.size() - pos - 2)))};
        }
    }
    // "name/unit": only when what follows the first slash looks like a unit (the name part must not be empty).
    if (const auto pos = cell.find('/'); pos != std::string_view::npos && pos > 0 && pos + 1 < cell.size()) {
        return {std::string(trim(cell.substr(0, pos))), std::string(trim(cell.substr(pos + 1)))};
    }
    return {std::string(cell), ""};
}

Trace parse_csv(std::string_view text, const std::string& source) {
    // Skip a UTF-8 byte-order mark.
    if (text.size() >= 3 && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    if (text.find('\0') != std::string_view::npos) {
        throw InputError(fmt::format("{}: not a text file (it contains NUL bytes)", source));
    }

    std::size_t position = 0;
    std::size_t line_number = 0;
    auto next_line = [&](std::string_view& line) {
        if (position >= text.size()) return false;
        const auto end = text.find('\n', position);
        const auto stop = end == std::string_view::npos ? text.size() : end;
        line = text.substr(position, stop - position);
        position = stop + 1;
        ++line_number;
        return true;
    };

    std::string_view line;
    bool have_header = false;
    std::map<std::string, double> constants;
    while (next_line(line)) {
        if (!is_comment_or_blank(line)) {
            have_header = true;
            break;
        }
        read_constant(line, constants);
    }
    if (!have_header) throw InputError(fmt::format("{}: empty file (no header row)", source));

    const char separator = detect_separator(line);
    const auto header = split_header(line, separator);
    const std::size_t columns = header.size();
    const std::size_t header_line = line_number;

    Trace trace;
    trace.source_path = source;
    trace.format = "csv";
    trace.constants = std::move(constants);
    trace.channels.reserve(columns);
    for (std::size_t c = 0; c < columns; ++c) {
        auto [name, unit] = split_name_unit(header[c]);
        if (name.empty()) {
            throw InputError(fmt::format("{}:{}: column {} has no name in the header", source, header_line, c + 1));
        }
        for (std::size_t previous = 0; previous < c; ++previous) {
            if (trace.channels[previous].name == name) {
                throw InputError(fmt::format("{}:{}: column name '{}' appears twice", source, header_line, name));
            }
        }
        // a header whose "names" are all numbers is data, not a header
        double probe = 0.0;
        const auto* first = name.data();
        if (fast_float::from_chars(first, first + name.size(), probe).ptr == first + name.size() && unit.empty()) {
            throw InputError(fmt::format("{}:{}: the first row holds numbers, not a header of channel names "
                                         "(write one like 'time [s],x [mm],i [A]')",
                                         source, header_line));
        }
        trace.channels.push_back(Channel{name, Role::other, "", unit, {}});
    }

    // Reserve from the size of the rest of the file and the length of the first data line.
    const std::size_t rest = text.size() - std::min(position, text.size());
    {
        const auto end = text.find('\n', position);
        const std::size_t first_length = (end == std::string_view::npos ? text.size() : end) - position + 1;
        const std::size_t estimate = first_length > 1 ? rest / first_length + 16 : 16;
        for (auto& channel : trace.channels) channel.values.reserve(estimate + estimate / 8);
    }

    // Decimal comma: only with ';' or tab separators, decided on the first data line holding a ',' in a number.
    char decimal_point = '.';
    bool decided = separator == ',';
    const fast_float::parse_options dot_options{fast_float::chars_format::general, '.'};
    const fast_float::parse_options comma_options{fast_float::chars_format::general, ','};

    std::size_t data_rows = 0;
    while (next_line(line)) {
        if (line.empty() || line.front() == '#' || is_comment_or_blank(line)) continue;
        if (!decided) {
            if (line.find(',') != std::string_view::npos) {
                decimal_point = ',';
                decided = true;
            } else if (line.find('.') != std::string_view::npos) {
                decided = true;
            }
        }
        const auto& options = decimal_point == ',' ? comma_options : dot_options;
        const char* p = line.data();
        const char* const end = line.data() + line.size();
        std::size_t c = 0;
        while (true) {
            while (p < end && (*p == ' ' || *p == '\t') && *p != separator) ++p;
            double value = missing;
            const char* cell_start = p;
            if (p < end && *p == '+') ++p;
            if (p < end && *p != separator && *p != '\r') {
                const auto parsed = fast_float::from_chars_advanced(p, end, value, options);
                if (parsed.ec != std::errc() || parsed.ptr == p) {
                    const char* cell_end = std::find(cell_start, end, separator);
                    std::string_view cell = trim(std::string_view(cell_start, static_cast<std::size_t>(cell_end - cell_start)));
                    if (cell == "NaN" || cell == "nan" || cell == "NA") {
                        value = missing;
                        p = cell_end;
                    } else {
                        throw InputError(fmt::format("{}:{}: column '{}' holds '{}', which is not a number", source,
                                                     line_number, c < columns ? trace.channels[c].name : "?", cell));
                    }
                } else {
                    p = parsed.ptr;
                }
            }
            while (p < end && (*p == ' ' || *p == '\t' || *p == '\r') && *p != separator) ++p;
            if (c >= columns) {
                throw InputError(fmt::format("{}:{}: row has more cells than the header's {} columns", source,
                                             line_number, columns));
            }
            trace.channels[c].values.push_back(value);
            ++c;
            if (p >= end) break;
            if (*p != separator) {
                const char* cell_end = std::find(cell_start, end, separator);
                throw InputError(fmt::format("{}:{}: column '{}' holds '{}', which is not a number", source,
                                             line_number, trace.channels[c - 1].name,
                                             trim(std::string_view(cell_start, static_cast<std::size_t>(cell_end - cell_start)))));
            }
            ++p;  // past the separator
        }
        if (c != columns) {
            throw InputError(fmt::format("{}:{}: row has {} cells, the header has {} columns", source, line_number, c,
                                         columns));
        }
        ++data_rows;
    }
    if (data_rows == 0) throw InputError(fmt::format("{}: the file has a header but no data rows", source));
    for (auto& channel : trace.channels) {
        if (channel.values.capacity() > channel.values.size() + channel.values.size() / 4) channel.values.shrink_to_fit();
    }
    return trace;
}

std::string write_csv(const Trace& trace) {
    fmt::memory_buffer out;
    for (const auto& [name, value] : trace.constants) fmt::format_to(std::back_inserter(out), "# {} = {}\n", name, value);
    for (std::size_t c = 0; c < trace.channels.size(); ++c) {
        const auto& channel = trace.channels[c];
        if (c > 0) out.push_back(',');
        if (channel.unit.empty()) fmt::format_to(std::back_inserter(out), "{}", channel.name);
        else fmt::format_to(std::back_inserter(out), "{} [{}]", channel.name, channel.unit);
    }
    out.push_back('\n');
    const std::size_t n = trace.samples();
    for (std::size_t k = 0; k < n; ++k) {
        for (std::size_t c = 0; c < trace.channels.size(); ++c) {
            if (c > 0) out.push_back(',');
            fmt::format_to(std::back_inserter(out), "{}", trace.channels[c].values[k]);
        }
        out.push_back('\n');
    }
    return fmt::to_string(out);
}

}  // namespace feedid
