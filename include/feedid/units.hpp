#pragma once
// Unit strings as found in real files, converted once, at import, to SI:
// m, s, m/s, m/s^2, A, V, N (linear axes) and rad, rad/s, N*m (rotary axes).

#include <optional>
#include <string>
#include <string_view>

namespace feedid {

enum class Quantity {
    dimensionless,
    length,                ///< SI: m
    angle,                 ///< SI: rad
    time,                  ///< SI: s
    velocity,              ///< SI: m/s
    angular_velocity,      ///< SI: rad/s
    acceleration,          ///< SI: m/s^2
    angular_acceleration,  ///< SI: rad/s^2
    current,               ///< SI: A
    voltage,               ///< SI: V
    force,                 ///< SI: N
    torque,                ///< SI: N*m
    frequency,             ///< SI: 1/s
};

/// The SI unit symbol feedid uses for a quantity ("m", "rad/s", "N*m", ...).
std::string_view si_symbol(Quantity quantity);

/// value_SI = scale * value + offset.
struct UnitConversion {
    Quantity quantity{Quantity::dimensionless};
    double scale{1.0};
    double offset{0.0};
    std::string si_unit;  ///< e.g. "m/s"
};

/// What some units need to be converted: rpm needs the lead (motor revolutions to table travel),
/// a percentage needs the rated value it is a percentage of.
struct UnitContext {
    std::optional<double> lead_m;            ///< Table travel per motor revolution [m]; makes rpm a linear velocity.
    std::optional<double> rated_value_si;    ///< What 100 % means, in SI (e.g. rated current 18 A).
    std::optional<Quantity> rated_quantity;  ///< The quantity of that rating (current, torque, ...).
};

/// Parses a unit string ("mm", "mm/min", "µm", "rpm", "Nm", "%", "1/min", ...). Returns nullopt for an unknown unit,
/// or a unit that needs context that was not given (rpm without a lead, % without a rating).
std::optional<UnitConversion> parse_unit(std::string_view unit, const UnitContext& context = {});

/// As parse_unit, but an unknown unit is an InputError naming the channel and the unit.
UnitConversion parse_unit_or_throw(std::string_view unit, std::string_view channel, const UnitContext& context = {});

}  // namespace feedid
