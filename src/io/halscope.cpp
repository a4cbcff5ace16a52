// LinuxCNC halscope exports (2.9 and older layouts) and halsampler output. See the header for the layouts.
#include "feedid/io/halscope.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "text_scan.hpp"
#include "channel_hint.hpp"

namespace feedid {

namespace {

constexpr double not_a_number = std::numeric_limits<double>::quiet_NaN();

void split_blanks(std::string_view line, std::vector<std::string_view>& tokens) {
    tokens.clear();
    std::size_t k = 0;
    while (k < line.size()) {
        while (k < line.size() && (line[k] == ' ' || line[k] == '\t')) ++k;
        const std::size_t start = k;
        while (k < line.size() && line[k] != ' ' && line[k] != '\t') ++k;
        if (k > start) tokens.push_back(line.substr(start, k - start));
    }
}

// "Sampling period is 1000000 ns" (optionally after "# ") -> seconds.
std::optional<double> sampling_period(std::string_view line) {
    line = scan::trim(line);
    if (line.starts_with("#")) line = scan::trim(line.substr(1));
    constexpr std::string_view prefix = "Sampling period is";
    if (!line.starts_with(prefix)) return std::nullopt;
    line = scan::trim(line.substr(prefix.size()));
    const auto space = line.find(' ');
    double nanoseconds = 0.0;
    if (space == std::string_view::npos || scan::trim(line.substr(space)) != "ns" ||
        !scan::parse_number(line.substr(0, space), nanoseconds)) {
        return not_a_number;
    }
    return nanoseconds * 1e-9;
}

bool ends_with(std::string_view text, std::string_view suffix) {
    return text.ends_with(suffix);
}

// Roles from HAL pin names: joint.N.motor-pos-fb, joint.N.pos-cmd, joint.N.vel-cmd, ... (LinuxCNC's motion pins).
void guess_roles(Trace& trace) {
    struct Rule {
        std::string_view suffix;
        Role role;
    };
    static constexpr Rule rules[] = {{"pos-fb", Role::position},
                                     {"pos-cmd", Role::reference_position},
                                     {"vel-cmd", Role::velocity_command},
                                     {"vel-fb", Role::velocity},
                                     {"current", Role::current}};
    for (const auto& rule : rules) {
        if (trace.has(rule.role)) continue;
        for (auto& channel : trace.channels) {
            if (channel.role != Role::other || !ends_with(channel.name, rule.suffix)) continue;
            channel.role = rule.role;
            trace.findings.push_back(
                fmt::format("channel '{}' taken as {} (guessed from the HAL pin name; set it with {})",
                            channel.name, role_name(rule.role),
                            io_detail::channel_option(role_name(rule.role), channel.name)));
            break;
        }
    }
}

void add_time(Trace& trace, std::size_t samples, double period_s) {
    std::vector<double> time(samples);
    for (std::size_t k = 0; k < samples; ++k) time[k] = static_cast<double>(k) * period_s;
    trace.channels.insert(trace.channels.begin(), Channel{"time", Role::time, "", "s", std::move(time)});
}

void check_period(double period_s, const std::string& source, std::size_t line) {
    if (!(period_s > 0.0) || !std::isfinite(period_s)) {
        throw InputError(fmt::format("{}: line {}: the sampling period is not a positive number of ns", source, line));
    }
}

Trace parse_new_layout(std::string_view text, std::size_t position, const std::string& source, double period_s) {
    Trace trace;
    trace.format = "halscope";
    std::size_t line_number = 1;
    std::vector<std::string_view> cells;
    auto split_semicolons = [&cells](std::string_view line) {
        cells.clear();
        std::size_t start = 0;
        while (true) {
            const auto end = line.find(';', start);
            cells.push_back(scan::trim(line.substr(start, end == std::string_view::npos ? end : end - start)));
            if (end == std::string_view::npos) break;
            start = end + 1;
        }
    };
    std::string_view header;
    while (position < text.size() && header.empty()) {
        header = scan::trim(scan::next_line(text, position));
        ++line_number;
    }
    if (header.empty()) throw InputError(fmt::format("{}: line {}: no line of channel names", source, line_number));
    split_semicolons(header);
    std::map<std::string, int> seen;
    for (const auto cell : cells) {
        std::string name(cell.empty() ? std::string_view("channel") : cell);
        if (name == "time") name = "time (channel)";
        if (const int count = seen[name]++; count > 0) name += fmt::format(" #{}", count + 1);
        trace.channels.push_back(Channel{name, Role::other, "", "", {}});
    }
    const std::size_t width = trace.channels.size();
    while (position < text.size()) {
        const std::string_view line = scan::trim(scan::next_line(text, position));
        ++line_number;
        if (line.empty() || line.front() == '#') continue;
        split_semicolons(line);
        if (cells.size() != width) {
            throw InputError(fmt::format("{}: line {}: {} values, the header names {} channels", source, line_number,
                                         cells.size(), width));
        }
        for (std::size_t c = 0; c < width; ++c) {
            double value = 0.0;
            if (!scan::parse_number(cells[c], value)) {
                throw InputError(fmt::format("{}: line {}: value '{}' of channel '{}' is not a number", source,
                                             line_number, cells[c], trace.channels[c].name));
            }
            trace.channels[c].values.push_back(value);
        }
    }
    const std::size_t samples = trace.channels.front().values.size();
    if (samples == 0) throw InputError(fmt::format("{}: no data rows after the channel names", source));
    add_time(trace, samples, period_s);
    return trace;
}

Trace parse_old_layout(std::string_view text, std::size_t position, const std::string& source, double period_s) {
    Trace trace;
    trace.format = "halscope";
    std::size_t line_number = 1;
    std::vector<std::string_view> tokens;
    std::map<std::string, std::size_t, std::less<>> index;
    std::size_t lines = 0;
    bool interlaced = false;
    while (position < text.size()) {
        const std::string_view line = scan::next_line(text, position);
        ++line_number;
        split_blanks(line, tokens);
        if (tokens.empty()) continue;
        if (tokens.size() % 2 != 0) {
            throw InputError(fmt::format("{}: line {}: expected 'name value' pairs", source, line_number));
        }
        ++lines;
        interlaced = interlaced || tokens.size() > 2;
        for (std::size_t k = 0; k < tokens.size(); k += 2) {
            double value = 0.0;
            if (!scan::parse_number(tokens[k + 1], value)) {
                throw InputError(fmt::format("{}: line {}: value '{}' of channel '{}' is not a number", source,
                                             line_number, tokens[k + 1], tokens[k]));
            }
            auto it = index.find(tokens[k]);
            if (it == index.end()) {
                it = index.emplace(std::string(tokens[k]), trace.channels.size()).first;
                trace.channels.push_back(Channel{std::string(tokens[k]), Role::other, "", "", {}});
            }
            trace.channels[it->second].values.push_back(value);
        }
    }
    if (lines == 0) throw InputError(fmt::format("{}: no samples after the sampling period", source));
    std::size_t shortest = std::numeric_limits<std::size_t>::max();
    std::size_t longest = 0;
    for (const auto& channel : trace.channels) {
        shortest = std::min(shortest, channel.values.size());
        longest = std::max(longest, channel.values.size());
    }
    // The pre-2.9 writer runs one sample past the capture: in interlaced order every channel gets it, in channel
    // order only the first one does (see the header).
    std::size_t keep = shortest;
    if (shortest == longest && shortest > 1 && interlaced) keep = shortest - 1;
    if (keep < longest) {
        trace.findings.push_back(
            fmt::format("the last {} sample(s) were dropped: the halscope writer before 2.9 "
                        "prints a sample past the end of the capture",
                        longest - keep));
    }
    if (keep == 0) throw InputError(fmt::format("{}: no complete sample", source));
    for (auto& channel : trace.channels) channel.values.resize(keep);
    add_time(trace, keep, period_s);
    return trace;
}

Trace parse_halsampler(std::string_view text, const std::string& source, std::optional<double> period_s) {
    Trace trace;
    trace.format = "halscope";
    std::vector<std::vector<double>> columns;
    std::vector<std::string_view> tokens;
    std::size_t position = 0;
    std::size_t line_number = 0;
    std::size_t overruns = 0;
    while (position < text.size()) {
        const std::string_view line = scan::next_line(text, position);
        ++line_number;
        split_blanks(line, tokens);
        if (tokens.empty()) continue;
        if (tokens.size() == 1 && tokens[0] == "overrun") {
            ++overruns;
            continue;
        }
        if (columns.empty()) columns.resize(tokens.size());
        if (tokens.size() != columns.size()) {
            throw InputError(fmt::format("{}: line {}: {} values, the first line has {}", source, line_number,
                                         tokens.size(), columns.size()));
        }
        for (std::size_t c = 0; c < tokens.size(); ++c) {
            double value = 0.0;
            if (!scan::parse_number(tokens[c], value)) {
                throw InputError(fmt::format("{}: line {}: '{}' is not a number", source, line_number, tokens[c]));
            }
            columns[c].push_back(value);
        }
    }
    if (columns.empty()) throw InputError(fmt::format("{}: no samples", source));
    if (!period_s) {
        throw InputError(
            fmt::format("{}: halsampler output carries no sampling period: state it (the thread period "
                        "times the sampler's decimation) with --sample-time SECONDS",
                        source));
    }
    check_period(*period_s, source, 1);
    // A first column of whole numbers that increase is the sample number written by `halsampler -t`.
    bool tagged = columns.size() > 1;
    for (std::size_t k = 0; tagged && k < columns[0].size(); ++k) {
        const double tag = columns[0][k];
        tagged = tag >= 0 && tag == std::floor(tag) && (k == 0 || tag > columns[0][k - 1]);
    }
    if (overruns > 0 && !tagged) {
        throw InputError(
            fmt::format("{}: {} 'overrun' line(s) mark lost samples, but the lines carry no sample "
                        "number (halsampler -t), so the time after a gap is unknown",
                        source, overruns));
    }
    const std::size_t samples = columns[0].size();
    std::vector<double> time(samples);
    for (std::size_t k = 0; k < samples; ++k) {
        time[k] = (tagged ? columns[0][k] - columns[0][0] : static_cast<double>(k)) * *period_s;
    }
    trace.channels.push_back(Channel{"time", Role::time, "", "s", std::move(time)});
    for (std::size_t c = tagged ? 1 : 0, pin = 0; c < columns.size(); ++c, ++pin) {
        trace.channels.push_back(Channel{fmt::format("pin.{}", pin), Role::other, "", "", std::move(columns[c])});
    }
    if (tagged) trace.findings.push_back("first column taken as the sample number (halsampler -t)");
    if (overruns > 0) {
        trace.findings.push_back(
            fmt::format("{} overrun(s): samples were lost; the time follows the sample numbers", overruns));
    }
    return trace;
}

}  // namespace

bool looks_like_halsampler(std::string_view head) {
    std::size_t position = 0;
    std::size_t numeric_lines = 0;
    std::vector<std::string_view> tokens;
    while (position < head.size() && numeric_lines < 3) {
        const std::string_view line = scan::next_line(head, position);
        if (position >= head.size() && !head.ends_with('\n') && numeric_lines > 0) break;  // a cut-off last line
        if (line.find_first_of(",;") != std::string_view::npos) return false;
        split_blanks(line, tokens);
        if (tokens.empty()) continue;
        if (tokens.size() == 1 && tokens[0] == "overrun") continue;
        for (const auto token : tokens) {
            double value = 0.0;
            if (!scan::parse_number(token, value)) return false;
        }
        ++numeric_lines;
    }
    return numeric_lines > 0;
}

Trace parse_halscope(std::string_view text, const std::string& source, std::optional<double> sample_time_s) {
    if (text.find('\0') != std::string_view::npos) {
        throw InputError(fmt::format("{}: not a text file (it contains NUL bytes)", source));
    }
    std::size_t position = 0;
    std::string_view first;
    while (position < text.size() && scan::trim(first).empty()) first = scan::next_line(text, position);
    Trace trace;
    if (const auto period = sampling_period(first)) {
        check_period(*period, source, 1);
        trace = scan::trim(first).starts_with("#") ? parse_new_layout(text, position, source, *period)
                                                   : parse_old_layout(text, position, source, *period);
        if (sample_time_s && std::abs(*sample_time_s - *period) > 1e-9 * *period) {
            trace.findings.push_back(
                fmt::format("the file states a sampling period of {} s; the stated {} s is "
                            "ignored",
                            *period, *sample_time_s));
        }
    } else {
        trace = parse_halsampler(text, source, sample_time_s);
    }
    guess_roles(trace);
    return trace;
}

}  // namespace feedid
