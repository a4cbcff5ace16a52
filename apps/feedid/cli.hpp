#pragma once
// Shared pieces of the feedid command line: options every trace-reading subcommand takes, output helpers, and the
// registration function of each subcommand (one file each in apps/feedid/).

#include <CLI/CLI.hpp>

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/model/drive.hpp"
#include "feedid/io/import.hpp"
#include "feedid/io/output_file.hpp"

namespace feedid::cli {

/// What a subcommand runs after parsing; returns the exit code (0 ok, 1 analysis failed, 2 bad input).
using Action = std::function<int()>;

/// A check of a numeric option at parse time: the value must be a finite number from `low` to `high` (`unit` says in
/// what). "nan", "inf" and values outside the range are refused before anything is read (exit 2), with a message
/// that names the option, the value and the allowed range: "--cutoff: 1e-300 is outside the allowed range 0.001 to
/// 1e+06 Hz". The ranges reach far past what machines have: they refuse what no unit could make sense of.
CLI::Validator allowed_range(double low, double high, const std::string& unit);
/// The allowed ranges of --lead [mm] and --gear-ratio (drive.hpp's allowed_lead_m, allowed_gear_ratio).
CLI::Validator lead_range();
CLI::Validator gear_ratio_range();
/// A delay with its unit ("0.5ms", "-250us", "0.001s"; a bare number is seconds) [s]; nullopt when not one.
std::optional<double> delay_seconds(const std::string& text);
/// What is wrong with a --delay value (auto, none or a time with its unit); "" when nothing.
std::string delay_problem(const std::string& text);
/// A --delay time that delay_problem accepted [s].
double parse_delay(const std::string& text);

/// `FILE [--channel ROLE=NAME]... [--unit ROLE=UNIT]... [--axis N] [--format F] [--sample-time S] [--skip-rows N]`
struct TraceArguments {
    std::string file;
    std::vector<std::string> channel_assignments;
    std::vector<std::string> unit_assignments;
    std::string axis;
    std::string format;
    std::optional<double> lead_mm;     // shared with DriveArguments when both are present
    std::optional<double> gear_ratio;  // likewise: rpm on a linear axis is a motor speed, geared to the screw
    std::string rated;                 // what 100 % means for % units: "18A", "2.4Nm" (a bare number: A)
    std::string join;                  // FILE[@SHIFT]: a second recording joined onto this one's time base
    std::optional<double> join_max_shift_s;
    std::vector<std::string> tare;  // roles zeroed from the samples at rest before the move
    std::vector<std::string> invert;  // roles whose sign is flipped (a drive counting the other way)
    std::optional<double> sample_time_s;
    std::size_t skip_rows{0};
    bool rotary{false};    // --rotary: the axis is rotary (SINUMERIK posn/velo in deg and rpm)
    bool describe{false};  // feedid info: several axes or no time column are described, not refused

    void add_to(CLI::App& app);
    [[nodiscard]] ImportOptions import_options() const;
    /// Reads and prepares the trace; prints the import findings (guessed roles, assumed units) to stderr.
    [[nodiscard]] Trace read(bool print_findings = true) const;
    /// The files this reads (the trace, a --join file), which no output may overwrite.
    [[nodiscard]] std::vector<GuardedFile> inputs() const;
};

struct DriveArguments;
/// Reads the trace with the drive's --lead and --gear-ratio also converting rpm channels (one --lead serves both).
[[nodiscard]] Trace read_trace_for_drive(const TraceArguments& trace, const DriveArguments& drive);

/// `[--kt K --lead L [--gear-ratio G]] [--force-constant K|NAME]`
struct DriveArguments {
    std::optional<double> kt;
    std::optional<double> lead_mm;
    double gear_ratio{DriveConstants{}.gear_ratio};
    std::string force_constant;

    void add_to(CLI::App& app);
    [[nodiscard]] DriveConstants constants() const;
};

/// Writes a JSON document to a path (atomically, io/output_file.hpp), or stdout for "-".
void write_json(const nlohmann::json& document, const std::string& path);
/// Reads a JSON document with the input limits of io/json_input.hpp; InputError naming the file on failure.
nlohmann::json read_json(const std::string& path);

Action add_info_command(CLI::App& app);
Action add_identify_command(CLI::App& app);
Action add_gains_command(CLI::App& app);
Action add_simulate_command(CLI::App& app);
Action add_synth_command(CLI::App& app);
Action add_plan_command(CLI::App& app);
Action add_history_command(CLI::App& app);
Action add_report_command(CLI::App& app);
Action add_scan_command(CLI::App& app);
Action add_watch_command(CLI::App& app);
Action add_publish_command(CLI::App& app);
Action add_fingerprint_command(CLI::App& app);

}  // namespace feedid::cli
