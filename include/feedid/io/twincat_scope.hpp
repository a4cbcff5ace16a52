#pragma once
// Beckhoff TwinCAT 3 Scope View CSV exports, in every export variant: separator tab, space, colon, semicolon or
// comma; decimal point or comma; one time column per channel or one shared by channels with the same time stamps
// (ExcludeDoubleTimestamp); channels sorted or not; an optional trailing "EOF" line; a trailing separator; CRLF.
//
// Layout: four file-info lines (Name, File, Starttime/Endtime of export), blank lines, then a channel header block
// whose rows start with a key (Name, Data-Type, SampleTime[ms], ..., Unit, Unit ScaleFactor, Unit Offset) and repeat
// the key in every time column; a blank line; then data rows where each time column [ms] is followed by the values
// of its channels. Channels that end early leave blank cells (or none at the end of a row).
//
// Values are taken as exported: the Scope applies a channel's ScaleFactor/Offset and Unit ScaleFactor/Unit Offset
// before writing (checked on the reference exports: func_scaled with ScaleFactor -1, Offset 1 is written as 1 - t),
// so they are not applied again; a finding lists the channels that carry such a scaling. The unit is the Unit row's
// symbol ("V (Voltage)" -> "V"; "(None)" -> none).
//
// Common time base: the time stamps of the channel group with the finest sample time, over the span where every
// channel has samples; a slower channel holds its latest sample (the value the Scope itself shows until the next
// sample). A finding says so when sample times differ, and how many samples fell outside the common span.

#include <string>
#include <string_view>

#include "feedid/core/trace.hpp"

namespace feedid {

/// Parses a TwinCAT Scope CSV export into raw channels (a "time" channel in ms, the others in their Scope units).
/// Throws InputError naming the file and line.
Trace parse_twincat_scope(std::string_view text, const std::string& source);

}  // namespace feedid
