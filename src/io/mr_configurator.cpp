// Mitsubishi MR Configurator2 graph exports. See the header for the layout and the checks.
#include "feedid/io/mr_configurator.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/units.hpp"
#include "text_scan.hpp"

namespace feedid {

namespace {

constexpr std::string_view count_key = "Number of sampling data";
constexpr std::string_view interval_key = "Sampling time interval(ms)";
constexpr std::string_view not_selected = "Not selected";

using scan::Lines;

// A preamble figure as stated, with the number of decimals it was written with (its rounding).
struct Stated {
    double value{0.0};
    int decimals{0};
};

struct Preamble {
    std::optional<Stated> samples;
    std::optional<Stated> interval_ms;
    std::string_view header;
    std::size_t header_line{0};
};

Stated stated_figure(std::string_view cell, std::string_view key, const std::string& source, std::size_t line) {
    Stated stated;
    if (!scan::parse_number(cell, stated.value) || !std::isfinite(stated.value) || stated.value <= 0.0) {
        throw InputError(fmt::format("{}:{}: '{}' is followed by '{}', not a positive number", source, line, key,
                                     std::string(cell.substr(0, 40))));
    }
    if (const auto point = cell.find('.'); point != std::string_view::npos)
        stated.decimals = static_cast<int>(cell.size() - point - 1);
    return stated;
}

// The lines up to the header row (`Time, Analog 1, ...`): `Axis1` and the two sampling figures.
Preamble read_preamble(Lines& lines, const std::string& source) {
    Preamble preamble;
    std::vector<std::string_view> cells;
    std::string_view line;
    while (lines.next(line)) {
        scan::split_cells(line, ',', cells);
        if (scan::iequals(cells[0], "Time")) {
            preamble.header = line;
            preamble.header_line = lines.number;
            break;
        }
        if (cells[0] == count_key || cells[0] == interval_key) {
            const auto figure = stated_figure(cells.size() > 1 ? cells[1] : "", cells[0], source, lines.number);
            (cells[0] == count_key ? preamble.samples : preamble.interval_ms) = figure;
        }
    }
    if (preamble.header.empty()) {
        throw InputError(
            fmt::format("{}: no header row starting with 'Time' (an MR Configurator2 graph export has "
                        "'Time,Analog 1,...' after its preamble)",
                        source));
    }
    if (!preamble.samples || !preamble.interval_ms) {
        throw InputError(fmt::format("{}: no '{}' line before the header row at line {}", source,
                                     preamble.samples ? interval_key : count_key, preamble.header_line));
    }
    return preamble;
}

std::string lower(std::string_view text) {
    std::string out(text);
    std::transform(out.begin(), out.end(), out.begin(),
                   [](unsigned char c) { return static_cast<char>(c >= 'A' && c <= 'Z' ? c + 32 : c); });
    return out;
}

// The unit MR Configurator2 plots a quantity in (its graph's axis labels); "" for digital and unknown slots.
std::string_view unit_of(std::string_view meaning) {
    const std::string key = lower(meaning);
    if (key.find("speed") != std::string::npos) return "r/min";
    if (key.find("droop") != std::string::npos || key.find("pulse") != std::string::npos) return "pulse";
    if (key.find("torque") != std::string::npos || key.find("current") != std::string::npos ||
        key.find("ratio") != std::string::npos || key.find("thrust") != std::string::npos)
        return "%";
    if (key.find("voltage") != std::string::npos) return "V";
    return "";
}

// A kept slot: its column in the rows and the channel it fills.
struct Slot {
    std::size_t column;
    std::size_t channel;
};

// The channels from the header row and the row under it (what each slot holds); "Not selected" slots are dropped.
std::vector<Slot> read_slots(Trace& trace, Lines& lines, const Preamble& preamble, const std::string& source) {
    std::vector<std::string_view> header;
    std::vector<std::string_view> meaning;
    scan::split_cells(preamble.header, ',', header);
    std::string_view line;
    if (!lines.next(line)) throw InputError(fmt::format("{}: the file ends after the header row", source));
    scan::split_cells(line, ',', meaning);
    if (header.size() > 1 && header.back().empty()) header.pop_back();
    if (meaning.size() > 1 && meaning.back().empty()) meaning.pop_back();
    if (meaning.size() != header.size()) {
        throw InputError(fmt::format("{}:{}: {} cells under a header of {} slots (line {})", source, lines.number,
                                     meaning.size(), header.size(), preamble.header_line));
    }
    const auto time_unit = parse_unit(meaning[0]);
    if (!time_unit || time_unit->quantity != Quantity::time) {
        throw InputError(fmt::format("{}:{}: the time column's unit is '{}', not a unit of time", source, lines.number,
                                     std::string(meaning[0].substr(0, 40))));
    }
    std::vector<Slot> slots;
    std::vector<std::string> names;
    std::vector<std::string> units;
    for (std::size_t c = 0; c < header.size(); ++c) {
        if (c > 0 && (meaning[c].empty() || scan::iequals(meaning[c], not_selected))) continue;
        const bool digital = lower(header[c]).starts_with("digital");
        names.emplace_back(c == 0 ? std::string("Time") : std::string(meaning[c]));
        units.emplace_back(c == 0 ? meaning[0] : digital ? "" : unit_of(meaning[c]));
        slots.push_back(Slot{c, slots.size()});
    }
    for (const auto& name : scan::number_repeated_names(names))
        trace.findings.push_back(
            fmt::format("slots holding '{}' appear more than once: numbered {}#2, ...", name, name));
    for (std::size_t k = 0; k < names.size(); ++k)
        trace.channels.push_back(Channel{names[k], Role::other, "", units[k], {}});
    return slots;
}

void read_rows(Trace& trace, Lines& lines, const std::vector<Slot>& slots, std::size_t columns,
               const std::string& source) {
    std::vector<std::string_view> cells;
    std::string_view line;
    while (lines.next(line)) {
        if (scan::trim(line).empty()) continue;
        scan::split_cells(line, ',', cells);
        if (cells.size() > columns && cells.back().empty()) cells.pop_back();
        if (cells.size() != columns) {
            throw InputError(fmt::format("{}:{}: row has {} cells, the header has {} slots", source, lines.number,
                                         cells.size(), columns));
        }
        for (const auto& slot : slots) {
            double value = 0.0;
            if (!scan::parse_number(cells[slot.column], value)) {
                throw InputError(fmt::format("{}:{}: slot {} ('{}') holds '{}', which is not a number", source,
                                             lines.number, slot.column + 1, trace.channels[slot.channel].name,
                                             std::string(cells[slot.column].substr(0, 40))));
            }
            trace.channels[slot.channel].values.push_back(value);
        }
    }
    if (trace.channels[0].values.empty()) throw InputError(fmt::format("{}: the file has no data rows", source));
}

// The preamble's figures against the rows: see the header for why the interval is an error and the count a finding.
void check_preamble(Trace& trace, const Preamble& preamble, const std::string& source) {
    const auto& time = trace.channels[0];
    const std::size_t rows = time.values.size();
    if (static_cast<double>(rows) != preamble.samples->value) {
        trace.findings.push_back(fmt::format("the preamble states {} samples ('{}'), the file holds {} rows",
                                             preamble.samples->value, count_key, rows));
    }
    if (rows < 2) return;
    const double to_ms = parse_unit(time.source_unit)->scale / 1e-3;
    const double measured_ms = (time.values.back() - time.values.front()) / static_cast<double>(rows - 1) * to_ms;
    const Stated& stated = *preamble.interval_ms;
    const double rounding = std::max(0.5 * std::pow(10.0, -stated.decimals), 1e-6 * stated.value);
    if (!(std::abs(measured_ms - stated.value) <= rounding)) {
        throw InputError(
            fmt::format("{}: the preamble states a sampling interval of {} ms ('{}'), the time column "
                        "steps by {:.6g} ms on average",
                        source, stated.value, interval_key, measured_ms));
    }
}

}  // namespace

bool looks_like_mr_configurator(std::string_view head) {
    head = scan::without_bom(head);
    return head.starts_with("Axis") &&
           (head.find(count_key) != std::string_view::npos || head.find(interval_key) != std::string_view::npos);
}

Trace parse_mr_configurator(std::string_view text, const std::string& source) {
    text = scan::without_bom(text);
    if (scan::trim(text).empty()) throw InputError(fmt::format("{}: empty file", source));
    Lines lines{text};
    const Preamble preamble = read_preamble(lines, source);
    Trace trace;
    trace.source_path = source;
    trace.format = "mr-configurator";
    const auto slots = read_slots(trace, lines, preamble, source);
    std::vector<std::string_view> header;
    scan::split_cells(preamble.header, ',', header);
    if (header.size() > 1 && header.back().empty()) header.pop_back();
    read_rows(trace, lines, slots, header.size(), source);
    check_preamble(trace, preamble, source);
    return trace;
}

}  // namespace feedid
