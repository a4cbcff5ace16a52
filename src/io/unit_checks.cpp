#include "feedid/io/unit_checks.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include <fmt/core.h>
#include <fmt/ranges.h>

#include "feedid/core/error.hpp"
#include "feedid/numeric/native_interval.hpp"
#include "feedid/numeric/signal.hpp"

namespace feedid {

namespace {

/// |x'| of a channel from differences over its own native interval (a held signal changes only every k samples).
std::vector<double> speeds_of(const Trace& trace, const Channel& channel) {
    const auto time = trace.column(Role::time);
    const double dt = trace.time_base().sample_time_s;
    const auto step = static_cast<std::size_t>(std::max(1L, std::lround(native_interval_of(trace, channel.role) / dt)));
    std::vector<double> speeds;
    for (std::size_t k = step; k < channel.values.size(); k += 1) {
        const double elapsed = time[k] - time[k - step];
        if (elapsed > 0.0) speeds.push_back(std::abs(channel.values[k] - channel.values[k - step]) / elapsed);
    }
    return speeds;
}

/// A typical level of a speed series and whether it stands above its noise.
struct Level {
    double typical{0.0};  ///< 95th percentile
    bool moving{false};
};

/// Of the speeds |values| (a velocity, or speeds already), without a copy of them.
Level level_of(std::span<const double> values, const std::vector<double>& signal, double noise_multiple) {
    Level level;
    level.typical = absolute_percentile(values, 0.95);
    const double noise = noise_floor(signal);
    level.moving = level.typical > 0.0 && level.typical > noise_multiple * noise;
    return level;
}

std::string unit_of(const Channel& channel) {
    return channel.source_unit.empty()
               ? "no unit, taken as " + (channel.unit.empty() ? std::string("SI") : channel.unit)
               : channel.source_unit;
}

/// The unit mix-up a factor suggests, if it is a known one (within 5 %).
std::string suspect(double ratio) {
    struct Known {
        double factor;
        const char* what;
    };
    static const std::array<Known, 6> known{{{1000.0, "m against mm, or mm against um"},
                                             {60.0, "per minute against per second"},
                                             {1000.0 / 60.0, "m/min against mm/s"},
                                             {60000.0, "mm/min against m/s"},
                                             {2.0 * std::numbers::pi, "rev against rad"},
                                             {25.4, "in against mm"}}};
    const double r = std::max(ratio, 1.0 / ratio);
    for (const auto& k : known) {
        if (std::abs(r / k.factor - 1.0) < 0.05) return fmt::format(" ({:g}: {}?)", k.factor, k.what);
    }
    return {};
}

void compare(const std::string& a, const Level& la, const std::string& b, const Level& lb, const char* unit,
             const ConsistencyOptions& options, std::vector<std::string>& problems) {
    if (!la.moving || !lb.moving) return;
    const double ratio = la.typical / lb.typical;
    if (ratio <= options.max_scale_ratio && ratio >= 1.0 / options.max_scale_ratio) return;
    problems.push_back(fmt::format(
        "{} and {} measure the same motion but differ by a factor of {:.4g} (95th percentiles of their speeds {:.4g} "
        "and {:.4g} {}): one of their units is wrong{}; state it with --unit ROLE=UNIT",
        a, b, ratio, la.typical, lb.typical, unit, suspect(ratio)));
}

// A position that jumps between samples (a log that writes the position rounded and late, a glitch, a re-homing):
// the path it covers, sum |dx|, far exceeds the one the logged velocity covers, integral |v| dt. A step is a jump when
// it exceeds three times what the velocity at its two ends covers plus two of the position's quanta (its smallest
// step), so that rounding to whole millimetres at 10 Hz is none. Such a trace compared by speeds looks like a unit
// mix-up; it is not one, and the message says what it is, where, and how to identify without the position.
std::optional<std::string> position_jumps(const Trace& trace, const Channel& position, const Channel& velocity) {
    const auto time = trace.column(Role::time);
    const auto& x = position.values;
    const auto& v = velocity.values;
    double quantum = std::numeric_limits<double>::max();
    for (std::size_t k = 1; k < x.size(); ++k)
        if (const double step = std::abs(x[k] - x[k - 1]); step > 0.0) quantum = std::min(quantum, step);
    double path = 0.0, travelled = 0.0, largest = 0.0;
    std::size_t jumps = 0, first = 0;
    for (std::size_t k = 1; k < x.size(); ++k) {
        const double dt = time[k] - time[k - 1];
        const double step = std::abs(x[k] - x[k - 1]);
        const double covered = 0.5 * (std::abs(v[k]) + std::abs(v[k - 1])) * dt;
        path += step;
        travelled += covered;
        if (!(dt > 0.0) || step <= 3.0 * covered + 2.0 * quantum) continue;
        if (jumps++ == 0) first = k;
        largest = std::max(largest, step);
    }
    if (jumps == 0 || !(path > 2.0 * travelled)) return std::nullopt;
    return fmt::format(
        "the {} '{}' jumps {} times between samples (first at t = {:.6g} s, by up to {:.4g} {}): it covers {:.4g} {} "
        "where the {} '{}' covers {:.4g} {}; not a unit error, a position that does not follow the motion: identify "
        "from the logged velocity alone with --channel position=none",
        role_name(position.role), position.name, jumps, time[first], largest, position.unit, path, position.unit,
        role_name(velocity.role), velocity.name, travelled, position.unit);
}

}  // namespace

std::vector<std::string> unit_inconsistencies(const Trace& trace, const ConsistencyOptions& options) {
    std::vector<std::string> problems;
    if (trace.samples() < 10) return problems;
    const Channel* position = trace.find(Role::position);
    const Channel* reference = trace.find(Role::reference_position);
    const Channel* velocity = trace.find(Role::velocity);
    const Channel* command = trace.find(Role::velocity_command);
    const Channel* current = trace.find(Role::current);
    const auto named = [](const Channel* c) {
        return fmt::format("the {} '{}' [{}]", role_name(c->role), c->name, unit_of(*c));
    };
    const double speed_limit = trace.rotary ? options.max_angular_speed : options.max_linear_speed;
    const char* speed_unit = trace.rotary ? "rad/s" : "m/s";

    std::optional<Level> position_speed;
    if (position != nullptr) {
        const auto speeds = speeds_of(trace, *position);
        position_speed = level_of(speeds, speeds, options.noise_multiple);
        if (const double fast = absolute_percentile(speeds, 0.99); fast > speed_limit) {
            problems.push_back(
                fmt::format("{} moves at up to {:.4g} {} (99th percentile): no feed drive moves that "
                            "fast; is its unit right? (state it with --unit position=UNIT)",
                            named(position), fast, speed_unit));
        }
    }
    std::optional<Level> logged_speed;
    if (velocity != nullptr) {
        logged_speed = level_of(velocity->values, velocity->values, options.noise_multiple);
        if (const double fast = absolute_percentile(velocity->values, 0.99); fast > speed_limit) {
            problems.push_back(
                fmt::format("{} reaches {:.4g} {} (99th percentile): no feed drive moves that fast; is "
                            "its unit right? (state it with --unit velocity=UNIT)",
                            named(velocity), fast, speed_unit));
        }
    }
    if (position != nullptr && velocity != nullptr) {
        if (const auto jumps = position_jumps(trace, *position, *velocity))
            problems.push_back(*jumps);
        else
            compare(named(velocity), *logged_speed, named(position), *position_speed, speed_unit, options, problems);
    }
    if (position != nullptr && reference != nullptr) {
        const auto speeds = speeds_of(trace, *reference);
        compare(named(position), *position_speed, named(reference), level_of(speeds, speeds, options.noise_multiple),
                speed_unit, options, problems);
    }
    if (command != nullptr) {
        const Level commanded = level_of(command->values, command->values, options.noise_multiple);
        if (velocity != nullptr)
            compare(named(velocity), *logged_speed, named(command), commanded, speed_unit, options, problems);
        else if (position != nullptr)
            compare(named(position), *position_speed, named(command), commanded, speed_unit, options, problems);
    }
    if (current != nullptr && current->unit == "A") {
        const double largest = absolute_percentile(current->values, 0.99);
        if (largest > options.max_current) {
            problems.push_back(
                fmt::format("{} reaches {:.4g} A (99th percentile): no feed drive draws that much; is "
                            "it in mA? (state it with --unit current=mA)",
                            named(current), largest));
        }
    }
    return problems;
}

void require_consistent_units(const Trace& trace, const ConsistencyOptions& options) {
    if (const auto problems = unit_inconsistencies(trace, options); !problems.empty()) {
        throw InputError(fmt::format("{}: {}", trace.source_path.empty() ? std::string("trace") : trace.source_path,
                                     fmt::join(problems, "; ")));
    }
}

}  // namespace feedid
