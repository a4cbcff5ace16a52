// The drive force: from a force channel, from a current times a constant, and from a motor torque on a linear axis.
#include <gtest/gtest.h>

#include <numbers>

#include "feedid/drive.hpp"
#include "feedid/error.hpp"

namespace {

feedid::Trace trace_with(feedid::Role role, const std::string& unit, std::vector<double> values) {
    feedid::Trace trace;
    trace.set("t", feedid::Role::time, "s", {0.0, 0.001, 0.002});
    trace.set("x", feedid::Role::position, "m", {0.0, 0.0, 0.0});
    trace.set("signal", role, unit, std::move(values));
    return trace;
}

TEST(DriveForce, CurrentTimesTorqueConstantThroughTheScrew) {
    const auto trace = trace_with(feedid::Role::current, "A", {1.0, -2.0, 0.5});
    feedid::DriveConstants drive;
    drive.torque_constant_Nm_per_A = 1.5;
    drive.lead_m = 0.01;
    drive.gear_ratio = 2.0;
    const auto force = feedid::drive_force(trace, drive);
    const double factor = 1.5 * 2.0 * std::numbers::pi * 2.0 / 0.01;  // K_t * 2*pi * g / lead
    ASSERT_EQ(force.size(), 3u);
    EXPECT_NEAR(force[1], -2.0 * factor, 1e-9 * factor);
}

TEST(DriveForce, AMotorTorqueOnALinearAxisNeedsTheLead) {
    const auto trace = trace_with(feedid::Role::force, "N*m", {0.1, -0.2, 0.3});
    EXPECT_THROW((void)feedid::drive_force(trace, {}), feedid::InputError);
    feedid::DriveConstants drive;
    drive.lead_m = 0.01;
    const auto force = feedid::drive_force(trace, drive);
    EXPECT_NEAR(force[2], 0.3 * 2.0 * std::numbers::pi / 0.01, 1e-9);
}

TEST(DriveForce, ATorqueOnARotaryAxisIsTheDriveTorque) {
    auto trace = trace_with(feedid::Role::force, "N*m", {0.1, -0.2, 0.3});
    trace.rotary = true;
    EXPECT_EQ(feedid::drive_force(trace, {}), (std::vector<double>{0.1, -0.2, 0.3}));
}

TEST(DriveForce, ACurrentWithoutAConstantIsRefusedNamingTheOptions) {
    const auto trace = trace_with(feedid::Role::current, "A", {1.0, 2.0, 3.0});
    try {
        (void)feedid::drive_force(trace, {});
        FAIL() << "no exception";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("--kt"), std::string::npos) << e.what();
    }
}

}  // namespace
