#pragma once
// The reference trajectory an NC's interpolator makes of a part program: per-axis reference positions every sample
// time, with the machine's limits. Every block starts and ends at rest (exact stop, G61) and follows a jerk-limited
// (S-curve, seven-phase) path-speed profile (motion_profile.hpp); its path limits come from the axis limits
// projected on the block:
//  - straight move along unit direction u: v <= min(F, v_i/|u_i|), a <= min a_i/|u_i|, j <= min j_i/|u_i|;
//  - arc (helix) of radius r, curvature k = r/(r^2 + c^2), c = dz/dtheta: the axis acceleration is bounded by the
//    tangential s'' plus the centripetal s'^2 k, and the jerk by s''' + s'^3 k^2 + 3 s' s'' k (the derivative of
//    s'' T + s'^2 k N): the planner takes v^2 k <= a_xy/2, v^3 k^2 <= j_xy/3, s'' <= min(a_xy/2, j_xy/(9 v k)) and
//    s''' <= j_xy/3, with a_xy, j_xy the smaller of X's and Y's limits, and Z's limits over |u_z|.
// Rapids (G0) run at the rapid rate capped by each axis' maximum velocity, feeds at F capped by the maximum feed.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "feedid/plan/gcode_reader.hpp"

namespace feedid {

struct AxisLimits {
    double velocity_m_per_s{0.5};       ///< maximum velocity [m/s] (30 m/min)
    double acceleration_m_per_s2{3.0};  ///< maximum acceleration [m/s^2]
    double jerk_m_per_s3{50.0};         ///< maximum jerk [m/s^3]
};

/// A job-shop vertical machining centre's limits (the defaults): X, Y, Z 30 m/min, 3 m/s^2, 50 m/s^3; rapid 30 m/min,
/// feed at most 10 m/min; the stock top at Z = 0; 1 ms interpolation cycle.
struct MachineLimits {
    std::array<AxisLimits, 3> axes{};      ///< X, Y, Z
    double rapid_m_per_s{0.5};             ///< G0 path speed [m/s]
    double max_feed_m_per_s{10.0 / 60.0};  ///< programmed feeds above this are capped [m/s]
    double stock_top_m{0.0};               ///< the tool cuts below this Z [m]
    double sample_time_s{1e-3};            ///< interpolation cycle and trace sample time [s]

    /// What is wrong ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// The reference, one entry per sample k (time k * sample_time_s).
struct Trajectory {
    double sample_time_s{1e-3};
    std::array<std::vector<double>, 3> position;  ///< X, Y, Z reference [m]
    std::vector<std::int32_t> block;              ///< index into the program's blocks
    std::vector<std::uint8_t> rapid;              ///< 1 in a G0 block
    std::vector<std::uint8_t> feed;               ///< 1 in a G1/G2/G3 block
    std::vector<std::uint8_t> cutting;            ///< 1 in a feed block with the spindle on and Z below the stock top
    std::vector<double> spindle_rpm;              ///< spindle speed [rpm], 0 when it is off

    [[nodiscard]] std::size_t samples() const { return block.size(); }
};

/// The reference of `program` with `limits`. InputError when the limits are invalid. Each block's end is reached
/// exactly (the sample after a block's end time holds it, as do dwells).
Trajectory plan_trajectory(const GcodeProgram& program, const MachineLimits& limits);

}  // namespace feedid
