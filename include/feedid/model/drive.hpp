#pragma once
// Drive constants: how the logged drive signal becomes a force (or torque).
//   linear axis:  F_d = K_t * i * g / R,  R = lead / 2*pi   (g: gear ratio motor:screw, motor turns per screw turn)
//   rotary axis:  T_d = K_t * i * g
//   or directly:  F_d = force_constant * signal   (a drive that logs a command voltage or a torque)
// A drive signal logged as a motor torque T (N*m, or % of a rated torque) is a force on a linear axis through the
// screw, F_d = T * g * 2*pi / lead (no K_t needed), and the drive torque as it is on a rotary axis.

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "feedid/core/trace.hpp"

namespace feedid {

struct DriveConstants {
    std::optional<double> torque_constant_Nm_per_A;  ///< K_t [N*m/A]
    std::optional<double> lead_m;                    ///< Ball-screw lead [m per screw revolution]
    double gear_ratio{1.0};                          ///< Motor revolutions per screw revolution
    std::optional<double> force_constant;            ///< [N (or N*m) per signal unit]
    std::string force_constant_name;                 ///< A trace constant to use as force_constant (e.g. "gtau")

    /// What is wrong with these options ("" when nothing): a value not finite or outside its allowed range (below),
    /// named with the range.
    [[nodiscard]] std::string validate() const;
    /// Values valid but outside what feed drives have, each named (a lead of 0.01 mm is a 10 mm lead given in metres):
    /// a lead outside 0.5..100 mm, a K_t outside 0.01..500 N*m/A, a gear ratio outside 0.01..1000.
    [[nodiscard]] std::vector<std::string> warnings() const;
    /// N (or N*m) per unit of the current channel, resolving force_constant_name against the trace's constants.
    /// nullopt when no constant is given (then the current is taken as force only if the trace has a force channel).
    /// InputError naming the constant when the file has none of that name, or one that is not a finite number within
    /// allowed_force_constant (a file's nan, inf or 0 is the file's fault, not the data's).
    [[nodiscard]] std::optional<double> force_per_signal(const Trace& trace) const;
};

/// The plausible ranges the warnings check [SI: m, N*m/A, motor turns per screw turn].
struct DriveConstantRange {
    double low;
    double high;
};
inline constexpr DriveConstantRange plausible_lead_m{0.5e-3, 100e-3};
inline constexpr DriveConstantRange plausible_torque_constant_Nm_per_A{0.01, 500.0};
inline constexpr DriveConstantRange plausible_gear_ratio{0.01, 1000.0};

/// The ranges validate() allows [SI: m, N*m/A, motor turns per screw turn; N (or N*m) per signal unit for the force
/// constant's magnitude, of either sign]: a thousand times past the plausible ones (the warnings' ranges) and more,
/// they refuse only what no unit could make sense of, such as a force constant of 1e308, whose forces have no
/// finite squares.
inline constexpr DriveConstantRange allowed_lead_m{0.5e-6, 100.0};
inline constexpr DriveConstantRange allowed_torque_constant_Nm_per_A{1e-5, 5e5};
inline constexpr DriveConstantRange allowed_gear_ratio{1e-5, 1e6};
inline constexpr DriveConstantRange allowed_force_constant{1e-9, 1e9};

/// The drive force (torque) column: the trace's force channel when it has one, otherwise the current channel times
/// force_per_signal; a channel in N*m on a linear axis is turned into force through the lead and gear ratio. Throws
/// InputError saying what is missing.
std::vector<double> drive_force(const Trace& trace, const DriveConstants& constants);

/// The injected test signal as a force (torque) per sample: the injection channel, a signal added to the controller's
/// output before the drive. In N (N*m on a rotary axis; a torque on a linear axis is turned into force by the lead, as
/// for the force channel) it is taken as it is; otherwise it is in the drive signal's units and is converted as the
/// drive signal is (times force_per_signal). Empty when the trace has no injection channel. Throws InputError naming
/// both channels and units when the injection is in other units than the drive signal, or when no constant converts it.
std::vector<double> injection_force(const Trace& trace, const DriveConstants& constants);

}  // namespace feedid
