#pragma once
// Internal to the test-plan code (test_plan.cpp, gcode_writer.cpp): rest-to-rest velocity profiles and the plan's timeline.

#include <optional>
#include <vector>

#include "feedid/plan/test_plan.hpp"

namespace feedid::detail {

struct ProfileState {
    double position{0.0};      ///< [m]
    double velocity{0.0};      ///< [m/s]
    double acceleration{0.0};  ///< [m/s^2]
};

/// A rest-to-rest move along +distance as pieces of constant jerk (trapezoid: zero jerk, acceleration steps).
struct Profile {
    struct Piece {
        double duration;
        double x0;
        double v0;
        double a0;
        double jerk;
    };
    std::vector<Piece> pieces;
    double duration{0.0};     ///< [s]
    double distance{0.0};     ///< [m]
    double peak_speed{0.0};   ///< [m/s] (below the feed when the move is too short to reach it)
    double cruise_time{0.0};  ///< time at the feedrate [s]

    /// State at time t after the move's start (clamped to [0, duration]).
    [[nodiscard]] ProfileState at(double t) const;
};

Profile make_profile(double distance, double feed, double acceleration, std::optional<double> jerk);

struct TimelineSegment {
    double start_time{0.0};
    double duration{0.0};
    double start_position{0.0};
    double direction{1.0};
    Profile profile;
    const Move* move{nullptr};
};

struct Timeline {
    std::vector<TimelineSegment> segments;
    double duration{0.0};
    double end_position{0.0};
};

Timeline make_timeline(const TestPlan& plan);

/// The commanded state every sample_time from rest_before seconds before the program to rest_after after its end.
std::vector<ProfileState> sample_timeline(const Timeline& timeline, double sample_time, double rest_before,
                                          double rest_after);

}  // namespace feedid::detail
