#include "feedid/plan/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/plan/motion_profile.hpp"

namespace feedid {

namespace {

// A move shorter than this is no move [m] (a rounding remainder of a program's coordinates).
constexpr double shortest_move_m = 1e-12;
// Sweeps within this of zero are full circles [rad] (LinuxCNC: an arc that ends where it starts turns once).
constexpr double full_circle_tolerance_rad = 1e-9;

}  // namespace

std::string MachineLimits::validate() const {
    for (int axis = 0; axis < 3; ++axis) {
        const auto& a = axes[static_cast<std::size_t>(axis)];
        for (const double value : {a.velocity_m_per_s, a.acceleration_m_per_s2, a.jerk_m_per_s3}) {
            if (!(value > 0.0 && std::isfinite(value)))
                return fmt::format("axis {}: velocity, acceleration and jerk limits must be positive", "XYZ"[axis]);
        }
    }
    if (!(rapid_m_per_s > 0.0 && std::isfinite(rapid_m_per_s))) return "the rapid rate must be positive";
    if (!(max_feed_m_per_s > 0.0 && std::isfinite(max_feed_m_per_s))) return "the maximum feed must be positive";
    if (!std::isfinite(stock_top_m)) return "the stock top must be a number";
    if (!(sample_time_s > 0.0 && sample_time_s <= 1.0)) return "the sample time must be in (0, 1] s";
    return {};
}

namespace {

// A block's geometry as a function of the path length s, and its path limits.
struct PathSegment {
    double length{0.0};
    double speed{0.0};  // path limits [m/s], [m/s^2], [m/s^3]
    double acceleration{0.0};
    double jerk{0.0};
    bool arc{false};
    double theta0{0.0}, sweep{0.0};  // arcs: start angle, signed sweep [rad]
    double radius0{0.0}, radius1{0.0};
};

void line_limits(const GcodeBlock& block, const MachineLimits& limits, double programmed, PathSegment& segment) {
    segment.speed = programmed;
    segment.acceleration = segment.jerk = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < 3; ++i) {
        const double u = std::abs(block.end[i] - block.start[i]) / segment.length;
        if (u == 0.0) continue;
        segment.speed = std::min(segment.speed, limits.axes[i].velocity_m_per_s / u);
        segment.acceleration = std::min(segment.acceleration, limits.axes[i].acceleration_m_per_s2 / u);
        segment.jerk = std::min(segment.jerk, limits.axes[i].jerk_m_per_s3 / u);
    }
}

// See the header: centripetal acceleration and the jerk of the turning acceleration share the in-plane limits.
void arc_limits(const GcodeBlock& block, const MachineLimits& limits, double programmed, PathSegment& segment) {
    const auto& x = limits.axes[0];
    const auto& y = limits.axes[1];
    const auto& z = limits.axes[2];
    const double a_xy = std::min(x.acceleration_m_per_s2, y.acceleration_m_per_s2);
    const double j_xy = std::min(x.jerk_m_per_s3, y.jerk_m_per_s3);
    const double dz = block.end[2] - block.start[2];
    const double c = dz / std::abs(segment.sweep);                     // dz/dtheta
    const double radius = std::min(segment.radius0, segment.radius1);  // the tighter end bends more
    const double curvature = radius / (radius * radius + c * c);
    const double u_z = std::abs(dz) / segment.length;
    double speed = std::min({programmed, x.velocity_m_per_s, y.velocity_m_per_s, std::sqrt(a_xy / (2.0 * curvature)),
                             std::cbrt(j_xy / (3.0 * curvature * curvature))});
    double acceleration = std::min(a_xy / 2.0, j_xy / (9.0 * speed * curvature));
    double jerk = j_xy / 3.0;
    if (u_z > 0.0) {
        speed = std::min(speed, z.velocity_m_per_s / u_z);
        acceleration = std::min(acceleration, z.acceleration_m_per_s2 / u_z);
        jerk = std::min(jerk, z.jerk_m_per_s3 / u_z);
    }
    segment.speed = speed;
    segment.acceleration = acceleration;
    segment.jerk = jerk;
}

PathSegment segment_of(const GcodeBlock& block, const MachineLimits& limits) {
    PathSegment segment;
    const double programmed =
        block.kind == BlockKind::rapid ? limits.rapid_m_per_s : std::min(block.feed_m_per_s, limits.max_feed_m_per_s);
    if (block.kind == BlockKind::arc_cw || block.kind == BlockKind::arc_ccw) {
        segment.arc = true;
        const double sx = block.start[0] - block.center[0], sy = block.start[1] - block.center[1];
        const double ex = block.end[0] - block.center[0], ey = block.end[1] - block.center[1];
        segment.theta0 = std::atan2(sy, sx);
        segment.radius0 = std::hypot(sx, sy);
        segment.radius1 = std::hypot(ex, ey);
        const double direction = block.kind == BlockKind::arc_ccw ? 1.0 : -1.0;
        double sweep = direction * (std::atan2(ey, ex) - segment.theta0);
        while (sweep <= full_circle_tolerance_rad) sweep += 2.0 * std::numbers::pi;
        segment.sweep = direction * sweep;
        const double mean_radius = 0.5 * (segment.radius0 + segment.radius1);
        segment.length = std::hypot(mean_radius * sweep, block.end[2] - block.start[2]);
        arc_limits(block, limits, programmed, segment);
        return segment;
    }
    segment.length =
        std::hypot(block.end[0] - block.start[0], block.end[1] - block.start[1], block.end[2] - block.start[2]);
    if (segment.length > shortest_move_m) line_limits(block, limits, programmed, segment);
    return segment;
}

std::array<double, 3> point_at(const GcodeBlock& block, const PathSegment& segment, double s) {
    const double fraction = segment.length > 0.0 ? s / segment.length : 1.0;
    if (fraction >= 1.0) return block.end;
    std::array<double, 3> p{};
    if (segment.arc) {
        const double theta = segment.theta0 + segment.sweep * fraction;
        const double radius = segment.radius0 + (segment.radius1 - segment.radius0) * fraction;
        p[0] = block.center[0] + radius * std::cos(theta);
        p[1] = block.center[1] + radius * std::sin(theta);
        p[2] = block.start[2] + (block.end[2] - block.start[2]) * fraction;
        return p;
    }
    for (std::size_t i = 0; i < 3; ++i) p[i] = block.start[i] + (block.end[i] - block.start[i]) * fraction;
    return p;
}

void push_sample(Trajectory& out, const GcodeBlock& block, std::size_t index, const std::array<double, 3>& p,
                 double stock_top) {
    for (std::size_t i = 0; i < 3; ++i) out.position[i].push_back(p[i]);
    const bool rapid = block.kind == BlockKind::rapid;
    const bool feed = !rapid && block.kind != BlockKind::dwell;
    out.block.push_back(static_cast<std::int32_t>(index));
    out.rapid.push_back(rapid ? 1 : 0);
    out.feed.push_back(feed ? 1 : 0);
    out.cutting.push_back(feed && block.spindle_on && p[2] < stock_top ? 1 : 0);
    out.spindle_rpm.push_back(block.spindle_on ? block.spindle_rpm : 0.0);
}

}  // namespace

Trajectory plan_trajectory(const GcodeProgram& program, const MachineLimits& limits) {
    if (const auto problem = limits.validate(); !problem.empty()) throw InputError("machine limits: " + problem);
    if (program.blocks.empty()) throw InputError("the program has no motion");
    Trajectory out;
    const double dt = limits.sample_time_s;
    out.sample_time_s = dt;
    double block_start = 0.0;  // time at which the current block starts [s]
    std::size_t k = 0;
    for (std::size_t b = 0; b < program.blocks.size(); ++b) {
        const auto& block = program.blocks[b];
        double duration = block.dwell_s;
        PathSegment segment;
        MotionProfile curve;
        if (block.kind != BlockKind::dwell) {
            segment = segment_of(block, limits);
            if (segment.length <= shortest_move_m) continue;
            curve = MotionProfile::rest_to_rest(segment.length, segment.speed, segment.acceleration, segment.jerk);
            duration = curve.duration;
        }
        const double end = block_start + duration;
        for (; static_cast<double>(k) * dt < end; ++k) {
            const double tau = static_cast<double>(k) * dt - block_start;
            const auto p =
                block.kind == BlockKind::dwell ? block.end : point_at(block, segment, curve.at(tau).position);
            push_sample(out, block, b, p, limits.stock_top_m);
        }
        block_start = end;
    }
    push_sample(out, program.blocks.back(), program.blocks.size() - 1, program.blocks.back().end, limits.stock_top_m);
    return out;
}

}  // namespace feedid
