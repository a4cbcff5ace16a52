#pragma once
// One rest-to-rest move as an NC's interpolator runs it under exact stop: the speed along the path rises from rest to
// a peak, holds it, and falls back to rest, in pieces of constant jerk. With a jerk limit j (SINUMERIK SOFT) seven
// phases: jerk +j, 0, -j, cruise, -j, 0, +j; without one (BRISK) a trapezoid: acceleration steps to +a, cruise, -a.
// Speeding up from rest to a speed v takes T_j = a/j at each end of a constant-acceleration part of v/a - a/j when
// v >= a^2/j, otherwise two jerk phases of sqrt(v/j) that peak at sqrt(v j) < a; the speed is point-symmetric about
// the middle of the phase, so it covers v * T_acc / 2. A move too short to reach its speed limit peaks at the largest
// speed whose speeding up and braking fit its distance, and does not cruise.
// Used by the test plan (its moves, duration and reference trajectory) and by the trajectory of a part program.

#include <array>
#include <cstddef>
#include <optional>
#include <span>

namespace feedid {

/// The commanded state at one time of a move, along its direction of travel.
struct MotionState {
    double position{0.0};      ///< from the move's start [m or rad]
    double velocity{0.0};      ///< [m/s or rad/s]
    double acceleration{0.0};  ///< [m/s^2 or rad/s^2]
};

/// A rest-to-rest move as pieces of constant jerk (see the top of the file).
struct MotionProfile {
    /// A piece of constant jerk and the state at its start.
    struct Piece {
        double duration{0.0};  ///< [s]
        MotionState start;
        double jerk{0.0};  ///< [m/s^3 or rad/s^3]; 0 in a trapezoid, whose acceleration steps between pieces
    };

    double distance{0.0};                    ///< [m or rad]
    double duration{0.0};                    ///< [s]
    double peak_speed{0.0};                  ///< below the speed limit when the move is too short to reach it [m/s]
    double peak_acceleration{0.0};           ///< below the limit when the speed is reached before it [m/s^2]
    double jerk_time{0.0};                   ///< each jerk phase, 0 in a trapezoid [s]
    double constant_acceleration_time{0.0};  ///< the constant-acceleration part of speeding up (and of braking) [s]
    double cruise_time{0.0};                 ///< time at the peak speed [s]

    /// The state at time t after the start, t clamped to [0, duration]: at rest at 0 before, at `distance` after.
    [[nodiscard]] MotionState at(double t) const;
    /// The pieces of positive duration, in order.
    [[nodiscard]] std::span<const Piece> pieces() const { return {pieces_.data(), piece_count_}; }

    /// The fastest rest-to-rest move over `distance` [m or rad] under the limits `speed` [m/s], `acceleration`
    /// [m/s^2] and, when given, `jerk` [m/s^3], all > 0. A distance or speed <= 0 gives an empty profile (duration 0,
    /// at() is the start).
    [[nodiscard]] static MotionProfile rest_to_rest(double distance, double speed, double acceleration,
                                                    std::optional<double> jerk);

private:
    std::array<Piece, 7> pieces_{};
    std::size_t piece_count_{0};
};

}  // namespace feedid
