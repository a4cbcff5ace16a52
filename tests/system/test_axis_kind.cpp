// The axis kind, decided once at import: from the position's unit, else the velocity's (a revolution speed is angular
// unless a lead makes it a table velocity); every role channel's unit must belong to that kind. Expected values are
// worked out by hand from the unit definitions (1 rev = 2*pi rad, 1 min = 60 s, 1 deg = pi/180 rad).
#include <gtest/gtest.h>

#include <numbers>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"
#include "testing.hpp"

using namespace feedid;
using feedid::testing::count_lines;
using feedid::testing::run_cli;
using feedid::testing::write_text;

namespace {

constexpr double pi = std::numbers::pi;

Trace imported(std::string_view text, const ImportOptions& options = {}) {
    Trace trace = parse_csv(text, "axis.csv");
    trace.source_path = "axis.csv";
    prepare_trace(trace, options);
    return trace;
}

std::string refusal(std::string_view text, const ImportOptions& options = {}) {
    try {
        (void)imported(text, options);
    } catch (const InputError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no InputError for:\n" << text;
    return {};
}

void expect_names(const std::string& message, const std::vector<std::string>& parts) {
    for (const auto& part : parts) EXPECT_NE(message.find(part), std::string::npos) << part << " in: " << message;
    const auto newline = message.find('\n');
    EXPECT_TRUE(newline == std::string::npos || newline + 1 == message.size()) << "one line: " << message;
}

ImportOptions with_lead(double lead_m, double gear_ratio = 1.0) {
    ImportOptions options;
    options.unit_context.lead_m = lead_m;
    options.unit_context.gear_ratio = gear_ratio;
    return options;
}

}  // namespace

TEST(AxisKind, DegreesAndRpmAreARotaryAxisWithoutALead) {
    // SINUMERIK writes a rotary axis's position in deg and its speed in rpm
    const Trace trace = imported("time [s],phi [deg],speed [rpm],T [Nm]\n0,90,60,1.5\n0.002,180,-30,-0.5\n");
    EXPECT_TRUE(trace.rotary);
    const auto* position = trace.find(Role::position);
    ASSERT_NE(position, nullptr);
    EXPECT_EQ(position->unit, "rad");
    EXPECT_NEAR(position->values[1], pi, 1e-15);
    const auto* velocity = trace.find("speed");
    ASSERT_NE(velocity, nullptr);
    EXPECT_EQ(velocity->unit, "rad/s");
    EXPECT_NEAR(velocity->values[0], 2.0 * pi, 1e-14);  // 60 rpm = 1 rev/s
    EXPECT_NEAR(velocity->values[1], -pi, 1e-14);
    EXPECT_EQ(trace.find("T")->unit, "N*m");
}

TEST(AxisKind, ALeadIsNotUsedOnARotaryAxis) {
    // --lead 360 on a rotary axis once gave m/s beside rad: the lead is now left out, and a finding says so
    const Trace trace = imported("time [s],phi [deg],speed [rpm]\n0,90,60\n0.002,180,-30\n", with_lead(0.360));
    EXPECT_TRUE(trace.rotary);
    EXPECT_EQ(trace.find("speed")->unit, "rad/s");
    EXPECT_NEAR(trace.find("speed")->values[0], 2.0 * pi, 1e-14);
    bool said = false;
    for (const auto& finding : trace.findings)
        said = said || finding.find("--lead 360 mm is not used") != std::string::npos;
    EXPECT_TRUE(said);
}

TEST(AxisKind, VelocityOnlyTracesTakeTheKindFromTheVelocityUnit) {
    const Trace angular = imported("time [s],speed [r/min]\n0,1500\n0.001,-600\n");
    EXPECT_TRUE(angular.rotary);
    EXPECT_NEAR(angular.find(Role::velocity)->values[0], 50.0 * pi, 1e-12);  // 25 rev/s
    const Trace degrees = imported("time [s],speed [deg/s]\n0,360\n0.001,-90\n");
    EXPECT_TRUE(degrees.rotary);
    EXPECT_NEAR(degrees.find(Role::velocity)->values[0], 2.0 * pi, 1e-14);
    // with a lead and a gear ratio the motor speed is a table velocity: 1500 rpm / 2 * 20 mm = 0.25 m/s
    const Trace table = imported("time [s],speed [r/min]\n0,1500\n0.001,-600\n", with_lead(0.020, 2.0));
    EXPECT_FALSE(table.rotary);
    EXPECT_EQ(table.find(Role::velocity)->unit, "m/s");
    EXPECT_NEAR(table.find(Role::velocity)->values[0], 0.25, 1e-15);
    EXPECT_NEAR(table.find(Role::velocity)->values[1], -0.1, 1e-15);
}

TEST(AxisKind, APositionWithoutAUnitFollowsTheVelocity) {
    const Trace trace = imported("time [s],pos,vel [deg/s]\n0,0.1,360\n0.001,0.2,-90\n");
    EXPECT_TRUE(trace.rotary);
    EXPECT_EQ(trace.find(Role::position)->unit, "rad");
}

TEST(AxisKind, LinearAxesStayLinear) {
    const Trace trace = imported("time [s],x [mm],v [mm/min],F [N]\n0,1,600,5\n0.001,2,-600,-5\n");
    EXPECT_FALSE(trace.rotary);
    const Trace no_units = imported("time,x,i\n0,1,2\n0.001,2,3\n");
    EXPECT_FALSE(no_units.rotary);
    EXPECT_EQ(no_units.find(Role::position)->unit, "m");
}

TEST(AxisKind, AMotorTorqueOnALinearAxisNeedsTheLead) {
    const std::string text = "time [s],x [mm],F [Nm]\n0,1,1.5\n0.001,2,-1.5\n";
    expect_names(refusal(text),
                 {"'F'", "'Nm'", "rotary unit", "axis is linear", "position channel 'x' in mm", "--lead"});
    const Trace trace = imported(text, with_lead(0.010));  // the drive turns it into force through the screw
    EXPECT_EQ(trace.find("F")->unit, "N*m");
    EXPECT_FALSE(trace.rotary);
}

TEST(AxisKind, UnitsOfTheOtherKindAreRefusedNamingChannelUnitAndKind) {
    // angular velocity on a linear axis
    expect_names(refusal("time [s],x [mm],v [deg/s]\n0,1,0\n0.001,2,3\n"),
                 {"axis.csv", "'v'", "'deg/s'", "rotary unit", "axis is linear"});
    // a revolution speed on a linear axis without a lead: the lead is what is missing
    expect_names(refusal("time [s],x [mm],v [rpm]\n0,1,0\n0.001,2,3\n"), {"'v'", "'rpm'", "axis is linear", "--lead"});
    // a table velocity on a rotary axis
    expect_names(refusal("time [s],phi [deg],v [mm/min]\n0,1,0\n0.001,2,3\n"),
                 {"'v'", "'mm/min'", "linear unit", "axis is rotary", "position channel 'phi' in deg"});
    // a force on a rotary axis
    expect_names(refusal("time [s],phi [deg],F [N]\n0,1,0\n0.001,2,3\n"),
                 {"'F'", "'N'", "linear unit", "axis is rotary"});
    // a drive signal in N on a rotary axis
    expect_names(refusal("time [s],phi [rad],i [N]\n0,1,0\n0.001,2,3\n"), {"'i'", "current", "axis is rotary"});
    // a reference position in deg beside a position in mm
    expect_names(refusal("time [s],x [mm],xref [deg]\n0,1,0\n0.001,2,3\n"),
                 {"'xref'", "reference_position", "'deg'", "axis is linear"});
}

TEST(AxisKind, TorqueInPercentOfTheRatedTorque) {
    // the MR Configurator2 drive logs torque in % of rated: 50 % of 2.4 N*m = 1.2 N*m
    ImportOptions options;
    options.unit_context.rated_value_si = 2.4;
    options.unit_context.rated_quantity = Quantity::torque;
    options.channels[Role::force] = "Torque";
    const Trace trace = imported("time [s],Speed [r/min],Torque [%]\n0,100,50\n0.001,-100,-25\n", options);
    EXPECT_TRUE(trace.rotary);
    EXPECT_EQ(trace.find("Torque")->unit, "N*m");
    EXPECT_NEAR(trace.find("Torque")->values[0], 1.2, 1e-15);
    EXPECT_NEAR(trace.find("Torque")->values[1], -0.6, 1e-15);
}

TEST(AxisKindCli, RefusalIsExitTwoWithOneLine) {
    const auto path = feedid::testing::temp_dir() / "mixed.csv";
    write_text(path, "time [s],phi [deg],v [mm/min]\n0,1,0\n0.001,2,3\n");
    const auto result = run_cli("info '" + path.string() + "'");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_EQ(count_lines(result.err), 1) << result.err;
    expect_names(result.err, {"'v'", "'mm/min'", "rotary"});
}

TEST(AxisKindCli, RatedTorqueOption) {
    const auto path = feedid::testing::temp_dir() / "percent.csv";
    write_text(path, "time [s],phi [deg],T [%]\n0,1,100\n0.001,2,-50\n");
    const auto result = run_cli("info '" + path.string() + "' --channel force=T --rated 2.4Nm --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    EXPECT_EQ(document.at("rotary"), true);
    const auto& torque = document.at("channels").at(2);
    EXPECT_EQ(torque.at("unit"), "N*m");
    EXPECT_NEAR(torque.at("max").get<double>(), 2.4, 1e-15);
    EXPECT_NEAR(torque.at("min").get<double>(), -1.2, 1e-15);
    const auto bad = run_cli("info '" + path.string() + "' --channel force=T --rated 2.4mm");
    EXPECT_EQ(bad.exit_code, 2);
    expect_names(bad.err, {"--rated 2.4mm", "'mm'"});
}

// A SINUMERIK trace states posn and velo without the axis kind: one statement that the axis is rotary holds for every
// such signal (deg, rpm), and the hint the import prints says so in words that work when pasted.
TEST(AxisKindCli, OneRotaryStatementCarriesOverToEverySinumerikSignal) {
    FEEDID_REQUIRE_SHARED("sinumerik-trace/X_BK300_1.xml");
    const std::string file = "'" + (feedid::testing::shared_data() / "sinumerik-trace/X_BK300_1.xml").string() + "'";
    const auto linear = run_cli("info " + file + " --json -");
    ASSERT_EQ(linear.exit_code, 0) << linear.err;
    std::string hint;
    const auto linear_document = nlohmann::json::parse(linear.out);
    for (const auto& finding : linear_document.at("findings")) {
        if (finding.get<std::string>().starts_with("SINUMERIK units taken")) hint = finding.get<std::string>();
    }
    ASSERT_FALSE(hint.empty());
    for (const std::string pasted : {"--rotary", "--unit position=deg", "--unit position=deg --unit velocity=rpm"}) {
        if (pasted.find("velocity") == std::string::npos) {
            EXPECT_NE(hint.find(pasted), std::string::npos) << pasted << " in: " << hint;
        }
        const auto result = run_cli("info " + file + " " + pasted + " --json -");
        ASSERT_EQ(result.exit_code, 0) << pasted << ": " << result.err;
        const auto document = nlohmann::json::parse(result.out);
        EXPECT_EQ(document.at("rotary"), true) << pasted;
        for (const auto& channel : document.at("channels")) {
            const std::string source = channel.at("source_unit");
            EXPECT_NE(source, "mm") << channel.at("name");
            EXPECT_NE(source, "mm/min") << channel.at("name");
            if (channel.at("role") == "motor_position" || channel.at("role") == "reference_position") {
                EXPECT_EQ(channel.at("unit"), "rad");
            }
            if (channel.at("role") == "velocity_command") {
                EXPECT_EQ(source, "rpm");
                EXPECT_EQ(channel.at("unit"), "rad/s");
            }
        }
    }
}

TEST(AxisKindCli, MessagesOnARotaryAxisNeverAskForALead) {
    FEEDID_REQUIRE_SHARED("sinumerik-trace/X_BK300_1.xml");
    const std::string file = "'" + (feedid::testing::shared_data() / "sinumerik-trace/X_BK300_1.xml").string() + "'";
    // identify works in the drive signal's units (this micro-step trace then fails as an analysis, exit 1); gains
    // needs the constant and says which
    const auto identified = run_cli("identify " + file + " --rotary");
    EXPECT_EQ(identified.exit_code, 1) << identified.err;
    EXPECT_EQ(identified.err.find("--lead"), std::string::npos) << identified.err;
    const auto gains = run_cli("gains " + file + " --rotary");
    EXPECT_EQ(gains.exit_code, 2) << gains.err;
    EXPECT_EQ(gains.err.find("--lead"), std::string::npos) << gains.err;
    EXPECT_NE(gains.err.find("--kt (and --gear-ratio)"), std::string::npos) << gains.err;
}

// feedid info describes a log of several axes (the University of Michigan mill's X1, Y1, Z1, S1, without a time
// column) instead of refusing it: every channel, the axes, and how to read one.
TEST(AxisKindCli, InfoDescribesAMultiAxisLogAndListsItsAxes) {
    FEEDID_REQUIRE_SHARED("umich-cnc-mill/experiment_01.csv");
    const std::string file = "'" + (feedid::testing::shared_data() / "umich-cnc-mill/experiment_01.csv").string() + "'";
    const auto result = run_cli("info " + file + " --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    EXPECT_EQ(document.at("axes"), nlohmann::json({"X1", "Y1", "Z1", "S1"}));
    EXPECT_TRUE(document.at("sample_time_s").is_null());
    EXPECT_EQ(document.at("samples"), 1055);
    EXPECT_GE(document.at("channels").size(), 40U);
    const auto text = run_cli("info " + file);
    ASSERT_EQ(text.exit_code, 0) << text.err;
    EXPECT_NE(text.out.find("X1, Y1, Z1, S1"), std::string::npos) << text.out;
    for (const std::string pasted : {"--sample-time 0.1", "--axis X1", "--axis X1 --sample-time 0.1"}) {
        const auto again = run_cli("info " + file + " " + pasted);
        EXPECT_EQ(again.exit_code, 0) << pasted << ": " << again.err;
    }
}
