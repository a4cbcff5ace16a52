#pragma once
// The import chain: read (a format reader) -> map channels to roles -> convert units to SI -> validate.
// read_trace() detects the format from the content and runs the whole chain.

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "feedid/io/join.hpp"
#include "feedid/core/trace.hpp"
#include "feedid/core/units.hpp"

namespace feedid {

struct ImportOptions {
    /// Explicit role -> source channel name (from `--channel ROLE=NAME`).
    std::map<Role, std::string> channels;
    /// Units for role channels whose source carries none, or overrides (from `--unit ROLE=UNIT`).
    std::map<Role, std::string> units;
    /// Context for units that need it (rpm needs a lead, % needs a rating).
    UnitContext unit_context;
    /// For sources holding several axes (a SINUMERIK trace): which axis to read, by NC axis index ("2", from the
    /// `[u1, 2]` suffix) or by axis name ("X"); empty = the only or first one. Also the axis label for the history.
    /// For other sources whose channel names carry CNC axis prefixes (`X1_ActualPosition`, `Y1_...`): the prefix whose
    /// channels are kept and guessed from (case-insensitive); several prefixes and none chosen is an InputError naming
    /// them, unless roles are given in `channels`.
    std::string axis;
    /// Sampling period [s] for sources that carry none (halsampler output, a CSV without a time column: a time channel
    /// is made from it, with a finding); ignored where the file has time stamps.
    std::optional<double> sample_time_s;
    /// CSV: lines skipped at the top of the file before the header is looked for (from `--skip-rows N`).
    std::size_t skip_rows{0};
    /// Force a format instead of detecting it ("csv", "mat", "sinumerik-trace", "twincat-scope", "halscope",
    /// "mr-configurator", "ni-daq").
    std::string format;
    /// A second recording joined onto this one's time base (`--join FILE[@SHIFT]`, see join.hpp). Channel and unit
    /// assignments may name channels of either file.
    std::optional<JoinSpec> join;
    /// Roles not guessed from names in this file (a joined file's channel holds them by --channel).
    std::vector<Role> assigned_elsewhere;
    /// Channels zeroed from the samples at rest before the move (`--tare ROLE`, see tare.hpp), after the join.
    std::vector<Role> tare;
    /// Channels whose sign is flipped after the units are converted (`--invert ROLE`): a drive whose current (or
    /// torque) is positive in the direction the NC counts negative. Before the tares.
    std::vector<Role> invert;
    /// The axis is rotary (`--rotary`): units the source states in its basic length system (a SINUMERIK trace's posn
    /// and velo signals) are degrees and rpm, and channels without a unit are taken in rad, rad/s and N*m. Stating an
    /// angle for a position role (`--unit position=deg`) says the same for the whole trace.
    bool rotary{false};
    /// Describe rather than analyse (`feedid info`): a file holding several axes and no --axis keeps every channel,
    /// guesses no role and lists the axes (Trace::axes); a file without a time column and no sample time is described
    /// without one (a finding says how to give it).
    bool describe{false};
};

/// Parses `ROLE=VALUE` (for --channel and --unit); throws InputError naming the option.
std::pair<Role, std::string> parse_role_assignment(std::string_view text, std::string_view option);

/// Assigns roles (explicit ones first, then guesses from common names, each guess recorded in trace.findings),
/// converts every channel with a known unit to SI, and validates. A role channel whose unit is unknown is an
/// InputError naming the channel and the unit; a role channel without any unit is taken as SI and that is recorded
/// in findings.
void prepare_trace(Trace& trace, const ImportOptions& options);

/// Reads any supported file (format from the content, then the extension) and prepares it; with `options.join`, the
/// second file is read the same way (its own format detected) and joined onto this one's time base; then the tares.
Trace read_trace(const std::filesystem::path& path, const ImportOptions& options = {});

/// The format reader alone: raw channels in their source units, roles unassigned (the first step of read_trace).
Trace read_source(const std::filesystem::path& path, const ImportOptions& options = {});

/// Names the format of a file from its first bytes and extension: "csv", "mat", "sinumerik-trace", "twincat-scope",
/// "halscope", "mr-configurator", "ni-daq", or "" when unknown.
std::string detect_format(const std::filesystem::path& path);

/// Reads a whole file into memory; InputError naming the file when it cannot be read.
std::string read_file_bytes(const std::filesystem::path& path);

}  // namespace feedid
