// Rest-to-rest velocity profiles of the test plan's moves and the plan's timeline (declared in motion_profile.hpp).
#include "motion_profile.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace feedid::detail {

namespace {

// Halvings of the bisection for the peak speed of a short move: 2^-200 of the feedrate is far below double precision.
constexpr int peak_speed_bisections = 200;
// A duration that is a whole number of samples, up to the rounding of the division, still gets its last sample.
constexpr double sample_count_rounding = 1e-9;

// Acceleration phase of a jerk-limited profile from rest to speed v: constant-jerk ramps of T_j = a/j around a
// constant-acceleration part when v >= a^2/j, otherwise two ramps of sqrt(v/j) with a peak acceleration below a.
// By symmetry the distance covered is v * T_acc / 2.
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

}  // namespace

Profile make_profile(double distance, double feed, double acceleration, std::optional<double> jerk) {
    Profile profile;
    if (distance <= 0.0 || feed <= 0.0) return profile;
    const auto accelerating_distance = [&](double speed) {
        return speed * acceleration_phase(speed, acceleration, jerk).time() / 2.0;
    };
    double peak_speed = feed;
    if (2.0 * accelerating_distance(feed) > distance) {
        // Too short to reach the feedrate: the largest peak speed whose acceleration and braking fit the distance.
        double low = 0.0;
        double high = feed;
        for (int iteration = 0; iteration < peak_speed_bisections; ++iteration) {
            const double middle = 0.5 * (low + high);
            (2.0 * accelerating_distance(middle) <= distance ? low : high) = middle;
        }
        peak_speed = low;
    }
    const auto phase = acceleration_phase(peak_speed, acceleration, jerk);
    const double cruise = std::max(0.0, (distance - 2.0 * accelerating_distance(peak_speed)) / peak_speed);
    profile.peak_speed = peak_speed;
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
    double x = 0.0;
    double v = 0.0;
    double a = 0.0;
    for (const auto& spec : specs) {
        if (spec.set_acceleration) a = *spec.set_acceleration;
        if (spec.duration <= 0.0) continue;
        profile.pieces.push_back({spec.duration, x, v, a, spec.jerk});
        const double t = spec.duration;
        x += v * t + a * t * t / 2.0 + spec.jerk * t * t * t / 6.0;
        v += a * t + spec.jerk * t * t / 2.0;
        a += spec.jerk * t;
        profile.duration += t;
    }
    profile.distance = distance;
    return profile;
}

ProfileState Profile::at(double t) const {
    if (pieces.empty() || t >= duration) return {distance, 0.0, 0.0};
    if (t <= 0.0) return {0.0, 0.0, 0.0};
    for (const auto& piece : pieces) {
        if (t <= piece.duration) {
            const double x = piece.x0 + piece.v0 * t + piece.a0 * t * t / 2.0 + piece.jerk * t * t * t / 6.0;
            const double v = piece.v0 + piece.a0 * t + piece.jerk * t * t / 2.0;
            const double a = piece.a0 + piece.jerk * t;
            return {std::min(x, distance), std::max(v, 0.0), a};
        }
        t -= piece.duration;
    }
    return {distance, 0.0, 0.0};
}

Timeline make_timeline(const TestPlan& plan) {
    Timeline timeline;
    const auto& options = plan.options;
    double position = options.start_position.value_or(plan.moves.empty() ? 0.0 : plan.moves.front().target);
    double time = 0.0;
    for (const auto& move : plan.moves) {
        TimelineSegment segment;
        segment.start_time = time;
        segment.start_position = position;
        segment.move = &move;
        if (move.kind == MoveKind::dwell) {
            segment.duration = move.dwell;
        } else {
            const double distance = move.target - position;
            segment.direction = distance >= 0.0 ? 1.0 : -1.0;
            segment.profile = make_profile(std::abs(distance), move.feed, options.acceleration, options.jerk);
            segment.duration = segment.profile.duration;
            position = move.target;
        }
        time += segment.duration;
        timeline.segments.push_back(std::move(segment));
    }
    timeline.duration = time;
    timeline.end_position = position;
    return timeline;
}

std::vector<ProfileState> sample_timeline(const Timeline& timeline, double sample_time, double rest_before,
                                          double rest_after) {
    const double total = rest_before + timeline.duration + rest_after;
    const auto count = static_cast<std::size_t>(std::floor(total / sample_time + sample_count_rounding)) + 1;
    std::vector<ProfileState> samples(count);
    const double first_position =
        timeline.segments.empty() ? timeline.end_position : timeline.segments.front().start_position;
    std::size_t segment_index = 0;
    for (std::size_t k = 0; k < count; ++k) {
        const double t = static_cast<double>(k) * sample_time - rest_before;
        if (t < 0.0 || timeline.segments.empty()) {
            samples[k] = {first_position, 0.0, 0.0};
            continue;
        }
        while (segment_index + 1 < timeline.segments.size() &&
               t >= timeline.segments[segment_index].start_time + timeline.segments[segment_index].duration) {
            ++segment_index;
        }
        const auto& segment = timeline.segments[segment_index];
        const double local = t - segment.start_time;
        if (local >= segment.duration) {  // after the last segment
            samples[k] = {timeline.end_position, 0.0, 0.0};
            continue;
        }
        if (segment.move->kind == MoveKind::dwell) {
            samples[k] = {segment.start_position, 0.0, 0.0};
        } else {
            const auto state = segment.profile.at(local);
            samples[k] = {segment.start_position + segment.direction * state.position,
                          segment.direction * state.velocity, segment.direction * state.acceleration};
        }
    }
    return samples;
}

}  // namespace feedid::detail
