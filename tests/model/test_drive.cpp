// The drive force: from a force channel, from a current times a constant, and from a motor torque on a linear axis.
#include <gtest/gtest.h>

#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "feedid/model/drive.hpp"
#include "feedid/core/error.hpp"

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

TEST(DriveForce, ATorqueDriveSignalOnALinearAxisGoesThroughTheScrew) {
    // % of a rated torque mapped as the drive signal: already N*m at import; no K_t is needed, only lead and gear
    const auto trace = trace_with(feedid::Role::current, "N*m", {0.5, -1.0, 2.0});
    EXPECT_THROW((void)feedid::drive_force(trace, {}), feedid::InputError);
    feedid::DriveConstants drive;
    drive.lead_m = 0.020;
    drive.gear_ratio = 3.0;
    const auto force = feedid::drive_force(trace, drive);
    // F = T * 2*pi * g / lead = -1 N*m * 2*pi * 3 / 0.02 m = -942.477... N
    EXPECT_NEAR(force[1], -300.0 * std::numbers::pi, 1e-9);
    auto rotary = trace;
    rotary.rotary = true;
    EXPECT_EQ(feedid::drive_force(rotary, drive), (std::vector<double>{0.5, -1.0, 2.0}));
}

TEST(DriveForce, CurrentOnARotaryAxisIsATorqueWithoutTheLead) {
    auto trace = trace_with(feedid::Role::current, "A", {1.0, -2.0, 0.5});
    trace.rotary = true;
    feedid::DriveConstants drive;
    drive.torque_constant_Nm_per_A = 1.5;
    drive.gear_ratio = 10.0;  // a worm gear: 10 motor turns per table turn
    drive.lead_m = 0.010;     // not used on a rotary axis
    const auto torque = feedid::drive_force(trace, drive);
    EXPECT_NEAR(torque[1], -2.0 * 1.5 * 10.0, 1e-12);  // T = K_t * i * g
}

TEST(DriveConstantWarnings, EachNamesTheValueOutsideItsRange) {
    const auto warnings_of = [](std::optional<double> lead_m, std::optional<double> kt, double gear) {
        feedid::DriveConstants drive;
        drive.lead_m = lead_m;
        drive.torque_constant_Nm_per_A = kt;
        drive.gear_ratio = gear;
        return drive.warnings();
    };
    EXPECT_TRUE(warnings_of(0.010, 1.45, 1.0).empty());
    EXPECT_TRUE(warnings_of(0.5e-3, 0.01, 0.01).empty());  // the bounds themselves are plausible
    EXPECT_TRUE(warnings_of(100e-3, 500.0, 1000.0).empty());
    // the classic mistake: a 10 mm lead given as metres, --lead 0.01 (mm)
    const auto lead = warnings_of(0.01e-3, std::nullopt, 1.0);
    ASSERT_EQ(lead.size(), 1u);
    EXPECT_NE(lead[0].find("--lead 0.01 mm"), std::string::npos) << lead[0];
    EXPECT_NE(lead[0].find("0.5 to 100 mm"), std::string::npos) << lead[0];
    EXPECT_EQ(warnings_of(0.360, std::nullopt, 1.0).size(), 1u);  // 360 mm: a rotary table's degrees as a lead
    const auto kt = warnings_of(std::nullopt, 1450.0, 1.0);
    ASSERT_EQ(kt.size(), 1u);
    EXPECT_NE(kt[0].find("--kt 1450 N*m/A"), std::string::npos) << kt[0];
    EXPECT_EQ(warnings_of(std::nullopt, 0.005, 1.0).size(), 1u);
    const auto gear = warnings_of(std::nullopt, std::nullopt, 5000.0);
    ASSERT_EQ(gear.size(), 1u);
    EXPECT_NE(gear[0].find("--gear-ratio 5000"), std::string::npos) << gear[0];
    EXPECT_EQ(warnings_of(std::nullopt, std::nullopt, 0.001).size(), 1u);
    EXPECT_EQ(warnings_of(0.01e-3, 1000.0, 2000.0).size(), 3u);
}

}  // namespace
