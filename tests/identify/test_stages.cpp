// The stages of identify, one at a time, on small hand-made inputs whose answers are known: preprocess() (values used,
// failures), select_samples() (a count per reason), and step 2's Levenberg-Marquardt Jacobian against finite
// differences.

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <span>
#include <tuple>
#include <vector>

#include "feedid/identify/stribeck_fit.hpp"
#include "feedid/core/error.hpp"
#include "feedid/identify/preprocess.hpp"
#include "feedid/identify/selection.hpp"
#include "feedid/numeric/signal.hpp"
#include "feedid/identify/step1.hpp"

namespace {

using feedid::Derivatives;

feedid::Trace sine_trace(double sample_rate_hz, std::size_t n, double amplitude_m = 0.01, double frequency_hz = 0.5) {
    std::vector<double> t(n), x(n), i(n, 0.0);
    for (std::size_t k = 0; k < n; ++k) {
        t[k] = static_cast<double>(k) / sample_rate_hz;
        x[k] = amplitude_m * std::sin(2.0 * std::numbers::pi * frequency_hz * t[k]);
    }
    feedid::Trace trace;
    trace.format = "synthetic";
    trace.set("t", feedid::Role::time, "s", t);
    trace.set("x", feedid::Role::position, "m", x);
    trace.set("F", feedid::Role::force, "N", i);
    return trace;
}

TEST(Preprocess, ReportsTheDefaultsItResolved) {
    for (const double fs : {1000.0, 250.0}) {
        const auto trace = sine_trace(fs, 4000);
        const std::vector<double> force(trace.samples(), 1.0);
        const Derivatives d = feedid::preprocess(trace, force, {});
        ASSERT_FALSE(d.failed()) << d.failure;
        const double cutoff = std::min(100.0, fs / 10.0);  // min(100 Hz, fs/10)
        EXPECT_DOUBLE_EQ(d.used.cutoff_hz, cutoff);
        EXPECT_EQ(d.used.differentiation, "butterworth");
        EXPECT_EQ(d.used.edge_samples, static_cast<std::size_t>(std::ceil(2.5 * fs / cutoff)));  // 2.5 filter periods
        EXPECT_EQ(d.used.decimation, 1);
        EXPECT_EQ(d.window, trace.samples() - 2 * d.used.edge_samples);
        EXPECT_EQ(d.size(), d.window);
        EXPECT_EQ(d.force.size(), d.size());
        EXPECT_DOUBLE_EQ(d.time.front(), static_cast<double>(d.used.edge_samples) / fs);
    }
}

TEST(Preprocess, DifferentiatesASineToItsDerivatives) {
    const double fs = 1000.0, amplitude = 0.01, frequency = 0.5, w = 2.0 * std::numbers::pi * frequency;
    const auto trace = sine_trace(fs, 6000, amplitude, frequency);
    const std::vector<double> force(trace.samples(), 0.0);
    for (const auto method : {feedid::Differentiation::butterworth, feedid::Differentiation::central,
                              feedid::Differentiation::savitzky_golay}) {
        feedid::PreprocessOptions options;
        options.differentiation = method;
        const Derivatives d = feedid::preprocess(trace, force, options);
        ASSERT_FALSE(d.failed()) << d.failure;
        // a 0.5 Hz sine is far below every cut-off: inside the trace (the first and last 5 % hold what is left of the
        // filters' start-up), velocity and acceleration within 0.1 % of their amplitude
        for (std::size_t k = d.size() / 20; k < d.size() - d.size() / 20; k += 97) {
            EXPECT_NEAR(d.velocity[k], amplitude * w * std::cos(w * d.time[k]), 1e-3 * amplitude * w);
            EXPECT_NEAR(d.acceleration[k], -amplitude * w * w * std::sin(w * d.time[k]), 1e-3 * amplitude * w * w);
        }
    }
}

TEST(Preprocess, DecimationKeepsEveryNthSampleOfEveryColumn) {
    const auto trace = sine_trace(1000.0, 5000);
    const std::vector<double> force(trace.samples(), 2.0);
    feedid::PreprocessOptions options;
    options.decimation = 4;
    const Derivatives d = feedid::preprocess(trace, force, options);
    ASSERT_FALSE(d.failed());
    EXPECT_EQ(d.used.decimation, 4);
    EXPECT_EQ(d.size(), feedid::decimation_indices(d.window, 4).size());
    EXPECT_EQ(d.full_rate_velocity.size(), d.window);
    EXPECT_EQ(d.time.size(), d.size());
    // decimate() (MATLAB's) passes a constant scaled by the Chebyshev filter's DC gain, applied twice (forwards and
    // backwards): an even order's DC gain is the pass-band ripple floor, -0.05 dB. The preprocessing takes it out, so
    // that a force stays the force it was (step 2 fits it against the speed).
    EXPECT_NEAR(feedid::decimation_dc_gain(4), std::pow(10.0, -2.0 * 0.05 / 20.0), 1e-12);
    EXPECT_NEAR(d.force[d.size() / 2], 2.0, 1e-9);
}

// A regressor column filtered in its own storage (filter_like_force on a column it may overwrite) has the values of the
// filtered copy to the last bit: one stretch, three stretches (time-stamp gaps: each filtered on its own), a
// Savitzky-Golay low-pass and a decimated trace (which filter a copy). With one stretch, the Butterworth and the
// capacity it asks for, the column does not move: no second column is formed.
TEST(Preprocess, AColumnFilteredInItsOwnStorageIsTheFilteredCopy) {
    const auto whole = sine_trace(1000.0, 9000);
    auto gapped = sine_trace(1000.0, 9000);
    std::vector<double> time(gapped.column(feedid::Role::time).begin(), gapped.column(feedid::Role::time).end());
    for (std::size_t k = 3000; k < time.size(); ++k) time[k] += k < 6000 ? 0.5 : 1.25;  // two gaps of many samples
    gapped.set("t", feedid::Role::time, "s", time);
    feedid::PreprocessOptions savitzky_golay, decimated;
    savitzky_golay.differentiation = feedid::Differentiation::savitzky_golay;
    decimated.decimation = 2;
    using Case = std::tuple<const feedid::Trace*, feedid::PreprocessOptions, std::size_t>;
    for (const auto& [trace, options, stretches] :
         {Case{&whole, {}, 1}, Case{&gapped, {}, 3}, Case{&whole, savitzky_golay, 1}, Case{&whole, decimated, 1}}) {
        const std::vector<double> force(trace->samples(), 1.0);
        const Derivatives d = feedid::preprocess(*trace, force, options);
        ASSERT_FALSE(d.failed()) << d.failure;
        ASSERT_EQ(d.segment_starts.size(), stretches);
        const auto& v = d.used.decimation > 1 ? d.full_rate_velocity : d.velocity;
        std::vector<double> sign;
        sign.reserve(feedid::filter_like_force_capacity(d, v.size()));
        for (const double value : v) sign.push_back(value > 0.0 ? 1.0 : value < 0.0 ? -1.0 : 0.0);
        const auto expected = feedid::filter_like_force(std::span<const double>(sign), d);
        const double* storage = sign.data();
        const auto filtered = feedid::filter_like_force(std::move(sign), d);
        EXPECT_EQ(filtered, expected);
        if (stretches == 1 && d.used.decimation == 1 && d.used.differentiation == "butterworth") {
            EXPECT_EQ(filtered.data(), storage);
        }
    }
}

TEST(Preprocess, SaysWhyATraceIsUnusable) {
    const auto trace = sine_trace(1000.0, 60);
    const std::vector<double> force(trace.samples(), 0.0);
    const Derivatives short_window = feedid::preprocess(trace, force, {});
    EXPECT_NE(short_window.failure.find("dropped at each edge: too short"), std::string::npos) << short_window.failure;

    auto still = sine_trace(1000.0, 2000, 0.0);
    const Derivatives no_motion = feedid::preprocess(still, std::vector<double>(2000, 0.0), {});
    EXPECT_NE(no_motion.failure.find("never changes"), std::string::npos) << no_motion.failure;

    feedid::PreprocessOptions window;
    window.from_s = 0.5;
    window.to_s = 0.51;
    const Derivatives tiny = feedid::preprocess(sine_trace(1000.0, 2000), std::vector<double>(2000, 0.0), window);
    EXPECT_NE(tiny.failure.find("only 11 samples in the analysis window"), std::string::npos) << tiny.failure;

    feedid::PreprocessOptions nyquist;
    nyquist.cutoff_hz = 600.0;
    EXPECT_THROW((void)feedid::preprocess(sine_trace(1000.0, 2000), std::vector<double>(2000, 0.0), nyquist),
                 feedid::InputError);
}

// A velocity profile of constant pieces (1 kHz): 100 at rest, 400 at +0.1 m/s, 300 at +2 mm/s, 200 at rest, 400 at
// -0.1 m/s, 300 at -2 mm/s, 100 at rest. With the threshold and the split given, every count is known.
Derivatives piecewise_constant_motion() {
    const std::vector<std::pair<std::size_t, double>> pieces{{100, 0.0},  {400, 0.1},    {300, 0.002}, {200, 0.0},
                                                             {400, -0.1}, {300, -0.002}, {100, 0.0}};
    Derivatives d;
    d.sample_time_s = 0.001;
    d.used.decimation = 1;
    // central differences: the force is not low-passed here, so no stop's force reaches into the fast samples (the
    // margin selection keeps around stops after a low-pass is tested in test_honest_numbers)
    d.used.differentiation = "central";
    d.source = "hand-made";
    for (const auto& [count, velocity] : pieces) {
        for (std::size_t i = 0; i < count; ++i) {
            d.time.push_back(static_cast<double>(d.time.size()) * d.sample_time_s);
            d.velocity.push_back(velocity);
            d.acceleration.push_back(0.0);
            d.force.push_back(50.0 * velocity + 20.0 * feedid::sign(velocity));
        }
    }
    d.total = d.window = d.velocity.size();
    return d;
}

TEST(Selection, CountsEverySampleByReason) {
    const Derivatives d = piecewise_constant_motion();
    const auto regressors = feedid::build_regressors(d, feedid::FrictionModelKind::symmetric, false);
    feedid::SelectionOptions options;
    options.moving_threshold = 1e-4;
    options.split_velocity = 0.01;
    const feedid::Selection s = feedid::select_samples(d, regressors, options);
    EXPECT_EQ(s.report.total, 1800u);
    EXPECT_EQ(s.report.moving, 1400u);  // 400 samples at rest
    EXPECT_EQ(s.report.step1, 800u);    // the two fast pieces, ramps included: nothing is steady-gated in step 1
    // quasi-static: 25 ms (25 samples) of constant velocity on either side, so each slow piece of 300 loses 25 at
    // its start and 25 at its end (sample k is steady while [k-25, k+25] stays inside the piece)
    EXPECT_EQ(s.report.step2, 2u * (300u - 50u));
    EXPECT_DOUBLE_EQ(s.report.split_velocity, 0.01);
    EXPECT_DOUBLE_EQ(s.report.moving_threshold, 1e-4);
    bool rest_note = false;
    for (const auto& note : s.report.notes) rest_note = rest_note || note.rfind("400 samples at rest", 0) == 0;
    EXPECT_TRUE(rest_note) << s.report.notes.front();
    for (const auto k : s.step2) EXPECT_TRUE(s.steady(k));
    // step 2 holds exactly the inner samples of the slow pieces
    EXPECT_EQ(s.step2.front(), 525u);
    EXPECT_EQ(s.step2[249], 774u);
    EXPECT_EQ(s.step2[250], 1425u);
}

/// Everything a selection holds, for comparing two.
void expect_same_selection(const feedid::Selection& a, const feedid::Selection& b) {
    EXPECT_EQ(a.moving, b.moving);
    EXPECT_EQ(a.step1, b.step1);
    EXPECT_EQ(a.step2, b.step2);
    EXPECT_EQ(a.quasi_static, b.quasi_static);
    EXPECT_EQ(a.resting_reach, b.resting_reach);
    EXPECT_EQ(a.stick_slip.flags, b.stick_slip.flags);
    EXPECT_EQ(a.stick_slip.passes.size(), b.stick_slip.passes.size());
    EXPECT_EQ(a.report.notes, b.report.notes);
    EXPECT_EQ(a.moving_notes, b.moving_notes);
    EXPECT_EQ(a.report.moving, b.report.moving);
    EXPECT_EQ(a.report.step1, b.report.step1);
    EXPECT_EQ(a.report.step2, b.report.step2);
    EXPECT_EQ(a.report.near_rest, b.report.near_rest);
    EXPECT_EQ(a.report.passes, b.report.passes);
    EXPECT_DOUBLE_EQ(a.report.moving_threshold, b.report.moving_threshold);
    EXPECT_DOUBLE_EQ(a.report.split_velocity, b.report.split_velocity);
    EXPECT_DOUBLE_EQ(a.report.initial_split, b.report.initial_split);
    EXPECT_DOUBLE_EQ(a.stribeck_band, b.stribeck_band);
}

TEST(Selection, AnotherSplitFromTheMovingSamplesOfOneSelectionIsTheSameAsSelectingAgain) {
    // the preprocessing family's split variant takes the nominal run's moving samples, quasi-static flags and
    // stick-slip passes: its selection must be the one select_samples() makes at that split
    const Derivatives d = piecewise_constant_motion();
    const auto regressors = feedid::build_regressors(d, feedid::FrictionModelKind::symmetric, false);
    feedid::SelectionOptions nominal;
    nominal.moving_threshold = 1e-4;  // the split from the data (default, Stribeck checks)
    for (const double split : {0.0015, 0.003, 0.01, 0.05}) {
        feedid::Selection first = feedid::select_samples(d, regressors, nominal);
        feedid::SelectionOptions at_split = nominal;
        at_split.split_velocity = split;
        const feedid::Selection again = feedid::select_samples(d, regressors, at_split);
        const feedid::Selection shared =
            feedid::select_samples(d, regressors, at_split, feedid::release_moving_samples(std::move(first)));
        SCOPED_TRACE(split);
        ASSERT_FALSE(again.step1.empty());
        expect_same_selection(again, shared);
    }
}

TEST(Selection, WithoutStribeckEveryMovingSampleIsStep1) {
    const Derivatives d = piecewise_constant_motion();
    const auto regressors = feedid::build_regressors(d, feedid::FrictionModelKind::symmetric, false);
    feedid::SelectionOptions options;
    options.moving_threshold = 1e-4;
    options.stribeck = false;
    const feedid::Selection s = feedid::select_samples(d, regressors, options);
    EXPECT_EQ(s.report.step1, 1400u);
    EXPECT_EQ(s.report.step2, 0u);
}

TEST(CurveFit, TheJacobianMatchesFiniteDifferences) {
    feedid::detail::FitSamples samples;
    for (int k = -60; k <= 60; ++k) {
        if (k == 0) continue;
        const double v = 0.0005 * k * std::abs(k) / 60.0;  // speeds from 8 um/s to 30 mm/s, both directions
        samples.push(0.3 * std::sin(k), v, 0.0, static_cast<std::size_t>(k + 60));
    }
    for (const bool asymmetric : {false, true}) {
        const feedid::detail::CurveModel model{asymmetric, true, asymmetric, true, true};
        const feedid::detail::CurveLayout layout(model);
        Eigen::VectorXd x(layout.size);
        for (int i = 0; i < layout.size; ++i) x(i) = 1.0 + 0.37 * i;
        for (const int g : {0, 1}) {
            if (layout.log_vs[g] >= 0) x(layout.log_vs[g]) = std::log(0.004 + 0.002 * g);
        }
        const Eigen::MatrixXd analytic = feedid::detail::curve_jacobian(samples, model, x);
        for (int i = 0; i < layout.size; ++i) {
            const double h = 1e-6 * std::max(1.0, std::abs(x(i)));
            Eigen::VectorXd up = x, down = x;
            up(i) += h;
            down(i) -= h;
            const Eigen::VectorXd numeric = (feedid::detail::curve_residuals(samples, model, up) -
                                             feedid::detail::curve_residuals(samples, model, down)) /
                                            (2.0 * h);
            const double scale = std::max(1.0, numeric.cwiseAbs().maxCoeff());
            EXPECT_LT((analytic.col(i) - numeric).cwiseAbs().maxCoeff(), 1e-7 * scale)
                << (asymmetric ? "asymmetric" : "symmetric") << " column " << i;
        }
    }
}

}  // namespace
