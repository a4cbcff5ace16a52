#pragma once
// Two recorders of one move (a drive's own trace and a DAQ's load cell, say) joined onto one time base.
//
// The second recording's channels are resampled by linear interpolation onto the first's time stamps after a time
// shift: a sample the second recorder stamped t2 lies at t2 + shift on the first one's time base. Samples of the
// first trace outside the second's shifted span are dropped (never extrapolated) and a finding says how many. The
// shift is given, or found by cross-correlating a channel of each recording within a bounded range (the peak's
// correlation coefficient is reported: a broad or weak peak is the user's cue to give the shift).

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "feedid/core/trace.hpp"

namespace feedid {

struct JoinOptions {
    /// Added to the second recording's time stamps [s]; unset = found by cross-correlation (below).
    std::optional<double> shift_s;
    /// The channels cross-correlated to find the shift: one of the first recording, one of the second (names as in
    /// the files). Empty: the channels that hold the same role in both.
    std::string ours;
    std::string theirs;
    /// The shift is searched within +/- this [s].
    double max_shift_s{0.1};
};

/// What join_traces did.
struct JoinReport {
    double shift_s{0.0};            ///< the shift applied [s]
    bool automatic{false};          ///< found by cross-correlation
    double correlation{0.0};        ///< correlation coefficient at the shift found (automatic only)
    std::size_t dropped_before{0};  ///< samples of the first trace before the second's span
    std::size_t dropped_after{0};   ///< ... and after it
};

/// `FILE[@SHIFT]` of --join: SHIFT is a time with a unit ("4ms", "-0.004s", "-0.004" = s), or "auto", or
/// "auto:OURS=THEIRS". Throws InputError naming the option on a malformed shift.
struct JoinSpec {
    std::string path;
    JoinOptions options;
};
JoinSpec parse_join_spec(std::string_view text);

/// The first trace with the second's channels (other than its time channel) resampled onto its time base; both in SI
/// units with roles assigned. A channel name that clashes with one of the first trace gets the suffix "_2" (a
/// finding says so); constants of the second trace are added where the first has none of that name. The findings of
/// the join (shift, correlation, dropped samples) are added to the trace's. Throws InputError when the spans do not
/// overlap or a named correlation channel does not exist.
Trace join_traces(const Trace& first, const Trace& second, const JoinOptions& options, JoinReport* report = nullptr);

/// The shift [s] that best lines `theirs` (sampled at `their_time`) up with `ours` (at `our_time`): the largest
/// |correlation coefficient| over shifts in steps of our sample time within +/- max_shift_s, refined to a fraction of
/// a sample by a parabola through the peak. Returns the shift and the coefficient there.
std::pair<double, double> find_shift(std::span<const double> our_time, std::span<const double> ours,
                                     std::span<const double> their_time, std::span<const double> theirs,
                                     double max_shift_s);

/// `values` (at `time`, ascending) linearly interpolated at `at`; NaN outside [time.front(), time.back()].
std::vector<double> interpolate_linear(std::span<const double> time, std::span<const double> values,
                                       std::span<const double> at);

}  // namespace feedid
