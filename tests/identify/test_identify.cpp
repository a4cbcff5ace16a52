// feedid identify against things nobody here wrote: the EMPS benchmark's published IDIM-LS results on its real
// recording, and synthetic drives with known parameters (generated here, open loop, with a quantised encoder and a
// noisy current). And what it says when the data cannot tell.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/sim/synth.hpp"
#include "testing.hpp"

namespace {

using feedid::testing::run_cli;
using Json = nlohmann::json;

// ---------------------------------------------------------------------------------------------------------------
// EMPS (../shared/data/README.md): published IDIM-LS on DATA_EMPS.mat.

const std::string emps_arguments = "--channel position=qm --channel current=vir --force-constant gtau";
// The EMPS reference preprocessing: 4th-order Butterworth at 100 Hz forwards and backwards, central differences,
// 49 edge samples dropped, every column decimated by 12, least squares on all the decimated samples.
const std::string emps_preprocessing =
    "--filter-order 4 --cutoff 100 --decimate 12 --edge-samples 49 --split-velocity 0 --moving-threshold 0";

Json identify_emps(const std::string& options) {
    const auto emps = feedid::testing::shared_data() / "emps" / "DATA_EMPS.mat";
    const auto run = run_cli("identify '" + emps.string() + "' " + emps_arguments + " " + options + " --json -");
    EXPECT_EQ(run.exit_code, 0) << run.err;
    return Json::parse(run.out.empty() ? std::string("{}") : run.out);
}

double value(const Json& result, const std::string& key) {
    const auto& v = result.at("parameters").at(key).at("value");
    return v.is_number() ? v.get<double>() : NAN;
}

#define EXPECT_WITHIN_PCT(actual, expected, pct) \
    EXPECT_NEAR((actual), (expected), std::abs(expected) * (pct) / 100.0) << #actual

TEST(IdentifyEmps, DefaultOptionsMatchThePublishedValues) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const Json result = identify_emps("--offset");
    if (HasFailure()) return;
    EXPECT_EQ(result.at("status"), "partial");  // F_B and v_s null
    EXPECT_WITHIN_PCT(value(result, "mass_kg"), 95.1089, 2.0);
    EXPECT_WITHIN_PCT(value(result, "viscous_Ns_per_m"), 203.5034, 2.0);
    EXPECT_WITHIN_PCT(value(result, "coulomb_N"), 20.3935, 2.0);
    EXPECT_WITHIN_PCT(value(result, "offset_N"), -3.1648, 10.0);
    // EMPS holds no slow constant-velocity passes: F_B and v_s are not pulled from noise
    EXPECT_TRUE(result.at("parameters").at("breakaway_N").at("value").is_null());
    EXPECT_TRUE(result.at("parameters").at("stribeck_velocity_m_per_s").at("value").is_null());
    EXPECT_FALSE(result.at("diagnostics").empty());
}

TEST(IdentifyEmps, ThePublishedPreprocessingReproducesTheBatchEstimate) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const Json result = identify_emps("--offset " + emps_preprocessing);
    if (HasFailure()) return;
    const Json& batch = result.at("step1").at("batch");
    EXPECT_WITHIN_PCT(batch.at("mass_kg").at("value").get<double>(), 95.1089, 0.5);
    EXPECT_WITHIN_PCT(batch.at("viscous_Ns_per_m").at("value").get<double>(), 203.5034, 0.5);
    EXPECT_WITHIN_PCT(batch.at("coulomb_N").at("value").get<double>(), 20.3935, 0.5);
    EXPECT_WITHIN_PCT(batch.at("offset_N").at("value").get<double>(), -3.1648, 3.0);
    EXPECT_WITHIN_PCT(result.at("fit").at("relative_error_pct").get<double>(), 4.0834, 5.0);
    EXPECT_WITHIN_PCT(result.at("fit").at("condition_number").get<double>(), 25.9883, 5.0);
    // the textbook standard errors (white residuals) are the published standard deviations' order: within a factor
    // 1.5; the reported ones allow for the residuals' correlation over neighbouring samples and are no smaller
    const Json& white = result.at("step1").at("white_noise_stderr");
    EXPECT_NEAR(white.at("mass_kg").get<double>(), 0.1085, 0.5 * 0.1085);
    EXPECT_NEAR(white.at("viscous_Ns_per_m").get<double>(), 1.1460, 0.5 * 1.1460);
    EXPECT_NEAR(white.at("coulomb_N").get<double>(), 0.1012, 0.5 * 0.1012);
    for (const std::string key : {"mass_kg", "viscous_Ns_per_m", "coulomb_N", "offset_N"})
        EXPECT_GE(batch.at(key).at("stderr").get<double>(), white.at(key).get<double>()) << key;
}

TEST(IdentifyEmps, PerDirectionFrictionMatchesThePublishedValues) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const Json result = identify_emps("--model asymmetric");
    if (HasFailure()) return;
    EXPECT_WITHIN_PCT(value(result, "mass_kg"), 95.1540, 3.0);
    EXPECT_WITHIN_PCT(value(result, "viscous_forward_Ns_per_m"), 166.7061, 3.0);
    EXPECT_WITHIN_PCT(value(result, "coulomb_forward_N"), 20.1440, 3.0);
    EXPECT_WITHIN_PCT(value(result, "viscous_reverse_Ns_per_m"), 240.4236, 3.0);
    EXPECT_WITHIN_PCT(value(result, "coulomb_reverse_N"), 20.6277, 3.0);
}

TEST(IdentifyEmps, RlsFinalValueAgreesWithTheBatchEstimate) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    for (const std::string variant : {"directional", "paper"}) {
        const Json result = identify_emps("--offset --rls " + variant);
        if (HasFailure()) return;
        const Json& batch = result.at("step1").at("batch");
        const Json& final = result.at("rls").at("final");
        for (const std::string key : {"mass_kg", "viscous_Ns_per_m", "coulomb_N"}) {
            EXPECT_WITHIN_PCT(final.at(key).get<double>(), batch.at(key).at("value").get<double>(), 2.0)
                << variant << " " << key;
        }
    }
}

TEST(IdentifyEmps, TheTableIsReadable) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto emps = feedid::testing::shared_data() / "emps" / "DATA_EMPS.mat";
    const auto run = run_cli("identify '" + emps.string() + "' " + emps_arguments + " --offset");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    EXPECT_NE(run.out.find("M "), std::string::npos) << run.out;
    EXPECT_NE(run.out.find("kg"), std::string::npos) << run.out;
    EXPECT_NE(run.out.find("±"), std::string::npos) << run.out;
    EXPECT_NE(run.out.find("N*s/m"), std::string::npos) << run.out;
}

// ---------------------------------------------------------------------------------------------------------------
// Synthetic drives with known parameters, generated here: velocity passes with smooth (cosine) ramps at a ladder of
// feeds in both directions, the exact acceleration, the friction of eq. (3) per direction, a 50 nm encoder and a
// current with white noise. Open loop: the axis follows the profile exactly (no stick-slip).

struct Branch {
    double viscous, coulomb, breakaway, stribeck_velocity;
    [[nodiscard]] double friction(double speed) const {
        return viscous * speed + coulomb + (breakaway - coulomb) * std::exp(-speed / stribeck_velocity);
    }
};

struct Drive {
    double mass;
    Branch forward, reverse;
    double offset{0.0};
};

struct Profile {
    std::vector<double> t, x, v, a;
};

// One pass: ramp up to `speed` (signed) in `ramp` s, cruise `cruise` s, ramp down, dwell.
void append_pass(Profile& p, double speed, double ramp, double cruise, double dwell, double dt) {
    const auto push = [&](double v, double a) {
        const double t = p.t.empty() ? 0.0 : p.t.back() + dt;
        const double x = p.x.empty() ? 0.0 : p.x.back() + 0.5 * (v + p.v.back()) * dt;
        p.t.push_back(t);
        p.x.push_back(x);
        p.v.push_back(v);
        p.a.push_back(a);
    };
    const double pi = std::numbers::pi;
    const auto steps = [&](double seconds) { return static_cast<int>(std::lround(seconds / dt)); };
    for (int k = 1; k <= steps(ramp); ++k) {
        const double s = k * dt / ramp;
        push(speed * 0.5 * (1.0 - std::cos(pi * s)), speed * 0.5 * pi / ramp * std::sin(pi * s));
    }
    for (int k = 0; k < steps(cruise); ++k) push(speed, 0.0);
    for (int k = 1; k <= steps(ramp); ++k) {
        const double s = k * dt / ramp;
        push(speed * 0.5 * (1.0 + std::cos(pi * s)), -speed * 0.5 * pi / ramp * std::sin(pi * s));
    }
    for (int k = 0; k < steps(dwell); ++k) push(0.0, 0.0);
}

feedid::Trace synthetic_trace(const Drive& drive, const std::vector<double>& feeds, unsigned seed) {
    const double dt = 1e-3;
    Profile p;
    for (int k = 0; k < 200; ++k) {
        p.t.push_back(k * dt);
        p.x.push_back(0.0);
        p.v.push_back(0.0);
        p.a.push_back(0.0);
    }
    for (const double feed : feeds) {
        const double ramp = std::max(0.05, feed / 2.0);  // at most 2 m/s^2 * pi/2
        const double cruise = std::clamp(0.01 / feed, 0.6, 1.5);
        append_pass(p, feed, ramp, cruise, 0.2, dt);
        append_pass(p, -feed, ramp, cruise, 0.2, dt);
    }
    std::mt19937 random(seed);
    std::normal_distribution<double> current_noise(0.0, 0.01);  // A
    const double quantum = 50e-9, force_per_ampere = 100.0;
    std::vector<double> x(p.t.size()), current(p.t.size());
    for (std::size_t k = 0; k < p.t.size(); ++k) {
        const double v = p.v[k];
        double friction = 0.0;  // at rest the drive holds nothing (open loop, no external force)
        if (v > 0) friction = drive.forward.friction(v);
        if (v < 0) friction = -drive.reverse.friction(-v);
        const double force = drive.mass * p.a[k] + friction + drive.offset;
        current[k] = force / force_per_ampere + current_noise(random);
        x[k] = quantum * std::round(p.x[k] / quantum);
    }
    feedid::Trace trace;
    trace.format = "synthetic";
    trace.set("t", feedid::Role::time, "s", p.t);
    trace.set("x", feedid::Role::position, "m", std::move(x));
    trace.set("i", feedid::Role::current, "A", std::move(current));
    trace.constants["force_constant"] = force_per_ampere;
    trace.validate();
    return trace;
}

nlohmann::json document_of(const feedid::IdentifyResult& r) {
    return r;
}

feedid::IdentifyOptions options_for(feedid::FrictionModelKind model, bool offset = false) {
    feedid::IdentifyOptions options;
    options.model = model;
    options.offset = offset;
    options.model_selection.automatic = false;  // the model named, as --model forces it
    options.drive.force_constant_name = "force_constant";
    return options;
}

const std::vector<double> slow_and_fast = {0.0005, 0.001, 0.002, 0.003, 0.005, 0.008, 0.012, 0.02, 0.05, 0.1, 0.2, 0.3};
const std::vector<double> papers_ladder = {0.02, 0.05, 0.1, 0.2, 0.3};  // fast passes only

const Drive asymmetric_drive{50.0, {80.0, 100.0, 130.0, 0.004}, {95.0, 110.0, 150.0, 0.005}};

double estimate(const feedid::IdentifyResult& r, const std::string& key) {
    const auto* p = r.find(key);
    return p && p->estimate.value ? *p->estimate.value : NAN;
}

TEST(IdentifySynthetic, PerDirectionFrictionWithSlowPasses) {
    const auto trace = synthetic_trace(asymmetric_drive, slow_and_fast, 7);
    const auto r = feedid::identify(trace, options_for(feedid::FrictionModelKind::asymmetric));
    ASSERT_NE(r.status, feedid::Status::failed) << document_of(r).dump(1);
    EXPECT_WITHIN_PCT(estimate(r, "mass_kg"), 50.0, 2.0);
    for (const auto& [name, branch] : {std::pair{std::string("forward"), asymmetric_drive.forward},
                                       std::pair{std::string("reverse"), asymmetric_drive.reverse}}) {
        SCOPED_TRACE(name);
        EXPECT_WITHIN_PCT(estimate(r, "viscous_" + name + "_Ns_per_m"), branch.viscous, 2.0);
        EXPECT_WITHIN_PCT(estimate(r, "coulomb_" + name + "_N"), branch.coulomb, 2.0);
        EXPECT_WITHIN_PCT(estimate(r, "breakaway_" + name + "_N"), branch.breakaway, 5.0);
        EXPECT_WITHIN_PCT(estimate(r, "stribeck_velocity_" + name + "_m_per_s"), branch.stribeck_velocity, 15.0);
    }
}

TEST(IdentifyFamily, EstimatesOnlyRerunsGiveTheEstimatesWithoutTheFitChecks) {
    // the preprocessing family's reruns (estimates_only) skip the lack-of-fit checks: those scale standard errors and
    // may set the status partial, they never move an estimate
    const auto trace = synthetic_trace(asymmetric_drive, slow_and_fast, 7);
    auto options = options_for(feedid::FrictionModelKind::asymmetric);
    options.systematic = false;
    const auto full = feedid::identify(trace, options);
    options.estimates_only = true;
    const auto rerun = feedid::identify(trace, options);
    ASSERT_NE(full.status, feedid::Status::failed) << document_of(full).dump(1);
    ASSERT_TRUE(full.model_choice && rerun.model_choice);
    EXPECT_FALSE(full.model_choice->fit_checks.empty());
    EXPECT_TRUE(rerun.model_choice->fit_checks.empty());
    ASSERT_EQ(full.parameters.size(), rerun.parameters.size());
    for (std::size_t i = 0; i < full.parameters.size(); ++i) {
        SCOPED_TRACE(full.parameters[i].key);
        ASSERT_TRUE(full.parameters[i].estimate.value && rerun.parameters[i].estimate.value);
        EXPECT_NEAR(*rerun.parameters[i].estimate.value, *full.parameters[i].estimate.value,
                    1e-12 * std::abs(*full.parameters[i].estimate.value));
    }
}

TEST(IdentifySynthetic, SymmetricDriveWithAnOffset) {
    const Drive drive{120.0, {60.0, 300.0, 380.0, 0.003}, {60.0, 300.0, 380.0, 0.003}, 150.0};
    const auto trace = synthetic_trace(drive, slow_and_fast, 11);
    const auto r = feedid::identify(trace, options_for(feedid::FrictionModelKind::symmetric, true));
    ASSERT_NE(r.status, feedid::Status::failed) << document_of(r).dump(1);
    EXPECT_WITHIN_PCT(estimate(r, "mass_kg"), 120.0, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "viscous_Ns_per_m"), 60.0, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "coulomb_N"), 300.0, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "offset_N"), 150.0, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "breakaway_N"), 380.0, 5.0);
    EXPECT_WITHIN_PCT(estimate(r, "stribeck_velocity_m_per_s"), 0.003, 15.0);
}

TEST(IdentifySynthetic, ThePapersLadderAloneLeavesBreakawayAndStribeckNull) {
    const auto trace = synthetic_trace(asymmetric_drive, papers_ladder, 3);
    const auto r = feedid::identify(trace, options_for(feedid::FrictionModelKind::asymmetric));
    ASSERT_NE(r.status, feedid::Status::failed) << document_of(r).dump(1);
    for (const std::string name : {"forward", "reverse"}) {
        SCOPED_TRACE(name);
        const auto* fb = r.find("breakaway_" + name + "_N");
        const auto* vs = r.find("stribeck_velocity_" + name + "_m_per_s");
        ASSERT_NE(fb, nullptr);
        ASSERT_NE(vs, nullptr);
        EXPECT_FALSE(fb->estimate.value.has_value()) << *fb->estimate.value;
        EXPECT_FALSE(vs->estimate.value.has_value()) << *vs->estimate.value;
        EXPECT_TRUE(document_of(r).at("parameters").at("breakaway_" + name + "_N").at("value").is_null());
    }
    bool explained = false;
    for (const auto& d : r.diagnostics) explained |= d.find("F_B and v_s") != std::string::npos;
    EXPECT_TRUE(explained) << ::testing::PrintToString(r.diagnostics);
    // and what it does estimate is still right
    EXPECT_WITHIN_PCT(estimate(r, "mass_kg"), 50.0, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "coulomb_forward_N"), 100.0, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "coulomb_reverse_N"), 110.0, 2.0);
}

TEST(IdentifySynthetic, ARotaryAxisReportsInertiaAndTorques) {
    // the same numbers read as a rotary table: rad, rad/s, N*m, kg*m^2
    const Drive drive{0.8, {0.5, 12.0, 15.0, 0.02}, {0.5, 12.0, 15.0, 0.02}};
    std::vector<double> feeds;
    for (const double f : slow_and_fast) feeds.push_back(10.0 * f);  // rad/s
    auto trace = synthetic_trace(drive, feeds, 13);
    trace.rotary = true;
    trace.find(feedid::Role::position)->unit = "rad";
    const auto r = feedid::identify(trace, options_for(feedid::FrictionModelKind::symmetric));
    ASSERT_NE(r.status, feedid::Status::failed) << document_of(r).dump(1);
    EXPECT_TRUE(document_of(r).at("rotary").get<bool>());
    EXPECT_WITHIN_PCT(estimate(r, "inertia_kgm2"), 0.8, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "viscous_Nms_per_rad"), 0.5, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "coulomb_Nm"), 12.0, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "breakaway_Nm"), 15.0, 5.0);
    EXPECT_WITHIN_PCT(estimate(r, "stribeck_velocity_rad_per_s"), 0.02, 15.0);
    EXPECT_FALSE(document_of(r).at("parameters").contains("mass_kg"));
}

// ---------------------------------------------------------------------------------------------------------------
// Closed loop (feedid synth's twin: P-PI cascade, 0.3 ms current lag, stick-slip; the paper's drive, the feed ladder
// with slow passes). The transients carry more than M*a (the lag, the drive signal held over a sample); the
// friction curve must not pick it up.

struct ClosedLoopTruth {
    double mass, viscous, coulomb, breakaway, stribeck_velocity;
};

ClosedLoopTruth truth_of(const feedid::SynthSpec& spec) {
    const auto& f = spec.axis.friction.forward;
    return {spec.axis.mass, f.viscous, f.coulomb, f.breakaway.value_or(NAN), f.stribeck_velocity.value_or(NAN)};
}

feedid::IdentifyResult identify_closed_loop(const feedid::SynthSpec& spec) {
    return feedid::identify(synthesize(spec), [] {
        feedid::IdentifyOptions options;
        options.drive.force_constant_name = "force_constant_N_per_A";
        return options;
    }());
}

TEST(IdentifyClosedLoop, TheTransientsDoNotBiasTheFrictionCurve) {
    // Exact current (no noise, no quantum): what is left is the model's own bias. A joint fit of M and the curve
    // over every sample put B 5 % high here.
    feedid::SynthSpec spec = feedid::demo_spec();
    spec.sensors.current_noise_A = 0.0;
    spec.sensors.current_resolution_A = 0.0;
    const auto truth = truth_of(spec);
    const auto r = identify_closed_loop(spec);
    ASSERT_EQ(r.status, feedid::Status::ok) << document_of(r).dump(1);
    EXPECT_WITHIN_PCT(estimate(r, "mass_kg"), truth.mass, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "viscous_Ns_per_m"), truth.viscous, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "coulomb_N"), truth.coulomb, 2.0);
    EXPECT_WITHIN_PCT(estimate(r, "breakaway_N"), truth.breakaway, 5.0);
    EXPECT_WITHIN_PCT(estimate(r, "stribeck_velocity_m_per_s"), truth.stribeck_velocity, 15.0);
    EXPECT_EQ(document_of(r).at("stribeck").at("nonlinear").at("method"),
              "quasi-static curve, mass from the transients");
}

TEST(IdentifyClosedLoop, DecimatingLeavesTheFrictionCurveWhereItWas) {
    // Step 2 fits the decimated force as a function of the decimated speed: the anti-alias filter's gain at 0 Hz
    // (0.9886 forwards and backwards) once put F_C and F_B 1.1 % low on this trace decimated by 2, 46 and 26 of their
    // standard errors. Decimated, the curve stays within 3 of its standard errors of the undecimated one and of the
    // truth (or 0.05 % of it: the undecimated fit's own bias is about that).
    const feedid::SynthSpec spec = feedid::demo_spec();
    const auto trace = synthesize(spec);
    const auto truth = truth_of(spec);
    const auto run = [&](int factor) {
        feedid::IdentifyOptions options;
        options.drive.force_constant_name = "force_constant_N_per_A";
        options.systematic = false;
        options.preprocess.decimation = factor;
        return feedid::identify(trace, options);
    };
    const auto full = run(1);
    ASSERT_EQ(full.status, feedid::Status::ok) << document_of(full).dump(1);
    for (const int factor : {2, 4}) {
        SCOPED_TRACE(fmt::format("decimated by {}", factor));
        const auto decimated = run(factor);
        ASSERT_NE(decimated.status, feedid::Status::failed) << document_of(decimated).dump(1);
        for (const auto& [key, true_value] : {std::pair{std::string("coulomb_N"), truth.coulomb},
                                              std::pair{std::string("breakaway_N"), truth.breakaway},
                                              std::pair{std::string("viscous_Ns_per_m"), truth.viscous}}) {
            SCOPED_TRACE(key);
            const auto* p = decimated.find(key);
            ASSERT_TRUE(p && p->estimate.value && p->estimate.standard_error);
            const double se = *p->estimate.standard_error;
            EXPECT_NEAR(*p->estimate.value, estimate(full, key), 3.0 * se);
            EXPECT_NEAR(*p->estimate.value, true_value, 3.0 * se + 5e-4 * true_value);
        }
    }
}

TEST(IdentifyClosedLoop, StandardErrorsMatchTheScatterOverRepeatedRuns) {
    // The same drive and test, twelve sensor-noise seeds: for every parameter the scatter of the estimates agrees
    // with the reported standard error (ratio within [0.5, 2]: about three standard errors of a 12-run standard
    // deviation) and the mean lies within three standard errors of the mean of the truth.
    constexpr int runs = 12;
    const feedid::SynthSpec base = feedid::demo_spec();
    const auto truth = truth_of(base);
    const std::vector<std::pair<std::string, double>> parameters = {
        {"mass_kg", truth.mass},
        {"viscous_Ns_per_m", truth.viscous},
        {"coulomb_N", truth.coulomb},
        {"breakaway_N", truth.breakaway},
        {"stribeck_velocity_m_per_s", truth.stribeck_velocity}};
    std::vector<std::vector<double>> values(parameters.size()), errors(parameters.size());
    for (int run = 0; run < runs; ++run) {
        feedid::SynthSpec spec = base;
        spec.seed = 100 + static_cast<std::uint64_t>(run);
        const auto r = identify_closed_loop(spec);
        ASSERT_EQ(r.status, feedid::Status::ok) << "seed " << spec.seed << ": " << document_of(r).dump(1);
        for (std::size_t i = 0; i < parameters.size(); ++i) {
            const auto* p = r.find(parameters[i].first);
            ASSERT_TRUE(p && p->estimate.value && p->estimate.standard_error) << parameters[i].first;
            values[i].push_back(*p->estimate.value);
            errors[i].push_back(*p->estimate.standard_error);
        }
    }
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        SCOPED_TRACE(parameters[i].first);
        double mean = 0.0, mean_error = 0.0;
        for (int run = 0; run < runs; ++run) {
            mean += values[i][static_cast<std::size_t>(run)] / runs;
            mean_error += errors[i][static_cast<std::size_t>(run)] / runs;
        }
        double variance = 0.0;
        for (const double v : values[i]) variance += (v - mean) * (v - mean) / (runs - 1);
        const double scatter = std::sqrt(variance);
        EXPECT_GT(scatter / mean_error, 0.5) << "scatter " << scatter << ", standard error " << mean_error;
        EXPECT_LT(scatter / mean_error, 2.0) << "scatter " << scatter << ", standard error " << mean_error;
        if (parameters[i].first == "mass_kg") {
            // M keeps a small bias of its own (-0.2 %, 2 standard errors of this mean): the twin holds the drive
            // force over a sample and lags it 0.3 ms, so the recorded force and the central-difference acceleration
            // are not sampled at quite the same instant. Within the 2 %; bounded here at 0.5 %.
            EXPECT_WITHIN_PCT(mean, parameters[i].second, 0.5);
        } else {
            EXPECT_NEAR(mean, parameters[i].second, 3.0 * scatter / std::sqrt(static_cast<double>(runs)));
        }
    }
}

TEST(IdentifySynthetic, TheDocumentHasTheContractsKeys) {
    const auto trace = synthetic_trace(asymmetric_drive, slow_and_fast, 5);
    const auto r = feedid::identify(trace, options_for(feedid::FrictionModelKind::symmetric));
    const Json document = document_of(r);
    for (const std::string key : {"feedid_version", "trace", "model", "parameters", "fit", "rls", "selection",
                                  "preprocessing", "status", "diagnostics"}) {
        EXPECT_TRUE(document.contains(key)) << key;
    }
    for (const std::string key :
         {"mass_kg", "viscous_Ns_per_m", "coulomb_N", "breakaway_N", "stribeck_velocity_m_per_s"}) {
        ASSERT_TRUE(document.at("parameters").contains(key)) << key;
        EXPECT_TRUE(document.at("parameters").at(key).contains("value")) << key;
        EXPECT_TRUE(document.at("parameters").at(key).contains("stderr")) << key;
    }
    const auto& selection = document.at("selection");
    EXPECT_GT(selection.at("step1").get<std::size_t>(), 1000u);
    EXPECT_GT(selection.at("step2").get<std::size_t>(), 100u);
    EXPECT_FALSE(selection.at("notes").empty());
}

// ---------------------------------------------------------------------------------------------------------------
// Bad input: one sentence saying what is missing, exit code 1 or 2.

struct Run {
    int exit_code;
    std::string err;
};

Run identify_csv(const std::string& csv, const std::string& options = "--force-constant 100") {
    const auto path = feedid::testing::temp_dir() / "trace.csv";
    feedid::testing::write_text(path, csv);
    const auto run = run_cli("identify '" + path.string() + "' " + options);
    return {run.exit_code, run.err};
}

std::string fmt_double(double value) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.17g", value);
    return buffer;
}

std::string csv_of(const feedid::Trace& trace) {
    return feedid::write_csv(trace);
}

// The lines of stderr that are not import findings (guessed roles, assumed units): the error itself.
int lines_of(const std::string& text) {
    int lines = 0;
    std::size_t start = 0;
    while (start < text.size()) {
        const auto end = std::min(text.find('\n', start), text.size());
        const auto line = text.substr(start, end - start);
        lines += !line.empty() && line.find("(guessed from its name") == std::string::npos &&
                 line.find("carries no unit") == std::string::npos;
        start = end + 1;
    }
    return lines;
}

TEST(IdentifyBadInput, NoPositionChannel) {
    auto trace = synthetic_trace(asymmetric_drive, papers_ladder, 1);
    trace.find(feedid::Role::position)->name = "unrelated";
    trace.find(feedid::Role::position)->role = feedid::Role::other;
    const auto run = identify_csv(csv_of(trace));
    EXPECT_EQ(run.exit_code, 2);
    EXPECT_NE(run.err.find("position"), std::string::npos) << run.err;
}

TEST(IdentifyBadInput, NoCurrentOrForceChannel) {
    auto trace = synthetic_trace(asymmetric_drive, papers_ladder, 1);
    trace.find(feedid::Role::current)->name = "unrelated";
    trace.find(feedid::Role::current)->role = feedid::Role::other;
    const auto run = identify_csv(csv_of(trace));
    EXPECT_EQ(run.exit_code, 2);
    EXPECT_TRUE(run.err.find("current") != std::string::npos || run.err.find("force") != std::string::npos) << run.err;
}

TEST(IdentifyBadInput, NoForceConstant) {
    const auto trace = synthetic_trace(asymmetric_drive, papers_ladder, 1);
    const auto run = identify_csv(csv_of(trace), "");
    EXPECT_EQ(run.exit_code, 2);
    EXPECT_NE(run.err.find("--kt"), std::string::npos) << run.err;
    EXPECT_EQ(lines_of(run.err), 1) << run.err;
}

TEST(IdentifyBadInput, ConstantPosition) {
    auto trace = synthetic_trace(asymmetric_drive, papers_ladder, 1);
    for (auto& x : trace.find(feedid::Role::position)->values) x = 0.125;
    const auto run = identify_csv(csv_of(trace));
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.err.find("did not move"), std::string::npos) << run.err;
    EXPECT_EQ(lines_of(run.err), 1) << run.err;
}

TEST(IdentifyBadInput, TooShortToIdentifyAnything) {
    const auto trace = synthetic_trace(asymmetric_drive, papers_ladder, 1).slice(300, 340);
    const auto run = identify_csv(csv_of(trace));
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.err.find("too short"), std::string::npos) << run.err;
    EXPECT_EQ(lines_of(run.err), 1) << run.err;
}

TEST(IdentifyCli, OneLeadConvertsTheDriveCurrentAndAnRpmChannel) {
    // a motor-speed channel in rpm needs the lead to become m/s; --lead (given for K_t) serves both
    const auto trace = synthetic_trace(asymmetric_drive, slow_and_fast, 1);
    std::string csv = "t [s],x [m],n [rpm],i [A]\n";
    const auto& t = trace.find(feedid::Role::time)->values;
    const auto& x = trace.find(feedid::Role::position)->values;
    const auto& i = trace.find(feedid::Role::current)->values;
    for (std::size_t k = 0; k + 1 < t.size(); ++k) {
        const double rpm = (x[k + 1] - x[k]) / (t[k + 1] - t[k]) / 0.01 * 60.0;  // 10 mm lead
        csv += std::to_string(t[k]) + "," + fmt_double(x[k]) + "," + fmt_double(rpm) + "," + fmt_double(i[k]) + "\n";
    }
    // K_t * 2*pi / lead = 100 N/A with a 10 mm lead
    const double kt = 100.0 * 0.01 / (2.0 * std::numbers::pi);
    const auto run = identify_csv(csv, "--channel velocity=n --kt " + fmt_double(kt) + " --lead 10");
    EXPECT_EQ(run.exit_code, 0) << run.err;
}

TEST(IdentifySinumerik, AMicroStepTestHasNoMassInformationEvenWithoutADriveConstant) {
    // channels mapped automatically, no force constant: whether a mass can be identified does not depend on the
    // force scale, so the answer is the data's, not a request for --kt
    FEEDID_REQUIRE_SHARED("sinumerik-trace/X_BK300_1.xml");
    const auto trace = feedid::testing::shared_data() / "sinumerik-trace" / "X_BK300_1.xml";
    const auto run = run_cli("identify '" + trace.string() + "'");
    EXPECT_EQ(run.exit_code, 1) << run.err;
    EXPECT_NE(run.err.find("no usable mass information"), std::string::npos) << run.err;
    EXPECT_NE(run.err.find("micro-step"), std::string::npos) << run.err;
}

TEST(IdentifyBadInput, OptionsThatMakeNoSense) {
    const auto trace = synthetic_trace(asymmetric_drive, papers_ladder, 1);
    for (const std::string options :
         {"--lambda 1.5", "--lambda 0", "--p0 -1", "--filter-order 0", "--from 5 --to 2", "--cutoff 900"}) {
        const auto run = identify_csv(csv_of(trace), "--force-constant 100 " + options);
        EXPECT_EQ(run.exit_code, 2) << options << ": " << run.err;
        EXPECT_FALSE(run.err.empty()) << options;
    }
}

}  // namespace
