// National Instruments DAQ CSV files. See the header for the layout and the checks.
#include "feedid/io/ni_daq.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "text_scan.hpp"

namespace feedid {

namespace {

using scan::Lines;

// The header block: per key ("Timestamp", "Interval", "Channel name", "Unit", ...) the value of each channel.
struct Header {
    char separator{','};
    std::size_t channels{0};
    std::map<std::string, std::vector<std::string>, std::less<>> values;
    std::string_view first_data_row;
    std::size_t first_data_line{0};
};

char separator_of(std::string_view first_line) {
    constexpr std::string_view key = "Timestamp";
    const char after = first_line.size() > key.size() ? first_line[key.size()] : ',';
    return after == ';' || after == '\t' ? after : ',';
}

bool parse_value(std::string_view cell, char separator, double& value) {
    return scan::parse_number(cell, value) || (separator != ',' && scan::parse_number(cell, value, ','));
}

// The key rows up to the first row that starts with a number.
Header read_header(Lines& lines, const std::string& source) {
    Header header;
    std::vector<std::string_view> cells;
    std::string_view line;
    while (lines.next(line)) {
        if (lines.number == 1) header.separator = separator_of(line);
        if (scan::trim(line).empty()) continue;
        scan::split_cells(line, header.separator, cells);
        if (cells.size() > 1 && cells.back().empty() && cells.size() % 2 == 1) cells.pop_back();
        double probe = 0.0;
        if (parse_value(cells[0], header.separator, probe)) {
            header.first_data_row = line;
            header.first_data_line = lines.number;
            break;
        }
        if (cells.size() % 2 != 0 || (header.channels != 0 && cells.size() / 2 != header.channels)) {
            throw InputError(fmt::format("{}:{}: {} cells: the header rows hold a (key, value) pair per channel",
                                         source, lines.number, cells.size()));
        }
        header.channels = cells.size() / 2;
        auto& values = header.values[std::string(cells[0])];
        values.clear();
        for (std::size_t c = 0; c < header.channels; ++c) {
            if (cells[2 * c] != cells[0]) {
                throw InputError(fmt::format("{}:{}: cell {} is '{}' where the row's key '{}' repeats", source,
                                             lines.number, 2 * c + 1, std::string(cells[2 * c].substr(0, 40)),
                                             std::string(cells[0])));
            }
            values.emplace_back(cells[2 * c + 1]);
        }
    }
    if (!header.values.contains("Channel name")) {
        throw InputError(fmt::format("{}: no 'Channel name' row in the header block", source));
    }
    if (header.first_data_row.empty()) throw InputError(fmt::format("{}: the file has no data rows", source));
    return header;
}

// Channels whose header cell under `key` differs from the first channel's: they are on another time base.
void check_same_cells(const Header& header, std::string_view key, const std::string& source) {
    const auto found = header.values.find(key);
    if (found == header.values.end()) return;
    const auto& cells = found->second;
    const auto& names = header.values.find("Channel name")->second;
    for (std::size_t c = 1; c < cells.size(); ++c) {
        if (cells[c] != cells[0]) {
            throw InputError(fmt::format("{}: channels '{}' and '{}' have different {} ({} and {}): not one time base",
                                         source, names[0], names[c], key, cells[0], cells[c]));
        }
    }
}

void read_row(Trace& trace, std::string_view line, std::size_t number, const Header& header,
              std::vector<std::string_view>& cells, const std::string& source) {
    scan::split_cells(line, header.separator, cells);
    if (cells.size() == 2 * header.channels + 1 && cells.back().empty()) cells.pop_back();
    if (cells.size() != 2 * header.channels) {
        throw InputError(fmt::format("{}:{}: row has {} cells, the header {} ({} channels with their time)", source,
                                     number, cells.size(), 2 * header.channels, header.channels));
    }
    for (std::size_t c = 0; c < 2 * header.channels; ++c) {
        double value = 0.0;
        if (!parse_value(cells[c], header.separator, value)) {
            throw InputError(fmt::format("{}:{}: the {} of channel '{}' is '{}', not a number", source, number,
                                         c % 2 == 0 ? "time" : "value", trace.channels[1 + c / 2].name,
                                         std::string(cells[c].substr(0, 40))));
        }
        if (c % 2 == 1) {
            trace.channels[1 + c / 2].values.push_back(value);
        } else if (c == 0) {
            trace.channels[0].values.push_back(value);
        } else if (value != trace.channels[0].values.back()) {
            throw InputError(fmt::format("{}:{}: channel '{}' is at time {} s where '{}' is at {} s: not one time base",
                                         source, number, trace.channels[1 + c / 2].name, value, trace.channels[1].name,
                                         trace.channels[0].values.back()));
        }
    }
}

// The stated Interval against the time column's mean step (within the rounding of the stated figure).
void check_interval(const Trace& trace, const Header& header, const std::string& source) {
    const auto found = header.values.find("Interval");
    const auto& time = trace.channels[0].values;
    if (found == header.values.end() || time.size() < 2) return;
    const std::string& text = found->second[0];
    double stated = 0.0;
    if (!parse_value(text, header.separator, stated) || !(stated > 0.0)) {
        throw InputError(fmt::format("{}: the Interval '{}' is not a positive number", source, text));
    }
    const auto point = text.find_first_of(".,");
    const int decimals = point == std::string::npos ? 0 : static_cast<int>(text.size() - point - 1);
    const double rounding = std::max(0.5 * std::pow(10.0, -decimals), 1e-6 * stated);
    const double measured = (time.back() - time.front()) / static_cast<double>(time.size() - 1);
    if (!(std::abs(measured - stated) <= rounding)) {
        throw InputError(
            fmt::format("{}: the header states an Interval of {} s, the time column steps by {:.6g} s "
                        "on average",
                        source, stated, measured));
    }
}

}  // namespace

bool looks_like_ni_daq(std::string_view head) {
    head = scan::without_bom(head);
    return head.starts_with("Timestamp") && head.find("\nInterval") != std::string_view::npos &&
           head.find("\nChannel name") != std::string_view::npos;
}

Trace parse_ni_daq(std::string_view text, const std::string& source) {
    text = scan::without_bom(text);
    if (scan::trim(text).empty()) throw InputError(fmt::format("{}: empty file", source));
    Lines lines{text};
    const Header header = read_header(lines, source);
    check_same_cells(header, "Timestamp", source);
    check_same_cells(header, "Interval", source);
    Trace trace;
    trace.source_path = source;
    trace.format = "ni-daq";
    std::vector<std::string> names = header.values.find("Channel name")->second;
    for (const auto& name : scan::number_repeated_names(names))
        trace.findings.push_back(
            fmt::format("channel name '{}' appears more than once: numbered {}#2, ...", name, name));
    const auto units = header.values.find("Unit");
    trace.channels.push_back(Channel{"Time", Role::other, "", "s", {}});
    for (std::size_t c = 0; c < header.channels; ++c) {
        if (names[c].empty()) throw InputError(fmt::format("{}: channel {} has no name", source, c + 1));
        trace.channels.push_back(
            Channel{names[c], Role::other, "", units != header.values.end() ? units->second[c] : "", {}});
    }
    std::vector<std::string_view> cells;
    read_row(trace, header.first_data_row, header.first_data_line, header, cells, source);
    std::string_view line;
    while (lines.next(line)) {
        if (!scan::trim(line).empty()) read_row(trace, line, lines.number, header, cells, source);
    }
    check_interval(trace, header, source);
    return trace;
}

}  // namespace feedid
