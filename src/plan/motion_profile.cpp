// Rest-to-rest moves in pieces of constant jerk (motion_profile.hpp).
#include "feedid/plan/motion_profile.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace feedid {

namespace {

// Halvings of the bisection for the peak speed of a short move: 2^-200 of the speed limit is far below double
// precision (the bracket is two neighbouring doubles after about 60).
constexpr int peak_speed_bisections = 200;

// Speeding up from rest to `speed` (see the header): jerk phases of T_j around a constant-acceleration part.
struct AccelerationPhase {
    double ramp{0.0};      // T_j [s]
    double constant{0.0};  // constant-acceleration time [s]
    double peak{0.0};      // peak acceleration [m/s^2]
    [[nodiscard]] double time() const { return 2.0 * ramp + constant; }
};

AccelerationPhase acceleration_phase(double speed, double acceleration, std::optional<double> jerk) {
    AccelerationPhase phase;
    if (!jerk) {
        phase.constant = speed / acceleration;
        phase.peak = acceleration;
        return phase;
    }
    const double j = *jerk;
    if (speed >= acceleration * acceleration / j) {
        phase.ramp = acceleration / j;
        phase.constant = speed / acceleration - acceleration / j;
        phase.peak = acceleration;
    } else {
        phase.ramp = std::sqrt(speed / j);
        phase.peak = j * phase.ramp;
    }
    return phase;
}

// The state after time t of constant jerk from `start`.
MotionState advance(const MotionState& start, double jerk, double t) {
    return {start.position + start.velocity * t + start.acceleration * t * t / 2.0 + jerk * t * t * t / 6.0,
            start.velocity + start.acceleration * t + jerk * t * t / 2.0, start.acceleration + jerk * t};
}

}  // namespace

MotionProfile MotionProfile::rest_to_rest(double distance, double speed, double acceleration,
                                          std::optional<double> jerk) {
    MotionProfile profile;
    if (distance <= 0.0 || speed <= 0.0) return profile;
    const auto accelerating_distance = [&](double v) {
        return v * acceleration_phase(v, acceleration, jerk).time() / 2.0;
    };
    double peak_speed = speed;
    if (2.0 * accelerating_distance(speed) > distance) {
        // Too short to reach the speed limit: the largest peak speed whose speeding up and braking fit the distance.
        double low = 0.0;
        double high = speed;
        for (int iteration = 0; iteration < peak_speed_bisections; ++iteration) {
            const double middle = 0.5 * (low + high);
            (2.0 * accelerating_distance(middle) <= distance ? low : high) = middle;
        }
        peak_speed = low;
    }
    const auto phase = acceleration_phase(peak_speed, acceleration, jerk);
    const double cruise = std::max(0.0, (distance - 2.0 * accelerating_distance(peak_speed)) / peak_speed);
    profile.distance = distance;
    profile.peak_speed = peak_speed;
    profile.peak_acceleration = phase.peak;
    profile.jerk_time = phase.ramp;
    profile.constant_acceleration_time = phase.constant;
    profile.cruise_time = cruise;

    // Pieces of constant jerk; the trapezoid sets its acceleration at each piece start (infinite jerk).
    struct Spec {
        double duration;
        double jerk;
        std::optional<double> set_acceleration;
    };
    std::vector<Spec> specs;
    if (!jerk) {
        specs = {{phase.constant, 0.0, phase.peak}, {cruise, 0.0, 0.0}, {phase.constant, 0.0, -phase.peak}};
    } else {
        const double j = *jerk;
        specs = {{phase.ramp, j, 0.0}, {phase.constant, 0.0, {}}, {phase.ramp, -j, {}}, {cruise, 0.0, 0.0},
                 {phase.ramp, -j, {}}, {phase.constant, 0.0, {}}, {phase.ramp, j, {}}};
    }
    MotionState state;
    for (const auto& spec : specs) {
        if (spec.set_acceleration) state.acceleration = *spec.set_acceleration;
        if (spec.duration <= 0.0) continue;
        profile.pieces_[profile.piece_count_++] = {spec.duration, state, spec.jerk};
        const double t = spec.duration;
        state.position += state.velocity * t + state.acceleration * t * t / 2.0 + spec.jerk * t * t * t / 6.0;
        state.velocity += state.acceleration * t + spec.jerk * t * t / 2.0;
        state.acceleration += spec.jerk * t;
        profile.duration += t;
    }
    return profile;
}

MotionState MotionProfile::at(double t) const {
    if (piece_count_ == 0 || t >= duration) return {distance, 0.0, 0.0};
    if (t <= 0.0) return {0.0, 0.0, 0.0};
    for (const auto& piece : pieces()) {
        if (t <= piece.duration) {
            const auto state = advance(piece.start, piece.jerk, t);
            return {std::min(state.position, distance), std::max(state.velocity, 0.0), state.acceleration};
        }
        t -= piece.duration;
    }
    return {distance, 0.0, 0.0};
}

}  // namespace feedid
