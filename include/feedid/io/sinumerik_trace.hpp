#pragma once
// SINUMERIK Solution Line servo trace XML (<traceSession>): sparse records, signals on their own intervals.
//
// Time base: the finest `interval` among the axis's signals, from the first to the last <rec> time. Records are
// sparse (a value is written only when it changed), so each signal is forward-filled on its own interval grid
// (origin: its first sample) and then read at each time of the fine base (its latest grid value at or before that
// time). Before a signal's first sample nothing is invented: the value is NaN. The trace then starts at the first
// sample where every role channel has a value; a finding says how many leading samples that drops.
//
// Units from `unitsType` (posn -> mm, velo -> mm/min, current -> A, torque -> N*m, percent -> %, accel -> m/s^2):
// a linear metric axis is assumed, and a finding says so (a rotary axis: --rotary or --unit position=deg, and the
// import then takes every posn signal in deg and every velo signal in rpm). Roles are guessed from the NC variable
// names (ActPos2ndEnc/measPos2 = direct measuring system = position; ActPos1stEnc/measPos1 = motor encoder:
// motor_position beside a direct system, position without one; CmdPos = reference_position; CmdVel = velocity_command;
// ActVel of the same measuring system = velocity; ActCurr = current iq), each guess recorded in findings.

#include <string>
#include <string_view>
#include <vector>

#include "feedid/core/trace.hpp"

namespace feedid {

/// How the finding that says the SINUMERIK units were taken for a linear metric axis begins: the import drops it once
/// the axis is known to be rotary (--unit position=deg).
inline constexpr std::string_view sinumerik_linear_units_finding = "SINUMERIK units taken for a linear metric axis";

/// Reads the signals of one axis into raw channels on the finest interval's time base (channel "time" in s, the
/// others in their source units, named after the NC variable without path and axis suffix, e.g.
/// "nckServoDataActPos2ndEnc64"). `axis` selects it by NC axis index ("2", from the `[u1, 2]` suffix) or by name;
/// empty = the first axis in the file. Throws InputError naming the file and element (with its line) on a malformed
/// file.
Trace parse_sinumerik_trace(std::string_view xml, const std::string& source, const std::string& axis = {});

/// One trace per axis in the file (signals without an axis suffix go into every one), in order of first appearance.
std::vector<Trace> parse_sinumerik_trace_axes(std::string_view xml, const std::string& source);

}  // namespace feedid
