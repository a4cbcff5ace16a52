#pragma once
// Mitsubishi MR Configurator2 graph exports (CSV), as the servo setup software writes them for MR-J4/MR-J5 drives.
//
// Layout: a preamble (`Axis1`, `Number of sampling data,1024`, `Sampling time interval(ms),0.667`), a header row of
// slot names (`Time, Analog 1..7, Digital 1..8`), a row of what each slot holds (`ms, Servo motor speed, Torque,
// Droop pulses (by 1 pls.), Not selected, ..., INP, ...`), then one row per sample.
//
// Channels are named by that second row (the slot names carry no meaning); "Not selected" slots are dropped. The
// time channel keeps the row's unit (ms). Units are those MR Configurator2 plots the quantities in: speeds in r/min,
// torque, current and load ratios in % of the rated value, droop pulses in pulses (a unit no analysis needs: left as
// is, with a finding); digital slots carry none.
//
// The preamble is checked against the data: a sample interval that differs from the time column's (beyond the
// rounding of the stated figure) is an error naming both, since every derivative scales with it; a sample count
// that differs from the rows is a finding naming both (the rows and their time stamps stand on their own).

#include <string>
#include <string_view>

#include "feedid/core/trace.hpp"

namespace feedid {

/// Parses an MR Configurator2 graph export into raw channels (time in the file's unit, the others in MR
/// Configurator2's units). Throws InputError naming the file and line.
Trace parse_mr_configurator(std::string_view text, const std::string& source);

/// True when the text starts like an MR Configurator2 graph export (an `Axis` line, then the sampling preamble).
bool looks_like_mr_configurator(std::string_view head);

}  // namespace feedid
