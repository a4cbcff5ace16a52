#include "feedid/drive.hpp"

#include <cmath>
#include <numbers>

#include <fmt/core.h>

#include "feedid/error.hpp"

namespace feedid {

std::string DriveConstants::validate() const {
    if (force_constant && force_constant_name.empty() && !(std::isfinite(*force_constant) && *force_constant != 0.0)) {
        return "--force-constant must be a finite, non-zero number";
    }
    if (torque_constant_Nm_per_A && !(*torque_constant_Nm_per_A > 0.0 && std::isfinite(*torque_constant_Nm_per_A))) {
        return "--kt must be a positive number [N*m/A]";
    }
    if (lead_m && !(*lead_m > 0.0 && std::isfinite(*lead_m))) return "--lead must be a positive length";
    if (!(gear_ratio > 0.0 && std::isfinite(gear_ratio))) return "--gear-ratio must be a positive number";
    if ((force_constant || !force_constant_name.empty()) && torque_constant_Nm_per_A) {
        return "give either --force-constant or --kt (with --lead), not both";
    }
    return {};
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

std::vector<double> drive_force(const Trace& trace, const DriveConstants& constants) {
    if (const auto problem = constants.validate(); !problem.empty()) throw InputError(problem);
    if (const auto* force = trace.find(Role::force)) {
        if (trace.rotary || force->unit != "N*m") return force->values;
        // a motor torque on a linear axis: the screw turns it into force, F = T * 2*pi * g / lead
        if (!constants.lead_m) {
            throw InputError(
                fmt::format("{}: the force channel '{}' is a torque (N*m) on a linear axis: give the "
                            "ball-screw lead (--lead, and --gear-ratio) to turn it into force",
                            trace.source_path.empty() ? "trace" : trace.source_path, force->name));
        }
        const double factor = 2.0 * std::numbers::pi * constants.gear_ratio / *constants.lead_m;
        std::vector<double> converted(force->values.size());
        for (std::size_t k = 0; k < converted.size(); ++k) converted[k] = factor * force->values[k];
        return converted;
    }
    const auto* current = trace.find(Role::current);
    if (current == nullptr) {
        throw InputError(
            fmt::format("{}: no drive signal: map a current channel (--channel current=NAME) or a force "
                        "channel (--channel force=NAME)",
                        trace.source_path.empty() ? "trace" : trace.source_path));
    }
    const auto factor = constants.force_per_signal(trace);
    if (!factor) {
        if (current->unit == "N" || current->unit == "N*m") return current->values;
        throw InputError(
            fmt::format("{}: the drive signal '{}' is in {} and no constant turns it into force: give "
                        "--kt and --lead, or --force-constant",
                        trace.source_path.empty() ? "trace" : trace.source_path, current->name,
                        current->unit.empty() ? std::string("unknown units") : current->unit));
    }
    std::vector<double> force(current->values.size());
    for (std::size_t k = 0; k < force.size(); ++k) force[k] = *factor * current->values[k];
    return force;
}

}  // namespace feedid
