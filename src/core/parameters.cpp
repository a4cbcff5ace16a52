#include "feedid/core/parameters.hpp"

#include <algorithm>
#include <array>
#include <numbers>

namespace feedid {

namespace {
std::string suffix(Direction direction, const char* forward, const char* reverse) {
    return direction == Direction::forward ? forward : direction == Direction::reverse ? reverse : "";
}
}  // namespace

std::string ParameterNaming::key(Term term, Direction direction) const {
    const std::string dir = suffix(direction, "_forward", "_reverse");
    switch (term) {
        case Term::mass: return rotary ? "inertia_kgm2" : "mass_kg";
        case Term::viscous: return "viscous" + dir + (rotary ? "_Nms_per_rad" : "_Ns_per_m");
        case Term::coulomb: return "coulomb" + dir + (rotary ? "_Nm" : "_N");
        case Term::breakaway: return "breakaway" + dir + (rotary ? "_Nm" : "_N");
        case Term::stribeck_velocity: return "stribeck_velocity" + dir + (rotary ? "_rad_per_s" : "_m_per_s");
        case Term::offset: return rotary ? "offset_Nm" : "offset_N";
    }
    return {};
}

std::string ParameterNaming::unit(Term term) const {
    switch (term) {
        case Term::mass: return rotary ? "kg*m^2" : "kg";
        case Term::viscous: return rotary ? "N*m*s/rad" : "N*s/m";
        case Term::coulomb:
        case Term::breakaway:
        case Term::offset: return rotary ? "N*m" : "N";
        case Term::stribeck_velocity: return rotary ? "rad/s" : "m/s";
    }
    return {};
}

double ParameterNaming::display_position_scale() const {
    return rotary ? 180.0 / std::numbers::pi : 1e3;
}

double ParameterNaming::display_feed_scale() const {
    return 60.0 * display_position_scale();
}

std::string ParameterNaming::velocity_gain_key() const {
    return rotary ? "velocity_gain_Nms_per_rad" : "velocity_gain_N_s_per_m";
}

std::string ParameterNaming::velocity_integral_gain_key() const {
    return rotary ? "velocity_integral_gain_Nm_per_rad" : "velocity_integral_gain_N_per_m";
}

std::string ParameterNaming::signal_velocity_gain_key() const {
    return rotary ? "velocity_gain_signal_per_rad_per_s" : "velocity_gain_signal_per_m_per_s";
}

std::string ParameterNaming::signal_integral_gain_key() const {
    return rotary ? "velocity_integral_gain_signal_per_rad" : "velocity_integral_gain_signal_per_m";
}

std::string ParameterNaming::signal_velocity_gain_unit(const std::string& signal_unit) const {
    return (signal_unit.empty() ? std::string("signal") : signal_unit) + (rotary ? "/(rad/s)" : "/(m/s)");
}

std::string ParameterNaming::symbol(Term term, Direction direction) {
    const std::string dir = suffix(direction, "+", "-");
    switch (term) {
        case Term::mass: return "M";
        case Term::viscous: return "B" + dir;
        case Term::coulomb: return "F_C" + dir;
        case Term::breakaway: return "F_B" + dir;
        case Term::stribeck_velocity: return "v_s" + dir;
        case Term::offset: return "F_0";
    }
    return {};
}

std::optional<ParameterKey> parse_parameter_key(std::string_view key) {
    for (const bool rotary : {false, true}) {
        for (const auto term : all_terms) {
            for (const auto direction : all_directions) {
                if (ParameterNaming{rotary}.key(term, direction) == key) return ParameterKey{term, direction, rotary};
            }
        }
    }
    return std::nullopt;
}

std::vector<std::string> parameter_keys() {
    std::vector<std::string> keys;
    for (const bool rotary : {false, true}) {
        for (const auto term : all_terms) {
            for (const auto direction : all_directions) {
                std::string key = ParameterNaming{rotary}.key(term, direction);
                if (std::find(keys.begin(), keys.end(), key) == keys.end()) keys.push_back(std::move(key));
            }
        }
    }
    return keys;
}

}  // namespace feedid
