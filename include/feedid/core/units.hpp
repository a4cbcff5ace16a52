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

/// The kind of axis a trace records: a linear one (m, m/s, N) or a rotary one (rad, rad/s, N*m).
enum class AxisKind { linear, rotary };

/// "linear" or "rotary".
std::string_view axis_kind_name(AxisKind kind);

/// The axis kind a quantity belongs to: length, velocity, acceleration and force are linear; angle, angular velocity,
/// angular acceleration and torque rotary; nullopt for quantities of either kind (time, current, voltage, ...).
std::optional<AxisKind> axis_kind_of(Quantity quantity);

/// What some units need to be converted: a revolution speed (rpm) becomes a table velocity only through the lead
/// (and the gear ratio); a percentage needs the rated value it is a percentage of.
struct UnitContext {
    /// Table travel per screw revolution [m]. With it, rpm is a motor speed turned into a linear table velocity;
    /// without it, rpm is an angular velocity (rad/s). The import drops it on a rotary axis.
    std::optional<double> lead_m;
    std::optional<double> gear_ratio;        ///< Motor revolutions per screw revolution (1 when not given).
    std::optional<double> rated_value_si;    ///< What 100 % means, in SI (e.g. rated current 18 A).
    std::optional<Quantity> rated_quantity;  ///< The quantity of that rating (current, torque, ...).
};

/// Parses a unit string ("mm", "mm/min", "µm", "rpm", "rev/min", "Nm", "%", "1/min", ...). Returns nullopt for an
/// unknown unit, or a unit that needs context that was not given (% without a rating). A revolution speed (rpm,
/// r/min, rev/min, 1/min, rps, rev/s) is an angular velocity in rad/s, or with context.lead_m a linear velocity:
/// v = n / gear_ratio * lead.
std::optional<UnitConversion> parse_unit(std::string_view unit, const UnitContext& context = {});

/// Whether a unit string is a revolution speed (rpm, r/min, rev/min, 1/min, rps, rev/s): the one unit whose
/// quantity depends on the context (a lead makes it linear).
bool is_revolution_speed(std::string_view unit);

/// What `--rated` says 100 % is: a value with its unit ("18A", "2.4Nm", "2.4 N*m", "500 N"); a bare number is
/// a current in A. Throws InputError naming the option for anything else.
struct Rating {
    double value_si{0.0};
    Quantity quantity{Quantity::current};
};
Rating parse_rating(std::string_view text);

/// As parse_unit, but an unknown unit is an InputError naming the channel and the unit.
UnitConversion parse_unit_or_throw(std::string_view unit, std::string_view channel, const UnitContext& context = {});

}  // namespace feedid
