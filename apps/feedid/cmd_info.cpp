// feedid info FILE: what a trace holds (channels, roles, units, sample time, findings).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/terminal_text.hpp"

namespace feedid::cli {

namespace {
// Smallest and largest finite value (a channel no analysis uses may hold NaN for missing cells), sample by sample:
// of equal values the first is kept, which tells 0 from -0.
std::optional<std::pair<double, double>> finite_range_in_order(const std::vector<double>& values) {
    std::optional<std::pair<double, double>> range;
    for (const double value : values) {
        if (!std::isfinite(value)) continue;
        if (!range) range = std::pair{value, value};
        range->first = std::min(range->first, value);
        range->second = std::max(range->second, value);
    }
    return range;
}

// The same, a few times faster: four running extremes over interleaved samples, held in registers (the pass above
// keeps its extremes in memory, a store and a load per sample). They agree with it unless an extreme is a zero, where
// only the pass in order knows which sign came first.
std::optional<std::pair<double, double>> finite_range(const std::vector<double>& values) {
    constexpr std::size_t lanes = 4;
    constexpr double infinity = std::numeric_limits<double>::infinity();
    std::array<double, lanes> low{infinity, infinity, infinity, infinity};
    std::array<double, lanes> high{-infinity, -infinity, -infinity, -infinity};
    const auto take = [&](std::size_t lane, double value) {
        const bool finite = std::isfinite(value);
        low[lane] = finite && value < low[lane] ? value : low[lane];
        high[lane] = finite && value > high[lane] ? value : high[lane];
    };
    const std::size_t n = values.size();
    std::size_t k = 0;
    for (; k + lanes <= n; k += lanes) {
        for (std::size_t lane = 0; lane < lanes; ++lane) take(lane, values[k + lane]);
    }
    for (; k < n; ++k) take(k % lanes, values[k]);
    const double smallest = *std::min_element(low.begin(), low.end());
    const double largest = *std::max_element(high.begin(), high.end());
    if (smallest > largest) return std::nullopt;  // no finite value
    if (smallest == 0.0 || largest == 0.0) return finite_range_in_order(values);
    return std::pair{smallest, largest};
}

// "4 ms (format)", "4 ms (detected)", "2 ms (time base)"; "-" when unknown.
std::string native_interval_text(const Channel& channel) {
    if (!channel.native_interval_s) return "-";
    return fmt::format("{:.6g} ms ({})", *channel.native_interval_s * 1e3,
                       interval_source_name(channel.interval_source));
}

struct InfoCommand {
    TraceArguments trace_arguments;
    std::string json_path;

    int run() const {
        require_separate_outputs({{"--json", json_path}}, trace_arguments.inputs());
        Trace trace = trace_arguments.read(false);
        // A file without a time column (and no --sample-time) is described without a time base.
        const bool timed = trace.has(Role::time);
        const TimeBase base = timed ? trace.time_base() : TimeBase{};
        const std::size_t samples = trace.channels.empty() ? 0 : trace.channels.front().values.size();
        nlohmann::json document;
        document["format"] = trace.format;
        document["samples"] = samples;
        document["sample_time_s"] = timed ? nlohmann::json(base.sample_time_s) : nlohmann::json();
        document["duration_s"] = timed ? nlohmann::json(base.duration_s) : nlohmann::json();
        document["rotary"] = trace.rotary;
        document["axes"] = trace.axes;
        document["channels"] = nlohmann::json::array();
        for (const auto& channel : trace.channels) {
            nlohmann::json entry{{"name", channel.name},
                                 {"role", role_name(channel.role)},
                                 {"unit", channel.unit},
                                 {"source_unit", channel.source_unit}};
            const auto range = finite_range(channel.values);
            entry["min"] = range ? nlohmann::json(range->first) : nlohmann::json();
            entry["max"] = range ? nlohmann::json(range->second) : nlohmann::json();
            entry["native_interval_s"] =
                channel.native_interval_s ? nlohmann::json(*channel.native_interval_s) : nlohmann::json();
            entry["interval_source"] = interval_source_name(channel.interval_source);
            document["channels"].push_back(entry);
        }
        document["constants"] = trace.constants;
        document["findings"] = trace.findings;
        if (!json_path.empty()) {
            write_json(document, json_path);
            return 0;
        }
        fmt::print("{}\n", terminal_text(trace.source_path));
        fmt::print("  format       {}\n", trace.format);
        fmt::print("  samples      {}\n", samples);
        if (timed) {
            fmt::print("  sample time  {:.6g} s ({:.6g} Hz){}\n", base.sample_time_s,
                       base.sample_time_s > 0 ? 1.0 / base.sample_time_s : 0.0, base.jittery ? ", jittery" : "");
            fmt::print("  duration     {:.6g} s\n", base.duration_s);
        } else {
            fmt::print("  sample time  unknown (no time column; give --sample-time SECONDS)\n");
        }
        fmt::print("  axis         {}\n", trace.rotary ? "rotary" : "linear");
        if (!trace.axes.empty()) {
            std::string axes;
            for (const auto& axis : trace.axes) axes += (axes.empty() ? "" : ", ") + terminal_text(axis);
            fmt::print("  axes         {} (read one with --axis NAME)\n", axes);
        }
        fmt::print("  channels\n");
        fmt::print("    {:<28} {:<20} {:<8} {:<10} {:>14} {:>14}  {}\n", "name", "role", "unit", "source", "min", "max",
                   "native interval");
        for (const auto& channel : trace.channels) {
            const auto range = finite_range(channel.values);
            fmt::print("    {:<28} {:<20} {:<8} {:<10} {:>14} {:>14}  {}\n", terminal_text(channel.name),
                       role_name(channel.role), channel.unit.empty() ? "-" : channel.unit,
                       channel.source_unit.empty() ? "-" : terminal_text(channel.source_unit),
                       range ? fmt::format("{:.6g}", range->first) : "-",
                       range ? fmt::format("{:.6g}", range->second) : "-", native_interval_text(channel));
        }
        if (!trace.constants.empty()) {
            fmt::print("  constants\n");
            for (const auto& [name, value] : trace.constants)
                fmt::print("    {:<28} {:.10g}\n", terminal_text(name), value);
        }
        if (!trace.findings.empty()) {
            fmt::print("  findings\n");
            for (const auto& finding : trace.findings) fmt::print("    - {}\n", terminal_message(finding));
        }
        return 0;
    }
};
}  // namespace

Action add_info_command(CLI::App& app) {
    auto command = std::make_shared<InfoCommand>();
    auto* sub = app.add_subcommand("info", "Show what a trace holds: channels, roles, units, sample time, findings");
    command->trace_arguments.describe = true;
    command->trace_arguments.add_to(*sub);
    sub->add_option("--json", command->json_path, "Write the info document to PATH ('-' for stdout)");
    sub->add_option("--lead", command->trace_arguments.lead_mm,
                    "Ball-screw lead [mm per revolution]: makes channels in rpm a table velocity (a linear axis)")
        ->check(lead_range());
    sub->add_option("--gear-ratio", command->trace_arguments.gear_ratio,
                    "Motor revolutions per screw revolution, with --lead for rpm channels")
        ->check(gear_ratio_range());
    sub->footer(
        "Example:\n  feedid info ../shared/data/emps/DATA_EMPS.mat\n"
        "  feedid info trace.csv --channel position=x_act --unit current=A --json -");
    return [command] { return command->run(); };
}

}  // namespace feedid::cli
