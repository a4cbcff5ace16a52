// The quasi-static friction curve fitted to speed bins (detail::fit_curve above curve_bin_above samples) against the
// same curve fitted sample by sample: the estimates agree to a fraction of a standard error, and the standard errors
// are right: across independent noise realisations the estimates scatter as the reported standard errors say.
// Synthetic quasi-static samples: the Stribeck curve of bench/stribeck_trace.hpp (B 54 N s/m, F_C 740 N, F_B 940 N,
// v_s 5 mm/s) at constant-speed passes of 0.5 to 200 mm/s in both directions, speed ripple of 2 %, force noise
// correlated over about 10 samples (AR(1) with 0.8, as a low-pass leaves it) and larger at speed (heteroscedastic).
// Measured when this was written: the binned estimates within 0.4 standard errors of the sample-by-sample ones, their
// standard errors 0.75-0.85 of those (inverse-variance weights: the estimates also scatter 10-20 % less), and 0.80-0.87
// of the scatter over 40 realisations (the sample-by-sample fit's: 0.89-0.96; both count correlation over blocks of 40
// samples, which misses a little of an AR(1) tail).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "feedid/identify/stribeck_fit.hpp"

namespace {

using feedid::detail::CurveFit;
using feedid::detail::CurveLayout;
using feedid::detail::CurveModel;
using feedid::detail::FitSamples;

constexpr double viscous = 54.0, coulomb = 740.0, rise = 200.0, vs = 0.005;

FitSamples quasi_static_samples(std::uint32_t seed, std::size_t per_pass) {
    std::mt19937 random(seed);
    std::normal_distribution<double> unit;
    FitSamples samples;
    samples.correlation_block = 40;  // two correlation lengths, as step 2 sets it
    const double speeds[] = {0.0005, 0.001, 0.002, 0.004, 0.008, 0.015, 0.03, 0.06, 0.1, 0.2};
    std::size_t index = 0;
    for (const double direction : {1.0, -1.0}) {
        for (const double speed : speeds) {
            double noise = 0.0;
            for (std::size_t k = 0; k < per_pass; ++k, ++index) {
                const double v = direction * speed * (1.0 + 0.02 * std::sin(0.05 * static_cast<double>(k)));
                const double s = std::abs(v);
                noise = 0.8 * noise + std::sqrt(1.0 - 0.8 * 0.8) * unit(random) * (1.0 + 20.0 * s);
                const double f = direction * (viscous * s + coulomb + rise * std::exp(-s / vs)) + noise;
                samples.push(0.0, v, f, index);
            }
        }
    }
    return samples;
}

constexpr CurveModel model{false, true, false, false, false};  // symmetric, Stribeck, no offset, no mass

TEST(BinnedCurve, AgreesWithTheSampleBySampleFit) {
    const FitSamples samples = quasi_static_samples(7, 6000);  // 120,000 samples
    const CurveFit binned = feedid::detail::fit_curve(samples, model, 0.0002, 0.05);
    const CurveFit full =
        feedid::detail::fit_curve(samples, model, 0.0002, 0.05, std::numeric_limits<std::size_t>::max());
    ASSERT_TRUE(binned.converged);
    ASSERT_TRUE(full.converged);
    EXPECT_EQ(binned.samples, samples.size());
    for (int i = 0; i < CurveLayout(model).size; ++i) {
        const double se = full.standard_errors(i);
        EXPECT_LT(std::abs(binned.parameters(i) - full.parameters(i)), 0.5 * se) << "parameter " << i;
        // inverse-variance weights make the binned estimate at least as efficient, never falsely precise
        EXPECT_GT(binned.standard_errors(i), 0.6 * se) << "parameter " << i;
        EXPECT_LT(binned.standard_errors(i), 1.1 * se) << "parameter " << i;
    }
    EXPECT_NEAR(binned.residual_std, full.residual_std, 0.02 * full.residual_std);
}

TEST(BinnedCurve, StandardErrorsMatchTheScatterOverNoiseRealisations) {
    constexpr int realisations = 40;
    const int p = CurveLayout(model).size;
    Eigen::MatrixXd estimates(realisations, p);
    Eigen::VectorXd mean_se = Eigen::VectorXd::Zero(p);
    for (int r = 0; r < realisations; ++r) {
        const FitSamples samples = quasi_static_samples(100 + static_cast<std::uint32_t>(r), 3000);  // 60,000
        const CurveFit fit = feedid::detail::fit_curve(samples, model, 0.0002, 0.05);
        ASSERT_TRUE(fit.converged);
        estimates.row(r) = fit.parameters.transpose();
        mean_se += fit.standard_errors / realisations;
    }
    for (int i = 0; i < p; ++i) {
        const Eigen::VectorXd column = estimates.col(i);
        const double mean = column.mean();
        const double scatter = std::sqrt((column.array() - mean).square().sum() / (realisations - 1));
        // the sample standard deviation of 40 draws is within about +-25 % of the truth (95 %); below 0.7 the
        // standard errors would claim a precision the data does not have
        EXPECT_GT(mean_se(i), 0.7 * scatter) << "parameter " << i;
        EXPECT_LT(mean_se(i), 1.4 * scatter) << "parameter " << i;
    }
    EXPECT_NEAR(estimates.col(CurveLayout(model).viscous[0]).mean(), viscous, 0.5);
    EXPECT_NEAR(estimates.col(CurveLayout(model).coulomb[0]).mean(), coulomb, 0.5);
}

}  // namespace
