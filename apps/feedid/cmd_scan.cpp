// feedid scan FILE: mass and friction from a production trace, no test needed: the online identifier
// run over the file, windows that carry information pooled, the others counted by why.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <vector>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/identify/brief_report.hpp"
#include "feedid/stream/scan.hpp"
#include "feedid/core/terminal_text.hpp"
#include "record_arguments.hpp"

namespace feedid::cli {

namespace {

struct ScanCommand {
    TraceArguments trace_arguments;
    DriveArguments drive_arguments;
    OnlineOptions options;
    bool no_robust{false};
    bool no_systematic{false};
    std::string delay{"auto"};
    std::vector<std::string> only_when;
    std::string json_path;
    std::size_t block_rows{0};
    RecordArguments record;

    void add_to(CLI::App& sub) {
        trace_arguments.add_to(sub);
        drive_arguments.add_to(sub);
        sub.add_option("--window", options.window_s, "Window length [s]")
            ->capture_default_str()
            ->check(allowed_range(0.01, 3600, "s"));
        sub.add_flag("--no-robust", no_robust,
                     "Plain least squares in every window (no Tukey weights, no window rejected for its residual; "
                     "on a log too coarse for a mass, in the friction-only fit): to see what the process forces do "
                     "to the estimate");
        sub.add_option("--only-when", only_when,
                       "Use only the samples where another channel meets a condition, e.g. 'spindle_load<5' (also >, "
                       "<=, >=; in the channel's units as read); repeat it for several, which are ANDed")
            ->take_all()
            ->allow_extra_args(false);
        sub.add_option("--forgetting", options.forgetting,
                       "Forgetting factor per window (1 = none): older windows weigh lambda^age, for slow drift")
            ->capture_default_str()
            ->check(allowed_range(1e-6, 1.0, ""));
        sub.add_flag("--no-systematic", no_systematic,
                     "Skip the second identifier (split speed doubled) that gives each parameter its systematic "
                     "uncertainty (on a log too coarse for a mass, identify's preprocessing family): standard errors "
                     "only, about 2x faster");
        sub.add_flag("--offset", options.offset,
                     "Always estimate a constant force offset (gravity, sensor offset); by default it is taken when "
                     "the windows show one (Wald test at 1e-3)")
            ->excludes(sub.add_flag_function(
                "--no-offset", [this](std::int64_t) { options.select_offset = false; },
                "Never estimate a constant force offset (no selection): the model of earlier versions"));
        sub.add_option("--delay", delay,
                       "The drive signal's delay behind the position: auto (estimated from the pooled windows and, "
                       "where significant, applied to every window; its uncertainty in every parameter), none (the "
                       "force as logged), or a known one, e.g. 0.5ms (within +-5 ms)")
            ->capture_default_str()
            ->check([](const std::string& text) { return delay_problem(text); });
        sub.add_option("--cutoff", options.cutoff_hz, "Butterworth cut-off [Hz] (default: min(100 Hz, fs / 10))")
            ->check(allowed_range(1e-3, 1e6, "Hz"));
        OnlineOptions rotary_options;
        rotary_options.rotary = true;
        sub.add_option("--split-velocity", options.split_velocity,
                       fmt::format("Step 1 uses |v| above, the Stribeck bins the quasi-static samples below [m/s; "
                                   "rad/s]; default {:g} m/s, {:g} rad/s on a rotary axis",
                                   OnlineOptions{}.split(), rotary_options.split()))
            ->check(allowed_range(1e-6, 1e4, "m/s or rad/s"));
        sub.add_option("--force-limit", options.force_limit,
                       "The drive's force limit [N]: a window reaching 99 % of it is rejected as saturated")
            ->check(allowed_range(1e-6, 1e9, "N"));
        sub.add_option("--block-rows", block_rows,
                       "Read a CSV file in blocks of this many lines (memory of one block; the same estimate; a log "
                       "too coarse for a mass, judged by its first block, is read whole). Default: blocks of 500000 "
                       "for CSV files above 256 MB, the whole file otherwise")
            ->check(allowed_range(1000, 1e9, "lines"));
        sub.add_option("--json", json_path, "Write the result document to PATH ('-' for stdout)");
        record.add_to(sub);
    }

    int run() const {
        OnlineOptions o = options;
        o.robust = !no_robust;
        o.estimate_delay = delay == "auto";
        if (delay != "auto" && delay != "none") o.drive_delay_s = parse_delay(delay);
        if (const auto problem = o.validate(); !problem.empty() && o.drive_delay_s != 0.0)
            throw InputError(fmt::format("--delay {}: {}", delay, problem));
        if (const auto problem = o.validate(); !problem.empty()) throw InputError(problem);
        std::vector<GateCondition> gates;
        for (const auto& text : only_when) gates.push_back(parse_gate_condition(text));
        std::vector<GuardedFile> inputs = trace_arguments.inputs();
        inputs.push_back({"the --record history database", record.database, true});
        require_separate_outputs({{"--json", json_path}}, inputs);
        record.check(trace_arguments.axis);
        ScanResult result = streamed() ? scan_streamed(o, gates) : scan_whole(o, gates);
        o.rotary = result.result.rotary;  // the split speed's default is the axis kind's
        result.result.options = options_document(o);
        const nlohmann::json document = scan_document(result);
        if (!json_path.empty()) write_json(document, json_path);
        if (json_path != "-") print_table(result);
        if (result.result.status == Status::failed) {
            if (result.friction_only)
                fmt::print(stderr, "feedid: {}\n", terminal_message(result.online.mass_reason));
            else if (result.online.windows.qualified() == 0)
                fmt::print(stderr, "feedid: no window qualified: {}\n", counts_text(result.online.windows));
            else
                fmt::print(stderr, "feedid: {} ({})\n", terminal_message(result.online.mass_reason),
                           counts_text(result.online.windows));
            return 1;
        }
        if (record.enabled()) record.record(document, trace_arguments.file, trace_arguments.axis, document["options"]);
        return 0;
    }

    bool streamed() const {
        if (block_rows > 0) return true;
        std::error_code error;
        const auto size = std::filesystem::file_size(trace_arguments.file, error);
        const bool csv = trace_arguments.format.empty() ? detect_format(trace_arguments.file) == "csv"
                                                        : trace_arguments.format == "csv";
        return !error && csv && size > (std::uintmax_t{256} << 20) && trace_arguments.join.empty() &&
               trace_arguments.tare.empty() && trace_arguments.invert.empty();
    }

    ScanResult scan_whole(const OnlineOptions& o, const std::vector<GateCondition>& gates) const {
        const Trace trace = read_trace_for_drive(trace_arguments, drive_arguments);
        const std::vector<double> force = drive_force(trace, drive_arguments.constants());
        const std::vector<char> use = gate_samples(trace, gates);
        return scan(trace, force, use, o, 65536, !no_systematic);
    }

    ScanResult scan_streamed(const OnlineOptions& o, const std::vector<GateCondition>& gates) const {
        TraceArguments arguments = trace_arguments;
        if (!arguments.lead_mm) arguments.lead_mm = drive_arguments.lead_mm;
        if (!arguments.gear_ratio) arguments.gear_ratio = drive_arguments.gear_ratio;
        std::vector<std::string> findings;
        ScanResult result = scan_csv_stream(arguments.file, arguments.import_options(), drive_arguments.constants(),
                                            gates, o, block_rows > 0 ? block_rows : 500000, findings, !no_systematic);
        for (const auto& finding : findings) fmt::print(stderr, "feedid: {}\n", terminal_message(finding));
        return result;
    }

    nlohmann::json options_document(const OnlineOptions& o) const {
        return {{"kind", "scan"},
                {"window_s", o.window_s},
                {"robust", o.robust},
                {"forgetting", o.forgetting},
                {"offset", o.offset},
                {"select_offset", o.select_offset},
                {"cutoff_hz", o.cutoff_hz ? nlohmann::json(*o.cutoff_hz) : nlohmann::json()},
                {"split_velocity", o.split()},
                {"delay", delay == "auto" || delay == "none" ? nlohmann::json(delay) : nlohmann::json(o.drive_delay_s)},
                {"systematic", !no_systematic},
                {"only_when", only_when},
                {"channels", trace_arguments.channel_assignments},
                {"units", trace_arguments.unit_assignments},
                {"axis", trace_arguments.axis},
                {"drive",
                 {{"kt_Nm_per_A", drive_arguments.kt ? nlohmann::json(*drive_arguments.kt) : nlohmann::json()},
                  {"lead_mm", drive_arguments.lead_mm ? nlohmann::json(*drive_arguments.lead_mm) : nlohmann::json()},
                  {"gear_ratio", drive_arguments.gear_ratio},
                  {"force_constant", drive_arguments.force_constant}}}};
    }

    static std::string counts_text(const WindowCounts& counts) {
        std::string text = fmt::format("{} windows, {} qualified", counts.total, counts.qualified());
        for (std::size_t v = 1; v < window_verdicts; ++v)
            if (counts.by_verdict[v] > 0)
                text += fmt::format(", {} {}", counts.by_verdict[v], verdict_name(static_cast<WindowVerdict>(v)));
        return text;
    }

    static void print_table(const ScanResult& s) {
        const IdentifyResult& r = s.result;
        fmt::print("{} ({} samples, {:.6g} s): production scan\n", terminal_text(r.trace.path), r.trace.samples,
                   r.trace.duration_s);
        if (s.friction_only)
            fmt::print("no windows: the log is too coarse for a mass; friction only, from its steady-speed samples\n\n");
        else
            fmt::print("windows: {}\n{}\n", counts_text(s.online.windows), timing_line(r));
        // the standard error (statistical) and the combined uncertainty (with the split speed's systematic part)
        fmt::print("{}", parameter_table_text(r));
        fmt::print("\n");
        for (const auto& line : scan_verdicts(s)) fmt::print("  {}\n", terminal_message(line));
        // the findings the verdicts above have not said already (they say the reasons of the null parameters)
        const auto null_reason = [&r](const std::string& reason, std::initializer_list<Term> terms) {
            return std::any_of(terms.begin(), terms.end(),
                               [&](Term term) {
                                   const Parameter* p = r.find(term);
                                   return p != nullptr && !p->estimate.value;
                               })
                       ? reason
                       : std::string();
        };
        const std::string mass = null_reason(s.online.mass_reason, {Term::mass, Term::viscous, Term::coulomb});
        const std::string stribeck = null_reason(s.online.stribeck_reason, {Term::breakaway, Term::stribeck_velocity});
        const auto said = [&](const std::string& line) { return line == mass || line == stribeck; };
        bool heading = false;
        for (const auto& line : r.diagnostics) {
            if (said(line)) continue;
            if (!heading) fmt::print("  diagnostics:\n");
            heading = true;
            fmt::print("    - {}\n", terminal_message(line));
        }
    }
};

}  // namespace

Action add_scan_command(CLI::App& app) {
    auto command = std::make_shared<ScanCommand>();
    auto* sub = app.add_subcommand("scan",
                                   "Identify an axis from the trace of ordinary production (no test): windows with "
                                   "information pooled, cutting forces weighed out");
    command->add_to(*sub);
    sub->footer(
        "Examples:\n"
        "  feedid scan shift.csv --axis X --kt 1.45 --lead 10 --only-when 'spindle_load<5'\n"
        "  feedid scan shift.csv --axis X --kt 1.45 --lead 10 --record shop.db --machine DMU50\n"
        "Exit codes: 0 identified (F_B and v_s may be null: see the verdicts), 1 no window qualified (the rejection "
        "counts say why), 2 bad usage or bad input.");
    return [command] { return command->run(); };
}

}  // namespace feedid::cli
