#pragma once
// The parameters of the axis model and how the result document names them: keys with their SI unit in the name
// ("mass_kg", "coulomb_forward_N"; rotary "inertia_kgm2", "coulomb_forward_Nm"), symbols ("M", "F_C+") and units.
// The one place where a parameter key is spelled.

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace feedid {

/// A term of the model F = M*x'' + B*x' + sgn(x')*(F_C + (F_B - F_C)*exp(-|x'|/v_s)) (+ F_0), by its parameter.
enum class Term { mass, viscous, coulomb, breakaway, stribeck_velocity, offset };
/// Which branch of the friction law a parameter belongs to: both (symmetric model), forward (v > 0), reverse (v < 0).
enum class Direction { both, forward, reverse };

/// Every term and every direction, in the order of the result document.
inline constexpr std::array all_terms{Term::mass,      Term::viscous,           Term::coulomb,
                                      Term::breakaway, Term::stribeck_velocity, Term::offset};
inline constexpr std::array all_directions{Direction::both, Direction::forward, Direction::reverse};

/// Sign of v: +1, -1, or 0 at v == 0 (the paper's sgn in eq. 3 and 11).
[[nodiscard]] constexpr double sign(double v) {
    return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0);
}

/// Keys, symbols and units of a linear axis (m, N) or a rotary one (rad, N*m).
struct ParameterNaming {
    bool rotary{false};

    /// Result-document key: "mass_kg", "viscous_forward_Ns_per_m", "stribeck_velocity_rad_per_s", ...
    [[nodiscard]] std::string key(Term term, Direction direction = Direction::both) const;
    /// "kg", "N*s/m", ... (rotary: "kg*m^2", "N*m*s/rad", ...)
    [[nodiscard]] std::string unit(Term term) const;
    /// "M", "B+", "F_C-", ...
    [[nodiscard]] static std::string symbol(Term term, Direction direction);

    [[nodiscard]] std::string force_unit() const { return rotary ? "N*m" : "N"; }
    /// Messages show linear speeds in mm/s, rotary ones in rad/s.
    [[nodiscard]] double display_velocity_scale() const { return rotary ? 1.0 : 1000.0; }
    [[nodiscard]] std::string display_velocity_unit() const { return rotary ? "rad/s" : "mm/s"; }
    /// Keys of the friction-curve plot series.
    [[nodiscard]] std::string curve_velocity_key() const { return rotary ? "velocity_rad_per_s" : "velocity_m_per_s"; }
    [[nodiscard]] std::string curve_force_key() const { return rotary ? "torque_Nm" : "force_N"; }

    /// "linear" or "rotary": the axis kind (runs in the history, messages).
    [[nodiscard]] std::string axis_kind() const { return rotary ? "rotary" : "linear"; }
    /// The SI unit of a position ("m", "rad") and the suffix of keys that hold one ("_m", "_rad").
    [[nodiscard]] std::string length_unit() const { return rotary ? "rad" : "m"; }
    [[nodiscard]] std::string length_key_suffix() const { return rotary ? "_rad" : "_m"; }
    /// Small lengths (tracking and modelling errors) are shown in mm, rotary ones in mrad: value * 1000.
    [[nodiscard]] static constexpr double display_small_length_scale() { return 1e3; }
    [[nodiscard]] std::string display_small_length_unit() const { return rotary ? "mrad" : "mm"; }
    /// Positions along the axis (stroke centres) are shown in mm, rotary ones in deg.
    [[nodiscard]] double display_position_scale() const;
    [[nodiscard]] std::string display_position_unit() const { return rotary ? "deg" : "mm"; }
    /// Feedrates of part programs and test advice: mm/min, rotary deg/min; value [SI/s] * scale.
    [[nodiscard]] double display_feed_scale() const;
    [[nodiscard]] std::string display_feed_unit() const { return rotary ? "deg/min" : "mm/min"; }

    /// Controller gains (gains and simulate documents): K_p per unit of velocity, K_i per unit of position, and the
    /// same per unit of the logged drive signal.
    [[nodiscard]] std::string velocity_gain_key() const;
    [[nodiscard]] std::string velocity_integral_gain_key() const;
    [[nodiscard]] std::string velocity_gain_unit() const { return rotary ? "N*m*s/rad" : "N*s/m"; }
    [[nodiscard]] std::string velocity_integral_gain_unit() const { return rotary ? "N*m/rad" : "N/m"; }
    [[nodiscard]] std::string signal_velocity_gain_key() const;
    [[nodiscard]] std::string signal_integral_gain_key() const;
    /// The drive-signal gain's unit: "V/(m/s)", "A/(rad/s)", ...
    [[nodiscard]] std::string signal_velocity_gain_unit(const std::string& signal_unit) const;
    /// The force-limit key of a controller ("saturation_N", "saturation_Nm").
    [[nodiscard]] std::string saturation_key() const { return rotary ? "saturation_Nm" : "saturation_N"; }
};

/// What a result-document key names: its term, direction and whether it is a rotary axis's key.
struct ParameterKey {
    Term term;
    Direction direction;
    bool rotary;
};
/// The inverse of ParameterNaming::key; nullopt for a key that is not one of feedid's parameters.
[[nodiscard]] std::optional<ParameterKey> parse_parameter_key(std::string_view key);

/// Every key ParameterNaming::key gives, each once: linear, then rotary; per term (all_terms) the symmetric key, then
/// the per-direction ones (mass and offset have no per-direction keys).
[[nodiscard]] std::vector<std::string> parameter_keys();

}  // namespace feedid
