// feedid plan on the command line: outputs, refusals with exit code 2, the JSON plan and its prediction.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "testing.hpp"

namespace {

using feedid::testing::run_cli;

std::string quoted(const std::filesystem::path& path) {
    return "'" + path.string() + "'";
}

TEST(PlanCli, HelpShowsAWorkedExample) {
    const auto result = run_cli("plan --help");
    EXPECT_EQ(result.exit_code, 0);
    EXPECT_NE(result.out.find("Example"), std::string::npos);
    EXPECT_NE(result.out.find("feedid plan --axis X --travel=-400:400 --centers=-300,0,300"), std::string::npos);
    EXPECT_NE(result.out.find("feedid synth --reference ref.csv"), std::string::npos);
}

TEST(PlanCli, WritesProgramReferenceAndJson) {
    const auto dir = feedid::testing::temp_dir();
    for (const std::string dialect : {"iso", "sinumerik", "linuxcnc"}) {
        const auto program = dir / ("test." + dialect);
        const auto json = dir / ("plan-" + dialect + ".json");
        const auto result =
            run_cli("plan --axis X --travel=-400:400 --centers=-300,0,300 --dialect " + dialect + " -o " +
                    quoted(program) + " --json " + quoted(json) + " --reference " + quoted(dir / "ref.csv"));
        ASSERT_EQ(result.exit_code, 0) << result.err;
        const auto text = feedid::testing::read_text(program);
        EXPECT_NE(text.find("feedid "), std::string::npos);
        const auto document = nlohmann::json::parse(feedid::testing::read_text(json));
        EXPECT_EQ(document.at("centers_m").size(), 3u);
        EXPECT_EQ(document.at("passes").size(), 3u * 14u);
        EXPECT_GT(document.at("duration_s").get<double>(), 200.0);
        EXPECT_LT(document.at("duration_s").get<double>(), 300.0);
        for (const auto* key :
             {"mass_kg", "viscous_Ns_per_m", "coulomb_N", "breakaway_N", "stribeck_velocity_m_per_s"}) {
            EXPECT_TRUE(document.at("prediction").at("parameters").at(key).at("identifiable").get<bool>()) << key;
        }
        // The summary goes to stdout when no output is on stdout.
        EXPECT_NE(result.out.find("predicted duration"), std::string::npos);
    }
    // The reference reads back with its roles guessed from the names.
    const auto info = run_cli("info " + quoted(dir / "ref.csv") + " --json -");
    ASSERT_EQ(info.exit_code, 0) << info.err;
    const auto document = nlohmann::json::parse(info.out);
    ASSERT_EQ(document.at("channels").size(), 2u);
    EXPECT_EQ(document.at("channels").at(0).at("role"), "time");
    EXPECT_EQ(document.at("channels").at(1).at("role"), "reference_position");
    EXPECT_EQ(document.at("channels").at(1).at("unit"), "m");
    EXPECT_NEAR(document.at("sample_time_s").get<double>(), 0.001, 1e-12);
}

// The reversal test in the three dialects, and plan -> synth -> fingerprint recovering the synthetic axis's truth
// (backlash 8 um, stiffness 150 N/um: within 10 % and 4 standard errors).
TEST(PlanCli, ReversalTestPlanSynthFingerprintRecoversTheTruth) {
    const auto dir = feedid::testing::temp_dir();
    for (const std::string dialect : {"iso", "sinumerik", "linuxcnc"}) {
        const auto program = dir / ("reversal." + dialect);
        const auto result = run_cli("plan --test reversal --axis X --travel=-400:400 --centers=-300,0 --dialect " +
                                    dialect + " -o " + quoted(program) + " --reference " + quoted(dir / "rev.csv"));
        ASSERT_EQ(result.exit_code, 0) << result.err;
        const auto text = feedid::testing::read_text(program);
        EXPECT_NE(text.find("reversal test"), std::string::npos) << text.substr(0, 400);
        EXPECT_NE(text.find("-299.999"), std::string::npos) << "a 1 um micro-step below -300 mm";
    }
    const auto synth = run_cli("synth --reference " + quoted(dir / "rev.csv") + " --backlash 8 --stiffness 150 --out " +
                               quoted(dir / "rev-synth.csv"));
    ASSERT_EQ(synth.exit_code, 0) << synth.err;
    const auto fingerprint = run_cli("fingerprint " + quoted(dir / "rev-synth.csv") +
                                     " --force-constant force_constant_N_per_A --json -");
    ASSERT_EQ(fingerprint.exit_code, 0) << fingerprint.err;
    const auto document = nlohmann::json::parse(fingerprint.out);
    const auto& figures = document.at("fingerprint");
    for (const auto& [key, truth] : std::map<std::string, double>{{"backlash_m", 8e-6}, {"stiffness_N_per_m", 150e6}}) {
        ASSERT_FALSE(figures.at(key).at("value").is_null()) << document.dump(1);
        const double value = figures.at(key).at("value");
        const double stderr_value = figures.at(key).at("stderr");
        EXPECT_LE(std::abs(value - truth), 0.1 * truth) << key << " " << value;
        EXPECT_LE(std::abs(value - truth), 4.0 * stderr_value) << key << " " << value << " +/- " << stderr_value;
    }
    EXPECT_EQ(document.at("reversals").at("forward"), document.at("reversals").at("reverse"));
}

TEST(PlanCli, ProgramOnStdoutSummaryOnStderr) {
    const auto result = run_cli("plan --travel=-400:400 --centers=-300 --slow-feeds none --dialect linuxcnc -o -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_EQ(result.out.rfind("(feedid ", 0), 0u);
    EXPECT_NE(result.out.find("\nM2\n"), std::string::npos);
    EXPECT_NE(result.err.find("predicted duration"), std::string::npos);
}

TEST(PlanCli, RefusesAPlanThatLeavesTheTravel) {
    const auto result = run_cli("plan --travel=-400:400 --centers=0,390 --slow-feeds none -o /dev/null");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << result.err;
    EXPECT_NE(result.err.find("move 61 (centre 2 at 390.000 mm, 1250 mm/min, cycle 1, stroke +) goes to 405.000 mm, "
                              "5.000 mm beyond the travel maximum 400.000 mm"),
              std::string::npos)
        << result.err;
    EXPECT_TRUE(result.out.empty());
}

TEST(PlanCli, RefusesFeedsAboveTheLimitAndBadArguments) {
    auto result = run_cli("plan --travel=-400:400 --centers=0 --max-feed 6000 -o /dev/null");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.err.find("6650 mm/min, 650 mm/min above the feedrate limit 6000 mm/min"), std::string::npos)
        << result.err;
    for (const std::string arguments :
         {"--travel=400:-400 --centers=0", "--travel=abc --centers=0", "--travel=-400:400 --centers=0,x",
          "--travel=-400:400 --centers=0 --dialect fanuc", "--travel=-400:400 --centers=0 --slow-feeds 10:",
          "--travel=-400:400 --centers=0 --cycles 0", "--centers=0"}) {
        result = run_cli("plan " + arguments + " -o /dev/null");
        EXPECT_EQ(result.exit_code, 2) << arguments;
        EXPECT_FALSE(result.err.empty()) << arguments;
    }
}

TEST(PlanCli, PapersLadderAlonePredictsNoStribeck) {
    const auto result = run_cli("plan --travel=-400:400 --centers=-300 --slow-feeds none --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    const auto& parameters = document.at("prediction").at("parameters");
    EXPECT_TRUE(parameters.at("coulomb_N").at("identifiable").get<bool>());
    EXPECT_FALSE(parameters.at("breakaway_N").at("identifiable").get<bool>());
    EXPECT_FALSE(parameters.at("stribeck_velocity_m_per_s").at("identifiable").get<bool>());
    EXPECT_NE(result.err.find("F_B and v_s are not identifiable"), std::string::npos) << result.err;
    EXPECT_NE(result.err.find("NOT identifiable"), std::string::npos);
}

// A rotary table end to end: the plan in degrees, its reference run by the rotary demo drive (feedid synth --rotary),
// and identify finds the drive the plan predicted identifiable, each parameter within 0.5 % of the truth (v_s 1 %).
// Not within 4 combined uncertainties: on this well-excited table identify reports F_C to 0.002 % and B to 0.014 %,
// and finds F_C 0.02 % high and B 0.17 % low (10 and 12 uncertainties) from the acceleration phases, where the
// synthetic drive's current and position are offset in time (the steady-speed samples alone give B = 5.00); the
// preprocessing family does not vary that offset yet.
TEST(PlanCli, ARotaryTablePlannedInDegreesIsIdentifiedFromItsReference) {
    const auto dir = feedid::testing::temp_dir();
    const auto reference = dir / "c.csv";
    auto result =
        run_cli("plan --axis C --travel=-360:360 --centers=0,120 --dialect linuxcnc -o " + quoted(dir / "c.ngc") +
                " --reference " + quoted(reference) + " --json " + quoted(dir / "c.json"));
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_NE(result.out.find("v_s 0.05 rad/s; torque noise 0.04 N*m"), std::string::npos) << result.out;
    EXPECT_EQ(feedid::testing::read_text(dir / "c.ngc").find(" mm"), std::string::npos);
    const auto plan = nlohmann::json::parse(feedid::testing::read_text(dir / "c.json"));
    const auto& predicted = plan.at("prediction").at("parameters");
    const auto trace = dir / "c-synth.csv";
    result = run_cli("synth --rotary --reference " + quoted(reference) + " --out " + quoted(trace));
    ASSERT_EQ(result.exit_code, 0) << result.err;
    result = run_cli("identify " + quoted(trace) + " --kt 2 --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto identified = nlohmann::json::parse(result.out);
    EXPECT_EQ(identified.at("status"), "ok");
    const std::map<std::string, double> truth{{"inertia_kgm2", 2.0},
                                              {"viscous_Nms_per_rad", 5.0},
                                              {"coulomb_Nm", 20.0},
                                              {"breakaway_Nm", 26.0},
                                              {"stribeck_velocity_rad_per_s", 0.05}};
    for (const auto& [key, value] : truth) {
        ASSERT_TRUE(predicted.at(key).at("identifiable").get<bool>()) << key;
        const auto& estimate = identified.at("parameters").at(key);
        const double tolerance = key == "stribeck_velocity_rad_per_s" ? 0.01 : 0.005;
        EXPECT_NEAR(estimate.at("value").get<double>(), value, tolerance * value) << key;
    }
}

}  // namespace
