#pragma once
// Internal to the test-plan code (test_plan.cpp): the plan's moves one after the other in time, each a rest-to-rest
// motion profile (feedid/plan/motion_profile.hpp), and the commanded state sampled along them.

#include <vector>

#include "feedid/plan/motion_profile.hpp"
#include "feedid/plan/test_plan.hpp"

namespace feedid::detail {

struct TimelineSegment {
    double start_time{0.0};
    double duration{0.0};
    double start_position{0.0};
    double direction{1.0};
    MotionProfile profile;
    const Move* move{nullptr};
};

struct Timeline {
    std::vector<TimelineSegment> segments;
    double duration{0.0};
    double end_position{0.0};
};

Timeline make_timeline(const TestPlan& plan);

/// The commanded state every sample_time from rest_before seconds before the program to rest_after after its end.
std::vector<MotionState> sample_timeline(const Timeline& timeline, double sample_time, double rest_before,
                                         double rest_after);

}  // namespace feedid::detail
