// Synthetic traces: the test reference, sensor models, determinism, the CSV the readers take back, drive files.
#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"
#include "feedid/sim/synth.hpp"
#include "testing.hpp"

namespace {

using feedid::testing::run_cli;

// A short test so that the suite stays fast: three feedrates and three slow passes.
feedid::SynthSpec short_spec() {
    auto spec = feedid::demo_spec();
    spec.test.feedrates_mm_per_min = {1250, 5000, 9350};
    spec.test.slow_feedrates_mm_per_min = {50, 300, 1000};
    return spec;
}

TEST(Synth, TestReferenceHasTheLadderAndTheSlowPasses) {
    feedid::TestReference test;
    const double dt = 1e-3;
    const auto reference = feedid::test_reference(test, dt);
    ASSERT_GT(reference.size(), 1000u);
    EXPECT_DOUBLE_EQ(reference.front(), 0.0);
    EXPECT_DOUBLE_EQ(reference.back(), 0.0);
    const auto [low, high] = std::minmax_element(reference.begin(), reference.end());
    EXPECT_NEAR(*low, 0.0, 1e-12);
    EXPECT_NEAR(*high, 0.030, 1e-12);
    // Every feedrate appears as a constant-velocity stretch, in both directions.
    const auto has_speed = [&](double mm_per_min) {
        const double speed = mm_per_min / 60000.0;
        int forward = 0, reverse = 0;
        for (std::size_t k = 1; k < reference.size(); ++k) {
            const double v = (reference[k] - reference[k - 1]) / dt;
            forward += std::abs(v - speed) < 1e-9 * std::max(1.0, speed * 1e3);
            reverse += std::abs(v + speed) < 1e-9 * std::max(1.0, speed * 1e3);
        }
        return forward > 10 && reverse > 10;
    };
    for (const double f : test.feedrates_mm_per_min) EXPECT_TRUE(has_speed(f)) << f << " mm/min";
    for (const double f : test.slow_feedrates_mm_per_min) EXPECT_TRUE(has_speed(f)) << f << " mm/min";
    // The acceleration limit holds.
    for (std::size_t k = 2; k < reference.size(); ++k) {
        const double a = (reference[k] - 2 * reference[k - 1] + reference[k - 2]) / (dt * dt);
        ASSERT_LE(std::abs(a), test.acceleration_m_per_s2 * 1.001 + 1e-9) << "sample " << k;
    }
    // Without slow passes: the paper's ladder alone, nothing slower than 1250 mm/min at constant velocity.
    test.slow_passes = false;
    const auto ladder = feedid::test_reference(test, dt);
    EXPECT_LT(ladder.size(), reference.size() / 2);
}

TEST(Synth, TraceHasChannelsUnitsConstantsAndSensors) {
    const auto spec = short_spec();
    const auto trace = feedid::synthesize(spec);
    ASSERT_TRUE(trace.has(feedid::Role::time));
    ASSERT_TRUE(trace.has(feedid::Role::reference_position));
    ASSERT_TRUE(trace.has(feedid::Role::position));
    ASSERT_TRUE(trace.has(feedid::Role::velocity_command));
    ASSERT_TRUE(trace.has(feedid::Role::current));
    EXPECT_EQ(trace.find(feedid::Role::current)->unit, "A");
    EXPECT_NEAR(trace.constants.at("force_constant_N_per_A"), 1.444 * 2 * M_PI / 0.020, 1e-9);
    EXPECT_DOUBLE_EQ(trace.constants.at("true_mass_kg"), 69.1);
    EXPECT_DOUBLE_EQ(trace.constants.at("true_breakaway_forward_N"), 946.2);
    EXPECT_DOUBLE_EQ(trace.constants.at("true_stribeck_velocity_reverse_m_per_s"), 0.005);
    // Position quantised to 10 nm, current to 5 mA.
    for (const double x : trace.column(feedid::Role::position)) {
        ASSERT_NEAR(x / 1e-8, std::round(x / 1e-8), 1e-6);
    }
    for (const double i : trace.column(feedid::Role::current)) {
        ASSERT_NEAR(i / 0.005, std::round(i / 0.005), 1e-6);
    }
    // Current noise: at rest at the start, the current scatters with about 0.02 A.
    const auto current = trace.column(feedid::Role::current);
    double sum = 0.0, squares = 0.0;
    for (std::size_t k = 0; k < 150; ++k) {
        sum += current[k];
        squares += current[k] * current[k];
    }
    const double deviation = std::sqrt(squares / 150 - (sum / 150) * (sum / 150));
    EXPECT_GT(deviation, 0.012);
    EXPECT_LT(deviation, 0.03);
    // The axis follows the reference closely (following error = v/K_v, at most a few mm here).
    const auto x = trace.column(feedid::Role::position);
    const auto r = trace.column(feedid::Role::reference_position);
    double largest = 0.0;
    for (std::size_t k = 0; k < x.size(); ++k) largest = std::max(largest, std::abs(r[k] - x[k]));
    EXPECT_LT(largest, 0.156 / feedid::position_gain_from_kv(2.0) * 1.2);
    EXPECT_GT(largest, 0.156 / feedid::position_gain_from_kv(2.0) * 0.8);
}

TEST(Synth, DeterministicForASeedAndDifferentForAnother) {
    auto spec = short_spec();
    const auto a = feedid::synthesize(spec);
    const auto b = feedid::synthesize(spec);
    EXPECT_EQ(a.find(feedid::Role::current)->values, b.find(feedid::Role::current)->values);
    spec.seed = 2;
    const auto c = feedid::synthesize(spec);
    EXPECT_NE(a.find(feedid::Role::current)->values, c.find(feedid::Role::current)->values);
    EXPECT_EQ(a.find(feedid::Role::position)->values, c.find(feedid::Role::position)->values)
        << "the noise is on the current sensor only; the motion is the same";
}

TEST(Synth, JitteredTimeStampsAreReportedOnImport) {
    auto spec = short_spec();
    spec.sensors.jitter_s = 0.1e-3;
    const auto dir = feedid::testing::temp_dir();
    feedid::testing::write_text(dir / "jitter.csv", feedid::write_csv(feedid::synthesize(spec)));
    const auto trace = feedid::read_trace(dir / "jitter.csv");
    EXPECT_TRUE(trace.time_base().jittery);
    EXPECT_NEAR(trace.time_base().sample_time_s, 1e-3, 1e-5);
}

TEST(Synth, CsvReadsBackWithRolesUnitsAndConstants) {
    const auto dir = feedid::testing::temp_dir();
    const auto original = feedid::synthesize(short_spec());
    feedid::testing::write_text(dir / "synth.csv", feedid::write_csv(original));
    const auto trace = feedid::read_trace(dir / "synth.csv");
    EXPECT_EQ(trace.samples(), original.samples());
    EXPECT_EQ(trace.column(feedid::Role::position)[500], original.column(feedid::Role::position)[500]);
    EXPECT_EQ(trace.column(feedid::Role::velocity_command)[700], original.column(feedid::Role::velocity_command)[700]);
    EXPECT_DOUBLE_EQ(trace.constants.at("force_constant_N_per_A"), original.constants.at("force_constant_N_per_A"));
}

TEST(Synth, FollowsAReferenceFileInMillimetres) {
    const auto dir = feedid::testing::temp_dir();
    std::string text = "t [s],x_ref [mm]\n";
    for (int k = 0; k <= 2000; ++k) {
        const double t = k * 1e-3;
        text += std::to_string(t) + "," + std::to_string(t < 1.0 ? 5.0 * t * t : 5.0 + 10.0 * (t - 1.0)) + "\n";
    }
    feedid::testing::write_text(dir / "reference.csv", text);
    const auto result = run_cli("synth --seed 3 --reference '" + (dir / "reference.csv").string() + "' --out '" +
                                (dir / "out.csv").string() + "'");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto trace = feedid::read_trace(dir / "out.csv");
    EXPECT_EQ(trace.samples(), 2001u);
    EXPECT_NEAR(trace.column(feedid::Role::reference_position).back(), 0.015, 1e-9);
    EXPECT_NEAR(trace.column(feedid::Role::position).back(), 0.015 - 0.010 / feedid::position_gain_from_kv(2.0), 2e-5);
}

TEST(Synth, DriveFileOverridesTheDemoAndRejectsUnknownKeys) {
    const auto spec = feedid::spec_from_json(nlohmann::json::parse(R"({
        "axis": {"mass_kg": 200, "coulomb_forward_N": 100, "coulomb_reverse_N": 120, "viscous_Ns_per_m": 300,
                 "offset_N": 50},
        "controller": {"kv_m_per_min_per_mm": 3, "tn_ms": 10},
        "sensors": {"sample_time_ms": 0.5, "position_resolution_um": 0.001},
        "slow_passes": false, "seed": 9})"),
                                             "drive.json");
    EXPECT_DOUBLE_EQ(spec.axis.mass, 200.0);
    EXPECT_DOUBLE_EQ(spec.axis.friction.reverse.coulomb, 120.0);
    EXPECT_DOUBLE_EQ(spec.axis.friction.forward.viscous, 300.0);
    EXPECT_FALSE(spec.axis.friction.forward.has_stribeck());
    EXPECT_DOUBLE_EQ(spec.axis.offset, 50.0);
    EXPECT_NEAR(spec.controller.position_gain_per_s, 50.0, 1e-12);
    EXPECT_NEAR(spec.controller.velocity_integral_gain_N_per_m, 40000.0 / 0.010, 1e-6);
    EXPECT_DOUBLE_EQ(spec.sensors.sample_time_s, 0.5e-3);
    EXPECT_FALSE(spec.test.slow_passes);
    EXPECT_EQ(spec.seed, 9u);
    // The printed drive file reads back to the same spec.
    const auto again = feedid::spec_from_json(feedid::spec_to_json(spec), "printed");
    EXPECT_EQ(feedid::spec_to_json(again), feedid::spec_to_json(spec));

    try {
        feedid::spec_from_json(nlohmann::json::parse(R"({"controller": {"kv": 3}})"), "drive.json");
        FAIL() << "expected an InputError";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("controller.kv"), std::string::npos) << e.what();
    }
    EXPECT_THROW(feedid::spec_from_json(nlohmann::json::parse(R"({"sensors": {"sample_time_ms": "fast"}})"), "d"),
                 feedid::InputError);
    EXPECT_THROW(feedid::spec_from_json(nlohmann::json::parse(R"({"sensors": {"jitter_us": 900}})"), "d"),
                 feedid::InputError);
}

TEST(Synth, ARotaryDriveIsWrittenInRotaryUnitsNotLinearOnes) {
    auto spec = feedid::rotary_demo_spec();
    spec.test.feedrates_mm_per_min = {1250, 9350};
    spec.test.slow_passes = false;
    const auto trace = feedid::synthesize(spec);
    EXPECT_TRUE(trace.rotary);
    EXPECT_EQ(trace.find(feedid::Role::position)->unit, "rad");
    EXPECT_EQ(trace.find(feedid::Role::velocity_command)->unit, "rad/s");
    // the test's 30 "mm" stroke is 30 degrees on a rotary axis
    const auto reference = trace.column(feedid::Role::reference_position);
    EXPECT_NEAR(*std::max_element(reference.begin(), reference.end()), 30.0 * M_PI / 180.0, 1e-12);
    // torque per ampere without a lead: K_t times the gear ratio
    EXPECT_DOUBLE_EQ(trace.constants.at("torque_constant_Nm_per_A"), 2.0);
    EXPECT_EQ(trace.constants.count("force_constant_N_per_A"), 0u);
    EXPECT_DOUBLE_EQ(trace.constants.at("true_viscous_forward_Nms_per_rad"), 5.0);
    // the printed drive file is rotary and reads back to the same spec
    const auto printed = feedid::spec_to_json(spec);
    EXPECT_TRUE(printed["axis"].contains("inertia_kgm2"));
    EXPECT_EQ(feedid::spec_to_json(feedid::spec_from_json(printed, "printed")), printed);
}

TEST(Synth, DriveFileFrictionZones) {
    const auto spec = feedid::spec_from_json(
        nlohmann::json::parse(R"({"friction_zones": [{"from_mm": -100, "to_mm": 50, "coulomb_factor": 1.3}]})"), "d");
    ASSERT_EQ(spec.friction_zones.size(), 1u);
    EXPECT_DOUBLE_EQ(spec.friction_zones[0].from_m, -0.1);
    EXPECT_DOUBLE_EQ(spec.friction_zones[0].to_m, 0.05);
    EXPECT_DOUBLE_EQ(spec.friction_zones[0].coulomb_factor, 1.3);
    EXPECT_EQ(feedid::spec_to_json(feedid::spec_from_json(feedid::spec_to_json(spec), "printed")),
              feedid::spec_to_json(spec));
    try {
        feedid::spec_from_json(
            nlohmann::json::parse(R"({"friction_zones": [{"from_mm": 0, "to_mm": 1, "factor": 2}]})"), "drive.json");
        FAIL() << "expected an InputError";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("friction_zones[0]"), std::string::npos) << e.what();
    }
    EXPECT_THROW(
        feedid::spec_from_json(
            nlohmann::json::parse(R"({"friction_zones": [{"from_mm": 5, "to_mm": 1, "coulomb_factor": 2}]})"), "d"),
        feedid::InputError);
}

TEST(Synth, CommandLineWritesATraceThatInfoReads) {
    const auto dir = feedid::testing::temp_dir();
    const auto out = dir / "synth.csv";
    const auto result = run_cli("synth --no-slow-passes --out '" + out.string() + "'");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto info = run_cli("info '" + out.string() + "' --json -");
    ASSERT_EQ(info.exit_code, 0) << info.err;
    const auto document = nlohmann::json::parse(info.out);
    EXPECT_NEAR(document["sample_time_s"].get<double>(), 1e-3, 1e-12);
    EXPECT_TRUE(document["constants"].contains("force_constant_N_per_A"));
    // A bad drive file is bad input: exit 2, one line.
    feedid::testing::write_text(dir / "bad.json", R"({"axis": {"mass_kg": -1, "coulomb_N": 1}})");
    const auto bad = run_cli("synth --drive '" + (dir / "bad.json").string() + "' --out '" + out.string() + "'");
    EXPECT_EQ(bad.exit_code, 2);
    EXPECT_EQ(feedid::testing::count_lines(bad.err), 1) << bad.err;
}

TEST(Synth, TomlDriveFile) {
    const auto dir = feedid::testing::temp_dir();
    feedid::testing::write_text(dir / "drive.toml", R"(# an asymmetric drive
seed = 3
slow_passes = false
[axis]
mass_kg = 120
viscous_Ns_per_m = 800.0
coulomb_forward_N = 300.0
coulomb_reverse_N = 340.0
[controller]
kv_m_per_min_per_mm = 2.5
tn_ms = 15
[test]
feedrates_mm_per_min = [1250, 9350]
)");
    const auto spec = feedid::read_spec(dir / "drive.toml");
    EXPECT_DOUBLE_EQ(spec.axis.mass, 120.0);
    EXPECT_DOUBLE_EQ(spec.axis.friction.reverse.coulomb, 340.0);
    EXPECT_NEAR(spec.controller.position_gain_per_s, feedid::position_gain_from_kv(2.5), 1e-12);
    EXPECT_EQ(spec.test.feedrates_mm_per_min.size(), 2u);
    EXPECT_FALSE(spec.test.slow_passes);
    EXPECT_EQ(spec.seed, 3u);
    const auto result =
        run_cli("synth --drive '" + (dir / "drive.toml").string() + "' --out '" + (dir / "out.csv").string() + "'");
    EXPECT_EQ(result.exit_code, 0) << result.err;
    // Syntax errors name the file and line; unknown keys are rejected as in JSON.
    feedid::testing::write_text(dir / "bad.toml", "[axis]\nmass_kg = = 3\n");
    const auto bad =
        run_cli("synth --drive '" + (dir / "bad.toml").string() + "' --out '" + (dir / "out.csv").string() + "'");
    EXPECT_EQ(bad.exit_code, 2);
    EXPECT_NE(bad.err.find("bad.toml:2"), std::string::npos) << bad.err;
    EXPECT_EQ(feedid::testing::count_lines(bad.err), 1) << bad.err;
    feedid::testing::write_text(dir / "typo.toml", "[sensors]\nsample_time = 1\n");
    EXPECT_THROW(feedid::read_spec(dir / "typo.toml"), feedid::InputError);
    // an axis key that looks like a friction key but is none is not ignored
    feedid::testing::write_text(dir / "axis_typo.toml", "[axis]\nmass_kg = 120\ncoulomb_N = 300\ncoulomb_typo_N = 1\n");
    try {
        (void)feedid::read_spec(dir / "axis_typo.toml");
        ADD_FAILURE() << "axis.coulomb_typo_N was accepted";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("unknown key 'axis.coulomb_typo_N'"), std::string::npos) << e.what();
    }
}

}  // namespace
