#pragma once
// Each channel's native interval: the interval at which its source signal was sampled before it was put on the
// trace's time base. NC traces mix rates (SINUMERIK: 2 ms and 4 ms signals) and the slower signals arrive held
// (forward-filled) on the finest grid; analysis defaults that depend on the sample rate (the differentiation filter's
// cut-off) must come from the signal's own rate, not from the grid's.

#include <cstddef>
#include <optional>
#include <span>
#include <vector>

#include "feedid/core/trace.hpp"

namespace feedid {

struct HoldDetectionOptions {
    int max_factor{64};  ///< the largest hold factor k looked for [grid samples]
    /// Value changes while the signal moves (steps above 1.5 of its smallest step) needed before anything is said.
    std::size_t minimum_moving_changes{20};
    /// Share of the value changes allowed off the hold grid (a dropped sample, a reader's rounding at the start).
    double exception_fraction{0.02};
};

/// A signal held over `factor` grid samples: its value changes only at grid indices j with j % factor == phase.
struct SampleAndHold {
    int factor{1};            ///< k >= 2 [grid samples per native sample]
    int phase{0};             ///< the grid index of a change, modulo k
    std::size_t changes{0};   ///< value changes in the signal
    std::size_t off_grid{0};  ///< of those, at other indices (the exceptions accepted)
};

/// Detects sample-and-hold: a signal sampled every k-th grid sample and forward-filled changes only on one residue
/// class modulo k. The evidence is the signal's moving parts only: while it moves by more than its smallest step
/// between changes, a signal sampled on the grid changes at consecutive samples, a held one every k-th. A quantised
/// signal at creep speed (a 1 um encoder at a few um/s) repeats values over several samples without being held, and
/// a standstill repeats one value: both change by one smallest step or not at all, so neither counts as evidence.
/// k is the most frequent gap between a moving change and the change before it; every change (moving or not) must lie
/// on the hold grid but for `exception_fraction` of them. NaN samples are skipped. Nullopt when the signal is not held
/// or the data cannot tell (fewer moving changes than `minimum_moving_changes`).
std::optional<SampleAndHold> detect_sample_and_hold(std::span<const double> values,
                                                    const HoldDetectionOptions& options = {});

/// The residue class modulo `factor` on which a held signal's values change (the most changes); 0 without changes.
int hold_phase(std::span<const double> values, int factor);

/// A held signal as it was sampled: the samples on its own grid (indices j % factor == phase) kept, the samples in
/// between linearly interpolated from the neighbouring ones (held at the ends). Holding delays a signal by
/// (factor - 1)/2 samples on average and puts steps into it; the interpolation takes both out. Finite values only.
std::vector<double> interpolate_held(std::span<const double> values, int factor, int phase);

/// Gives every channel of a validated trace its native interval: the format's where the reader set one, otherwise k
/// times the sample time where detect_sample_and_hold() finds the channel held over k samples (recorded in
/// `findings`), otherwise the sample time. Needs the time base (two samples or more; a shorter trace is left as is).
void resolve_native_intervals(Trace& trace);

/// The interval [s] to take the sample rate of the channel with this role from: its native interval, or the trace's
/// sample time when it has none (or no such channel).
double native_interval_of(const Trace& trace, Role role);

}  // namespace feedid
