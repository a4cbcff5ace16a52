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
// burst brief.

#include <cstddef>
#include <vector>

#include "feedid/identify/preprocess.hpp"

namespace feedid {

struct StickSlipOptions {
    /// A stop: |v| below this fraction of the commanded speed (with a reference) or the moving threshold.
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
    /// dwells [s]; a pass needs at least `stops_without_reference` of them.
    double max_stick_s{1.0};
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

}  // namespace feedid
