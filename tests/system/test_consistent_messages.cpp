// Messages that say one thing (issue 13). Before: "settled at 23.9 s (did not settle)"; "current-loop lag 2.71e-17 ms";
// "T_n 6.01831e+06 ms" reported as a significant integral gain of a trace a few seconds long; `history --check` said
// "2 run(s) checked" while the listing said none were.

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "history_testing.hpp"
#include "testing.hpp"

namespace {

using feedid::testing::quoted;
using feedid::testing::run_cli;
using feedid::testing::write_text;
using Json = nlohmann::json;

const std::string drive_options = " --force-constant force_constant_N_per_A";
const std::string synth_channels =
    " --channel time=t --channel position=x --channel reference_position=x_ref --channel velocity_command=v_cmd "
    "--channel current=i";

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

TEST(ConsistentMessages, ALagBelowAThousandthOfASampleIsZero) {
    // A lag of 2.71e-20 s (what three steps of -0.1 sample from 0.3 samples leave) is no lag.
    const auto dir = feedid::testing::temp_dir();
    const auto trace = dir / "synth.csv";
    ASSERT_EQ(run_cli("synth --no-slow-passes --out " + quoted(trace)).exit_code, 0);
    const auto result = run_cli("gains " + quoted(trace) + drive_options + synth_channels +
                                " --current-lag-ms 2.71e-17 --json " + quoted(dir / "gains.json"));
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_TRUE(contains(result.out, "current-loop lag 0 ms\n")) << result.out;
    const auto document = Json::parse(feedid::testing::read_text(dir / "gains.json"));
    EXPECT_EQ(document["structure"]["current_lag_s"].get<double>(), 0.0);
}

TEST(ConsistentMessages, AResetTimeLongerThanTheTraceIsNoIntegralAction) {
    // A velocity loop with K_i = 5 N/m (T_n = K_p/K_i = 8000 s) on a 15 s trace without current noise: K_i comes out
    // "significant" (about 4 +- 0.3 N/m), but an integrator that slow cannot be told from a drift within the trace.
    const auto dir = feedid::testing::temp_dir();
    write_text(dir / "drive.toml",
               "[controller]\nvelocity_integral_gain_N_per_m = 5.0\n[sensors]\ncurrent_noise_A = 0.0\n"
               "current_resolution_A = 0.0\n");
    const auto trace = dir / "synth.csv";
    ASSERT_EQ(
        run_cli("synth --no-slow-passes --drive " + quoted(dir / "drive.toml") + " --out " + quoted(trace)).exit_code,
        0);
    const auto automatic = run_cli("gains " + quoted(trace) + drive_options + synth_channels + " --json -");
    ASSERT_EQ(automatic.exit_code, 0) << automatic.err;
    const auto document = Json::parse(automatic.out);
    EXPECT_TRUE(document["gains"]["velocity_integral_gain_N_per_m"]["value"].is_null()) << document.dump(1);
    EXPECT_TRUE(document["nc_units"]["tn_ms"].is_null());
    EXPECT_EQ(document["structure"]["velocity_loop"], "P");
    const std::string diagnostics = document["diagnostics"].dump();
    EXPECT_TRUE(contains(diagnostics, "no integral action in the velocity loop within the trace: T_n = K_p/K_i = "))
        << diagnostics;
    EXPECT_TRUE(contains(diagnostics, "ms is longer than the trace (14.93 s)")) << diagnostics;
    const auto printed = run_cli("gains " + quoted(trace) + drive_options + synth_channels);
    EXPECT_TRUE(contains(printed.out, "K_i   — (P-only velocity loop)")) << printed.out;
    EXPECT_FALSE(contains(printed.out, "T_n  ")) << printed.out;

    // Asked for a PI loop, it fits one and says what K_i and T_n are worth.
    const auto pi = run_cli("gains " + quoted(trace) + drive_options + synth_channels + " --velocity-loop pi");
    ASSERT_EQ(pi.exit_code, 0) << pi.err;
    EXPECT_TRUE(contains(pi.out, "is longer than the trace (14.93 s)")) << pi.out;
    EXPECT_TRUE(contains(pi.out, "K_i and T_n, fitted as --velocity-loop pi asks, are not to be trusted")) << pi.out;
}

// The printed RLS line agrees with the document's rls.settled: "settled at T s", or "did not settle ..." alone.
void expect_settle_wording_of(const std::string& identify_arguments, const std::filesystem::path& json) {
    const auto result = run_cli("identify " + identify_arguments + " --json " + quoted(json) + " --offset");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    // the --json file is written and the table printed (a path, not "-")
    const auto document = Json::parse(feedid::testing::read_text(json));
    const bool settled = document.at("rls").at("settled").get<bool>();
    if (settled) {
        EXPECT_TRUE(contains(result.out, "RLS (directional): settled at ")) << result.out;
        EXPECT_FALSE(contains(result.out, "did not settle")) << result.out;
    } else {
        EXPECT_TRUE(contains(result.out,
                             "RLS (directional): did not settle before the last tenth of the data (within "
                             "tolerance of the final values only from "))
            << result.out;
        EXPECT_TRUE(contains(result.out, " s on); averaged = final")) << result.out;
        EXPECT_FALSE(contains(result.out, "settled at")) << result.out;
    }
}

TEST(ConsistentMessages, RlsSettleWordingSaysOneThing) {
    // EMPS: the directional RLS came within tolerance of its final values only in the last tenth of the data ("settled
    // at 23.9 s (did not settle)"); the demo trace settles.
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto dir = feedid::testing::temp_dir();
    expect_settle_wording_of("'" + (feedid::testing::shared_data() / "emps/DATA_EMPS.mat").string() +
                                 "' --channel position=qm --channel current=vir --force-constant gtau",
                             dir / "emps.json");
    const auto trace = dir / "synth.csv";
    ASSERT_EQ(run_cli("synth --out " + quoted(trace)).exit_code, 0);
    expect_settle_wording_of(quoted(trace) + drive_options + synth_channels, dir / "demo.json");
}

TEST(ConsistentMessages, HistoryCheckCountsTheRunsTheListingChecks) {
    const auto dir = feedid::testing::temp_dir();
    const auto results = feedid::testing::write_small_results(dir, "run", 2);
    const std::string db = quoted(dir / "shop.db");
    ASSERT_EQ(run_cli("history " + db + " --add " + quoted(results[0]) + " --add " + quoted(results[1]) +
                      " --machine M1 --axis X")
                  .exit_code,
              0);
    // two runs, a baseline of eight: the listing checks none, and so does --check
    const auto listing = run_cli("history " + db);
    EXPECT_TRUE(contains(listing.out, "the baseline is still forming (2 of 8 runs); nothing is checked yet"))
        << listing.out;
    const auto check = run_cli("history " + db + " --check");
    EXPECT_EQ(check.exit_code, 0) << check.err;
    EXPECT_EQ(check.out,
              "no drift alarm, but nothing checked yet: the baseline is still forming (machine 'M1' axis 'X': 2 of "
              "8 runs)\n");
    // a baseline of two: complete, and no run after it
    EXPECT_EQ(run_cli("history " + db + " --check --baseline-runs 2").out,
              "no drift alarm, but nothing checked yet: no run after the baseline\n");
    // a baseline of one: the second run is checked against it
    EXPECT_EQ(run_cli("history " + db + " --check --baseline-runs 1").out,
              "no drift alarm: 1 run(s) of 1 axis/axes checked against their baseline\n");
}

}  // namespace
