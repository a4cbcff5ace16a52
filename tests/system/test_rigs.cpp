// Acceptance on real recordings of other people's rigs (../shared/data/README.md):
//  - the Mitsubishi rack-and-pinion rig: the drive's MR Configurator2 export joined with the NI DAQ's load cell;
//    identify gives the moving mass the authors state (24.7 kg) and the friction of their fitted model at 0.3 m/s;
//  - the UMich mill's own 10 Hz log: friction only, the mass null with the reason in figures.
// The Stribeck step is left out on the rig: one move, no slow constant-speed passes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/identify/identify.hpp"
#include "testing.hpp"

namespace {

using feedid::testing::run_cli;
using feedid::testing::shared_data;
using Json = nlohmann::json;

std::string quoted(const std::filesystem::path& path) {
    return "'" + path.string() + "'";
}

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

double value(const Json& result, const std::string& key) {
    const auto& v = result.at("parameters").at(key).at("value");
    return v.is_number() ? v.get<double>() : NAN;
}

// The authors' processing (README): v = rpm * 20 mm / 60 (--lead 20), load cell 200 N/V (their sign is for the speed
// taken positive; with the drive's negative speed the driving force is +200 N/V), its zero from the samples at rest
// before the move (the move goes one way only: an offset would be collinear with Coulomb friction), the DAQ's time
// stamps 4 ms early against the drive's.
const std::string mitsubishi_arguments =
    " --lead 20 --channel current=Force --force-constant 200 --tare current --no-stribeck --json -";

// The authors' fitted friction model p = [10.0, 67.44, 29.63, 0.01352]: F = p1 + p2*v = 30.2 N at 0.3 m/s.
constexpr double published_mass_kg = 24.7, published_friction_at_0_3_N = 30.2;

double friction_at(const Json& result, double speed) {
    return value(result, "viscous_Ns_per_m") * speed + value(result, "coulomb_N");
}

}  // namespace

TEST(MitsubishiRig, TheJoinedLoadCellGivesTheMovingMassAndTheFriction) {
    FEEDID_REQUIRE_SHARED("mitsubishi-mr/a3MR.csv");
    const auto dir = shared_data() / "mitsubishi-mr";
    const auto run = run_cli("identify " + quoted(dir / "a3MR.csv") + " --join " + quoted(dir / "a3NI.csv") + "@4ms" +
                             " --channel 'velocity=Servo motor speed'" + mitsubishi_arguments);
    ASSERT_EQ(run.exit_code, 0) << run.err;
    const Json result = Json::parse(run.out);
    EXPECT_EQ(result.at("preprocessing").at("velocity_source"), "velocity");  // no position in either file
    // acceptance (issue 12): the mass within 4 %, the friction at 0.3 m/s within 5 %
    EXPECT_NEAR(value(result, "mass_kg"), published_mass_kg, 0.04 * published_mass_kg) << run.out;
    EXPECT_NEAR(friction_at(result, 0.3), published_friction_at_0_3_N, 0.05 * published_friction_at_0_3_N) << run.out;
    EXPECT_TRUE(contains(run.err, "--tare current")) << run.err;
    EXPECT_TRUE(contains(run.err, "shifted by 4 ms")) << run.err;
}

TEST(MitsubishiRig, AnAutomaticShiftIsReportedWithItsCorrelation) {
    FEEDID_REQUIRE_SHARED("mitsubishi-mr/a3MR.csv");
    const auto dir = shared_data() / "mitsubishi-mr";
    const auto run = run_cli("info " + quoted(dir / "a3MR.csv") + " --join " + quoted(dir / "a3NI.csv") +
                             "@auto:Torque=Force --lead 20");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    // the torque leads the load cell by the motor's own inertia: the broad peak lies at 6 to 9 ms (found outside
    // feedid with numpy), a few ms from the authors' 4 ms, and the figure is printed so that the user can judge it
    const std::string text = run.out + run.err;
    const std::regex finding(
        R"(shift ([-0-9.]+) ms found by cross-correlation \(correlation coefficient ([-0-9.]+)\))");
    std::smatch match;
    ASSERT_TRUE(std::regex_search(text, match, finding)) << text;
    EXPECT_GT(std::stod(match[1]), 6.0) << text;
    EXPECT_LT(std::stod(match[1]), 9.0) << text;
    EXPECT_GT(std::stod(match[2]), 0.9) << text;
}

namespace {

/// The mill log's columns of one axis (pandas CSV: an unnamed index column, 48 named ones, text columns), read here
/// with a plain split so that the test depends on the estimator, not on the CSV options of the importer: time from
/// the documented 100 ms per row, position [mm], velocity [mm/s], current [A] converted to SI.
feedid::Trace umich_axis(const std::filesystem::path& file, const std::string& axis) {
    std::istringstream text(feedid::testing::read_text(file));
    std::string line;
    std::getline(text, line);
    const auto split = [](const std::string& row) {
        std::vector<std::string> cells;
        std::stringstream cells_text(row);
        for (std::string cell; std::getline(cells_text, cell, ',');) cells.push_back(cell);
        return cells;
    };
    const auto header = split(line);
    const auto column = [&](const std::string& name) {
        const auto at = std::find(header.begin(), header.end(), axis + "_" + name);
        EXPECT_NE(at, header.end()) << name;
        return static_cast<std::size_t>(at - header.begin());
    };
    const std::size_t x = column("ActualPosition"), v = column("ActualVelocity"), i = column("CurrentFeedback");
    std::vector<double> time, position, velocity, current;
    while (std::getline(text, line)) {
        const auto cells = split(line);
        time.push_back(0.1 * static_cast<double>(time.size()));
        position.push_back(std::stod(cells.at(x)) * 1e-3);
        velocity.push_back(std::stod(cells.at(v)) * 1e-3);
        current.push_back(std::stod(cells.at(i)));
    }
    feedid::Trace trace;
    trace.source_path = file.string();
    trace.set("time", feedid::Role::time, "s", std::move(time));
    trace.set(axis + "_ActualPosition", feedid::Role::position, "m", std::move(position));
    trace.set(axis + "_ActualVelocity", feedid::Role::velocity, "m/s", std::move(velocity));
    trace.set(axis + "_CurrentFeedback", feedid::Role::current, "A", std::move(current));
    trace.validate();
    return trace;
}

}  // namespace

TEST(UmichMill, TheCoarseLogGivesFrictionOnlyForXAndY) {
    FEEDID_REQUIRE_SHARED("umich-cnc-mill/experiment_01.csv");
    const auto file = shared_data() / "umich-cnc-mill" / "experiment_01.csv";
    for (const std::string axis : {"X1", "Y1"}) {
        feedid::IdentifyOptions options;
        // the friction in the drive signal's unit (A): the log carries no motor data, and none is invented
        options.drive.force_constant = 1.0;
        // symmetric: the steady passes forward are all at the 6 mm/s feed, so B and F_C per direction are not
        // separable; the rapid moves at 18 (X) and 32 mm/s (Y) separate B from F_C when the directions share them
        const feedid::IdentifyResult result = feedid::identify(umich_axis(file, axis), options);
        ASSERT_EQ(result.status, feedid::Status::partial)
            << axis << ": " << (result.diagnostics.empty() ? "" : result.diagnostics.front());
        EXPECT_FALSE(result.find("mass_kg")->estimate.value) << axis;
        EXPECT_FALSE(result.find("breakaway_N")->estimate.value) << axis;
        for (const std::string key : {"viscous_Ns_per_m", "coulomb_N"}) {
            const auto& estimate = result.find(key)->estimate;
            ASSERT_TRUE(estimate.value && estimate.standard_error) << axis << " " << key;
            EXPECT_GT(*estimate.value, 0.0) << axis << " " << key;
            // determined: beyond 3 standard errors of zero. (This asked for a standard error below 25 % of the value,
            // which the standard errors met only while they left out that each steady pass keeps its own level: X1's
            // B rests on one rapid pass, and its honest standard error is 31 % of it.)
            EXPECT_GT(*estimate.value, 3.0 * *estimate.standard_error) << axis << " " << key;
        }
        ASSERT_TRUE(result.friction_only) << axis;
        const std::string& reason = result.friction_only->reason;
        EXPECT_TRUE(contains(reason, "mass not identifiable: 10 Hz sampling and")) << reason;
        EXPECT_TRUE(contains(reason, "mm position resolution")) << reason;
        EXPECT_FALSE(contains(reason, "micro-step")) << reason;
    }
}

TEST(UmichMill, PerDirectionTheLogSaysWhichSpeedIsMissing) {
    FEEDID_REQUIRE_SHARED("umich-cnc-mill/experiment_01.csv");
    const auto file = shared_data() / "umich-cnc-mill" / "experiment_01.csv";
    feedid::IdentifyOptions options;
    options.drive.force_constant = 1.0;
    options.model = feedid::FrictionModelKind::asymmetric;
    const feedid::IdentifyResult result = feedid::identify(umich_axis(file, "X1"), options);
    ASSERT_EQ(result.status, feedid::Status::failed);
    const std::string& why = result.diagnostics.back();
    EXPECT_TRUE(contains(why, "10 Hz sampling and 1 mm position resolution")) << why;
    EXPECT_TRUE(contains(why, "the steady speeds forward are nearly all")) << why;
    EXPECT_FALSE(contains(why, "micro-step")) << why;
}

TEST(UmichMill, TheCommandLineReadsThePandasFileAsItIs) {
    FEEDID_REQUIRE_SHARED("umich-cnc-mill/experiment_01.csv");
    const auto file = shared_data() / "umich-cnc-mill" / "experiment_01.csv";
    for (const std::string axis : {"X1", "Y1"}) {
        const auto run =
            run_cli("identify " + quoted(file) + " --axis " + axis +
                    " --sample-time 0.1 --unit position=mm --unit velocity=mm/s --unit reference_position=mm "
                    "--unit velocity_command=mm/s --force-constant 1 --json -");
        ASSERT_EQ(run.exit_code, 0) << axis << ": " << run.err;
        const Json document = Json::parse(run.out);
        EXPECT_EQ(document.at("status"), "partial") << axis;
        EXPECT_TRUE(document.at("parameters").at("mass_kg").at("value").is_null()) << axis;
        // the same numbers as the library on the columns read by hand (above)
        feedid::IdentifyOptions options;
        options.drive.force_constant = 1.0;
        const feedid::IdentifyResult library = feedid::identify(umich_axis(file, axis), options);
        for (const std::string key : {"viscous_Ns_per_m", "coulomb_N"}) {
            ASSERT_TRUE(library.find(key)->estimate.value) << axis << " " << key;
            EXPECT_NEAR(value(document, key), *library.find(key)->estimate.value,
                        1e-9 * std::abs(*library.find(key)->estimate.value))
                << axis << " " << key;
        }
        EXPECT_TRUE(contains(document.at("friction_only").at("reason").get<std::string>(), "10 Hz sampling")) << axis;
    }
}

namespace {

// The UMich log of X1 with its position written 50 mm off on every 50th row (a glitch of the log, as some of the
// mill's other runs have): 21 rows, 42 jumps, the first at t = 5 s.
std::filesystem::path umich_with_jumps() {
    const auto source = shared_data() / "umich-cnc-mill" / "experiment_01.csv";
    const auto out = feedid::testing::temp_dir() / "umich_jumps.csv";
    std::ifstream in(source);
    std::ofstream file(out);
    std::string line;
    std::getline(in, line);
    file << line << '\n';
    std::vector<std::string> header;
    std::stringstream names(line);
    for (std::string cell; std::getline(names, cell, ',');) header.push_back(cell);
    const auto x = static_cast<std::size_t>(std::find(header.begin(), header.end(), "X1_ActualPosition") - header.begin());
    for (std::size_t row = 0; std::getline(in, line); ++row) {
        std::vector<std::string> cells;
        std::stringstream text(line);
        for (std::string cell; std::getline(text, cell, ',');) cells.push_back(cell);
        if (row > 0 && row % 50 == 0) cells.at(x) = std::to_string(std::stod(cells.at(x)) + 50.0);
        for (std::size_t c = 0; c < cells.size(); ++c) file << (c > 0 ? "," : "") << cells[c];
        file << '\n';
    }
    return out;
}

const std::string umich_options =
    " --axis X1 --sample-time 0.1 --unit position=mm --unit velocity=mm/s --unit reference_position=mm "
    "--unit velocity_command=mm/s --force-constant 1";

}  // namespace

// A position that jumps is named as such, with the count and where, not taken for a unit error; and the logged
// velocity alone (--channel position=none) gives the friction of the log without the jumps, M null with the reason.
TEST(UmichMill, APositionThatJumpsIsNamedAndTheVelocityAloneGivesTheFriction) {
    FEEDID_REQUIRE_SHARED("umich-cnc-mill/experiment_01.csv");
    const auto jumpy = umich_with_jumps();
    const auto refused = run_cli("identify " + quoted(jumpy) + umich_options + " --json -");
    EXPECT_EQ(refused.exit_code, 2) << refused.err;
    const std::string last = refused.err.substr(refused.err.rfind("feedid: "));
    EXPECT_TRUE(contains(last, "'X1_ActualPosition' jumps 42 times between samples (first at t = 5 s")) << last;
    EXPECT_TRUE(contains(last, "--channel position=none")) << last;
    EXPECT_FALSE(contains(last, "units is wrong")) << last;
    const auto scanned = run_cli("scan " + quoted(jumpy) + umich_options + " --json -");
    EXPECT_EQ(scanned.exit_code, 2) << scanned.err;
    EXPECT_TRUE(contains(scanned.err, "jumps 42 times")) << scanned.err;

    const auto clean =
        run_cli("identify " + quoted(shared_data() / "umich-cnc-mill" / "experiment_01.csv") + umich_options +
                " --json -");
    ASSERT_EQ(clean.exit_code, 0) << clean.err;
    const auto velocity_only = run_cli("identify " + quoted(jumpy) + umich_options + " --channel position=none --json -");
    ASSERT_EQ(velocity_only.exit_code, 0) << velocity_only.err;
    const Json with = Json::parse(clean.out), without = Json::parse(velocity_only.out);
    EXPECT_TRUE(without.at("parameters").at("mass_kg").at("value").is_null());
    EXPECT_TRUE(contains(without.at("friction_only").at("reason").get<std::string>(), "mass not identifiable: 10 Hz"));
    for (const std::string key : {"viscous_Ns_per_m", "coulomb_N"}) {
        ASSERT_FALSE(without.at("parameters").at(key).at("value").is_null()) << key;
        EXPECT_GT(value(without, key), 0.0) << key;
        // the friction-only step reads the logged velocity: the same numbers as the log with its position
        EXPECT_NEAR(value(without, key), value(with, key), 1e-9 * std::abs(value(with, key))) << key;
    }
}

namespace {

double standard_error(const Json& result, const std::string& key) {
    const auto& v = result.at("parameters").at(key).at("stderr");
    return v.is_number() ? v.get<double>() : NAN;
}

}  // namespace

// scan applies identify's rule for a log too coarse for a mass: M null with the reason in figures, the friction from
// the steady-speed samples; the two agree within their combined standard error (README's options, X1 and Y1), also
// from the logged velocity alone (--channel position=none), where scan had exited 1 with 50 low_excitation windows.
TEST(UmichMill, ScanAndIdentifyAgreeOnTheCoarseLogWithinTheirUncertainties) {
    FEEDID_REQUIRE_SHARED("umich-cnc-mill/experiment_01.csv");
    const auto file = quoted(shared_data() / "umich-cnc-mill" / "experiment_01.csv");
    const std::string options =
        " --sample-time 0.1 --unit position=mm --unit velocity=mm/s --unit reference_position=mm "
        "--unit velocity_command=mm/s --force-constant 1 --json -";
    for (const std::string axis : {"X1", "Y1"}) {
        const auto identified = run_cli("identify " + file + " --axis " + axis + options);
        ASSERT_EQ(identified.exit_code, 0) << axis << ": " << identified.err;
        const Json reference = Json::parse(identified.out);
        for (const std::string extra : {"", " --channel position=none"}) {
            const auto scanned = run_cli("scan " + file + " --axis " + axis + options + extra);
            ASSERT_EQ(scanned.exit_code, 0) << axis << extra << ": " << scanned.err;
            const Json document = Json::parse(scanned.out);
            EXPECT_EQ(document.at("kind"), "scan");
            EXPECT_EQ(document.at("status"), "partial") << axis << extra;
            EXPECT_TRUE(document.at("parameters").at("mass_kg").at("value").is_null()) << axis << extra;
            EXPECT_TRUE(contains(document.at("friction_only").at("reason").get<std::string>(),
                                 "mass not identifiable: 10 Hz sampling"))
                << axis << extra;
            for (const std::string key : {"viscous_Ns_per_m", "coulomb_N"}) {
                const double scan_value = value(document, key), identify_value = value(reference, key);
                const double combined = std::hypot(standard_error(document, key), standard_error(reference, key));
                ASSERT_TRUE(std::isfinite(scan_value) && std::isfinite(combined)) << axis << extra << " " << key;
                EXPECT_GT(scan_value, 0.0) << axis << extra << " " << key;
                EXPECT_LE(std::abs(scan_value - identify_value), combined) << axis << extra << " " << key;
            }
        }
    }
}

// A file read in blocks (--block-rows; any CSV above 256 MB) applies the coarse-log rule and the velocity-only mode as
// the whole file does: the first block judged, the coarse log then read whole and given the same result, also with
// its time from --sample-time and without its position.
TEST(UmichMill, ReadInBlocksTheCoarseLogGivesTheWholeFilesResult) {
    FEEDID_REQUIRE_SHARED("umich-cnc-mill/experiment_01.csv");
    const auto file = quoted(shared_data() / "umich-cnc-mill" / "experiment_01.csv");
    const std::string options =
        " --sample-time 0.1 --unit position=mm --unit velocity=mm/s --unit reference_position=mm "
        "--unit velocity_command=mm/s --force-constant 1 --json -";
    for (const std::string axis : {"X1", "Y1"}) {
        for (const std::string extra : {"", " --channel position=none"}) {
            const auto whole = run_cli("scan " + file + " --axis " + axis + options + extra);
            const auto blocks = run_cli("scan " + file + " --axis " + axis + options + extra + " --block-rows 1000");
            ASSERT_EQ(whole.exit_code, 0) << axis << extra << ": " << whole.err;
            ASSERT_EQ(blocks.exit_code, 0) << axis << extra << ": " << blocks.err;
            const Json a = Json::parse(whole.out), b = Json::parse(blocks.out);
            ASSERT_TRUE(b.contains("friction_only")) << axis << extra;
            EXPECT_EQ(a.at("friction_only"), b.at("friction_only")) << axis << extra;
            EXPECT_EQ(a.at("parameters"), b.at("parameters")) << axis << extra;
            EXPECT_EQ(a.at("trace").at("samples"), b.at("trace").at("samples")) << axis << extra;
            EXPECT_TRUE(b.at("parameters").at("mass_kg").at("value").is_null()) << axis << extra;
        }
    }
}
