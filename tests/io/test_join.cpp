// Two recorders joined onto one time base (--join), and the tare of a sensor's zero (--tare): on constructed traces
// whose shift and offset are known, and through the command line.
#include "feedid/io/join.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/import.hpp"
#include "feedid/io/tare.hpp"
#include "testing.hpp"

using namespace feedid;
using feedid::testing::run_cli;

namespace {

/// Samples every dt from t0, n of them, of f(t).
template <class F>
Trace sampled(const std::string& path, double t0, double dt, std::size_t n, const std::string& name, Role role,
              const std::string& unit, F f) {
    Trace trace;
    trace.source_path = path;
    std::vector<double> t(n), x(n);
    for (std::size_t k = 0; k < n; ++k) {
        t[k] = t0 + dt * static_cast<double>(k);
        x[k] = f(t[k]);
    }
    trace.set("time", Role::time, "s", std::move(t));
    trace.set(name, role, unit, std::move(x));
    return trace;
}

/// A smooth move with a distinct shape (no symmetry a wrong shift could match): a chirp under a bump.
double pulse(double t) {
    return std::exp(-std::pow((t - 0.3) / 0.08, 2)) * (1.0 + 0.3 * std::sin(40.0 * t * t));
}

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

std::string joined_findings(const Trace& trace) {
    std::string all;
    for (const auto& f : trace.findings) all += f + "\n";
    return all;
}

}  // namespace

TEST(Join, ResamplingIsExactOnLinearDataAfterTheShift) {
    // first: 1.5 kHz from 0; second: 2 kHz from 0, stamped 4 ms early (t_first = t_second + 0.004)
    const Trace first =
        sampled("drive.csv", 0.0, 1.0 / 1500.0, 1024, "speed", Role::velocity, "m/s", [](double t) { return t; });
    const double shift = 0.004;
    const Trace second = sampled("daq.csv", 0.0, 0.0005, 1077, "load", Role::force, "N",
                                 [&](double t) { return 3.0 + 250.0 * (t + shift); });  // on the first's time base
    JoinOptions options;
    options.shift_s = shift;
    JoinReport report;
    const Trace joined = join_traces(first, second, options, &report);
    const auto& t = joined.find(Role::time)->values;
    const auto& force = joined.find("load")->values;
    ASSERT_EQ(force.size(), t.size());
    for (std::size_t k = 0; k < t.size(); ++k) ASSERT_NEAR(force[k], 3.0 + 250.0 * t[k], 1e-9) << k;
    // the first trace's samples outside [0.004, 0.5420] dropped, never extrapolated
    EXPECT_GE(t.front(), 0.004 - 1e-12);
    EXPECT_LE(t.back(), 0.0005 * 1076 + 0.004 + 1e-12);
    EXPECT_EQ(report.dropped_before, 6u);  // 0, 0.67, ..., 3.33 ms
    EXPECT_EQ(report.dropped_before + report.dropped_after + t.size(), 1024u);
    EXPECT_TRUE(contains(joined_findings(joined), "dropped")) << joined_findings(joined);
    EXPECT_EQ(joined.find(Role::force)->name, "load");
    EXPECT_EQ(joined.find(Role::velocity)->name, "speed");
}

TEST(Join, ClashingNamesAreMadeUniqueAndSaid) {
    const Trace first = sampled("a.csv", 0.0, 0.001, 100, "x", Role::position, "m", [](double t) { return t; });
    const Trace second = sampled("b.csv", 0.0, 0.001, 100, "x", Role::other, "m", [](double t) { return 2 * t; });
    JoinOptions options;
    options.shift_s = 0.0;
    const Trace joined = join_traces(first, second, options);
    ASSERT_NE(joined.find("x_2"), nullptr);
    EXPECT_NEAR(joined.find("x_2")->values[50], 0.1, 1e-12);
    EXPECT_TRUE(contains(joined_findings(joined), "renamed 'x_2'")) << joined_findings(joined);
}

TEST(Join, AutomaticShiftRecoversAKnownDelayWithinOneSample) {
    const double dt = 1.0 / 1500.0;
    for (const double delay : {0.004, -0.0123, 0.0307}) {
        const Trace first =
            sampled("drive.csv", 0.0, dt, 1024, "speed", Role::velocity, "m/s", [](double t) { return pulse(t); });
        // the second recorder sees the same shape, scaled and inverted, and stamps it `delay` early
        const Trace second = sampled("daq.csv", 0.0, 0.0005, 1300, "load", Role::force, "N",
                                     [&](double t) { return 5.0 - 80.0 * pulse(t + delay); });
        JoinOptions options;
        options.ours = "speed";
        options.theirs = "load";
        JoinReport report;
        const Trace joined = join_traces(first, second, options, &report);
        EXPECT_TRUE(report.automatic);
        EXPECT_NEAR(report.shift_s, delay, dt) << "delay " << delay;
        EXPECT_LT(report.correlation, -0.99);  // inverted
        EXPECT_TRUE(contains(joined_findings(joined), "cross-correlation")) << joined_findings(joined);
    }
}

TEST(Join, AutomaticShiftNeedsChannelsToCompare) {
    const Trace first = sampled("a.csv", 0.0, 0.001, 100, "x", Role::position, "m", [](double t) { return t; });
    const Trace second = sampled("b.csv", 0.0, 0.001, 100, "f", Role::force, "N", [](double t) { return t; });
    try {
        (void)join_traces(first, second, JoinOptions{});
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_TRUE(contains(e.what(), "@auto:OURS=THEIRS")) << e.what();
    }
    JoinOptions named;
    named.ours = "x";
    named.theirs = "nothing";
    try {
        (void)join_traces(first, second, named);
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_TRUE(contains(e.what(), "b.csv has no channel named 'nothing'")) << e.what();
    }
}

TEST(Join, SpansThatDoNotOverlapAreRefused) {
    const Trace first = sampled("a.csv", 0.0, 0.001, 100, "x", Role::position, "m", [](double t) { return t; });
    const Trace second = sampled("b.csv", 5.0, 0.001, 100, "f", Role::force, "N", [](double t) { return t; });
    JoinOptions options;
    options.shift_s = 0.0;
    EXPECT_THROW((void)join_traces(first, second, options), InputError);
}

TEST(Join, TheShiftIsATimeWithAUnit) {
    EXPECT_NEAR(*parse_join_spec("daq.csv@4ms").options.shift_s, 0.004, 1e-15);
    EXPECT_NEAR(*parse_join_spec("daq.csv@-0.004").options.shift_s, -0.004, 1e-15);
    EXPECT_NEAR(*parse_join_spec("daq.csv@-4 ms").options.shift_s, -0.004, 1e-15);
    EXPECT_NEAR(*parse_join_spec("daq.csv@250us").options.shift_s, 0.00025, 1e-15);
    EXPECT_EQ(parse_join_spec("daq.csv").path, "daq.csv");
    EXPECT_EQ(*parse_join_spec("daq.csv").options.shift_s, 0.0);
    const JoinSpec automatic = parse_join_spec("dir/daq.csv@auto:Torque=Force");
    EXPECT_EQ(automatic.path, "dir/daq.csv");
    EXPECT_FALSE(automatic.options.shift_s);
    EXPECT_EQ(automatic.options.ours, "Torque");
    EXPECT_EQ(automatic.options.theirs, "Force");
    EXPECT_FALSE(parse_join_spec("daq.csv@auto").options.shift_s);
    for (const char* bad : {"daq.csv@4 furlongs", "daq.csv@", "daq.csv@auto:Torque", "@4ms", "daq.csv@4mm"}) {
        try {
            (void)parse_join_spec(bad);
            ADD_FAILURE() << bad << " accepted";
        } catch (const InputError& e) {
            EXPECT_TRUE(contains(e.what(), "--join")) << e.what();
        }
    }
}

// ---- tare

TEST(Tare, RemovesTheMeanOverTheLeadingRestSamples) {
    // at rest for 0.1 s, then moving; the load cell reads -26 N of offset plus the force of the move
    const double dt = 0.001;
    Trace trace = sampled("rig.csv", 0.0, dt, 500, "v", Role::velocity, "m/s",
                          [](double t) { return t < 0.1 - 1e-9 ? 0.0 : -1.0; });
    std::vector<double> force(500);
    for (std::size_t k = 0; k < force.size(); ++k) {
        const double t = dt * static_cast<double>(k);
        force[k] = -26.0 + (t < 0.1 - 1e-9 ? 0.0 : 40.0) + (k % 2 == 0 ? 0.5 : -0.5);  // alternating sensor noise
    }
    trace.set("F", Role::force, "N", force);
    const TareReport report = tare(trace, Role::force);
    EXPECT_NEAR(report.removed, -26.0, 0.5 / 40.0 + 1e-12);  // 80 rest samples of +-0.5: the mean is within 1/80
    EXPECT_EQ(report.samples, 80u);                          // 100 at rest (0 .. 0.099 s), less the last fifth
    EXPECT_NEAR(trace.find(Role::force)->values[300], force[300] - report.removed, 1e-12);
    EXPECT_TRUE(contains(joined_findings(trace), "--tare force")) << joined_findings(trace);
}

TEST(Tare, WithoutRestBeforeTheMoveItSaysSo) {
    Trace trace = sampled("rig.csv", 0.0, 0.001, 200, "v", Role::velocity, "m/s", [](double t) { return 0.5 + t; });
    trace.set("F", Role::force, "N", std::vector<double>(200, 1.0));
    try {
        (void)tare(trace, Role::force);
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_TRUE(contains(e.what(), "rig.csv: --tare force: only 0 samples at rest")) << e.what();
    }
    try {
        (void)tare(trace, Role::current);
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_TRUE(contains(e.what(), "no current channel")) << e.what();
    }
}

// ---- through the command line

namespace {

struct RigFiles {
    std::filesystem::path drive, daq;
};

/// A drive file (1.5 kHz, time in ms, speed in r/min) and a DAQ file (2 kHz, load cell in V with an offset) of one
/// move with known mass and friction, the DAQ stamped 4 ms early.
RigFiles write_rig(const std::filesystem::path& dir) {
    constexpr double lead = 0.020, mass = 24.7, viscous = 67.44, coulomb = 10.0, shift = 0.004, volts_per_N = 1.0 / 200;
    const auto speed = [](double t) {  // m/s: rest, a smooth ramp to -0.6 m/s and back
        if (t < 0.05 || t > 0.45) return 0.0;
        return -0.6 * std::pow(std::sin(std::numbers::pi * (t - 0.05) / 0.4), 2);
    };
    const auto acceleration = [](double t) {
        if (t < 0.05 || t > 0.45) return 0.0;
        const double w = std::numbers::pi / 0.4;
        return -0.6 * w * std::sin(2.0 * w * (t - 0.05));
    };
    std::string drive = "time [ms],speed [rpm]\n";
    for (int k = 0; k < 800; ++k) {
        const double t = k / 1500.0;
        drive += fmt::format("{:.9g},{:.9g}\n", t * 1e3, speed(t) / lead * 60.0);
    }
    std::string daq = "time [s],Force [V]\n";
    for (int k = 0; k < 1100; ++k) {
        const double t_daq = k * 0.0005, t = t_daq + shift;  // the drive's time of this sample
        const double v = speed(t);
        const double force = mass * acceleration(t) + viscous * v + (v < 0 ? -coulomb : v > 0 ? coulomb : 0.0);
        daq += fmt::format("{:.9g},{:.12g}\n", t_daq, -0.13 + force * volts_per_N);
    }
    RigFiles files{dir / "drive.csv", dir / "daq.csv"};
    feedid::testing::write_text(files.drive, drive);
    feedid::testing::write_text(files.daq, daq);
    return files;
}

}  // namespace

TEST(JoinCli, InfoListsTheJoinedChannelsAndTheShift) {
    const auto files = write_rig(feedid::testing::temp_dir());
    const auto run = run_cli("info '" + files.drive.string() + "' --join '" + files.daq.string() +
                             "@4ms' --lead 20 --channel current=Force --json -");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    EXPECT_TRUE(contains(run.out, "\"Force\"")) << run.out;
    EXPECT_TRUE(contains(run.err + run.out, "shifted by 4 ms")) << run.err << run.out;
}

TEST(JoinCli, IdentifyFromTheJoinedLoadCellRecoversTheMassAndFriction) {
    const auto files = write_rig(feedid::testing::temp_dir());
    const auto run = run_cli("identify '" + files.drive.string() + "' --join '" + files.daq.string() +
                             "@4ms' --lead 20 --channel current=Force --force-constant 200 --tare current "
                             "--no-stribeck --json -");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    const auto result = nlohmann::json::parse(run.out);
    EXPECT_EQ(result.at("preprocessing").at("velocity_source"), "velocity");
    EXPECT_NEAR(result.at("parameters").at("mass_kg").at("value").get<double>(), 24.7, 24.7 * 0.01);
    EXPECT_NEAR(result.at("parameters").at("viscous_Ns_per_m").at("value").get<double>(), 67.44, 67.44 * 0.02);
    EXPECT_NEAR(result.at("parameters").at("coulomb_N").at("value").get<double>(), 10.0, 10.0 * 0.03);
    EXPECT_TRUE(contains(run.err, "--tare current")) << run.err;
}

TEST(JoinCli, BadJoinsNameWhatIsWrong) {
    const auto files = write_rig(feedid::testing::temp_dir());
    const std::string drive = "'" + files.drive.string() + "' --lead 20 ";
    auto run = run_cli("info " + drive + "--join '" + files.daq.string() + "@4 parsecs'");
    EXPECT_EQ(run.exit_code, 2);
    EXPECT_TRUE(contains(run.err, "is not a time")) << run.err;
    run = run_cli("info " + drive + "--join '" + files.daq.string() + "@auto:speed=Nope'");
    EXPECT_EQ(run.exit_code, 2);
    EXPECT_TRUE(contains(run.err, "no channel named 'Nope'")) << run.err;
    run = run_cli("info " + drive + "--join '" + files.daq.string() + "' --channel force=Missing");
    EXPECT_EQ(run.exit_code, 2);
    EXPECT_TRUE(contains(run.err, "neither")) << run.err;
    run = run_cli("info " + drive + "--join '" + files.daq.string() + "@10s'");
    EXPECT_EQ(run.exit_code, 2);
    EXPECT_TRUE(contains(run.err, "does not overlap")) << run.err;
    run = run_cli("info " + drive + "--tare time");
    EXPECT_EQ(run.exit_code, 2);
    EXPECT_TRUE(contains(run.err, "--tare time")) << run.err;
    EXPECT_EQ(feedid::testing::count_lines(run.err), 1) << run.err;
}
