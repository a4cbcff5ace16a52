// TwinCAT 3 Scope View CSV exports. See the header for the layout and the time-base rule.
#include "feedid/io/twincat_scope.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <map>
#include <optional>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
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

// The export read line by line, with the number of the line last read (for messages).
struct Lines {
    std::string_view text;
    std::size_t position{0};
    std::size_t number{0};

    [[nodiscard]] bool more() const { return position < text.size(); }
    std::string_view next() {
        ++number;
        return scan::next_line(text, position);
    }
};

using Header = std::map<std::string_view, HeaderRow>;

// The first line starts with the key "Name" and the separator every row of the export uses.
char read_separator(Lines& lines, const std::string& source) {
    const std::string_view first = lines.next();
    if (first.size() < 5 || !first.starts_with("Name")) {
        throw InputError(
            fmt::format("{}: line 1: not a TwinCAT Scope export (it starts with 'Name' and a separator)", source));
    }
    const char separator = first[4];
    if (separator != '\t' && separator != ' ' && separator != ':' && separator != ';' && separator != ',') {
        throw InputError(fmt::format("{}: line 1: unknown separator '{}' after 'Name'", source, first[4]));
    }
    return separator;
}

// The channel header block: from the second line that starts with the key "Name" to the next blank line.
Header read_header_block(Lines& lines, char separator, const std::string& source) {
    Header header;
    std::size_t header_line = 0;
    while (lines.more()) {
        const std::string_view line = lines.next();
        if (header_line == 0) {
            if (key_of(line, separator) == "Name") {
                header_line = lines.number;
                header["Name"] = {line, lines.number};
            }
            continue;
        }
        if (is_blank(line)) break;
        const auto key = key_of(line, separator);
        if (!header.contains(key)) header[key] = {line, lines.number};
    }
    if (header_line == 0) {
        throw InputError(
            fmt::format("{}: no channel header (a line starting with 'Name' after the file information)", source));
    }
    return header;
}

struct Layout {
    std::string_view key;       // the row the columns are taken from
    std::vector<Group> groups;  // only groups with channels
    std::size_t columns{0};
    std::size_t channel_count{0};
};

// The column layout from the Data-Type row (its cells never hold a separator), else from the Name row.
Layout column_layout(const Header& header, char separator, const std::string& source) {
    Layout layout;
    layout.key = header.contains("Data-Type") ? "Data-Type" : "Name";
    const HeaderRow& row = header.at(layout.key);
    std::vector<std::string_view> cells;
    split_cells(row.text, separator, cells);
    if (cells.size() > 1 && is_blank(cells.back())) cells.pop_back();
    for (std::size_t c = 0; c < cells.size(); ++c) {
        if (scan::trim(cells[c]) == layout.key) {
            layout.groups.push_back({c, {}});
        } else if (layout.groups.empty()) {
            throw InputError(
                fmt::format("{}: line {}: the {} row does not start with its key", source, row.line, layout.key));
        } else {
            layout.groups.back().channel_columns.push_back(c);
        }
    }
    layout.columns = cells.size();
    std::erase_if(layout.groups, [](const Group& group) { return group.channel_columns.empty(); });
    if (layout.groups.empty())
        throw InputError(fmt::format("{}: line {}: no channels in the header", source, row.line));
    for (const auto& group : layout.groups) layout.channel_count += group.channel_columns.size();
    return layout;
}

// An empty name becomes "channel", "time" (the time base's name) "time (channel)", and a repeated one gets " #2", ...
void make_names_unique(std::vector<std::string>& names) {
    std::map<std::string, int> seen;
    for (auto& name : names) {
        if (name.empty()) name = "channel";
        if (name == "time") name = "time (channel)";
        if (const int count = seen[name]++; count > 0) name += fmt::format(" #{}", count + 1);
    }
}

std::vector<std::string> channel_names(const Header& header, const Layout& layout, char separator,
                                       const std::string& source, std::vector<std::string>& findings) {
    const HeaderRow& name_row = header.at("Name");
    std::vector<std::string> names;
    if (auto row = row_cells(name_row.text, "Name", separator, layout.groups, layout.columns)) {
        names = std::move(*row);
    } else if (separator == ' ') {
        for (std::size_t k = 0; k < layout.channel_count; ++k) names.push_back(fmt::format("channel {}", k + 1));
        findings.push_back(
            "the channel names of this space-separated export cannot be told apart (a name holds a "
            "space); channels are named 'channel 1', 'channel 2', ... in column order");
    } else {
        throw InputError(fmt::format("{}: line {}: the Name row does not match the columns of the {} row", source,
                                     name_row.line, layout.key));
    }
    make_names_unique(names);
    return names;
}

std::vector<std::string> channel_units(const Header& header, const Layout& layout, char separator,
                                       std::vector<std::string>& findings) {
    std::vector<std::string> units(layout.channel_count);
    const auto unit_row = header.find("Unit");
    if (unit_row == header.end()) return units;
    if (auto row = row_cells(unit_row->second.text, "Unit", separator, layout.groups, layout.columns)) {
        for (std::size_t k = 0; k < layout.channel_count; ++k) units[k] = unit_symbol((*row)[k]);
    } else {
        findings.push_back(fmt::format("line {}: the Unit row does not match the columns; channels taken without units",
                                       unit_row->second.line));
    }
    return units;
}

// Scalings the Scope already applied (informational; see the header).
void note_applied_scalings(const Header& header, const Layout& layout, char separator,
                           const std::vector<std::string>& names, std::vector<std::string>& findings) {
    std::vector<std::string> scaled;
    for (const std::string_view key : {"ScaleFactor", "Offset", "Unit ScaleFactor", "Unit Offset"}) {
        const auto found = header.find(key);
        if (found == header.end()) continue;
        const auto row = row_cells(found->second.text, key, separator, layout.groups, layout.columns);
        if (!row) continue;
        const double neutral = key.ends_with("Offset") ? 0.0 : 1.0;
        for (std::size_t k = 0; k < layout.channel_count; ++k) {
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

// What the data rows hold: each group's time stamps [ms] and each channel's values (NaN for a blank cell).
struct Samples {
    std::vector<std::vector<double>> times;   // per group
    std::vector<std::vector<double>> values;  // per channel, in column order
    std::vector<std::size_t> first_channel;   // per group: the index of its first channel
};

// Reads the data rows one at a time, checking each against the layout; every problem names its line.
class SampleReader {
public:
    SampleReader(const Layout& layout, const std::vector<std::string>& names, char separator, const std::string& source)
        : layout_(layout),
          names_(names),
          separator_(separator),
          source_(source),
          decimal_known_(separator == ','),
          ended_(layout.groups.size(), 0) {
        const auto& groups = layout.groups;
        samples_.times.resize(groups.size());
        samples_.values.resize(layout.channel_count);
        samples_.first_channel.resize(groups.size());
        for (std::size_t g = 0, k = 0; g < groups.size(); k += groups[g].channel_columns.size(), ++g) {
            samples_.first_channel[g] = k;
        }
    }

    void read_row(std::string_view line, std::size_t line_number) {
        split_cells(line, separator_, cells_);
        const std::size_t columns = layout_.columns;
        if (cells_.size() > columns && !(cells_.size() == columns + 1 && is_blank(cells_.back()))) {
            throw InputError(fmt::format("{}: line {}: {} cells, the header has {} columns", source_, line_number,
                                         cells_.size(), columns));
        }
        if (!decimal_known_) learn_decimal_mark();
        for (std::size_t g = 0; g < layout_.groups.size(); ++g) read_group(g, line_number);
    }

    // Every group must have samples.
    Samples finish() {
        for (std::size_t g = 0; g < layout_.groups.size(); ++g) {
            if (samples_.times[g].empty()) {
                throw InputError(fmt::format("{}: channel '{}' has no samples", source_, group_name(g)));
            }
        }
        return std::move(samples_);
    }

private:
    // Decimal comma: a comma inside a number cell (the separator is not a comma here).
    void learn_decimal_mark() {
        for (const auto cell : cells_) {
            if (cell.find(',') != std::string_view::npos) {
                decimal_ = ',';
                decimal_known_ = true;
                return;
            }
            if (cell.find('.') != std::string_view::npos) {
                decimal_known_ = true;
                return;
            }
        }
    }

    [[nodiscard]] std::string_view cell_at(std::size_t column) const {
        return column < cells_.size() ? cells_[column] : std::string_view{};
    }
    [[nodiscard]] const std::string& group_name(std::size_t g) const { return names_[samples_.first_channel[g]]; }

    // One group's cells of a row: its time stamp and its channels' values. A group whose time cell is blank has
    // ended (its channels must be blank too, and stay so).
    void read_group(std::size_t g, std::size_t line_number) {
        const auto& group = layout_.groups[g];
        auto& times = samples_.times[g];
        const auto time_cell = cell_at(group.time_column);
        if (is_blank(time_cell)) {
            for (const auto column : group.channel_columns) {
                if (!is_blank(cell_at(column))) {
                    throw InputError(fmt::format("{}: line {}: channel '{}' has a value but no time stamp", source_,
                                                 line_number, group_name(g)));
                }
            }
            ended_[g] = !times.empty();
            return;
        }
        double time = 0.0;
        if (!scan::parse_number(time_cell, time, decimal_) || !std::isfinite(time)) {
            throw InputError(fmt::format("{}: line {}: time stamp '{}' of channel '{}' is not a number", source_,
                                         line_number, scan::trim(time_cell), group_name(g)));
        }
        if (!times.empty() && !(time > times.back())) {
            throw InputError(fmt::format("{}: line {}: time stamps of channel '{}' do not increase ({} ms after {} ms)",
                                         source_, line_number, group_name(g), time, times.back()));
        }
        if (ended_[g]) {
            throw InputError(fmt::format("{}: line {}: channel '{}' resumes after blank cells", source_, line_number,
                                         group_name(g)));
        }
        times.push_back(time);
        for (std::size_t c = 0; c < group.channel_columns.size(); ++c) {
            const std::size_t k = samples_.first_channel[g] + c;
            const auto cell = cell_at(group.channel_columns[c]);
            double value = not_a_number;
            if (!is_blank(cell) && !scan::parse_number(cell, value, decimal_)) {
                throw InputError(fmt::format("{}: line {}: value '{}' of channel '{}' is not a number", source_,
                                             line_number, scan::trim(cell), names_[k]));
            }
            samples_.values[k].push_back(value);
        }
    }

    const Layout& layout_;
    const std::vector<std::string>& names_;
    char separator_;
    const std::string& source_;
    char decimal_{'.'};
    bool decimal_known_;
    std::vector<char> ended_;  // per group: its time cells have turned blank
    std::vector<std::string_view> cells_;
    Samples samples_;
};

// The data rows, up to the end of the text or an "EOF" line.
Samples read_samples(Lines& lines, const Layout& layout, const std::vector<std::string>& names, char separator,
                     const std::string& source) {
    SampleReader reader(layout, names, separator, source);
    while (lines.more()) {
        const std::string_view line = lines.next();
        if (is_blank(line)) continue;
        if (scan::trim(line) == "EOF") break;
        reader.read_row(line, lines.number);
    }
    return reader.finish();
}

double median_step(const std::vector<double>& t) {
    if (t.size() < 2) return std::numeric_limits<double>::infinity();
    std::vector<double> steps(t.size() - 1);
    for (std::size_t k = 0; k + 1 < t.size(); ++k) steps[k] = t[k + 1] - t[k];
    std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
    return steps[steps.size() / 2];
}

struct CommonTimeBase {
    std::size_t finest{0};      // the group with the finest sample time
    std::vector<double> steps;  // each group's median sample time [ms]
    double begin{-std::numeric_limits<double>::infinity()};
    double end{std::numeric_limits<double>::infinity()};
    double tolerance{0.0};       // [ms]
    std::vector<double> stamps;  // [ms]
};

// The common time base: the finest group's stamps within the span every channel covers.
CommonTimeBase common_time_base(const std::vector<std::vector<double>>& times, const std::string& source) {
    CommonTimeBase base;
    base.steps.resize(times.size());
    for (std::size_t g = 0; g < times.size(); ++g) {
        base.steps[g] = median_step(times[g]);
        if (base.steps[g] < base.steps[base.finest]) base.finest = g;
        base.begin = std::max(base.begin, times[g].front());
        base.end = std::min(base.end, times[g].back());
    }
    if (!(base.end >= base.begin)) {
        throw InputError(
            fmt::format("{}: the channels do not overlap in time (one ends at {} ms before another starts at {} ms)",
                        source, base.end, base.begin));
    }
    const double finest_step = base.steps[base.finest];
    base.tolerance = std::isfinite(finest_step) ? 1e-6 * finest_step : 1e-9;
    for (const double t : times[base.finest]) {
        if (t >= base.begin - base.tolerance && t <= base.end + base.tolerance) base.stamps.push_back(t);
    }
    return base;
}

// Said when the groups are sampled at different times or the common span leaves samples out.
std::optional<std::string> mixed_rate_finding(const std::vector<std::vector<double>>& times,
                                              const CommonTimeBase& base) {
    const auto& steps = base.steps;
    bool mixed = false;
    for (std::size_t g = 0; g < steps.size(); ++g) {
        mixed = mixed || std::abs(steps[g] - steps[base.finest]) > base.tolerance;
    }
    const std::size_t longest = std::max_element(times.begin(), times.end(), [](const auto& a, const auto& b) {
                                    return a.size() < b.size();
                                })->size();
    if (!mixed && base.stamps.size() >= longest) return std::nullopt;
    std::vector<double> distinct;
    for (const double step : steps) {
        if (std::isfinite(step) && std::none_of(distinct.begin(), distinct.end(),
                                                [&](double d) { return std::abs(d - step) <= base.tolerance; })) {
            distinct.push_back(step);
        }
    }
    std::sort(distinct.begin(), distinct.end());
    std::string list;
    for (const double step : distinct) list += fmt::format("{}{:g}", list.empty() ? "" : ", ", step);
    return fmt::format(
        "channels sampled at {} ms: all are put on the finest time stamps ({:g} ms) from {:g} ms to {:g} ms, where "
        "every channel has samples; a slower channel holds its latest sample",
        list, steps[base.finest], base.begin, base.end);
}

// A channel's values on the common time base: the finest group's own values over the common span; a slower group's
// latest sample at each stamp.
std::vector<double> values_on_base(const std::vector<double>& t, const std::vector<double>& values, bool finest,
                                   const CommonTimeBase& base) {
    const auto& stamps = base.stamps;
    if (finest) {
        const auto offset =
            static_cast<std::size_t>(std::lower_bound(t.begin(), t.end(), base.begin - base.tolerance) - t.begin());
        return {values.begin() + static_cast<std::ptrdiff_t>(offset),
                values.begin() + static_cast<std::ptrdiff_t>(offset + stamps.size())};
    }
    std::vector<double> held(stamps.size());
    std::size_t sample = 0;
    for (std::size_t j = 0; j < stamps.size(); ++j) {
        while (sample + 1 < t.size() && t[sample + 1] <= stamps[j] + base.tolerance) ++sample;
        held[j] = values[sample];
    }
    return held;
}

}  // namespace

Trace parse_twincat_scope(std::string_view text, const std::string& source) {
    if (text.size() >= 3 && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    if (text.find('\0') != std::string_view::npos) {
        throw InputError(fmt::format("{}: not a text file (it contains NUL bytes)", source));
    }
    Lines lines{text};
    const char separator = read_separator(lines, source);
    const Header header = read_header_block(lines, separator, source);
    const Layout layout = column_layout(header, separator, source);
    std::vector<std::string> findings;
    const auto names = channel_names(header, layout, separator, source, findings);
    const auto units = channel_units(header, layout, separator, findings);
    note_applied_scalings(header, layout, separator, names, findings);
    const Samples samples = read_samples(lines, layout, names, separator, source);
    const CommonTimeBase base = common_time_base(samples.times, source);

    Trace trace;
    trace.format = "twincat-scope";
    trace.findings = std::move(findings);
    if (auto finding = mixed_rate_finding(samples.times, base)) trace.findings.push_back(std::move(*finding));
    trace.channels.push_back(Channel{"time", Role::time, "", "ms", base.stamps});
    for (std::size_t g = 0; g < layout.groups.size(); ++g) {
        for (std::size_t c = 0; c < layout.groups[g].channel_columns.size(); ++c) {
            const std::size_t k = samples.first_channel[g] + c;
            Channel channel{names[k], Role::other, "", units[k],
                            values_on_base(samples.times[g], samples.values[k], g == base.finest, base)};
            // each group's own sample time (its median time step, in ms)
            if (std::isfinite(base.steps[g])) {
                channel.native_interval_s = base.steps[g] * 1e-3;
                channel.interval_source = IntervalSource::format;
            }
            trace.channels.push_back(std::move(channel));
        }
    }
    return trace;
}

}  // namespace feedid
