#include "feedid/model/drive.hpp"

#include <cmath>
#include <numbers>

#include <fmt/core.h>

#include "feedid/core/error.hpp"

namespace feedid {

namespace {

bool within(double value, DriveConstantRange range) {
    return std::isfinite(value) && value >= range.low && value <= range.high;
}

// "a force constant of either sign with a magnitude from 1e-09 to 1e+09 N per signal unit"
std::string force_constant_range() {
    return fmt::format(
        "a finite number of either sign with a magnitude from {:g} to {:g} N (N*m on a rotary axis) "
        "per unit of the drive signal",
        allowed_force_constant.low, allowed_force_constant.high);
}

}  // namespace

std::string DriveConstants::validate() const {
    if (force_constant && force_constant_name.empty() && !within(std::abs(*force_constant), allowed_force_constant)) {
        return fmt::format("--force-constant {:g} is not allowed: a force constant is {}", *force_constant,
                           force_constant_range());
    }
    if (torque_constant_Nm_per_A && !within(*torque_constant_Nm_per_A, allowed_torque_constant_Nm_per_A)) {
        return fmt::format("--kt {:g} is outside the allowed range {:g} to {:g} N*m/A", *torque_constant_Nm_per_A,
                           allowed_torque_constant_Nm_per_A.low, allowed_torque_constant_Nm_per_A.high);
    }
    if (lead_m && !within(*lead_m, allowed_lead_m)) {
        return fmt::format("--lead {:g} mm is outside the allowed range {:g} to {:g} mm", *lead_m * 1e3,
                           allowed_lead_m.low * 1e3, allowed_lead_m.high * 1e3);
    }
    if (!within(gear_ratio, allowed_gear_ratio)) {
        return fmt::format("--gear-ratio {:g} is outside the allowed range {:g} to {:g}", gear_ratio,
                           allowed_gear_ratio.low, allowed_gear_ratio.high);
    }
    if ((force_constant || !force_constant_name.empty()) && torque_constant_Nm_per_A) {
        return "give either --force-constant or --kt (with --lead), not both";
    }
    return {};
}

std::vector<std::string> DriveConstants::warnings() const {
    std::vector<std::string> out;
    const auto outside = [](double value, DriveConstantRange range) { return value < range.low || value > range.high; };
    if (lead_m && std::isfinite(*lead_m) && outside(*lead_m, plausible_lead_m)) {
        out.push_back(
            fmt::format("--lead {:g} mm is outside 0.5 to 100 mm, the leads of ball screws (give the lead in "
                        "mm per revolution: a 10 mm lead given in metres reads 0.01 mm)",
                        *lead_m * 1e3));
    }
    if (torque_constant_Nm_per_A && std::isfinite(*torque_constant_Nm_per_A) &&
        outside(*torque_constant_Nm_per_A, plausible_torque_constant_Nm_per_A)) {
        out.push_back(fmt::format("--kt {:g} N*m/A is outside 0.01 to 500 N*m/A, the torque constants of servo motors",
                                  *torque_constant_Nm_per_A));
    }
    if (std::isfinite(gear_ratio) && outside(gear_ratio, plausible_gear_ratio)) {
        out.push_back(fmt::format("--gear-ratio {:g} is outside 0.01 to 1000 (motor revolutions per screw revolution)",
                                  gear_ratio));
    }
    return out;
}

std::optional<double> DriveConstants::force_per_signal(const Trace& trace) const {
    if (!force_constant_name.empty()) {
        const auto found = trace.constants.find(force_constant_name);
        if (found == trace.constants.end()) {
            std::string names;
            for (const auto& [name, value] : trace.constants) names += (names.empty() ? "" : ", ") + name;
            throw InputError(fmt::format(
                "--force-constant {}: the file has no scalar named '{}'{}", force_constant_name, force_constant_name,
                names.empty() ? std::string(" (it has no scalars)") : " (it has: " + names + ")"));
        }
        if (!within(std::abs(found->second), allowed_force_constant)) {
            throw InputError(
                fmt::format("--force-constant {}: the file's constant '{}' is {:g}, which is not a force "
                            "constant: a force constant is {}; give the number with --force-constant K",
                            force_constant_name, force_constant_name, found->second, force_constant_range()));
        }
        return found->second;
    }
    if (force_constant) return *force_constant;
    if (torque_constant_Nm_per_A) {
        if (trace.rotary) return *torque_constant_Nm_per_A * gear_ratio;
        if (!lead_m)
            throw InputError("--kt needs --lead (the ball-screw lead) to turn torque into force on a linear axis");
        // eq. (2): F_d = K_t * i / R with R = l / 2*pi, times the gear ratio motor:screw
        return *torque_constant_Nm_per_A * gear_ratio * 2.0 * std::numbers::pi / *lead_m;
    }
    return std::nullopt;
}

namespace {

std::string where(const Trace& trace) {
    return trace.source_path.empty() ? std::string("trace") : trace.source_path;
}

bool is_force_unit(const std::string& unit) {
    return unit == "N" || unit == "N*m";
}

// A channel in N or N*m as force: a motor torque on a linear axis is turned into force by the screw,
// F = T * 2*pi * g / lead.
std::vector<double> as_force(const Trace& trace, const Channel& channel, const DriveConstants& constants) {
    if (trace.rotary || channel.unit != "N*m") return channel.values;
    if (!constants.lead_m) {
        throw InputError(
            fmt::format("{}: the {} channel '{}' is a torque (N*m) on a linear axis: give the ball-screw lead "
                        "(--lead, and --gear-ratio) to turn it into force",
                        where(trace), role_name(channel.role), channel.name));
    }
    const double factor = 2.0 * std::numbers::pi * constants.gear_ratio / *constants.lead_m;
    std::vector<double> converted(channel.values.size());
    for (std::size_t k = 0; k < converted.size(); ++k) converted[k] = factor * channel.values[k];
    return converted;
}

std::vector<double> scaled(std::span<const double> values, double factor) {
    std::vector<double> out(values.size());
    for (std::size_t k = 0; k < out.size(); ++k) out[k] = factor * values[k];
    return out;
}

}  // namespace

std::vector<double> drive_force(const Trace& trace, const DriveConstants& constants) {
    if (const auto problem = constants.validate(); !problem.empty()) throw InputError(problem);
    if (const auto* force = trace.find(Role::force)) return as_force(trace, *force, constants);
    const auto* current = trace.find(Role::current);
    if (current == nullptr) {
        throw InputError(
            fmt::format("{}: no drive signal: map a current channel (--channel current=NAME) or a force "
                        "channel (--channel force=NAME)",
                        where(trace)));
    }
    const auto factor = constants.force_per_signal(trace);
    if (!factor) {
        if (is_force_unit(current->unit)) return as_force(trace, *current, constants);
        // a rotary axis has no lead: K_t (and the gear ratio) make the torque
        throw InputError(fmt::format(
            "{}: the drive signal '{}' is in {} and no constant turns it into {}: give {}, or --force-constant",
            where(trace), current->name, current->unit.empty() ? std::string("unknown units") : current->unit,
            trace.rotary ? "torque" : "force", trace.rotary ? "--kt (and --gear-ratio)" : "--kt and --lead"));
    }
    return scaled(current->values, *factor);
}

std::vector<double> injection_force(const Trace& trace, const DriveConstants& constants) {
    const auto* injection = trace.find(Role::injection);
    if (injection == nullptr) return {};
    if (const auto problem = constants.validate(); !problem.empty()) throw InputError(problem);
    if (is_force_unit(injection->unit)) return as_force(trace, *injection, constants);
    // In the drive signal's units: converted as the drive signal is.
    const auto* drive = trace.find(Role::current);
    if (drive == nullptr) drive = trace.find(Role::force);
    const std::string unit = injection->unit.empty() ? std::string("no unit") : injection->unit;
    if (drive != nullptr && drive->role == Role::current && drive->unit == injection->unit) {
        if (const auto factor = constants.force_per_signal(trace)) return scaled(injection->values, *factor);
    }
    if (drive != nullptr && drive->role == Role::current && drive->unit != injection->unit) {
        throw InputError(
            fmt::format("{}: the injection channel '{}' is in {}, the drive signal '{}' in {}: an injection is in "
                        "the drive signal's units or a force; state its unit with --unit injection=UNIT",
                        where(trace), injection->name, unit, drive->name, drive->unit));
    }
    throw InputError(fmt::format(
        "{}: the injection channel '{}' is in {} and no constant turns it into {}: give --force-constant (or {}), or "
        "--unit injection={} when it is already a {}",
        where(trace), injection->name, unit, trace.rotary ? "torque" : "force",
        trace.rotary ? "--kt" : "--kt and --lead", trace.rotary ? "N*m" : "N", trace.rotary ? "torque" : "force"));
}

}  // namespace feedid
