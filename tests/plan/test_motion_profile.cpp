// The rest-to-rest motion profile against its closed form (duration, peak speed and acceleration, distance at every
// time), its limits kept over a sweep of moves, and the two users of it (the test plan's reference trajectory and the
// trajectory of a part program) commanding the same samples for the same move.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <string>

#include "feedid/plan/gcode_reader.hpp"
#include "feedid/plan/motion_profile.hpp"
#include "feedid/plan/test_plan.hpp"
#include "feedid/plan/trajectory.hpp"

namespace {

using feedid::MotionProfile;

// Closed form of a rest-to-rest move (independent of the implementation: no bisection, no pieces). Speeding up to v
// covers d(v) = v (v/a + a/j) / 2 when v >= a^2/j (a is reached), d(v) = v sqrt(v/j) otherwise; without a jerk limit
// d(v) = v^2 / (2a). A move with 2 d(v_max) > L peaks where 2 d(v) = L:
//   a reached:      v = a/2 (sqrt(a^2/j^2 + 4 L/a) - a/j);
//   a not reached:  v = (L^2 j / 4)^(1/3);
//   trapezoid:      v = sqrt(a L).
struct ClosedForm {
    double length{0.0};
    double jerk{0.0};  // 0: trapezoid
    double peak_speed{0.0};
    double jerk_time{0.0};      // T_j
    double constant_time{0.0};  // T_a - 2 T_j
    double cruise_time{0.0};
    double peak_acceleration{0.0};

    [[nodiscard]] double ramp_time() const { return 2.0 * jerk_time + constant_time; }
    [[nodiscard]] double duration() const { return 2.0 * ramp_time() + cruise_time; }

    // Distance after time t of speeding up from rest.
    [[nodiscard]] double speeding_up(double t) const {
        const double a = peak_acceleration;
        const double tj = jerk_time;
        if (t <= tj) return jerk * t * t * t / 6.0;
        const double s1 = jerk * tj * tj * tj / 6.0;
        const double v1 = jerk * tj * tj / 2.0;
        if (t <= tj + constant_time) return s1 + v1 * (t - tj) + a * (t - tj) * (t - tj) / 2.0;
        const double u = t - tj - constant_time;
        const double s2 = s1 + v1 * constant_time + a * constant_time * constant_time / 2.0;
        const double v2 = v1 + a * constant_time;
        return s2 + v2 * u + a * u * u / 2.0 - jerk * u * u * u / 6.0;
    }
    // Distance at time t: speeding up, cruising, and braking as speeding up backwards in time.
    [[nodiscard]] double position(double t) const {
        if (t <= 0.0) return 0.0;
        if (t >= duration()) return length;
        if (t <= ramp_time()) return speeding_up(t);
        if (t <= ramp_time() + cruise_time) return speeding_up(ramp_time()) + peak_speed * (t - ramp_time());
        return length - speeding_up(duration() - t);
    }
};

ClosedForm closed_form(double L, double v, double a, std::optional<double> j) {
    ClosedForm c;
    c.length = L;
    if (!j) {
        c.peak_speed = v * v / a <= L ? v : std::sqrt(a * L);
        c.constant_time = c.peak_speed / a;
        c.peak_acceleration = a;
        c.cruise_time = std::max(0.0, (L - c.peak_speed * c.peak_speed / a) / c.peak_speed);
        return c;
    }
    c.jerk = *j;
    const auto speeding_up_distance = [&](double s) {
        return s >= a * a / *j ? s * (s / a + a / *j) / 2.0 : s * std::sqrt(s / *j);
    };
    c.peak_speed = v;
    if (2.0 * speeding_up_distance(v) > L) {
        const double reaching_a = a / 2.0 * (std::sqrt(a * a / (*j * *j) + 4.0 * L / a) - a / *j);
        c.peak_speed = reaching_a >= a * a / *j ? reaching_a : std::cbrt(L * L * *j / 4.0);
    }
    if (c.peak_speed >= a * a / *j) {
        c.jerk_time = a / *j;
        c.constant_time = c.peak_speed / a - a / *j;
        c.peak_acceleration = a;
    } else {
        c.jerk_time = std::sqrt(c.peak_speed / *j);
        c.peak_acceleration = *j * c.jerk_time;
    }
    c.cruise_time = std::max(0.0, (L - 2.0 * speeding_up_distance(c.peak_speed)) / c.peak_speed);
    return c;
}

// Relative agreement of the profile with its closed form: the bisection and the pieces' sums round at ~1e-16.
constexpr double closed_form_tolerance = 1e-12;

void expect_closed_form(double L, double v, double a, std::optional<double> j, const std::string& name) {
    const auto profile = MotionProfile::rest_to_rest(L, v, a, j);
    const auto c = closed_form(L, v, a, j);
    EXPECT_NEAR(profile.duration, c.duration(), closed_form_tolerance * c.duration()) << name;
    EXPECT_NEAR(profile.peak_speed, c.peak_speed, closed_form_tolerance * v) << name;
    EXPECT_NEAR(profile.peak_acceleration, c.peak_acceleration, closed_form_tolerance * a) << name;
    EXPECT_NEAR(profile.jerk_time, c.jerk_time, closed_form_tolerance * c.duration()) << name;
    EXPECT_NEAR(profile.constant_acceleration_time, c.constant_time, closed_form_tolerance * c.duration()) << name;
    EXPECT_NEAR(profile.cruise_time, c.cruise_time, closed_form_tolerance * c.duration()) << name;
    EXPECT_DOUBLE_EQ(profile.at(profile.duration).position, L) << name;
    double peak_velocity = 0.0;
    double peak_acceleration = 0.0;
    for (int k = 0; k <= 1000; ++k) {
        const double t = profile.duration * k / 1000.0;
        const auto state = profile.at(t);
        EXPECT_NEAR(state.position, c.position(t), closed_form_tolerance * L) << name << " t " << t;
        peak_velocity = std::max(peak_velocity, state.velocity);
        peak_acceleration = std::max(peak_acceleration, std::abs(state.acceleration));
    }
    EXPECT_LE(peak_velocity, c.peak_speed * (1 + closed_form_tolerance)) << name;
    EXPECT_LE(peak_acceleration, c.peak_acceleration * (1 + closed_form_tolerance)) << name;
    // the peaks are reached: the speed in the middle of the move, the acceleration in the middle of speeding up
    EXPECT_NEAR(profile.at(c.duration() / 2).velocity, c.peak_speed, closed_form_tolerance * v) << name;
    const double accelerating = c.jerk_time + c.constant_time / 2;
    EXPECT_NEAR(profile.at(accelerating).acceleration, c.peak_acceleration, closed_form_tolerance * a) << name;
    EXPECT_NEAR(profile.at(c.duration() - accelerating).acceleration, -c.peak_acceleration, closed_form_tolerance * a)
        << name;
}

TEST(MotionProfile, AgreesWithTheClosedFormInEveryCase) {
    // trapezoid: cruising (t_acc 0.1 s, 5 mm each way, 0.2 s at 0.1 m/s), and a triangle peaking at sqrt(a L)
    expect_closed_form(0.030, 0.1, 1.0, std::nullopt, "trapezoid, cruising");
    expect_closed_form(0.004, 0.1, 1.0, std::nullopt, "trapezoid, triangle");
    // jerk-limited: reaching v and a; reaching a but not v; neither; reaching v but not a (v < a^2/j = 0.18 m/s)
    expect_closed_form(0.3, 0.5, 3.0, 50.0, "S-curve, seven phases");
    expect_closed_form(0.05, 0.5, 3.0, 50.0, "S-curve, no cruise");
    expect_closed_form(0.001, 0.5, 3.0, 50.0, "S-curve, jerk phases only");
    expect_closed_form(0.3, 0.1, 3.0, 50.0, "S-curve, acceleration not reached");
}

TEST(MotionProfile, AnExampleByHand) {
    // 30 mm at 6000 mm/min, 1 m/s^2, no jerk limit: 0.1 s to speed over 5 mm, 0.2 s cruising, 0.1 s braking
    const auto p = MotionProfile::rest_to_rest(0.030, 0.1, 1.0, std::nullopt);
    EXPECT_NEAR(p.duration, 0.4, 1e-15);
    EXPECT_NEAR(p.cruise_time, 0.2, 1e-15);
    EXPECT_NEAR(p.at(0.1).position, 0.005, 1e-15);
    EXPECT_NEAR(p.at(0.1).velocity, 0.1, 1e-15);
    EXPECT_NEAR(p.at(0.05).acceleration, 1.0, 1e-15);
    EXPECT_NEAR(p.at(0.35).acceleration, -1.0, 1e-15);
    EXPECT_NEAR(p.at(0.2).position, 0.015, 1e-15);
    EXPECT_EQ(p.pieces().size(), 3u);
    // nothing to move: an empty profile
    const auto none = MotionProfile::rest_to_rest(0.0, 0.1, 1.0, 10.0);
    EXPECT_EQ(none.duration, 0.0);
    EXPECT_TRUE(none.pieces().empty());
    EXPECT_EQ(none.at(1.0).position, 0.0);
}

// Over a sweep of moves from 1 um to 3 m, speeds, accelerations and jerks over decades: every sample keeps the
// limits, the pieces join without a jump in position, velocity or acceleration (a trapezoid's acceleration steps),
// their jerk is +-j or 0, and the move ends at rest exactly at its distance.
TEST(MotionProfile, KeepsItsLimitsOverASweepOfMoves) {
    std::mt19937 generator(7);
    std::uniform_real_distribution<double> decade(-1.0, 1.0);
    for (int n = 0; n < 2000; ++n) {
        const double L = std::pow(10.0, 3.0 * decade(generator) - 2.5);
        const double v = std::pow(10.0, decade(generator) - 1.0);
        const double a = std::pow(10.0, 1.5 * decade(generator) + 0.5);
        const std::optional<double> j =
            n % 3 == 0 ? std::nullopt : std::optional<double>(std::pow(10.0, 2.0 * decade(generator) + 2.0));
        const auto p = MotionProfile::rest_to_rest(L, v, a, j);
        const std::string name = "L " + std::to_string(L) + " v " + std::to_string(v) + " a " + std::to_string(a) +
                                 " j " + (j ? std::to_string(*j) : std::string("none"));
        constexpr double rounding = 1e-12;
        ASSERT_GT(p.duration, 0.0) << name;
        EXPECT_LE(p.peak_speed, v) << name;
        EXPECT_LE(p.peak_acceleration, a * (1 + rounding)) << name;
        double time = 0.0;
        const auto& pieces = p.pieces();
        for (std::size_t k = 0; k < pieces.size(); ++k) {
            const auto& piece = pieces[k];
            time += piece.duration;
            if (j) {
                EXPECT_TRUE(piece.jerk == 0.0 || std::abs(piece.jerk) == *j) << name;
            } else {
                EXPECT_EQ(piece.jerk, 0.0) << name;
            }
            if (k + 1 == pieces.size()) continue;
            // across the join: what moves in 2 eps at the largest speed, acceleration and jerk
            const double eps = 1e-10 * p.duration;
            const auto before = p.at(time - eps);
            const auto after = p.at(time + eps);
            EXPECT_NEAR(before.position, after.position, 4.0 * eps * v + rounding * L) << name;
            EXPECT_NEAR(before.velocity, after.velocity, 4.0 * eps * a + rounding * v) << name;
            if (j) {
                EXPECT_NEAR(before.acceleration, after.acceleration, 4.0 * eps * *j + rounding * a) << name;
            }
        }
        EXPECT_NEAR(time, p.duration, rounding * p.duration) << name;
        for (int k = 0; k <= 200; ++k) {
            const auto state = p.at(p.duration * k / 200.0);
            EXPECT_GE(state.velocity, 0.0) << name;
            EXPECT_LE(state.velocity, v * (1 + rounding)) << name;
            EXPECT_LE(std::abs(state.acceleration), a * (1 + rounding)) << name;
            EXPECT_GE(state.position, 0.0) << name;
            EXPECT_LE(state.position, L) << name;
        }
        const auto end = p.at(p.duration);
        EXPECT_EQ(end.position, L) << name;
        EXPECT_EQ(end.velocity, 0.0) << name;
        // the pieces' own end, integrated from their starts, is the distance to rounding
        const auto& last = pieces.back();
        const double t = last.duration;
        const double x = last.start.position + last.start.velocity * t + last.start.acceleration * t * t / 2.0 +
                         last.jerk * t * t * t / 6.0;
        EXPECT_NEAR(x, L, 1e-12 * L + 1e-18) << name;
    }
}

// One feed move planned both ways: as a test plan's move (its reference trajectory, half a second at rest before) and
// as the block of a part program (plan_trajectory, with X's limits the plan's acceleration and jerk). The sample
// times differ by the rounding of k * dt - 0.5 s against (k - 500) * dt, ~1e-16 s, so positions agree to far below a
// nanometre rather than to the bit.
TEST(MotionProfile, TheTestPlanAndThePartProgramCommandTheSameSamples) {
    constexpr double acceleration = 2.0;
    constexpr double jerk = 40.0;
    for (const std::string block : {"G1 X30 F3000", "G1 X0.5 F6000", "G1 X-120 F9000"}) {
        const auto program = feedid::read_gcode("G21 G90 G94\n" + block + "\nM2\n", "move.ngc");
        ASSERT_EQ(program.blocks.size(), 1u);
        const auto& move = program.blocks.front();

        feedid::MachineLimits limits;
        limits.axes[0] = {1.0, acceleration, jerk};
        limits.max_feed_m_per_s = 1.0;
        const auto trajectory = feedid::plan_trajectory(program, limits);

        feedid::TestPlan plan;
        plan.options.acceleration = acceleration;
        plan.options.jerk = jerk;
        plan.options.start_position = move.start[0];
        plan.moves.push_back({feedid::MoveKind::feed, move.end[0], move.feed_m_per_s, 0.0, 0, 0, block});
        const auto reference = feedid::reference_trajectory(plan);
        const auto x = reference.column(feedid::Role::reference_position);

        constexpr std::size_t rest_samples = 500;  // 0.5 s at 1 ms
        ASSERT_GE(x.size(), trajectory.samples() + rest_samples) << block;
        double largest = 0.0;
        for (std::size_t k = 0; k < trajectory.samples(); ++k) {
            largest = std::max(largest, std::abs(trajectory.position[0][k] - x[k + rest_samples]));
        }
        EXPECT_LE(largest, 1e-12) << block;
        EXPECT_EQ(x[trajectory.samples() + rest_samples - 1], move.end[0]) << block;
    }
}

}  // namespace
