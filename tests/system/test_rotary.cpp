// A rotary axis through every command: the demo drive's synthetic trace read once as a linear axis (m, N) and once
// as the same motion of a rotary table (deg, rpm, N*m), scaled by s = 2*pi/lead rad per m (one screw turn of 20 mm is
// one table turn). By virtual work T = F/s, so J = M/s^2, B_rot = B/s^2, F_C,rot = F_C/s, v_s,rot = v_s*s, and the
// controller's K_p and K_i scale by 1/s^2 while K_v stays. identify, gains, simulate and report must give those
// numbers, under the rotary keys, with no linear unit anywhere in what they print or write.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <regex>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/sim/synth.hpp"
#include "testing.hpp"

using feedid::testing::read_text;
using feedid::testing::run_cli;
using feedid::testing::write_text;

namespace {

constexpr double lead_m = 0.020;
constexpr double s = 2.0 * std::numbers::pi / lead_m;                    // rad per m
constexpr double degrees_per_m = s * 180.0 / std::numbers::pi;           // 18000: 1 mm of travel is 18 deg
constexpr double rpm_per_m_per_s = s * 60.0 / (2.0 * std::numbers::pi);  // 3000

std::string quoted(const std::filesystem::path& path) {
    std::string text(1, '\'');
    text.append(path.string());
    text.push_back('\'');
    return text;
}

struct Files {
    std::filesystem::path dir;
    std::filesystem::path linear;
    std::filesystem::path rotary;
};

// The demo drive's trace, written twice: as recorded on a linear axis and as a rotary table's SINUMERIK-style units.
const Files& files() {
    static const Files written = [] {
        Files f;
        f.dir = feedid::testing::suite_dir("rotary-axis");
        f.linear = f.dir / "linear.csv";
        f.rotary = f.dir / "rotary.csv";
        const feedid::SynthSpec spec = feedid::demo_spec();
        const feedid::Trace trace = feedid::synthesize(spec);
        const auto t = trace.column(feedid::Role::time);
        const auto reference = trace.column(feedid::Role::reference_position);
        const auto position = trace.column(feedid::Role::position);
        const auto command = trace.column(feedid::Role::velocity_command);
        const auto current = trace.column(feedid::Role::current);
        const double force_per_ampere = spec.force_constant_N_per_A();
        std::string linear = "t [s],x_ref [m],x [m],v_cmd [m/s],F [N]\n";
        std::string rotary = "t [s],phi_ref [deg],phi [deg],n_cmd [rpm],T [Nm]\n";
        for (std::size_t k = 0; k < trace.samples(); ++k) {
            const double force = force_per_ampere * current[k];
            linear += fmt::format("{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}\n", t[k], reference[k], position[k],
                                  command[k], force);
            rotary += fmt::format("{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}\n", t[k], reference[k] * degrees_per_m,
                                  position[k] * degrees_per_m, command[k] * rpm_per_m_per_s, force / s);
        }
        write_text(f.linear, linear);
        write_text(f.rotary, rotary);
        return f;
    }();
    return written;
}

const std::string linear_roles =
    " --channel reference_position=x_ref --channel position=x --channel "
    "velocity_command=v_cmd --channel force=F";
const std::string rotary_roles =
    " --channel reference_position=phi_ref --channel position=phi --channel "
    "velocity_command=n_cmd --channel force=T";

// Linear units and keys, as they could appear in printed text or a JSON document (the command line's own option
// names, such as lead_mm in a result's "options", are not units of the axis and are left out by the callers).
std::vector<std::string> linear_units_in(const std::string& text) {
    static const std::vector<std::regex> patterns{
        std::regex(R"(\bmm\b)"),
        std::regex(R"([^a-z]m/s)"),
        std::regex(R"(\(m/min\))"),
        std::regex(R"(N\*s/m)"),
        std::regex(R"(N/m\b)"),
        std::regex(R"(\bkg\b(?!\*m|·m))"),
        std::regex(R"([0-9] N\b(?!\*|·))"),
        std::regex(R"(\[N\])"),
        std::regex(R"(_(m|N|kg|mm|Ns_per_m|N_s_per_m|N_per_m|m_per_s|per_m_per_s|per_m|m_per_min_per_mm)\")"),
    };
    std::vector<std::string> found;
    for (const auto& pattern : patterns) {
        for (auto it = std::sregex_iterator(text.begin(), text.end(), pattern); it != std::sregex_iterator(); ++it) {
            const auto at = static_cast<std::size_t>(it->position());
            found.push_back(text.substr(at > 30 ? at - 30 : 0, 70));
        }
    }
    return found;
}

void expect_no_linear_units(const std::string& what, const std::string& text) {
    for (const auto& context : linear_units_in(text)) ADD_FAILURE() << what << ": a linear unit in '" << context << "'";
}

void expect_no_linear_units(const std::string& what, nlohmann::json document) {
    if (document.is_object()) document.erase("options");  // the command line as given (lead_mm, ...)
    expect_no_linear_units(what, document.dump());
}

nlohmann::json run_json(const std::string& arguments) {
    const auto result = run_cli(arguments + " --json -");
    EXPECT_EQ(result.exit_code, 0) << arguments << "\n" << result.err;
    return result.exit_code == 0 ? nlohmann::json::parse(result.out) : nlohmann::json::object();
}

// The ratio rotary/linear of a parameter, by its term.
double scale_of(feedid::Term term) {
    switch (term) {
        case feedid::Term::mass:
        case feedid::Term::viscous: return 1.0 / (s * s);
        case feedid::Term::coulomb:
        case feedid::Term::breakaway:
        case feedid::Term::offset: return 1.0 / s;
        case feedid::Term::stribeck_velocity: return s;
    }
    return 1.0;
}

}  // namespace

TEST(RotaryAxis, IdentifyGivesTheScaledParametersUnderRotaryKeys) {
    const auto& f = files();
    const auto linear = run_json("identify " + quoted(f.linear) + linear_roles);
    const auto rotary = run_json("identify " + quoted(f.rotary) + rotary_roles);
    ASSERT_TRUE(rotary.contains("parameters"));
    EXPECT_EQ(rotary.at("rotary"), true);
    EXPECT_TRUE(rotary["parameters"].contains("inertia_kgm2"));
    EXPECT_FALSE(rotary["parameters"].contains("mass_kg"));
    int compared = 0;
    for (const auto& [key, entry] : linear.at("parameters").items()) {
        const auto parsed = feedid::parse_parameter_key(key);
        ASSERT_TRUE(parsed && !parsed->rotary) << key;
        const std::string rotary_key = feedid::ParameterNaming{true}.key(parsed->term, parsed->direction);
        ASSERT_TRUE(rotary["parameters"].contains(rotary_key)) << rotary_key;
        const auto& value = entry.at("value");
        const auto& rotary_value = rotary["parameters"][rotary_key].at("value");
        ASSERT_EQ(value.is_number(), rotary_value.is_number()) << key;
        if (!value.is_number()) continue;
        const double expected = value.get<double>() * scale_of(parsed->term);
        EXPECT_NEAR(rotary_value.get<double>(), expected, 1e-6 * std::abs(expected)) << rotary_key;
        ++compared;
    }
    EXPECT_GE(compared, 4);
    EXPECT_NEAR(rotary["fit"]["relative_error_pct"].get<double>(), linear["fit"]["relative_error_pct"].get<double>(),
                1e-6);
    expect_no_linear_units("identify --json", rotary);

    const auto printed = run_cli("identify " + quoted(f.rotary) + rotary_roles);
    ASSERT_EQ(printed.exit_code, 0) << printed.err;
    EXPECT_NE(printed.out.find("kg*m^2"), std::string::npos) << printed.out;
    EXPECT_NE(printed.out.find("N*m*s/rad"), std::string::npos) << printed.out;
    expect_no_linear_units("identify", printed.out + printed.err);
}

TEST(RotaryAxis, GainsInRotaryUnitsAndKeys) {
    const auto& f = files();
    const auto linear = run_json("gains " + quoted(f.linear) + linear_roles);
    const auto rotary = run_json("gains " + quoted(f.rotary) + rotary_roles);
    ASSERT_TRUE(rotary.contains("gains"));
    const auto& g = rotary["gains"];
    EXPECT_EQ(rotary.at("rotary"), true);
    EXPECT_FALSE(g.contains("velocity_gain_N_s_per_m"));
    ASSERT_TRUE(g.contains("velocity_gain_Nms_per_rad")) << g.dump();
    const double kv = linear["gains"]["position_gain_per_s"]["value"].get<double>();
    const double kp = linear["gains"]["velocity_gain_N_s_per_m"]["value"].get<double>();
    EXPECT_NEAR(g["position_gain_per_s"]["value"].get<double>(), kv, 1e-6 * kv);
    EXPECT_NEAR(g["velocity_gain_Nms_per_rad"]["value"].get<double>(), kp / (s * s), 1e-6 * kp / (s * s));
    const auto& ki = linear["gains"]["velocity_integral_gain_N_per_m"]["value"];
    ASSERT_TRUE(ki.is_number());
    EXPECT_NEAR(g["velocity_integral_gain_Nm_per_rad"]["value"].get<double>(), ki.get<double>() / (s * s),
                1e-6 * ki.get<double>() / (s * s));
    EXPECT_FALSE(rotary["nc_units"].contains("kv_m_per_min_per_mm"));
    expect_no_linear_units("gains --json", rotary);

    const auto printed = run_cli("gains " + quoted(f.rotary) + rotary_roles);
    ASSERT_EQ(printed.exit_code, 0) << printed.err;
    EXPECT_NE(printed.out.find("N*m*s/rad"), std::string::npos) << printed.out;
    EXPECT_NE(printed.out.find("N*m/rad"), std::string::npos) << printed.out;
    expect_no_linear_units("gains", printed.out + printed.err);
}

TEST(RotaryAxis, SimulateAndReportInRotaryUnits) {
    const auto& f = files();
    const auto dir = feedid::testing::temp_dir();
    std::map<std::string, nlohmann::json> simulated;
    for (const auto& [kind, trace, roles] :
         {std::tuple{"linear", f.linear, linear_roles}, std::tuple{"rotary", f.rotary, rotary_roles}}) {
        const auto result = dir / (std::string(kind) + "-result.json");
        const auto gains = dir / (std::string(kind) + "-gains.json");
        ASSERT_EQ(run_cli("identify " + quoted(trace) + roles + " --json " + quoted(result)).exit_code, 0);
        ASSERT_EQ(run_cli("gains " + quoted(trace) + roles + " --json " + quoted(gains)).exit_code, 0);
        const std::string simulate =
            "simulate " + quoted(trace) + roles + " --result " + quoted(result) + " --gains " + quoted(gains);
        simulated[kind] = run_json(simulate);
        if (std::string(kind) != "rotary") continue;
        // The gains document reads back with its rotary keys: simulate used K_p in N*m*s/rad.
        EXPECT_TRUE(simulated[kind]["controller"].contains("velocity_gain_Nms_per_rad"));
        expect_no_linear_units("simulate --json", simulated[kind]);
        const auto printed = run_cli(simulate);
        ASSERT_EQ(printed.exit_code, 0) << printed.err;
        EXPECT_NE(printed.out.find("mrad"), std::string::npos) << printed.out;
        expect_no_linear_units("simulate", printed.out + printed.err);

        const auto sim_path = dir / "rotary-simulation.json";
        write_text(sim_path, simulated[kind].dump());
        const auto report = run_cli("report " + quoted(result) + " --simulation " + quoted(sim_path) + " -o -");
        ASSERT_EQ(report.exit_code, 0) << report.err;
        EXPECT_NE(report.out.find("rad"), std::string::npos);
        expect_no_linear_units("report", report.out);
    }
    for (const char* signal : {"position", "velocity", "force"}) {
        const double linear = simulated["linear"]["relative_error_pct"][signal].get<double>();
        const double rotary = simulated["rotary"]["relative_error_pct"][signal].get<double>();
        EXPECT_NEAR(rotary, linear, 1e-6 * linear + 1e-9) << signal;
    }
    const double linear_mae = simulated["linear"]["tracking_error_mae_m"]["model"].get<double>();
    EXPECT_NEAR(simulated["rotary"]["tracking_error_mae_rad"]["model"].get<double>(), linear_mae * s,
                1e-6 * linear_mae * s);
}

// plan takes a rotary axis in degrees (test_plan_cli has the whole chain); its degrees are checked against the travel.
TEST(RotaryAxis, PlanTakesARotaryAxisInDegrees) {
    auto result = run_cli("plan --axis C --travel=-400:400 --centers=0 -o -");
    EXPECT_EQ(result.exit_code, 0) << result.err;
    EXPECT_NE(result.out.find("(feedid "), std::string::npos);
    EXPECT_NE(result.out.find("for rotary axis C"), std::string::npos);
    result = run_cli("plan --axis C --travel=-10:10 --centers=0 -o /dev/null");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.err.find("goes to -14.860 deg, 4.860 deg beyond the travel minimum -10.000 deg"),
              std::string::npos)
        << result.err;
    EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << result.err;
}

TEST(RotaryAxis, DriveConstantWarningsAreShownAndKept) {
    const auto& f = files();
    // a 20 mm lead given in metres: 0.02 mm
    const auto result = run_cli("identify " + quoted(f.linear) + linear_roles + " --lead 0.02 --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_NE(result.err.find("feedid: warning: --lead 0.02 mm is outside 0.5 to 100 mm"), std::string::npos)
        << result.err;
    const auto document = nlohmann::json::parse(result.out);
    bool kept = false;
    for (const auto& line : document["diagnostics"]) kept = kept || line.get<std::string>().starts_with("--lead 0.02");
    EXPECT_TRUE(kept) << document["diagnostics"].dump();
}

TEST(RotaryAxis, GainsDocumentsReadBackWithEitherKeySet) {
    const nlohmann::json linear = nlohmann::json::parse(R"({"gains": {"position_gain_per_s": {"value": 33.3},
        "velocity_gain_N_s_per_m": {"value": 40000}, "velocity_integral_gain_N_per_m": {"value": 2e6}},
        "structure": {"saturation_N": 5000, "sample_time_s": 0.001}})");
    const nlohmann::json rotary = nlohmann::json::parse(R"({"rotary": true, "gains": {"position_gain_per_s":
        {"value": 33.3}, "velocity_gain_Nms_per_rad": {"value": 0.405}, "velocity_integral_gain_Nm_per_rad":
        {"value": 20.3}}, "structure": {"saturation_Nm": 2.5, "sample_time_s": 0.001}})");
    const auto from_linear = feedid::controller_from_document(linear, "linear.json");
    EXPECT_EQ(from_linear.velocity_gain_N_s_per_m, 40000.0);
    EXPECT_EQ(from_linear.velocity_integral_gain_N_per_m, 2e6);
    EXPECT_EQ(from_linear.saturation_N, 5000.0);
    const auto from_rotary = feedid::controller_from_document(rotary, "rotary.json");
    EXPECT_EQ(from_rotary.position_gain_per_s, 33.3);
    EXPECT_EQ(from_rotary.velocity_gain_N_s_per_m, 0.405);
    EXPECT_EQ(from_rotary.velocity_integral_gain_N_per_m, 20.3);
    EXPECT_EQ(from_rotary.saturation_N, 2.5);
    // without "rotary", the keys say which; a rotary document without its K_p names the rotary key
    auto unmarked = rotary;
    unmarked.erase("rotary");
    EXPECT_EQ(feedid::controller_from_document(unmarked, "unmarked.json").velocity_gain_N_s_per_m, 0.405);
    auto missing = rotary;
    missing["gains"].erase("velocity_gain_Nms_per_rad");
    try {
        (void)feedid::controller_from_document(missing, "missing.json");
        ADD_FAILURE() << "no InputError";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("velocity_gain_Nms_per_rad"), std::string::npos) << e.what();
    }
}

TEST(RotaryAxis, SimulateRefusesAResultOfTheOtherAxisKind) {
    const auto& f = files();
    const auto dir = feedid::testing::temp_dir();
    ASSERT_EQ(run_cli("identify " + quoted(f.linear) + linear_roles + " --json " + quoted(dir / "r.json")).exit_code,
              0);
    const auto result = run_cli("simulate " + quoted(f.rotary) + rotary_roles + " --result " + quoted(dir / "r.json"));
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.err.find("the result is of a linear axis"), std::string::npos) << result.err;
    EXPECT_NE(result.err.find("of a rotary axis"), std::string::npos) << result.err;
}

TEST(RotaryAxis, ASinumerikTraceStatedRotaryDropsTheLinearAssumption) {
    FEEDID_REQUIRE_SHARED("sinumerik-trace/X_BK300_1.xml");
    const auto path = feedid::testing::shared_data() / "sinumerik-trace/X_BK300_1.xml";
    const auto linear = run_cli("info " + quoted(path) + " --json -");
    ASSERT_EQ(linear.exit_code, 0) << linear.err;
    EXPECT_NE(linear.out.find("linear metric axis"), std::string::npos);
    // the same file read as a rotary axis (its numbers are not one; the units are what is checked): one statement
    // of the axis kind carries over to every posn and velo signal
    const auto stated_once = run_cli("info " + quoted(path) + " --unit position=deg --json -");
    ASSERT_EQ(stated_once.exit_code, 0) << stated_once.err;
    EXPECT_EQ(nlohmann::json::parse(stated_once.out).at("rotary"), true);
    // a CSV states its units per channel: a length beside an angle is still refused
    const auto mixed = feedid::testing::temp_dir() / "mixed-kinds.csv";
    feedid::testing::write_text(mixed, "t [s],x [deg],x_ref [mm]\n0,1,1\n0.001,2,2\n");
    const auto refused = run_cli("info " + quoted(mixed));
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_NE(refused.err.find("(reference_position) has unit 'mm'"), std::string::npos) << refused.err;
    EXPECT_NE(refused.err.find("axis is rotary"), std::string::npos) << refused.err;
    const auto rotary = run_cli("info " + quoted(path) +
                                " --unit position=deg --unit reference_position=deg --unit velocity=rpm "
                                "--unit velocity_command=rpm --json -");
    ASSERT_EQ(rotary.exit_code, 0) << rotary.err;
    const auto document = nlohmann::json::parse(rotary.out);
    EXPECT_EQ(document.at("rotary"), true);
    EXPECT_EQ(rotary.out.find("linear metric axis"), std::string::npos) << rotary.out;
}

TEST(RotaryAxis, FrictionMapPositionsInRadAndDegrees) {
    const auto& f = files();
    // the centre as given: 15 mm of table travel is 270 deg of the table (--centers takes deg on a rotary axis)
    const auto linear = run_json("identify " + quoted(f.linear) + linear_roles + " --by-location --centers=15");
    const auto rotary = run_json("identify " + quoted(f.rotary) + rotary_roles + " --by-location --centers=270");
    ASSERT_FALSE(linear["locations"].empty());
    ASSERT_EQ(rotary["locations"].size(), linear["locations"].size());
    EXPECT_EQ(rotary.at("rotary"), true);
    const double center_m = linear["locations"][0]["center_m"].get<double>();
    EXPECT_NEAR(center_m, 0.015, 1e-15);
    EXPECT_NEAR(rotary["locations"][0]["center_rad"].get<double>(), center_m * s, 1e-9 * std::abs(center_m * s));
    const double coulomb = linear["locations"][0]["parameters"]["coulomb_N"]["value"].get<double>();
    EXPECT_NEAR(rotary["locations"][0]["parameters"]["coulomb_Nm"]["value"].get<double>(), coulomb / s,
                1e-6 * coulomb / s);
    expect_no_linear_units("identify --by-location --json", rotary);
    const auto printed = run_cli("identify " + quoted(f.rotary) + rotary_roles + " --by-location --centers=270");
    ASSERT_EQ(printed.exit_code, 0) << printed.err;
    EXPECT_NE(printed.out.find("centre [deg]"), std::string::npos) << printed.out;
    EXPECT_NE(printed.out.find(fmt::format("{:.3f}", center_m * degrees_per_m)), std::string::npos) << printed.out;
    expect_no_linear_units("identify --by-location", printed.out + printed.err);
}
