#pragma once
// National Instruments DAQ CSV files (LabVIEW / FlexLogger "one time column per channel" layout).
//
// Layout: an optional UTF-8 byte-order mark; a header block of key rows, each holding a (key, value) pair per channel:
// `Timestamp,2020-03-16 17:04:51,Timestamp,...`, `Interval,0.0005,...`, `Channel name,"Force",...`, `Unit,"V",...`;
// then data rows of a (time [s], value) pair per channel. Separator `,` (or `;`/tab, with a decimal comma).
//
// One time channel ("Time", s) is kept: the channels' time columns must be exactly equal, row by row, and their
// Timestamp and Interval cells too; otherwise the file is refused with the channels named (they are on different time
// bases, which this reader does not resample). A stated Interval is checked against the time column's mean step.
// Channels are named by `Channel name`, with the `Unit` row's unit as stated (a load cell's "V" stays volts: scaling it
// to newtons is `--force-constant`'s job).

#include <string>
#include <string_view>

#include "feedid/core/trace.hpp"

namespace feedid {

/// Parses an NI DAQ CSV into raw channels ("Time" in s, the others in their stated units). Throws InputError naming
/// the file and line.
Trace parse_ni_daq(std::string_view text, const std::string& source);

/// True when the text starts like an NI DAQ CSV (a `Timestamp` row followed by `Interval` and `Channel name` rows).
bool looks_like_ni_daq(std::string_view head);

}  // namespace feedid
