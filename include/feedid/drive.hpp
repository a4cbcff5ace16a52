#pragma once
// Drive constants: how the logged drive signal becomes a force (or torque).
//   linear axis:  F_d = K_t * i * g / R,  R = lead / 2*pi   (g: gear ratio motor:screw, motor turns per screw turn)
//   rotary axis:  T_d = K_t * i * g
//   or directly:  F_d = force_constant * signal   (a drive that logs a command voltage or a torque)

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "feedid/trace.hpp"

namespace feedid {

struct DriveConstants {
    std::optional<double> torque_constant_Nm_per_A;  ///< K_t [N*m/A]
    std::optional<double> lead_m;                    ///< Ball-screw lead [m per screw revolution]
    double gear_ratio{1.0};                          ///< Motor revolutions per screw revolution
    std::optional<double> force_constant;            ///< [N (or N*m) per signal unit]
    std::string force_constant_name;                 ///< A trace constant to use as force_constant (e.g. "gtau")

    /// What is wrong with these options ("" when nothing).
    [[nodiscard]] std::string validate() const;
    /// N (or N*m) per unit of the current channel, resolving force_constant_name against the trace's constants.
    /// nullopt when no constant is given (then the current is taken as force only if the trace has a force channel).
    [[nodiscard]] std::optional<double> force_per_signal(const Trace& trace) const;
};

/// The drive force (torque) column: the trace's force channel when it has one, otherwise the current channel times
/// force_per_signal. Throws InputError saying what is missing.
std::vector<double> drive_force(const Trace& trace, const DriveConstants& constants);

/// The injected test signal as a force (torque) per sample: the injection channel, a signal added to the controller's
/// output before the drive. In N (N*m on a rotary axis; a torque on a linear axis is turned into force by the lead, as
/// for the force channel) it is taken as it is; otherwise it is in the drive signal's units and is converted as the
/// drive signal is (times force_per_signal). Empty when the trace has no injection channel. Throws InputError naming
/// both channels and units when the injection is in other units than the drive signal, or when no constant converts it.
std::vector<double> injection_force(const Trace& trace, const DriveConstants& constants);

}  // namespace feedid
