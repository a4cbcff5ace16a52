#pragma once
// Stick-slip: passes in which the axis sticks and slips instead of following a steady command. A slow pass on a
// drive whose friction falls with speed (the Stribeck region: F_B above F_C) can stick while the position error, and
// with it the controller's integral, builds up, then slip in a burst faster than commanded and stick again. Such a
// pass carries neither steady-speed friction (the speed is never steady) nor clean mass information (the bursts are
// short and violent, the friction in them anywhere between the static limits), so selection keeps it out of both
// steps.
//
// With a reference (the reference position or the velocity command), a pass is a stretch of commanded motion in one
// direction, and it stick-slips when, while the command runs at a steady speed, the axis returns to (nearly) zero or
// swings about the command by more than half of it, more than once. Without one, a pass is a stretch of motion in one
// direction, and it stick-slips when the axis stops and restarts in the same direction at least twice, each stop and
// burst brief. That rule is StickSlipTracker's, sample by sample: identify runs it over the trace, the online
// identifier (online_identifier.hpp) over its stream, window after window, with the same options.

#include <cstddef>
#include <optional>
#include <vector>

#include "feedid/identify/preprocess.hpp"

namespace feedid {

struct StickSlipOptions {
    /// A stop: |v| below this fraction of the commanded speed (with a reference) or of the peak speed of the burst
    /// before it (without one), and not above the moving threshold.
    double stop_fraction{0.2};
    /// A swing: |v - v_ref| above this fraction of the commanded speed.
    double swing_fraction{0.5};
    /// Swings (separate excursions) that make a pass stick-slip; one stop is enough.
    int swings{2};
    /// The command is steady where its speed lies within this fraction of the pass's median commanded speed ...
    double steady_reference_fraction{0.05};
    /// ... and has been for this long (the axis settles after the ramp) [s].
    double settle_s{0.1};
    /// Passes whose commanded speed is below this many velocity noise floors divided by stop_fraction are not judged
    /// (a stop could not be told from noise).
    double noise_multiple{3.0};
    /// Without a reference: stops (and the bursts between them) shorter than this are stick-slip, not commanded
    /// dwells and moves [s]; a pass needs at least `stops_without_reference` of them. The demo drive's slow passes
    /// stick for 3-100 ms and slip for 5-190 ms; production moves between dwells last 0.2 s and more.
    double max_stick_s{0.2};
    int stops_without_reference{2};
};

/// One pass: a stretch of (commanded) motion in one direction, [first, last) in the analysed samples.
struct MotionPass {
    std::size_t first{0};
    std::size_t last{0};
    int direction{0};   ///< +1 forward, -1 reverse
    double speed{0.0};  ///< the commanded (or median actual) speed [m/s]
    bool stick_slip{false};
};

struct StickSlip {
    std::vector<MotionPass> passes;
    std::vector<char> flags;  ///< per analysed sample: 1 inside a stick-slip pass
    std::size_t stick_slip_passes{0};
    std::size_t samples{0};  ///< analysed samples inside stick-slip passes
    bool by_reference{false};
};

/// Finds the passes and which of them stick-slip; `moving_threshold` [m/s] is selection's.
StickSlip detect_stick_slip(const Derivatives& derivatives, double moving_threshold,
                            const StickSlipOptions& options = {});

/// The rule without a reference, sample by sample: O(1) state, nothing allocated, never throws. A pass runs from the
/// first to the last sample moving (|v| above the moving threshold) in one direction before the motion reverses; a stop
/// inside it is |v| at or below stop_fraction of the peak |v| of the burst before it (at least the moving threshold),
/// until |v| rises above that level again. The pass stick-slips when at least stops_without_reference of its stops were
/// shorter than max_stick_s and every burst that ended in a stop was too. Sample indices count the samples added.
class StickSlipTracker {
public:
    /// `moving_threshold` [m/s or rad/s] > 0.
    StickSlipTracker(double moving_threshold, const StickSlipOptions& options);

    /// The next sample: time [s], velocity [m/s or rad/s]. Returns the pass it ended (by reversing), if any; its
    /// `speed` is the peak |v| of its bursts.
    std::optional<MotionPass> add(double time, double velocity);
    /// Ends the pass in progress (the end of the data) and returns it, if any.
    std::optional<MotionPass> finish();
    /// Whether the pass in progress stick-slips on what has been seen of it; false without one.
    [[nodiscard]] bool stick_slipping() const;
    /// The pass in progress, if any (its `last` is one past its latest moving sample).
    [[nodiscard]] std::optional<MotionPass> current() const;
    /// Samples added so far: the index the next sample gets.
    [[nodiscard]] std::size_t samples() const { return samples_; }

private:
    [[nodiscard]] MotionPass closed() const;

    double moving_threshold_;
    StickSlipOptions options_;
    std::size_t samples_{0};
    MotionPass pass_{};  ///< direction 0: no pass in progress
    bool stopped_{false};
    double burst_start_s_{0.0};
    double stop_start_s_{0.0};
    double burst_peak_{0.0};
    double stop_level_{0.0};
    double longest_burst_s_{0.0};
    double pass_peak_{0.0};
    int brief_stops_{0};
};

}  // namespace feedid
