// Round trip through the command line, as a user runs it: `feedid synth` with known parameters and P-PI gains, then
// `feedid identify` and `feedid gains` on its output recover them; `feedid simulate` prints the paper's validation
// table. For a symmetric drive, an asymmetric one and a vertical axis with an offset.
#include <cmath>
#include <sstream>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/model/drive.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/io/import.hpp"
#include "feedid/sim/synth.hpp"
#include "testing.hpp"

namespace {

using feedid::testing::run_cli;

std::string quoted(const std::filesystem::path& path) {
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on "'" + string + "'".
    std::string text(1, '\'');
    text.append(path.string());
    text.push_back('\'');
    return text;
}

struct Drive {
    std::string name;
    std::string json;                     // the drive file
    std::string identify_options;         // model and offset
    std::map<std::string, double> truth;  // result-document key -> true value
    double position_gain;
    double velocity_gain;
    double integral_gain;
};

// Tolerances of the identification issue's synthetic round trip (with slow passes).
double tolerance_for(const std::string& key) {
    if (key.starts_with("breakaway")) return 0.05;
    if (key.starts_with("stribeck_velocity")) return 0.15;
    return 0.02;  // mass, viscous, Coulomb (and the offset)
}

void round_trip(const Drive& drive) {
    const auto dir = feedid::testing::temp_dir();
    feedid::testing::write_text(dir / "drive.json", drive.json);
    const auto trace = dir / "synth.csv";
    const auto synth = run_cli("synth --drive " + quoted(dir / "drive.json") + " --out " + quoted(trace));
    ASSERT_EQ(synth.exit_code, 0) << synth.err;

    // Gains within 3 %.
    const auto gains = run_cli("gains " + quoted(trace) + " --force-constant force_constant_N_per_A --json " +
                               quoted(dir / "gains.json"));
    ASSERT_EQ(gains.exit_code, 0) << gains.err;
    const auto gain_document = nlohmann::json::parse(feedid::testing::read_text(dir / "gains.json"));
    const auto& g = gain_document["gains"];
    EXPECT_NEAR(g["position_gain_per_s"]["value"].get<double>(), drive.position_gain, 0.03 * drive.position_gain);
    EXPECT_NEAR(g["velocity_gain_N_s_per_m"]["value"].get<double>(), drive.velocity_gain, 0.03 * drive.velocity_gain);
    ASSERT_TRUE(g["velocity_integral_gain_N_per_m"]["value"].is_number()) << gain_document.dump(2);
    EXPECT_NEAR(g["velocity_integral_gain_N_per_m"]["value"].get<double>(), drive.integral_gain,
                0.03 * drive.integral_gain);
    EXPECT_NEAR(gain_document["nc_units"]["tn_ms"].get<double>(), 1e3 * drive.velocity_gain / drive.integral_gain,
                0.03 * 1e3 * drive.velocity_gain / drive.integral_gain);

    // Parameters within the identification issue's tolerances.
    const auto identified = run_cli("identify " + quoted(trace) + " --force-constant force_constant_N_per_A " +
                                    drive.identify_options + " --json " + quoted(dir / "result.json"));
    ASSERT_EQ(identified.exit_code, 0) << identified.err;
    const auto result = nlohmann::json::parse(feedid::testing::read_text(dir / "result.json"));
    for (const auto& [key, truth] : drive.truth) {
        const auto& entry = result["parameters"][key]["value"];
        ASSERT_TRUE(entry.is_number()) << key << " is not identified: " << result["diagnostics"].dump();
        EXPECT_NEAR(entry.get<double>(), truth, tolerance_for(key) * std::abs(truth)) << drive.name << ": " << key;
    }

    // The digital twin: the identified axis with the identified gains tracks like the synthetic machine.
    const auto simulated =
        run_cli("simulate " + quoted(trace) + " --force-constant force_constant_N_per_A --result " +
                quoted(dir / "result.json") + " --gains " + quoted(dir / "gains.json") + " --json -");
    ASSERT_EQ(simulated.exit_code, 0) << simulated.err;
    const auto validation = nlohmann::json::parse(simulated.out);
    const double model = validation["tracking_error_mae_m"]["model"].get<double>();
    const double machine = validation["tracking_error_mae_m"]["machine"].get<double>();
    EXPECT_NEAR(model, machine, 0.02 * machine) << drive.name;
    EXPECT_LT(validation["modelling_error_mae_m"].get<double>(), 0.02 * machine) << drive.name;
    EXPECT_LT(validation["relative_error_pct"]["force"].get<double>(), 10.0) << drive.name;
}

TEST(TwinRoundTrip, SymmetricDrive) {
    round_trip({"symmetric",
                R"({"axis": {"mass_kg": 120, "viscous_Ns_per_m": 800, "coulomb_N": 300, "breakaway_N": 400,
                             "stribeck_velocity_m_per_s": 0.005},
                    "controller": {"kv_m_per_min_per_mm": 2.5, "velocity_gain_N_s_per_m": 40000, "tn_ms": 15},
                    "seed": 11})",
                "--model symmetric",
                {{"mass_kg", 120},
                 {"viscous_Ns_per_m", 800},
                 {"coulomb_N", 300},
                 {"breakaway_N", 400},
                 {"stribeck_velocity_m_per_s", 0.005}},
                feedid::position_gain_from_kv(2.5),
                40000,
                40000 / 0.015});
}

TEST(TwinRoundTrip, AsymmetricDrive) {
    round_trip({"asymmetric",
                R"({"axis": {"mass_kg": 90, "viscous_forward_Ns_per_m": 700, "viscous_reverse_Ns_per_m": 900,
                             "coulomb_forward_N": 280, "coulomb_reverse_N": 340,
                             "breakaway_forward_N": 380, "breakaway_reverse_N": 430,
                             "stribeck_velocity_forward_m_per_s": 0.004, "stribeck_velocity_reverse_m_per_s": 0.006},
                    "controller": {"kv_m_per_min_per_mm": 2, "velocity_gain_N_s_per_m": 35000, "tn_ms": 20},
                    "seed": 12})",
                "--model asymmetric",
                {{"mass_kg", 90},
                 {"viscous_forward_Ns_per_m", 700},
                 {"viscous_reverse_Ns_per_m", 900},
                 {"coulomb_forward_N", 280},
                 {"coulomb_reverse_N", 340},
                 {"breakaway_forward_N", 380},
                 {"breakaway_reverse_N", 430},
                 {"stribeck_velocity_forward_m_per_s", 0.004},
                 {"stribeck_velocity_reverse_m_per_s", 0.006}},
                feedid::position_gain_from_kv(2.0),
                35000,
                35000 / 0.020});
}

TEST(TwinRoundTrip, VerticalAxisWithOffset) {
    round_trip({"vertical",
                R"({"axis": {"mass_kg": 150, "offset_N": 600, "viscous_Ns_per_m": 600, "coulomb_N": 250,
                             "breakaway_N": 330, "stribeck_velocity_m_per_s": 0.005},
                    "controller": {"kv_m_per_min_per_mm": 1.5, "velocity_gain_N_s_per_m": 45000, "tn_ms": 25},
                    "seed": 13})",
                "--model symmetric --offset",
                {{"mass_kg", 150},
                 {"offset_N", 600},
                 {"viscous_Ns_per_m", 600},
                 {"coulomb_N", 250},
                 {"breakaway_N", 330},
                 {"stribeck_velocity_m_per_s", 0.005}},
                feedid::position_gain_from_kv(1.5),
                45000,
                45000 / 0.025});
}

TEST(TwinRoundTrip, GainsFromTheStructureWhenTheVelocityCommandIsNotLogged) {
    // Without the velocity command, K_v, K_p and K_i come from F = K_p*(K_v*e - v) + K_i*integral(...) alone.
    auto spec = feedid::demo_spec();
    spec.test.feedrates_mm_per_min = {1250, 4000, 9350};
    spec.test.slow_feedrates_mm_per_min = {100, 500};
    auto trace = feedid::synthesize(spec);
    std::erase_if(trace.channels, [](const auto& c) { return c.role == feedid::Role::velocity_command; });
    feedid::DriveConstants drive;
    drive.force_constant_name = "force_constant_N_per_A";
    const auto force = feedid::drive_force(trace, drive);
    const auto result = feedid::identify_gains(trace, force);
    EXPECT_EQ(result.method, "structure");
    EXPECT_NEAR(*result.position_gain_per_s.value, spec.controller.position_gain_per_s,
                0.03 * spec.controller.position_gain_per_s);
    EXPECT_NEAR(*result.velocity_gain_N_s_per_m.value, spec.controller.velocity_gain_N_s_per_m,
                0.03 * spec.controller.velocity_gain_N_s_per_m);
    ASSERT_TRUE(result.velocity_integral_gain_N_per_m.value);
    EXPECT_NEAR(*result.velocity_integral_gain_N_per_m.value, spec.controller.velocity_integral_gain_N_per_m,
                0.03 * spec.controller.velocity_integral_gain_N_per_m);
}

TEST(TwinRoundTrip, ValidationTablePrintedSideBySide) {
    // The paper's Fig. 6 figures on a synthetic trace: mean absolute tracking error of model and machine side by
    // side, and the modelling error, printed by `feedid simulate`. The model here is the true one, so the model
    // tracks the machine to within the sensor noise.
    const auto dir = feedid::testing::temp_dir();
    const auto trace = dir / "synth.csv";
    ASSERT_EQ(run_cli("synth --no-slow-passes --out " + quoted(trace)).exit_code, 0);
    feedid::testing::write_text(dir / "result.json", R"({"parameters": {
        "mass_kg": {"value": 69.1}, "viscous_Ns_per_m": {"value": 54.2}, "coulomb_N": {"value": 742.8},
        "breakaway_N": {"value": 946.2}, "stribeck_velocity_m_per_s": {"value": 0.005}}})");
    const auto printed = run_cli("simulate " + quoted(trace) + " --force-constant force_constant_N_per_A --result " +
                                 quoted(dir / "result.json"));
    ASSERT_EQ(printed.exit_code, 0) << printed.err;
    EXPECT_NE(printed.out.find("model"), std::string::npos) << printed.out;
    EXPECT_NE(printed.out.find("machine"), std::string::npos) << printed.out;
    EXPECT_NE(printed.out.find("mean absolute tracking error"), std::string::npos) << printed.out;
    EXPECT_NE(printed.out.find("mean absolute modelling error"), std::string::npos) << printed.out;
    const auto json = run_cli("simulate " + quoted(trace) + " --force-constant force_constant_N_per_A --result " +
                              quoted(dir / "result.json") + " --json -");
    ASSERT_EQ(json.exit_code, 0) << json.err;
    const auto document = nlohmann::json::parse(json.out);
    const double machine = document["tracking_error_mae_m"]["machine"].get<double>();
    const double model = document["tracking_error_mae_m"]["model"].get<double>();
    const double modelling = document["modelling_error_mae_m"].get<double>();
    EXPECT_GT(machine, 1e-4);  // the ladder at K_v = 2 (m/min)/mm lags by up to 4.7 mm
    EXPECT_NEAR(model, machine, 0.01 * machine);
    EXPECT_LT(modelling, 0.01 * machine);
    EXPECT_LT(document["relative_error_pct"]["position"].get<double>(), 0.05);

    // The printed rows hold the same figures, in mm: model and machine side by side on one row, then the modelling
    // error.
    const auto numbers_after = [&](const std::string& label) {
        std::vector<double> numbers;
        const auto at = printed.out.find(label);
        if (at == std::string::npos) return numbers;
        std::istringstream row(printed.out.substr(at + label.size(), printed.out.find('\n', at) - at - label.size()));
        double value = 0.0;
        while (row >> value) numbers.push_back(value);
        return numbers;
    };
    const auto tracking = numbers_after("mean absolute tracking error");
    ASSERT_EQ(tracking.size(), 2u) << printed.out;
    EXPECT_NEAR(tracking[0], model * 1e3, 1e-3 * model * 1e3) << printed.out;
    EXPECT_NEAR(tracking[1], machine * 1e3, 1e-3 * machine * 1e3) << printed.out;
    const auto modelling_row = numbers_after("mean absolute modelling error");
    ASSERT_GE(modelling_row.size(), 1u) << printed.out;
    EXPECT_NEAR(modelling_row[0], modelling * 1e3, 1e-3 * modelling * 1e3 + 1e-7) << printed.out;
    const auto header = printed.out.find("model");
    EXPECT_LT(header, printed.out.find("machine")) << "model column first, machine beside it";
}

}  // namespace

namespace {

TEST(TwinCli, HelpShowsAWorkedExampleForEachCommand) {
    for (const std::string command : {"gains", "simulate", "synth"}) {
        const auto help = feedid::testing::run_cli(command + " --help");
        EXPECT_EQ(help.exit_code, 0) << command;
        EXPECT_NE(help.out.find("Examples:"), std::string::npos) << command << ":\n" << help.out;
        EXPECT_NE(help.out.find("\n  feedid " + command + " "), std::string::npos) << command << ":\n" << help.out;
    }
}

}  // namespace
