// gains and simulate judge their own work (issue 13): a fit or a simulation that gives numbers that are not finite,
// diverges or does not follow the machine is status "failed" with exit 1 and the reason in figures; a model that does
// not fit the trace (other axis kind, other units, other sign) is refused with exit 2; the --json documents hold no
// NaN or infinity, and every null in them is named in a diagnostic with its reason.
// Before: `gains` on a current of 1e300 printed "K_p -nan" with exit 0; `simulate` with gains of 1e300 or 1e-300, or a
// viscous friction of -1e308 in the result, printed "position -nan %" and wrote documents of nulls (about 1,700 in
// the series) without a word on them.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <regex>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "feedid/model/drive.hpp"
#include "feedid/core/error.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"
#include "feedid/core/null_reasons.hpp"
#include "feedid/sim/simulate.hpp"
#include "feedid/sim/synth.hpp"
#include "feedid/core/trace.hpp"
#include "history_testing.hpp"
#include "testing.hpp"

namespace {

using feedid::testing::quoted;
using feedid::testing::read_text;
using feedid::testing::run_cli;
using feedid::testing::write_text;
using Json = nlohmann::json;

const std::string drive_options = " --force-constant force_constant_N_per_A";
// Every role of a synthetic trace stated, so that stderr holds only what the command has to say.
const std::string synth_channels =
    " --channel time=t --channel position=x --channel reference_position=x_ref --channel velocity_command=v_cmd "
    "--channel current=i";

// The demo drive's true values as a result document, and its true controller as a gains document.
const char* true_result = R"({"parameters": {"mass_kg": {"value": 69.1}, "viscous_Ns_per_m": {"value": 54.2},
    "coulomb_N": {"value": 742.8}, "breakaway_N": {"value": 946.2}, "stribeck_velocity_m_per_s": {"value": 0.005}}})";

std::string gains_document(double position_gain, double velocity_gain) {
    return Json{{"gains",
                 {{"position_gain_per_s", {{"value", position_gain}}},
                  {"velocity_gain_N_s_per_m", {{"value", velocity_gain}}},
                  {"velocity_integral_gain_N_per_m", {{"value", 2e6}}}}},
                {"structure", {{"sample_time_s", 0.001}, {"current_lag_s", 0.0003}}}}
        .dump();
}

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// "nan", "-nan", "inf" as printed numbers (not inside words such as "information").
bool prints_non_finite(const std::string& text) {
    static const std::regex number(R"((^|[^A-Za-z])-?(nan|inf)([^A-Za-z]|$))", std::regex::icase);
    return std::regex_search(text, number);
}

// A demo trace (15 s, the paper's ladder) in `dir`.
std::filesystem::path demo_trace(const std::filesystem::path& dir) {
    const auto trace = dir / "synth.csv";
    const auto made = run_cli("synth --no-slow-passes --out " + quoted(trace));
    EXPECT_EQ(made.exit_code, 0) << made.err;
    return trace;
}

// The paths of the nulls in a document, arrays as "name[]" (an independent walk, not the library's).
void nulls_in(const Json& node, const std::string& path, std::set<std::string>& out) {
    if (node.is_null()) out.insert(path);
    if (node.is_object())
        for (const auto& [key, child] : node.items()) nulls_in(child, path.empty() ? key : path + "." + key, out);
    if (node.is_array())
        for (const auto& child : node) nulls_in(child, path + "[]", out);
}

// Parses the text of a --json document and checks the rules: no NaN or infinity in the text, and every null named in
// a diagnostic (by its path) that says why.
Json checked_document(const std::string& text) {
    EXPECT_FALSE(prints_non_finite(text)) << "NaN or infinity in the document";
    const Json document = Json::parse(text);
    std::set<std::string> nulls;
    nulls_in(document, "", nulls);
    const std::string diagnostics = document.at("diagnostics").dump();
    for (const auto& path : nulls) {
        if (path.rfind("diagnostics", 0) == 0) continue;
        EXPECT_TRUE(contains(diagnostics, path + ": null, ") || contains(diagnostics, path + ", ") ||
                    contains(diagnostics, path + " ("))
            << path << " is null without a diagnostic naming it: " << diagnostics;
    }
    return document;
}

TEST(FitGates, GainsOnACurrentOf1e300FailsWithTheForceInFigures) {
    const auto dir = feedid::testing::temp_dir();
    auto trace = feedid::read_trace(demo_trace(dir));
    for (auto& value : trace.find(feedid::Role::current)->values) value *= 1e300;
    write_text(dir / "big.csv", feedid::write_csv(trace));
    const auto result = run_cli("gains " + quoted(dir / "big.csv") + drive_options + synth_channels + " --json " +
                                quoted(dir / "g.json"));
    EXPECT_EQ(result.exit_code, 1) << result.out << result.err;
    EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << result.err;
    EXPECT_TRUE(std::regex_search(result.err, std::regex(R"(the drive force reaches \d\.\d+e\+30[23] N)")))
        << result.err;
    EXPECT_FALSE(prints_non_finite(result.out)) << result.out;
    EXPECT_TRUE(contains(result.out, "status         failed")) << result.out;
    const Json document = checked_document(read_text(dir / "g.json"));
    EXPECT_EQ(document["status"], "failed");
    EXPECT_TRUE(document["gains"]["velocity_gain_N_s_per_m"]["value"].is_null());
    EXPECT_TRUE(document["fit"]["relative_error_pct"].is_null()) << "nothing was fitted: no fit figure";
}

TEST(FitGates, GainsOfTheWrongSignAreNoControllerAndNameTheFix) {
    // EMPS with the drive signal's sign turned: the fit is as good as ever (0.24 %), K_p = -8555 N*s/m. Before, a note
    // and exit 0.
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto result =
        run_cli("gains '" + (feedid::testing::shared_data() / "emps/DATA_EMPS.mat").string() +
                "' --channel time=t --channel position=qm --channel reference_position=qg --channel current=vir "
                "--force-constant -35.15 "
                "--unit position=m --unit reference_position=m --unit time=s --unit current=V");
    EXPECT_EQ(result.exit_code, 1) << result.err;
    EXPECT_EQ(result.err,
              "feedid: the velocity loop gain came out negative (K_p = -8555 N*s/m), which no stable controller has: "
              "the drive signal's sign is the opposite of the motion's (drive and NC count directions differently); "
              "give the force constant with the other sign, --force-constant 35.15\n");
    // reference and position the wrong way round: K_v < 0
    const auto dir = feedid::testing::temp_dir();
    const auto swapped =
        run_cli("gains " + quoted(demo_trace(dir)) + drive_options +
                " --channel time=t --channel position=x_ref --channel reference_position=x --channel "
                "velocity_command=v_cmd --channel current=i");
    EXPECT_EQ(swapped.exit_code, 1) << swapped.err;
    EXPECT_TRUE(contains(swapped.err, "the position loop gain came out negative (K_v = -33.33 1/s)")) << swapped.err;
}

TEST(FitGates, SimulateWithGainsOf1e300Or1e300thFailsWithoutAnyNan) {
    const auto dir = feedid::testing::temp_dir();
    const auto trace = demo_trace(dir);
    write_text(dir / "result.json", true_result);
    struct Case {
        double position_gain;
        double velocity_gain;
        const char* reason;
    };
    for (const auto& [kv, kp, reason] :
         {Case{33.3333, 1e300, "the simulation diverged: its position, velocity or force is not a finite number"},
          Case{1e300, 40000.0, "the simulation diverged: its position, velocity or force is not a finite number"},
          Case{33.3333, 1e-300, "the simulation diverged: the simulated axis came"},
          Case{1e-300, 40000.0, "the simulated axis does not follow the machine"}}) {
        write_text(dir / "gains.json", gains_document(kv, kp));
        const auto result = run_cli("simulate " + quoted(trace) + drive_options + synth_channels + " --result " +
                                    quoted(dir / "result.json") + " --gains " + quoted(dir / "gains.json") +
                                    " --json " + quoted(dir / "simulate.json"));
        const std::string which = fmt::format("K_v {:g}, K_p {:g}", kv, kp);
        EXPECT_EQ(result.exit_code, 1) << which << ": " << result.err;
        EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << which << ": " << result.err;
        EXPECT_TRUE(contains(result.err, reason)) << which << ": " << result.err;
        const Json document = checked_document(read_text(dir / "simulate.json"));
        EXPECT_EQ(document["status"], "failed") << which;
        EXPECT_TRUE(contains(document["diagnostics"][0].get<std::string>(), reason)) << which;
        // the error series ends where the simulation stopped being a number: no nulls in it
        for (const auto& [key, values] : document["series"].items()) {
            if (!values.is_array()) continue;
            for (const auto& value : values) EXPECT_TRUE(value.is_number()) << which << ": series." << key;
        }
        // the printed table shows the same
        const auto printed = run_cli("simulate " + quoted(trace) + drive_options + synth_channels + " --result " +
                                     quoted(dir / "result.json") + " --gains " + quoted(dir / "gains.json"));
        EXPECT_FALSE(prints_non_finite(printed.out)) << which << ":\n" << printed.out;
        EXPECT_TRUE(contains(printed.out, "status         failed")) << which << ":\n" << printed.out;
    }
}

TEST(FitGates, SimulateRefusesAResultWithAViscousFrictionOfMinus1e308) {
    const auto dir = feedid::testing::temp_dir();
    const auto trace = demo_trace(dir);
    auto result_document = Json::parse(true_result);
    result_document["parameters"]["viscous_Ns_per_m"]["value"] = -1e308;
    write_text(dir / "result.json", result_document.dump());
    write_text(dir / "gains.json", gains_document(33.3333, 40000.0));
    const auto result = run_cli("simulate " + quoted(trace) + drive_options + synth_channels + " --result " +
                                quoted(dir / "result.json") + " --gains " + quoted(dir / "gains.json") + " --json " +
                                quoted(dir / "simulate.json"));
    EXPECT_EQ(result.exit_code, 2) << result.err;
    EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << result.err;
    EXPECT_TRUE(contains(result.err, "result.json: the result does not fit the trace")) << result.err;
    EXPECT_TRUE(std::regex_search(result.err, std::regex(R"(reaches \d\.\d+e\+30[5-8] N, the trace's drive force)")))
        << result.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "simulate.json")) << "nothing simulated, nothing written";
}

TEST(FitGates, SimulateRefusesAResultInOtherUnitsOrWithTheOtherSign) {
    const auto dir = feedid::testing::temp_dir();
    const auto trace = demo_trace(dir);
    write_text(dir / "result.json", true_result);
    write_text(dir / "gains.json", gains_document(33.3333, 40000.0));
    const std::string common = "simulate " + quoted(trace) + synth_channels + " --result " +
                               quoted(dir / "result.json") + " --gains " + quoted(dir / "gains.json");
    // the true drive constant: the axis's own model fits
    const auto fits = run_cli(common + drive_options);
    EXPECT_EQ(fits.exit_code, 0) << fits.err;
    // the demo drive's 453.646 N/A given per mA, or with the other sign
    for (const auto& [constant, expected] :
         {std::pair{"453646", "the best factor between them is 1e+03, where the axis's own model gives about 1"},
          std::pair{"-453.646",
                    "the best factor between them is -1, where the axis's own model gives about 1: the "
                    "drive signal's sign is the opposite"}}) {
        const auto result = run_cli(common + " --force-constant " + constant);
        EXPECT_EQ(result.exit_code, 2) << constant << ": " << result.err;
        EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << result.err;
        EXPECT_TRUE(contains(result.err, expected)) << constant << ": " << result.err;
    }
}

TEST(FitGates, ModelScaleAgainstTheTraceInTheLibrary) {
    auto spec = feedid::demo_spec();
    spec.test.slow_passes = false;
    const auto trace = feedid::synthesize(spec);
    feedid::DriveConstants drive;
    drive.force_constant_name = "force_constant_N_per_A";
    const auto force = feedid::drive_force(trace, drive);
    EXPECT_EQ(feedid::model_does_not_fit(spec.axis, trace, force), "");
    // a mass given in g and friction in mN (a result in other units) lies far outside; a mass 3x off does not
    auto other_units = spec.axis;
    other_units.mass *= 1000.0;
    other_units.friction.forward.viscous *= 1000.0;
    other_units.friction.reverse.viscous *= 1000.0;
    other_units.friction.forward.coulomb *= 1000.0;
    other_units.friction.reverse.coulomb *= 1000.0;
    other_units.friction.forward.breakaway = *other_units.friction.forward.breakaway * 1000.0;
    other_units.friction.reverse.breakaway = *other_units.friction.reverse.breakaway * 1000.0;
    EXPECT_TRUE(contains(feedid::model_does_not_fit(other_units, trace, force),
                         "the best factor between them is "
                         "0.001"));
    auto heavier = spec.axis;
    heavier.mass *= 3.0;
    EXPECT_EQ(feedid::model_does_not_fit(heavier, trace, force), "");
}

TEST(FitGates, SimulateRefusesGainsOfTheOtherAxisKind) {
    const auto dir = feedid::testing::temp_dir();
    const auto trace = demo_trace(dir);
    write_text(dir / "result.json", true_result);
    write_text(dir / "gains.json", R"({"rotary": true, "gains": {"position_gain_per_s": {"value": 33.3},
        "velocity_gain_Nms_per_rad": {"value": 5.0}}, "structure": {"sample_time_s": 0.001}})");
    const auto result = run_cli("simulate " + quoted(trace) + drive_options + synth_channels + " --result " +
                                quoted(dir / "result.json") + " --gains " + quoted(dir / "gains.json"));
    EXPECT_EQ(result.exit_code, 2) << result.err;
    EXPECT_TRUE(contains(result.err, "gains.json: the gains are of a rotary axis, the trace")) << result.err;
    EXPECT_TRUE(contains(result.err, "of a linear axis")) << result.err;
    EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << result.err;
}

TEST(FitGates, NoGainsToIdentifyIsAnAnalysisFailureNotBadGains) {
    // The twin's gains are identified from the trace when no gains document is given; from a drive force of 1e300 N
    // there are none. The library says so (AnalysisError: exit 1), not "K_p must be a positive number" (exit 2).
    auto spec = feedid::demo_spec();
    spec.test.slow_passes = false;
    const auto trace = feedid::synthesize(spec);
    feedid::DriveConstants drive;
    drive.force_constant_name = "force_constant_N_per_A";
    auto force = feedid::drive_force(trace, drive);
    for (auto& value : force) value *= 1e300;
    try {
        (void)feedid::identified_twin_controller(trace, force, {});
        ADD_FAILURE() << "a twin without gains";
    } catch (const feedid::AnalysisError& e) {
        EXPECT_TRUE(contains(e.what(),
                             "no simulation: no gains could be identified from the trace: the drive force "
                             "reaches"))
            << e.what();
    }
    // On the command line the result's forces do not fit such a trace in the first place (exit 2).
    const auto dir = feedid::testing::temp_dir();
    auto logged = feedid::read_trace(demo_trace(dir));
    for (auto& value : logged.find(feedid::Role::current)->values) value *= 1e300;
    write_text(dir / "big.csv", feedid::write_csv(logged));
    write_text(dir / "result.json", true_result);
    const auto result = run_cli("simulate " + quoted(dir / "big.csv") + drive_options + synth_channels + " --result " +
                                quoted(dir / "result.json"));
    EXPECT_EQ(result.exit_code, 2) << result.err;
    EXPECT_TRUE(contains(result.err, "the result does not fit the trace")) << result.err;
}

TEST(FitGates, AGoodRunsDocumentsNameTheirNullsToo) {
    const auto dir = feedid::testing::temp_dir();
    const auto trace = demo_trace(dir);
    const auto gains = run_cli("gains " + quoted(trace) + drive_options + synth_channels + " --json -");
    ASSERT_EQ(gains.exit_code, 0) << gains.err;
    const Json gains_json = checked_document(gains.out);
    EXPECT_EQ(gains_json["status"], "ok");
    EXPECT_TRUE(gains_json["gains"]["velocity_feedforward"]["value"].is_null());
    EXPECT_TRUE(contains(gains_json["diagnostics"].dump(), "--feedforward not given"));
    write_text(dir / "result.json", true_result);
    const auto simulate = run_cli("simulate " + quoted(trace) + drive_options + synth_channels + " --result " +
                                  quoted(dir / "result.json") + " --json -");
    ASSERT_EQ(simulate.exit_code, 0) << simulate.err;
    const Json simulate_json = checked_document(simulate.out);
    EXPECT_EQ(simulate_json["status"], "ok");
}

TEST(NullReasons, NonFiniteNumbersBecomeNullsNamedWithTheirReason) {
    Json document{{"a", {{"value", NAN}, {"stderr", 1.0}}},
                  {"series", {1.0, INFINITY, -INFINITY, 2.0}},
                  {"b", nullptr},
                  {"diagnostics", {"first"}}};
    const auto paths = feedid::null_paths(document);
    EXPECT_EQ(paths, (std::vector<std::string>{"a.value", "b", "series[1]", "series[2]"}));
    EXPECT_TRUE(document["a"]["value"].is_null());
    EXPECT_FALSE(contains(document.dump(), "NaN"));
    feedid::explain_nulls(
        document, [](std::string_view path) { return path == "b" ? std::string("not asked for") : std::string(); });
    EXPECT_EQ(document["diagnostics"], Json({"first", "a.value, series[] (2 of 4 values): null, not a finite number",
                                             "b: null, not asked for"}));
}

}  // namespace
