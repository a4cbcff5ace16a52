#pragma once
// Unit mix-ups that a trace gives away by itself. A position written in mm but labelled m makes a feed drive move at
// 156 m/s; a velocity in mm/min labelled mm/s runs 60 times faster than the position it belongs to. Either would
// give a mass or a viscous friction off by the same factor, with a small standard error and exit 0. The checks:
//   plausibility: the speeds the position (or logged velocity) shows lie below what any feed drive reaches
//                 (linear 20 m/s; rotary 3000 rad/s, about 29,000 rpm) and the current below 3000 A;
//   redundancy:   two channels that measure the same motion agree in scale within a factor of 4: the position
//                 and the reference position (their spans), the logged velocity and the position's derivative,
//                 the velocity command and the (logged or derived) velocity (their 95th percentiles of |v|).
// A factor between 4 and 1/4 passes (tracking, filtering and overshoot never make one), so only real mix-ups are
// caught: 1000 (m/mm), 60 (per minute/per second), 2*pi (rev/rad), 25.4 (in/mm) and their products. Channels that
// barely move (below 20 times their noise) are not compared.

#include <string>
#include <vector>

#include "feedid/core/trace.hpp"

namespace feedid {

struct ConsistencyOptions {
    double max_linear_speed{20.0};     ///< [m/s]
    double max_angular_speed{3000.0};  ///< [rad/s]
    double max_current{3000.0};        ///< [A]
    double max_scale_ratio{4.0};       ///< two measures of one motion may differ by at most this factor
    double noise_multiple{20.0};       ///< a channel is compared only when it moves this far above its noise
};

/// One message per inconsistency found, each naming the channels, their units as the file gave them and the
/// factor; empty when none.
std::vector<std::string> unit_inconsistencies(const Trace& trace, const ConsistencyOptions& options = {});

/// The check identify and scan run before anything else: an InputError naming the trace and every inconsistency
/// unit_inconsistencies finds; nothing when there is none.
void require_consistent_units(const Trace& trace, const ConsistencyOptions& options = {});

}  // namespace feedid
