#pragma once
// Friction of a feed drive, per direction (the paper's eq. 3, with per-direction parameters):
//   F_f(v) = B*v + F_C*sgn(v) + (F_B - F_C)*sgn(v)*exp(-|v|/v_s) + offset-free
// Forward parameters apply for v > 0, reverse for v < 0; all magnitudes are positive. A constant force offset
// (gravity on a vertical axis, a current-sensor offset) is part of the axis model, not of friction.
// Linear axes in N, N*s/m, m/s; rotary axes in N*m, N*m*s/rad, rad/s.

#include <cmath>
#include <optional>

namespace feedid {

/// The friction law, eq. (3), for one direction, with the Stribeck term unpacked. Every model of friction in feedid
/// evaluates it: the identified axis (FrictionBranch::magnitude), the simulator's time loop (no optionals to test, no
/// division, inline), the synthetic drive and step 2's curve fit.
struct FrictionLaw {
    double viscous{0.0};                    ///< B [N*s/m]
    double coulomb{0.0};                    ///< F_C [N]
    double stribeck_rise{0.0};              ///< F_B - F_C [N]; 0 = no Stribeck term
    double inverse_stribeck_velocity{0.0};  ///< 1/v_s [s/m]; 0 = no Stribeck term

    /// Friction magnitude at speed |v| = speed >= 0 [N].
    [[nodiscard]] double magnitude(double speed) const noexcept {
        // eq. (3): B*|v| + F_C + (F_B - F_C)*exp(-|v|/v_s)
        double value = viscous * speed + coulomb;
        if (stribeck_rise != 0.0) value += stribeck_rise * std::exp(-speed * inverse_stribeck_velocity);
        return value;
    }
};

struct FrictionBranch {
    double viscous{0.0};                      ///< B [N*s/m]
    double coulomb{0.0};                      ///< F_C [N]
    std::optional<double> breakaway;          ///< F_B [N]; none = no Stribeck term
    std::optional<double> stribeck_velocity;  ///< v_s [m/s]; none = no Stribeck term

    /// Friction magnitude at speed |v| = speed >= 0.
    [[nodiscard]] double magnitude(double speed) const { return law().magnitude(speed); }
    [[nodiscard]] bool has_stribeck() const { return breakaway && stribeck_velocity && *stribeck_velocity > 0.0; }
    /// The law unpacked (no Stribeck term without has_stribeck()).
    [[nodiscard]] FrictionLaw law() const;
};

struct Friction {
    FrictionBranch forward;
    FrictionBranch reverse;

    /// Same parameters in both directions.
    static Friction symmetric(const FrictionBranch& branch) { return {branch, branch}; }

    /// F_f(v), signed; 0 at v == 0 (static friction is handled by the simulator's stick logic).
    [[nodiscard]] double force(double velocity) const;
    /// The breakaway force the drive must exceed to start moving in a direction (F_B, or F_C without Stribeck).
    [[nodiscard]] double breakaway_force(bool forward_direction) const;
};

/// Mass and friction of one axis: M*x'' = F_d - F_f(x') - offset.
struct AxisModel {
    double mass{0.0};  ///< M [kg] (rotary: inertia [kg*m^2])
    Friction friction;
    double offset{0.0};  ///< Constant force [N] the drive must hold (gravity, sensor offset); F_d = ... + offset
    bool rotary{false};
};

}  // namespace feedid
