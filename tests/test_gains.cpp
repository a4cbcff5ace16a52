// Gain identification: EMPS (published gains) and synthetic closed-loop traces with known gains.
#include <cmath>

#include <nlohmann/json.hpp>

#include "feedid/drive.hpp"
#include "feedid/gains.hpp"
#include "feedid/io/import.hpp"
#include "feedid/simulate.hpp"
// synth.hpp (later)
#include "testing.hpp"

namespace {

using feedid::testing::run_cli;
using feedid::testing::shared_data;

feedid::Trace read_emps() {
    feedid::ImportOptions options;
    options.channels[feedid::Role::position] = "qm";
    options.channels[feedid::Role::reference_position] = "qg";
    options.channels[feedid::Role::current] = "vir";
    return feedid::read_trace(shared_data() / "emps/DATA_EMPS.mat", options);
}

TEST(Gains, EmpsPublishedGainsFromTheLibrary) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto trace = read_emps();
    feedid::DriveConstants drive;
    drive.force_constant_name = "gtau";
    const auto force = feedid::drive_force(trace, drive);
    const double gtau = trace.constants.at("gtau");
    feedid::GainOptions options;
    options.force_per_signal = gtau;
    const auto result = feedid::identify_gains(trace, force, options);
    EXPECT_EQ(result.method, "structure");
    ASSERT_TRUE(result.position_gain_per_s.value);
    EXPECT_NEAR(*result.position_gain_per_s.value, 160.18, 0.02 * 160.18);
    EXPECT_NEAR(*result.velocity_gain_N_s_per_m.value / gtau, 243.45, 0.02 * 243.45);
    EXPECT_FALSE(result.velocity_integral_gain_N_per_m.value) << "EMPS has a P velocity loop";
    EXPECT_EQ(result.velocity_difference_samples, 2) << "the [0.5 0.5] filter then a difference";
    EXPECT_GT(*result.position_gain_per_s.standard_error, 0.0);
}

TEST(Gains, EmpsCommandLine) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto result = run_cli("gains '" + (shared_data() / "emps/DATA_EMPS.mat").string() +
                                "' --channel position=qm --channel reference_position=qg --channel current=vir "
                                "--force-constant gtau --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    const double kp = document["gains"]["position_gain_per_s"]["value"].get<double>();
    const double kv = document["gains"]["velocity_gain_signal_per_m_per_s"]["value"].get<double>();
    EXPECT_NEAR(kp, 160.18, 0.02 * 160.18);
    EXPECT_NEAR(kv, 243.45, 0.02 * 243.45);
    EXPECT_NEAR(document["nc_units"]["kv_m_per_min_per_mm"].get<double>(), 160.18 * 0.06, 0.02 * 9.61);
    EXPECT_TRUE(document["gains"]["velocity_integral_gain_N_per_m"]["value"].is_null());
    EXPECT_TRUE(document["nc_units"]["tn_ms"].is_null());
}

TEST(Gains, MissingReferenceIsBadInput) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto result = run_cli("gains '" + (shared_data() / "emps/DATA_EMPS.mat").string() +
                                "' --channel position=qm --channel current=qg --channel reference_position=nothing "
                                "--force-constant gtau");
    EXPECT_EQ(result.exit_code, 2) << result.err;
    EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << result.err;
}

}  // namespace
