#pragma once
// `feedid scan`: the online identifier (online_identifier.hpp) run over a recorded trace, block by block, and its estimate as
// the identify result document (the same "parameters" keys, value and stderr, null with a diagnostic) with the
// windows' verdicts and each parameter's information.

#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/model/drive.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/io/import.hpp"
#include "feedid/identify/online_identifier.hpp"
#include "feedid/core/trace.hpp"

namespace feedid {

/// One --only-when condition: a sample is used only where channel `channel` compares with `value` as `op` says.
struct GateCondition {
    std::string channel;
    std::string op;  ///< "<", ">", "<=", ">="
    double value{0.0};
};

/// Parses "NAME<VALUE" (also >, <=, >=). InputError naming the text when it is not one.
GateCondition parse_gate_condition(const std::string& text);

/// Per sample, 1 where every condition holds (the channel's values as the trace holds them). InputError naming the
/// channel and the trace's channels when one is missing.
std::vector<char> gate_samples(const Trace& trace, std::span<const GateCondition> conditions);

struct ScanResult {
    IdentifyResult result;  ///< status, parameters, trace, diagnostics, as identify's
    OnlineEstimate online;
    /// The log is too coarse for a mass (identify's rule): no windows, identify's friction-only estimate, M null.
    bool friction_only{false};
};

/// Pushes the trace's time, position and `force` [N] (drive_force()) through an OnlineIdentifier in blocks of
/// `block` samples; `use` (empty = all) is the --only-when gate. Without a position, the logged velocity integrated
/// is the motion; InputError for a trace with neither. A trace too coarse for a mass (identify's rule,
/// assess_trace_resolution, on the samples the gate keeps) is not scanned by windows: `friction_only`, identify's
/// friction-only estimate (B, F_C from the steady-speed samples; M, F_B, v_s null with the reason). With
/// `systematic`, a second identifier runs with the split speed doubled: each parameter's systematic part is how far it
/// moves (Estimate::set_systematic), with a finding where that exceeds twice its standard error.
ScanResult scan(const Trace& trace, std::span<const double> force, std::span<const char> use,
                const OnlineOptions& options, std::size_t block = 65536, bool systematic = true);

/// The same over a CSV file read in blocks of `block_rows` lines, for files larger than memory: the first block goes
/// through the importer as a whole file would (header, units, roles, constants), and every later block is parsed with
/// the lines before the first data row put in front of it, so that its values are converted exactly as the whole
/// file's would be; the identifier sees the same samples, in the same order, whatever the block size. Memory is that
/// of one block. `findings` receives the first block's import findings. InputError as read_trace; also for options
/// a block cannot apply (--join, --tare, --invert, a time base from --sample-time): read the file whole for those.
ScanResult scan_csv_stream(const std::filesystem::path& path, const ImportOptions& import, const DriveConstants& drive,
                           std::span<const GateCondition> gates, const OnlineOptions& options, std::size_t block_rows,
                           std::vector<std::string>& findings, bool systematic = true);

/// The result document: identify's keys plus "kind": "scan", "windows" {total, qualified, rejected: {reason: n}}
/// and "information" {key: {"inverse_variance": 1/var [1/unit^2]}, "eigenvalues": [...] (of the information matrix
/// with each parameter in units of its standard error: 1 for parameters the data separates, near 0 for a
/// combination it cannot)}.
nlohmann::json scan_document(const ScanResult& scan);

/// The one-line verdicts: "M from 212 windows, sigma 0.4 %" per parameter, or why it is null.
std::vector<std::string> scan_verdicts(const ScanResult& scan);

}  // namespace feedid
