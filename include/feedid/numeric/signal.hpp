#pragma once
// Preprocessing: differentiation, zero-phase filtering, decimation, data selection.

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace feedid {

/// A digital filter as second-order sections: each row b0 b1 b2 a0 a1 a2 (a0 == 1).
struct SecondOrderSections {
    std::vector<std::array<double, 6>> sections;
};

/// Butterworth low-pass of the given order, cut-off [Hz] at sample rate [Hz], by the bilinear transform with
/// pre-warping (as MATLAB's butter).
SecondOrderSections butterworth_lowpass(int order, double cutoff_hz, double sample_rate_hz);
/// Chebyshev type I low-pass (pass-band ripple [dB]) as MATLAB's cheby1; used for decimation (order 8, 0.05 dB).
SecondOrderSections chebyshev1_lowpass(int order, double ripple_db, double cutoff_hz, double sample_rate_hz);

/// Forward-backward (zero-phase) filtering with odd reflection padding of 3 * (filter order) samples at both ends (at
/// most n - 1) and steady-state initial conditions, as MATLAB's filtfilt(b, a, x) on the cascade's transfer function.
std::vector<double> filtfilt(const SecondOrderSections& filter, std::span<const double> x);
/// The same into `out` (x.size() values), padding in `workspace`, which grows only when x is longer than before: no
/// allocation once it has held the longest signal (the online identifier's windows). An empty `out` leaves the
/// filtered signal in workspace[pad, pad + n) (the padding: max(1, 3 * order), at most n - 1).
void filtfilt(const SecondOrderSections& filter, std::span<const double> x, std::span<double> out,
              std::vector<double>& workspace);

/// filtfilt(filter, x) in x's own storage: the padding is added around the signal in place (x's capacity grown to
/// the padded length only if it is short of it: reserve filtfilt_capacity() first to filter without a second column),
/// and cut off again. The same values as filtfilt(filter, x), bit for bit.
void filtfilt_in_place(const SecondOrderSections& filter, std::vector<double>& x);
/// The capacity filtfilt_in_place() needs for a signal of n samples: n and the padding at both ends.
std::size_t filtfilt_capacity(const SecondOrderSections& filter, std::size_t n);

/// Central differences: d[k] = (x[k+1] - x[k-1]) / (2*dt); one-sided at the ends.
std::vector<double> central_difference(std::span<const double> x, double dt);

/// Savitzky-Golay smoothing derivative of order `derivative` (0, 1, 2) with a centred window of `window` samples
/// (odd) and polynomial order `polynomial`; the ends use the same polynomial fitted to the first/last window.
std::vector<double> savitzky_golay(std::span<const double> x, int window, int polynomial, int derivative, double dt);

/// Decimation by `factor` as MATLAB's decimate: an order-8 Chebyshev I low-pass at 0.8 * (fs/2)/factor applied
/// forwards and backwards, then every factor-th sample, ending on the last one.
std::vector<double> decimate(std::span<const double> x, int factor);
/// The gain decimate()'s filter has at 0 Hz, forwards and backwards: that of the even-order Chebyshev I, the
/// ripple's trough, squared (0.05 dB twice: 0.98855), not 1. A constant comes out of decimate() scaled by it.
double decimation_dc_gain(int factor);

/// The indices decimate() keeps for a signal of n samples.
std::vector<std::size_t> decimation_indices(std::size_t n, int factor);

/// Indices that thin signals sampled together to at most `max_points` for plotting without losing a spike: the
/// samples are cut into equal buckets and each bucket keeps, in time order, the samples where one of the signals has
/// its smallest or its largest value (NaN ignored). So every signal's extremes, overall and per bucket, survive;
/// averages do not. All indices when n <= max_points. Precondition: every signal has n samples and
/// max_points >= 2 * signals.size().
std::vector<std::size_t> extreme_preserving_indices(std::span<const std::span<const double>> signals, std::size_t n,
                                                    std::size_t max_points);

/// Robust statistics used as thresholds (a noise floor, a quantum) look at every sample up to this many values, and
/// above it at an evenly spread sample of between half this many and this many.
inline constexpr std::size_t robust_sample_size = std::size_t{1} << 18;

/// The stride of that sample for `n` values (1 up to robust_sample_size).
inline std::size_t robust_sample_stride(std::size_t n) {
    return n <= robust_sample_size ? 1 : (n + robust_sample_size - 1) / robust_sample_size;
}

/// Robust noise floor of a signal: 1.4826 * median absolute deviation of its first differences / sqrt(2)
/// (the standard deviation of white noise on the samples); above robust_sample_size differences from an evenly spread
/// sample of them (0.5 % relative standard error).
double noise_floor(std::span<const double> x);

/// The rank percentile() selects among `count` values (count > 0): floor(fraction * (count - 1)), the fraction
/// clamped to 0..1. A test that counts values instead of selecting one decides by the same rank.
std::size_t percentile_rank(std::size_t count, double fraction);
/// The value below which `fraction` (0..1) of the values lie: the element of rank floor(fraction * (n - 1)), no
/// interpolation; 0 for no values.
double percentile(std::vector<double> values, double fraction);
/// The same in place: reorders `values` (no copy), so that several percentiles of one buffer cost no memory.
double percentile_in_place(std::span<double> values, double fraction);
/// percentile() of the magnitudes |values| without a copy of them: the same value, bit for bit. Magnitudes order as
/// their bit patterns, so a histogram of the leading 16 bits (the exponent and 4 bits of the mantissa) finds the
/// bucket the rank falls in, and only the values in that bucket (a few per cent of scattered residuals; all of them at
/// worst) are gathered and selected among. 0 for no values.
double absolute_percentile(std::span<const double> values, double fraction);
/// absolute_percentile() of the `count` values that `each` visits, never gathered: each(f) calls f(x) for every one
/// of them, the same values in the same order every time (two or three calls), so that the percentile of a subset of
/// a column (the moving samples' speeds, a pass's) costs a pass or two and no copy. The same value, bit for bit.
template <class Each>
double absolute_percentile_of(std::size_t count, const Each& each, double fraction);
/// How many values `each` visits (as absolute_percentile_of takes it): one pass.
template <class Each>
std::size_t visited_count(const Each& each) {
    std::size_t count = 0;
    each([&count](double) { ++count; });
    return count;
}
/// Whether percentile(values, fraction) >= threshold, by counting in one pass (no selection, no reordering): the
/// element of rank r is at least `threshold` exactly when at most r values lie below it. False for no values.
bool percentile_at_least(std::span<const double> values, double fraction, double threshold);

/// The minimum and the maximum of x over the window [k - half, k + half] (clipped to the trace) for k = 0, 1, ...,
/// n - 1 in turn, each handed to visit(k, low, high); of equal values the latest in the window. By van Herk and
/// Gil-Werman: with blocks of the window's length w = 2 half + 1 from sample 0, a window lies in at most two blocks,
/// and its extreme is that of the extreme from its start to its block's end (a suffix) and of the extreme from its
/// end's block's start to its end (a prefix): three comparisons per sample and extreme whatever the window's length,
/// and memory for four blocks, not a column.
template <class Visit>
void window_extremes(std::span<const double> x, std::size_t half, const Visit& visit);

namespace detail {
/// The element of rank `rank` of `members` (reordered).
double select_rank(std::vector<double>& members, std::size_t rank);
}  // namespace detail

template <class Each>
double absolute_percentile_of(std::size_t count, const Each& each, double fraction) {
    if (count == 0) return 0.0;
    const std::size_t rank = percentile_rank(count, fraction);
    std::vector<double> members;
    constexpr std::size_t small = 4096;  // a copy this short costs less than the histogram
    if (count <= small) {
        members.reserve(count);
        each([&](double v) { members.push_back(std::abs(v)); });
        return detail::select_rank(members, rank);
    }
    constexpr int shift = 48;  // the leading 16 bits of a magnitude: its (zero) sign, exponent, 4 bits of mantissa
    const auto bucket_of = [](double v) { return std::bit_cast<std::uint64_t>(std::abs(v)) >> shift; };
    std::vector<std::size_t> counts(std::size_t{1} << (64 - shift), 0);
    each([&](double v) { ++counts[bucket_of(v)]; });
    std::size_t below = 0, bucket = 0;
    while (below + counts[bucket] <= rank) below += counts[bucket++];
    members.reserve(counts[bucket]);
    each([&](double v) {
        if (bucket_of(v) == bucket) members.push_back(std::abs(v));
    });
    return detail::select_rank(members, rank - below);
}

template <class Visit>
void window_extremes(std::span<const double> x, std::size_t half, const Visit& visit) {
    const std::size_t n = x.size();
    if (n == 0) return;
    const std::size_t w = std::min(n, 2 * half + 1);  // a window no longer than the trace: one block or two
    // of two values, the earlier only where strictly more extreme
    const auto lower = [](double earlier, double later) { return earlier < later ? earlier : later; };
    const auto higher = [](double earlier, double later) { return earlier > later ? earlier : later; };
    std::vector<double> low_prefix(w), high_prefix(w), low_suffix(w), high_suffix(w);
    std::size_t a_start = 0, b_start = 0, formed = 0;  // the blocks of the window's ends; prefixes formed to `formed`
    bool suffixes = false;                             // whether the suffixes of a's block are formed
    for (std::size_t k = 0; k < n; ++k) {
        const std::size_t a = k > half ? k - half : 0, b = std::min(n - 1, k + half);
        for (; formed <= b; ++formed) {
            if (formed == b_start + w) b_start += w;
            const std::size_t i = formed - b_start;
            low_prefix[i] = i == 0 ? x[formed] : lower(low_prefix[i - 1], x[formed]);
            high_prefix[i] = i == 0 ? x[formed] : higher(high_prefix[i - 1], x[formed]);
        }
        if (a == a_start + w) {
            a_start += w;
            suffixes = false;
        }
        if (a_start == b_start && a == a_start) {  // the window starts its block: the prefix alone
            visit(k, low_prefix[b - b_start], high_prefix[b - b_start]);
            continue;
        }
        if (!suffixes) {
            const std::size_t last = std::min(n, a_start + w) - 1;
            low_suffix[last - a_start] = high_suffix[last - a_start] = x[last];
            for (std::size_t i = last; i-- > a_start;) {
                low_suffix[i - a_start] = lower(x[i], low_suffix[i + 1 - a_start]);
                high_suffix[i - a_start] = higher(x[i], high_suffix[i + 1 - a_start]);
            }
            suffixes = true;
        }
        const std::size_t i = a - a_start;
        if (a_start == b_start)  // within one block only where the window ends at the trace's end, as the suffix
            visit(k, low_suffix[i], high_suffix[i]);
        else
            visit(k, lower(low_suffix[i], low_prefix[b - b_start]), higher(high_suffix[i], high_prefix[b - b_start]));
    }
}

}  // namespace feedid
