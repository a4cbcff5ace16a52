// The test plan's moves in time and the commanded state sampled along them (timeline.hpp).
#include "timeline.hpp"

#include <cmath>
#include <utility>

namespace feedid::detail {

namespace {

// A duration that is a whole number of samples, up to the rounding of the division, still gets its last sample.
constexpr double sample_count_rounding = 1e-9;

}  // namespace

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
            segment.profile =
                MotionProfile::rest_to_rest(std::abs(distance), move.feed, options.acceleration, options.jerk);
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

std::vector<MotionState> sample_timeline(const Timeline& timeline, double sample_time, double rest_before,
                                         double rest_after) {
    const double total = rest_before + timeline.duration + rest_after;
    const auto count = static_cast<std::size_t>(std::floor(total / sample_time + sample_count_rounding)) + 1;
    std::vector<MotionState> samples(count);
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
