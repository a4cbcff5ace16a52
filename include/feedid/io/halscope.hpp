#pragma once
// LinuxCNC halscope text exports and halsampler output.
//
// Three layouts, told apart from the content:
//  - halscope 2.9 and later: "# Sampling period is N ns", a line of channel names separated by ';', optional
//    "# Position: ..." / "# Scale: ..." comment lines, then one ';'-separated row per sample.
//  - halscope before 2.9: "Sampling period is N ns", then one line per sample of "name +value name +value ..."
//    (interlaced), or one "name +value" per line channel after channel. That writer prints one sample past the
//    capture (its loop runs to n <= samples), so the surplus last sample is dropped and a finding says so.
//  - halsampler: one line per sample of blank-separated numbers in the order of the sampler's pins, optionally
//    tagged with the sample number first (-t), "overrun" on a line of its own where samples were lost. It carries
//    neither names (channels are named pin.0, pin.1, ... like the sampler's pins) nor the sampling period, which must
//    be given.
//
// HAL values carry no units (LinuxCNC works in the machine units of its INI file); roles are guessed from HAL pin
// names (…pos-fb = position, …pos-cmd = reference_position, …vel-cmd = velocity_command, …vel-fb = velocity) and
// said in findings.

#include <optional>
#include <string>
#include <string_view>

#include "feedid/core/trace.hpp"

namespace feedid {

/// Parses halscope / halsampler text into raw channels with a "time" channel [s] built from the sampling period
/// (halscope: from the file; halsampler: `sample_time_s`, required there). Throws InputError naming the file and line.
Trace parse_halscope(std::string_view text, const std::string& source,
                     std::optional<double> sample_time_s = std::nullopt);

/// True when the text looks like halsampler output (lines of blank-separated numbers, no header): used by format
/// detection.
bool looks_like_halsampler(std::string_view head);

}  // namespace feedid
