// The preprocessing primitives (feedid/numeric/signal.hpp) against SciPy: tests/numeric/signal_reference.hpp, written by
// scripts/reference/signal_reference.py, which also says how each SciPy call is made to follow feedid's (MATLAB's)
// conventions. Agreement is scored in significant digits.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "signal_reference.hpp"
#include "feedid/numeric/signal.hpp"
#include "testing.hpp"

namespace {

namespace reference = feedid::signal_reference;

// Where the algorithms are the same, only rounding separates feedid from SciPy: 13.5 to 17 digits agree here, a
// convention that differs (padding, where the ends start) costs 2 to 6.
constexpr double same_algorithm_digits = 12.0;

// -log10 of the largest difference relative to the largest reference magnitude: elements near zero (a filtered
// signal crossing zero, a small filter coefficient) are judged on the scale of the whole, not their own. 17 when equal.
double significant_digits(std::span<const double> actual, std::span<const double> expected) {
    if (actual.size() != expected.size()) return 0.0;
    double error = 0.0;
    double scale = 0.0;
    for (std::size_t k = 0; k < expected.size(); ++k) {
        error = std::max(error, std::abs(actual[k] - expected[k]));
        scale = std::max(scale, std::abs(expected[k]));
    }
    if (error == 0.0) return 17.0;
    if (!std::isfinite(error)) return 0.0;
    return -std::log10(error / std::max(scale, std::numeric_limits<double>::min()));
}

std::vector<std::array<double, 6>> copied(std::span<const reference::Section> sections) {
    return {sections.begin(), sections.end()};
}

// The denominators (b0 b1 b2 a0 a1 a2 -> a1 a2), sorted by pole radius^2 (a2) then a1: SciPy orders the sections by
// the poles' distance from the unit circle, feedid by the analog poles' angle, and neither order changes the filter.
std::vector<double> sorted_denominators(std::span<const std::array<double, 6>> sections) {
    std::vector<std::array<double, 2>> rows;
    for (const auto& s : sections) rows.push_back({s[5], s[4]});
    std::sort(rows.begin(), rows.end());
    std::vector<double> flat;
    for (const auto& r : rows) flat.insert(flat.end(), {r[1], r[0]});
    return flat;
}

// The product of the sections' numerators, as a polynomial in z^-1: SciPy gives an odd order's real pole two zeros
// and a complex pair one, feedid the other way round, and puts the gain in another section; the product is the same.
std::vector<double> numerator_polynomial(std::span<const std::array<double, 6>> sections) {
    std::vector<double> product{1.0};
    for (const auto& s : sections) {
        std::vector<double> next(product.size() + 2, 0.0);
        for (std::size_t i = 0; i < product.size(); ++i) {
            for (std::size_t j = 0; j < 3; ++j) next[i + j] += product[i] * s[j];
        }
        product = next;
    }
    return product;
}

feedid::SecondOrderSections design_with_feedid(const reference::Design& design) {
    if (design.ripple_db == 0.0) {
        return feedid::butterworth_lowpass(design.order, design.cutoff_hz, design.sample_rate_hz);
    }
    return feedid::chebyshev1_lowpass(design.order, design.ripple_db, design.cutoff_hz, design.sample_rate_hz);
}

std::string describe(const reference::Design& design) {
    if (design.ripple_db == 0.0) {
        return fmt::format("butter({}, {} Hz, fs {} Hz)", design.order, design.cutoff_hz, design.sample_rate_hz);
    }
    return fmt::format("cheby1({}, {} dB, {} Hz, fs {} Hz)", design.order, design.ripple_db, design.cutoff_hz,
                       design.sample_rate_hz);
}

}  // namespace

// ---- Filter design -------------------------------------------------------------------------------------------------

TEST(SignalReference, FilterDesignsHaveScipysPolesZerosAndGain) {
    for (const auto& design : reference::designs) {
        SCOPED_TRACE(describe(design));
        const auto feedid_sections = design_with_feedid(design).sections;
        ASSERT_EQ(feedid_sections.size(), design.sos.size());
        for (const auto& s : feedid_sections) EXPECT_EQ(s[3], 1.0);
        EXPECT_GE(significant_digits(sorted_denominators(feedid_sections), sorted_denominators(design.sos)),
                  same_algorithm_digits);
        EXPECT_GE(significant_digits(numerator_polynomial(feedid_sections), numerator_polynomial(design.sos)),
                  same_algorithm_digits);
    }
}

// ---- Zero-phase filtering ------------------------------------------------------------------------------------------

// SciPy's sosfiltfilt with odd padding of 3 * (filter order) samples (padlen, clamped to n - 1 on the 10-sample case)
// and steady-state initial conditions at both passes: the same algorithm, fed the same sections.
TEST(SignalReference, FiltfiltWithScipysSectionsIsSosfiltfilt) {
    for (const auto& c : reference::filtfilt_cases) {
        SCOPED_TRACE(fmt::format("{} on {} samples", describe(c.design), c.samples));
        EXPECT_EQ(c.padding, std::min<std::size_t>(3 * static_cast<std::size_t>(c.design.order), c.samples - 1));
        const auto filtered =
            feedid::filtfilt({copied(c.design.sos)}, std::span<const double>(reference::signal).first(c.samples));
        EXPECT_GE(significant_digits(filtered, c.filtered), same_algorithm_digits);
    }
}

// The whole chain: feedid's own design (other section order and gain placement, so other rounding) and filtfilt.
TEST(SignalReference, FiltfiltWithFeedidsDesignIsSosfiltfilt) {
    for (const auto& c : reference::filtfilt_cases) {
        SCOPED_TRACE(fmt::format("{} on {} samples", describe(c.design), c.samples));
        const auto filtered =
            feedid::filtfilt(design_with_feedid(c.design), std::span<const double>(reference::signal).first(c.samples));
        EXPECT_GE(significant_digits(filtered, c.filtered), same_algorithm_digits);
    }
}

// In a column's own storage: the same values as filtfilt to the last bit, on every case of the reference (10 samples,
// where the padding is cut to n - 1, and longer), with the padding in the column's capacity or not; with it reserved
// (filtfilt_capacity) the column does not move, so no second column exists while it is filtered.
TEST(SignalReference, FiltfiltInPlaceIsFiltfiltInTheColumnsOwnStorage) {
    for (const auto& c : reference::filtfilt_cases) {
        SCOPED_TRACE(fmt::format("{} on {} samples", describe(c.design), c.samples));
        const feedid::SecondOrderSections design = design_with_feedid(c.design);
        const auto signal = std::span<const double>(reference::signal).first(c.samples);
        const auto expected = feedid::filtfilt(design, signal);
        std::vector<double> short_of_room(signal.begin(), signal.end());
        short_of_room.shrink_to_fit();
        feedid::filtfilt_in_place(design, short_of_room);
        EXPECT_EQ(short_of_room, expected);
        std::vector<double> column;
        column.reserve(feedid::filtfilt_capacity(design, signal.size()));
        EXPECT_EQ(feedid::filtfilt_capacity(design, signal.size()), c.samples + 2 * c.padding);
        column.assign(signal.begin(), signal.end());
        const double* storage = column.data();
        feedid::filtfilt_in_place(design, column);
        EXPECT_EQ(column, expected);
        EXPECT_EQ(column.data(), storage);
    }
    // no sections: the signal itself, as filtfilt gives it
    std::vector<double> column(reference::signal.begin(), reference::signal.end());
    feedid::filtfilt_in_place({}, column);
    EXPECT_EQ(column, feedid::filtfilt({}, reference::signal));
}

// ---- Derivatives ---------------------------------------------------------------------------------------------------

TEST(SignalReference, CentralDifferenceIsNumpyGradient) {
    const auto derivative = feedid::central_difference(reference::signal, reference::sample_time);
    EXPECT_GE(significant_digits(derivative, reference::central_difference), same_algorithm_digits);
}

// The filter's weights, read off its response to a unit impulse well inside the signal:
// y[m + half - i] = c[i] for savgol_coeffs(use="dot").
TEST(SignalReference, SavitzkyGolayWeightsAreSavgolCoeffs) {
    for (const auto& c : reference::savitzky_golay_cases) {
        SCOPED_TRACE(fmt::format("window {}, polynomial {}, derivative {}", c.window, c.polynomial, c.derivative));
        const auto window = static_cast<std::size_t>(c.window);
        const std::size_t half = window / 2;
        const std::size_t impulse_at = 2 * window;
        std::vector<double> impulse(4 * window, 0.0);
        impulse[impulse_at] = 1.0;
        const auto response =
            feedid::savitzky_golay(impulse, c.window, c.polynomial, c.derivative, reference::sample_time);
        std::vector<double> weights(window);
        for (std::size_t i = 0; i < window; ++i) weights[i] = response[impulse_at + half - i];
        EXPECT_GE(significant_digits(weights, c.coefficients), same_algorithm_digits);
    }
}

// savgol_filter(mode="interp"): the centred weights inside, the first and last window's polynomial at the ends.
TEST(SignalReference, SavitzkyGolayIsSavgolFilterInterp) {
    for (const auto& c : reference::savitzky_golay_cases) {
        SCOPED_TRACE(fmt::format("window {}, polynomial {}, derivative {}", c.window, c.polynomial, c.derivative));
        const auto filtered =
            feedid::savitzky_golay(reference::signal, c.window, c.polynomial, c.derivative, reference::sample_time);
        EXPECT_GE(significant_digits(filtered, c.filtered), same_algorithm_digits);
    }
}

// ---- Decimation ----------------------------------------------------------------------------------------------------

TEST(SignalReference, DecimationKeepsEveryFactorthSampleEndingOnTheLast) {
    for (const auto& c : reference::index_cases) {
        SCOPED_TRACE(fmt::format("{} samples by {}", c.samples, c.factor));
        const std::vector<std::size_t> expected(c.indices.begin(), c.indices.end());
        EXPECT_EQ(feedid::decimation_indices(c.samples, c.factor), expected);
    }
}

// The order-8 Chebyshev I (0.05 dB) at 0.8 / factor of Nyquist, forwards and backwards with 24 reflected samples,
// at the kept samples.
TEST(SignalReference, DecimateIsChebyshevSosfiltfiltAtTheKeptSamples) {
    for (const auto& c : reference::decimate_cases) {
        SCOPED_TRACE(fmt::format("factor {}", c.factor));
        EXPECT_GE(significant_digits(feedid::decimate(reference::signal, c.factor), c.decimated),
                  same_algorithm_digits);
    }
}

// ---- Noise floor ---------------------------------------------------------------------------------------------------

// 1.4826 * MAD(diff x) / sqrt(2): the same as SciPy's median_abs_deviation for an odd number of differences, but for
// the rounded constant (1.4826 instead of 1.482602218505602, 1.5e-6 relative).
TEST(SignalReference, NoiseFloorIsTheScaledMedianAbsoluteDeviationOfTheDifferences) {
    ASSERT_EQ(reference::signal.size() % 2, 0U);  // an odd number of differences: one middle value
    const double floor = feedid::noise_floor(reference::signal);
    EXPECT_NEAR(floor, reference::noise_floor_rounded_constant, 1e-13 * reference::noise_floor_rounded_constant);
    EXPECT_NEAR(floor, reference::noise_floor, 2e-6 * reference::noise_floor);
}

// The element of the rank, for every rank tried, on a random column, on one ordered in time (ramps and plateaus), with
// ties, and with a few outliers at the end; the buffer reordered, not changed.
TEST(Percentile, LongColumnsGiveTheElementOfTheRankExactly) {
    const std::size_t n = 300'001;
    std::vector<std::vector<double>> columns(4, std::vector<double>(n));
    std::uint64_t state = 12345;
    const auto uniform = [&state] {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        return static_cast<double>(state >> 11) * 0x1.0p-53;
    };
    for (std::size_t k = 0; k < n; ++k) {
        columns[0][k] = uniform() - 0.5;
        columns[1][k] = std::min(1.0, static_cast<double>(k % 50'000) / 20'000.0) + 1e-3 * uniform();
        columns[2][k] = std::floor(8.0 * uniform());
        columns[3][k] = k < n - 100 ? 1.0 : 2.0 + static_cast<double>(k);
    }
    for (const auto& column : columns) {
        for (const double fraction : {0.0, 0.01, 0.1, 0.5, 0.9, 0.95, 0.99, 0.9999, 1.0}) {
            std::vector<double> sorted = column;
            std::sort(sorted.begin(), sorted.end());
            const auto rank = static_cast<std::size_t>(fraction * static_cast<double>(n - 1));
            std::vector<double> buffer = column;
            EXPECT_EQ(feedid::percentile_in_place(buffer, fraction), sorted[rank]) << fraction;
            std::sort(buffer.begin(), buffer.end());
            EXPECT_EQ(buffer, sorted);  // reordered, not changed: the next percentile of the buffer is right too
        }
    }
}

// The counted test agrees with the element of the rank at thresholds just below, at and just above it (ties too),
// and says no for no values.
// The percentile of the magnitudes without their copy is the percentile of the copied magnitudes, bit for bit: short
// and long columns (on both sides of the length where the histogram takes over), scattered residuals, ties, zeros of
// both signs, magnitudes over hundreds of binades, and a column whose every value shares one bucket.
TEST(Percentile, OfTheMagnitudesIsThePercentileOfTheCopiedMagnitudes) {
    std::mt19937_64 random(29);
    std::normal_distribution<double> normal(0.0, 3.0);
    std::uniform_int_distribution<int> binade(-300, 300), tie(-3, 3);
    const auto magnitudes = [](std::vector<double> v) {
        for (double& x : v) x = std::abs(x);
        return v;
    };
    for (const std::size_t n : {std::size_t{1}, std::size_t{10}, std::size_t{4096}, std::size_t{4097},
                                std::size_t{100'000}, std::size_t{1'000'000}}) {
        std::vector<std::vector<double>> columns(5, std::vector<double>(n));
        for (std::size_t k = 0; k < n; ++k) {
            columns[0][k] = normal(random);
            columns[1][k] = static_cast<double>(tie(random));  // ties and zeros
            columns[2][k] =
                (k % 2 == 0 ? -1.0 : 1.0) * std::ldexp(1.0 + 0.5 * std::abs(normal(random)) / 10.0, binade(random));
            columns[3][k] = k % 3 == 0 ? -0.0 : (k % 3 == 1 ? 0.0 : normal(random));
            columns[4][k] = 1.0 + 1e-12 * static_cast<double>(k % 977);  // one bucket holds them all
        }
        for (std::size_t c = 0; c < columns.size(); ++c) {
            for (const double fraction : {0.0, 0.01, 0.5, 0.75, 0.99, 1.0}) {
                SCOPED_TRACE(fmt::format("column {} of {} values, fraction {}", c, n, fraction));
                const double expected = feedid::percentile(magnitudes(columns[c]), fraction);
                const double found = feedid::absolute_percentile(columns[c], fraction);
                EXPECT_EQ(std::bit_cast<std::uint64_t>(found), std::bit_cast<std::uint64_t>(expected));
            }
        }
    }
    EXPECT_EQ(feedid::absolute_percentile({}, 0.5), 0.0);
}

TEST(Percentile, AtLeastAgreesWithTheElementOfTheRank) {
    const std::size_t n = 10'001;
    std::uint64_t state = 7;
    std::vector<double> random(n), ties(n);
    for (std::size_t k = 0; k < n; ++k) {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        random[k] = static_cast<double>(state >> 11) * 0x1.0p-53;
        ties[k] = std::floor(4.0 * random[k]);
    }
    for (const auto& column : {random, ties}) {
        for (const double fraction : {0.0, 0.1, 0.5, 0.9, 1.0}) {
            const double element = feedid::percentile(column, fraction);
            for (const double threshold : {std::nextafter(element, -1e9), element, std::nextafter(element, 1e9)}) {
                EXPECT_EQ(feedid::percentile_at_least(column, fraction, threshold), element >= threshold)
                    << fraction << " " << threshold;
            }
        }
    }
    EXPECT_FALSE(feedid::percentile_at_least(std::vector<double>{}, 0.5, 0.0));
}

namespace {
/// window_extremes' lows and highs as columns, checking that every k comes once, in order.
std::pair<std::vector<double>, std::vector<double>> extremes_of(std::span<const double> x, std::size_t half) {
    std::vector<double> low, high;
    feedid::window_extremes(x, half, [&](std::size_t k, double lo, double hi) {
        EXPECT_EQ(k, low.size());
        low.push_back(lo);
        high.push_back(hi);
    });
    return {low, high};
}
}  // namespace

TEST(WindowExtremes, AreTheWindowsMinimumAndMaximum) {
    std::uint64_t state = 99;
    const auto next = [&state] {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        return state >> 40;
    };
    // lengths that are and are not multiples of the windows, and values with many ties (a few levels)
    for (const std::size_t n : std::array<std::size_t, 6>{1, 2, 5, 2'000, 2'003, 4'099}) {
        for (const bool ties : {false, true}) {
            std::vector<double> x(n);
            for (auto& v : x) v = ties ? static_cast<double>(next() % 4) : static_cast<double>(next());
            for (const std::size_t half : std::array<std::size_t, 7>{0, 1, 2, 7, 50, 1'000, 5'000}) {
                const auto [low, high] = extremes_of(x, half);
                ASSERT_EQ(low.size(), n);
                ASSERT_EQ(high.size(), n);
                for (std::size_t k = 0; k < n; ++k) {
                    const std::size_t from = k > half ? k - half : 0, to = std::min(n, k + half + 1);
                    const auto [lo, hi] = std::minmax_element(x.begin() + static_cast<std::ptrdiff_t>(from),
                                                              x.begin() + static_cast<std::ptrdiff_t>(to));
                    ASSERT_EQ(low[k], *lo) << n << " " << half << " " << k;
                    ASSERT_EQ(high[k], *hi) << n << " " << half << " " << k;
                }
            }
        }
    }
    // of equal values the latest: a zero's sign says which
    const std::vector<double> zeros{-0.0, 0.0, 1.0, 0.0, -0.0};
    const auto [low, high] = extremes_of(zeros, 1);
    EXPECT_FALSE(std::signbit(low[0]));  // {-0, +0}: +0
    EXPECT_FALSE(std::signbit(low[2]));  // {+0, 1, +0}
    EXPECT_TRUE(std::signbit(low[3]));   // {1, +0, -0}: -0
    EXPECT_TRUE(std::signbit(high[4]));  // {+0, -0}: -0
    EXPECT_TRUE(extremes_of(std::vector<double>{}, 3).first.empty());
}
