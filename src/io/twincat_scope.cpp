// TwinCAT 3 Scope View CSV exports. See the header for the layout and the time-base rule.
#include "feedid/io/twincat_scope.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <map>
#include <optional>

#include <fmt/core.h>

#include "feedid/error.hpp"
#include "text_scan.hpp"

namespace feedid {

namespace {

constexpr double not_a_number = std::numeric_limits<double>::quiet_NaN();

bool is_blank(std::string_view cell) {
    return scan::trim(cell).empty();
}

// Splits a line on the separator. With a space separator a blank cell (" ") between two separators reads as two
// empty tokens, so pairs of empty tokens are one blank cell there.
void split_cells(std::string_view line, char separator, std::vector<std::string_view>& cells) {
    cells.clear();
    std::size_t start = 0;
    while (true) {
        const std::size_t end = line.find(separator, start);
        if (end == std::string_view::npos) {
            cells.push_back(line.substr(start));
            break;
        }
        cells.push_back(line.substr(start, end - start));
        start = end + 1;
    }
    if (separator == ' ') {
        std::size_t out = 0;
        for (std::size_t k = 0; k < cells.size(); ++k) {
            if (cells[k].empty() && k + 1 < cells.size() && cells[k + 1].empty()) {
                cells[out++] = std::string_view{};
                ++k;
            } else {
                cells[out++] = cells[k];
            }
        }
        cells.resize(out);
    }
}

struct HeaderRow {
    std::string_view text;
    std::size_t line{0};
};

// Header keys, longest first, so that "Unit ScaleFactor" is not read as "Unit" (with a space separator the key
// itself is split in tokens).
constexpr std::string_view known_keys[] = {
    "Unit ScaleFactor", "Unit Offset", "SampleTime[ms]", "SymbolComment", "VariableSize", "SymbolBased",
    "IndexGroup",       "IndexOffset", "SymbolName",     "ScaleFactor",   "Data-Type",    "BitMask",
    "Offset",           "NetID",       "Port",           "Unit",          "Name"};

std::string_view key_of(std::string_view line, char separator) {
    for (const auto key : known_keys) {
        if (line.starts_with(key) && (line.size() == key.size() || line[key.size()] == separator)) return key;
    }
    const auto end = line.find(separator);
    return line.substr(0, end);
}

struct Group {
    std::size_t time_column{0};
    std::vector<std::size_t> channel_columns;
};

// The cells of a header row, grouped like the layout: for each group, the cells after its key marker. With a space
// separator a cell may itself contain spaces ("test space", "V (Voltage)"): tokens are joined back (see join_tokens).
std::optional<std::vector<std::string>> row_cells(std::string_view row, std::string_view key, char separator,
                                                  const std::vector<Group>& groups, std::size_t columns) {
    std::vector<std::string_view> cells;
    split_cells(row, separator, cells);
    std::vector<std::string> out;
    if (separator != ' ') {
        if (cells.size() == columns + 1 && is_blank(cells.back())) cells.pop_back();
        if (cells.size() != columns) return std::nullopt;
        for (const auto& group : groups) {
            if (scan::trim(cells[group.time_column]) != key) return std::nullopt;
            for (const auto column : group.channel_columns) out.emplace_back(scan::trim(cells[column]));
        }
        return out;
    }
    // Space separator: walk the tokens, a marker being the key's own token sequence.
    std::vector<std::string_view> key_tokens;
    split_cells(key, ' ', key_tokens);
    std::vector<std::vector<std::string>> per_group;
    std::size_t k = 0;
    while (k < cells.size()) {
        bool marker = k + key_tokens.size() <= cells.size();
        for (std::size_t m = 0; marker && m < key_tokens.size(); ++m) marker = cells[k + m] == key_tokens[m];
        if (marker) {
            per_group.emplace_back();
            k += key_tokens.size();
            continue;
        }
        if (per_group.empty()) return std::nullopt;
        if (!cells[k].empty()) per_group.back().emplace_back(cells[k]);
        ++k;
    }
    if (per_group.size() != groups.size()) return std::nullopt;
    for (std::size_t g = 0; g < groups.size(); ++g) {
        auto& tokens = per_group[g];
        const std::size_t wanted = groups[g].channel_columns.size();
        // A token in parentheses belongs to the one before it ("dV (Voltage)", "test space (1)"), unless that one is
        // itself complete in parentheses ("(None)"). Then symbol names (MAIN.var_REAL, var_INT8) hold no spaces and
        // free-text names are plain words: adjacent plain words are joined until the count fits. Each pass is one
        // sweep (a header line of many thousand tokens must not take quadratic time).
        auto join_while = [&](auto&& belongs_to_previous) {
            if (tokens.size() <= wanted) return;
            std::size_t excess = tokens.size() - wanted;
            std::vector<std::string> joined;
            joined.reserve(tokens.size());
            for (auto& token : tokens) {
                const bool belongs = belongs_to_previous(joined.empty() ? nullptr : &joined.back(), token);
                if (belongs && excess > 0) {
                    joined.back() += ' ';
                    joined.back() += token;
                    --excess;
                } else {
                    joined.push_back(std::move(token));
                }
            }
            tokens = std::move(joined);
        };
        join_while([](const std::string* previous, const std::string& token) {
            return previous != nullptr && token.front() == '(' && previous->back() != ')';
        });
        auto plain = [](const std::string& token) {
            return token.find('_') == std::string::npos && token.find('.') == std::string::npos;
        };
        // Whether the last token so far is plain, kept as a flag: plain words joined stay plain, and rescanning a
        // growing joined token would be quadratic.
        bool previous_plain = false;
        join_while([&](const std::string* previous, const std::string& token) {
            const bool is_plain = plain(token);
            const bool join = previous != nullptr && previous_plain && is_plain;
            if (!join) previous_plain = is_plain;
            return join;
        });
        if (tokens.size() != wanted) return std::nullopt;
        for (auto& token : tokens) out.push_back(std::move(token));
    }
    return out;
}

// "V (Voltage)" -> "V", "(None)" -> "", "mm" -> "mm".
std::string unit_symbol(std::string_view cell) {
    cell = scan::trim(cell);
    if (cell.empty() || cell.front() == '(') return {};
    if (cell.back() == ')') {
        if (const auto open = cell.rfind(" ("); open != std::string_view::npos) cell = cell.substr(0, open);
    }
    return std::string(scan::trim(cell));
}

}  // namespace

Trace parse_twincat_scope(std::string_view text, const std::string& source) {
    if (text.size() >= 3 && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    if (text.find('\0') != std::string_view::npos) {
        throw InputError(fmt::format("{}: not a text file (it contains NUL bytes)", source));
    }
    std::size_t position = 0;
    std::size_t line_number = 0;
    const std::string_view first = scan::next_line(text, position);
    ++line_number;
    if (first.size() < 5 || !first.starts_with("Name")) {
        throw InputError(
            fmt::format("{}: line 1: not a TwinCAT Scope export (it starts with 'Name' and a separator)", source));
    }
    const char separator = first[4];
    if (separator != '\t' && separator != ' ' && separator != ':' && separator != ';' && separator != ',') {
        throw InputError(fmt::format("{}: line 1: unknown separator '{}' after 'Name'", source, first[4]));
    }

    // The channel header block: from the second line that starts with the key "Name" to the next blank line.
    std::map<std::string_view, HeaderRow> header;
    std::size_t header_line = 0;
    while (position < text.size()) {
        const std::string_view line = scan::next_line(text, position);
        ++line_number;
        if (header_line == 0) {
            if (key_of(line, separator) == "Name") {
                header_line = line_number;
                header["Name"] = {line, line_number};
            }
            continue;
        }
        if (is_blank(line)) break;
        const auto key = key_of(line, separator);
        if (!header.contains(key)) header[key] = {line, line_number};
    }
    if (header_line == 0) {
        throw InputError(
            fmt::format("{}: no channel header (a line starting with 'Name' after the file information)", source));
    }

    // The column layout from the Data-Type row (its cells never hold a separator), else from the Name row.
    const auto layout_row = header.contains("Data-Type") ? header["Data-Type"] : header["Name"];
    const std::string_view layout_key = header.contains("Data-Type") ? "Data-Type" : "Name";
    std::vector<std::string_view> cells;
    split_cells(layout_row.text, separator, cells);
    if (cells.size() > 1 && is_blank(cells.back())) cells.pop_back();
    std::vector<Group> groups;
    for (std::size_t c = 0; c < cells.size(); ++c) {
        if (scan::trim(cells[c]) == layout_key) {
            groups.push_back({c, {}});
        } else if (groups.empty()) {
            throw InputError(fmt::format("{}: line {}: the {} row does not start with its key", source, layout_row.line,
                                         layout_key));
        } else {
            groups.back().channel_columns.push_back(c);
        }
    }
    const std::size_t columns = cells.size();
    std::erase_if(groups, [](const Group& group) { return group.channel_columns.empty(); });
    if (groups.empty())
        throw InputError(fmt::format("{}: line {}: no channels in the header", source, layout_row.line));
    std::size_t channel_count = 0;
    for (const auto& group : groups) channel_count += group.channel_columns.size();

    std::vector<std::string> names;
    std::vector<std::string> findings;
    if (auto row = row_cells(header["Name"].text, "Name", separator, groups, columns)) {
        names = std::move(*row);
    } else if (separator == ' ') {
        for (std::size_t k = 0; k < channel_count; ++k) names.push_back(fmt::format("channel {}", k + 1));
        findings.push_back(
            "the channel names of this space-separated export cannot be told apart (a name holds a "
            "space); channels are named 'channel 1', 'channel 2', ... in column order");
    } else {
        throw InputError(fmt::format("{}: line {}: the Name row does not match the columns of the {} row", source,
                                     header_line, layout_key));
    }
    {
        std::map<std::string, int> seen;
        for (auto& name : names) {
            if (name.empty()) name = "channel";
            if (name == "time") name = "time (channel)";
            if (const int count = seen[name]++; count > 0) name += fmt::format(" #{}", count + 1);
        }
    }
    std::vector<std::string> units(channel_count);
    if (header.contains("Unit")) {
        if (auto row = row_cells(header["Unit"].text, "Unit", separator, groups, columns)) {
            for (std::size_t k = 0; k < channel_count; ++k) units[k] = unit_symbol((*row)[k]);
        } else {
            findings.push_back(
                fmt::format("line {}: the Unit row does not match the columns; channels taken without "
                            "units",
                            header["Unit"].line));
        }
    }
    // Scalings the Scope already applied (informational; see the header).
    {
        std::vector<std::string> scaled;
        for (const std::string_view key : {"ScaleFactor", "Offset", "Unit ScaleFactor", "Unit Offset"}) {
            if (!header.contains(key)) continue;
            const auto row = row_cells(header[key].text, key, separator, groups, columns);
            if (!row) continue;
            const double neutral = key.ends_with("Offset") ? 0.0 : 1.0;
            for (std::size_t k = 0; k < channel_count; ++k) {
                double value = neutral;
                const char decimal = separator == ',' ? '.' : ((*row)[k].find(',') != std::string::npos ? ',' : '.');
                if (scan::parse_number((*row)[k], value, decimal) && value != neutral) {
                    scaled.push_back(fmt::format("'{}' {} {}", names[k], key, (*row)[k]));
                }
            }
        }
        if (!scaled.empty()) {
            std::string list;
            for (const auto& item : scaled) list += (list.empty() ? "" : ", ") + item;
            findings.push_back("values taken as exported (the Scope applies these scalings before writing): " + list);
        }
    }

    // Data rows.
    std::vector<std::vector<double>> times(groups.size());
    std::vector<std::vector<double>> values(channel_count);
    std::vector<std::size_t> first_channel(groups.size());
    for (std::size_t g = 0, k = 0; g < groups.size(); k += groups[g].channel_columns.size(), ++g) first_channel[g] = k;
    char decimal = '.';
    bool decimal_known = separator == ',';
    std::vector<char> ended(groups.size(), 0);
    while (position < text.size()) {
        const std::string_view line = scan::next_line(text, position);
        ++line_number;
        if (is_blank(line)) continue;
        if (scan::trim(line) == "EOF") break;
        split_cells(line, separator, cells);
        if (cells.size() > columns && !(cells.size() == columns + 1 && is_blank(cells.back()))) {
            throw InputError(fmt::format("{}: line {}: {} cells, the header has {} columns", source, line_number,
                                         cells.size(), columns));
        }
        if (!decimal_known) {
            // Decimal comma: a comma inside a number cell (the separator is not a comma here).
            for (const auto cell : cells) {
                if (cell.find(',') != std::string_view::npos) {
                    decimal = ',';
                    decimal_known = true;
                    break;
                }
                if (cell.find('.') != std::string_view::npos) {
                    decimal_known = true;
                    break;
                }
            }
        }
        auto cell_at = [&](std::size_t column) { return column < cells.size() ? cells[column] : std::string_view{}; };
        for (std::size_t g = 0; g < groups.size(); ++g) {
            const auto& group = groups[g];
            const auto time_cell = cell_at(group.time_column);
            if (is_blank(time_cell)) {
                for (const auto column : group.channel_columns) {
                    if (!is_blank(cell_at(column))) {
                        throw InputError(fmt::format("{}: line {}: channel '{}' has a value but no time stamp", source,
                                                     line_number, names[first_channel[g]]));
                    }
                }
                ended[g] = !times[g].empty();
                continue;
            }
            double time = 0.0;
            if (!scan::parse_number(time_cell, time, decimal) || !std::isfinite(time)) {
                throw InputError(fmt::format("{}: line {}: time stamp '{}' of channel '{}' is not a number", source,
                                             line_number, scan::trim(time_cell), names[first_channel[g]]));
            }
            if (!times[g].empty() && !(time > times[g].back())) {
                throw InputError(
                    fmt::format("{}: line {}: time stamps of channel '{}' do not increase ({} ms after "
                                "{} ms)",
                                source, line_number, names[first_channel[g]], time, times[g].back()));
            }
            if (ended[g]) {
                throw InputError(fmt::format("{}: line {}: channel '{}' resumes after blank cells", source, line_number,
                                             names[first_channel[g]]));
            }
            times[g].push_back(time);
            for (std::size_t c = 0; c < group.channel_columns.size(); ++c) {
                const auto cell = cell_at(group.channel_columns[c]);
                double value = not_a_number;
                if (!is_blank(cell) && !scan::parse_number(cell, value, decimal)) {
                    throw InputError(fmt::format("{}: line {}: value '{}' of channel '{}' is not a number", source,
                                                 line_number, scan::trim(cell), names[first_channel[g] + c]));
                }
                values[first_channel[g] + c].push_back(value);
            }
        }
    }
    for (std::size_t g = 0; g < groups.size(); ++g) {
        if (times[g].empty()) {
            throw InputError(fmt::format("{}: channel '{}' has no samples", source, names[first_channel[g]]));
        }
    }

    // The common time base: the finest group's stamps within the span every channel covers.
    auto median_step = [](const std::vector<double>& t) {
        if (t.size() < 2) return std::numeric_limits<double>::infinity();
        std::vector<double> steps(t.size() - 1);
        for (std::size_t k = 0; k + 1 < t.size(); ++k) steps[k] = t[k + 1] - t[k];
        std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
        return steps[steps.size() / 2];
    };
    std::size_t finest = 0;
    std::vector<double> steps(groups.size());
    double begin = -std::numeric_limits<double>::infinity();
    double end = std::numeric_limits<double>::infinity();
    for (std::size_t g = 0; g < groups.size(); ++g) {
        steps[g] = median_step(times[g]);
        if (steps[g] < steps[finest]) finest = g;
        begin = std::max(begin, times[g].front());
        end = std::min(end, times[g].back());
    }
    if (!(end >= begin)) {
        throw InputError(
            fmt::format("{}: the channels do not overlap in time (one ends at {} ms before another "
                        "starts at {} ms)",
                        source, end, begin));
    }
    const double tolerance = std::isfinite(steps[finest]) ? 1e-6 * steps[finest] : 1e-9;
    std::vector<double> base;
    for (const double t : times[finest]) {
        if (t >= begin - tolerance && t <= end + tolerance) base.push_back(t);
    }

    Trace trace;
    trace.format = "twincat-scope";
    trace.findings = std::move(findings);
    bool mixed = false;
    for (std::size_t g = 0; g < groups.size(); ++g) mixed = mixed || std::abs(steps[g] - steps[finest]) > tolerance;
    const std::size_t longest = std::max_element(times.begin(), times.end(), [](const auto& a, const auto& b) {
                                    return a.size() < b.size();
                                })->size();
    if (mixed || base.size() < longest) {
        std::vector<double> distinct;
        for (const double step : steps) {
            if (std::isfinite(step) && std::none_of(distinct.begin(), distinct.end(),
                                                    [&](double d) { return std::abs(d - step) <= tolerance; })) {
                distinct.push_back(step);
            }
        }
        std::sort(distinct.begin(), distinct.end());
        std::string list;
        for (const double step : distinct) list += fmt::format("{}{:g}", list.empty() ? "" : ", ", step);
        trace.findings.push_back(
            fmt::format("channels sampled at {} ms: all are put on the finest time stamps "
                        "({:g} ms) from {:g} ms to {:g} ms, where every channel has samples; a "
                        "slower channel holds its latest sample",
                        list, steps[finest], begin, end));
    }

    trace.channels.push_back(Channel{"time", Role::time, "", "ms", base});
    for (std::size_t g = 0; g < groups.size(); ++g) {
        const auto& t = times[g];
        for (std::size_t c = 0; c < groups[g].channel_columns.size(); ++c) {
            const std::size_t k = first_channel[g] + c;
            Channel channel{names[k], Role::other, "", units[k], {}};
            if (g == finest) {
                const auto offset =
                    static_cast<std::size_t>(std::lower_bound(t.begin(), t.end(), begin - tolerance) - t.begin());
                channel.values.assign(values[k].begin() + static_cast<std::ptrdiff_t>(offset),
                                      values[k].begin() + static_cast<std::ptrdiff_t>(offset + base.size()));
            } else {
                channel.values.resize(base.size());
                std::size_t sample = 0;
                for (std::size_t j = 0; j < base.size(); ++j) {
                    while (sample + 1 < t.size() && t[sample + 1] <= base[j] + tolerance) ++sample;
                    channel.values[j] = values[k][sample];
                }
            }
            trace.channels.push_back(std::move(channel));
        }
    }
    return trace;
}

}  // namespace feedid
