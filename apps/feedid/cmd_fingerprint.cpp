// feedid fingerprint FILE: the axis's mechanical fingerprint (lost motion, backlash, stiffness, reversal error,
// breakaway force) from a trace with the motor encoder beside the scale.
#include <cmath>
#include <cstdio>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/terminal_text.hpp"
#include "feedid/core/version.hpp"
#include "feedid/identify/fingerprint.hpp"
#include "feedid/report/fingerprint_report.hpp"
#include "record_arguments.hpp"

namespace feedid::cli {

namespace {

// "1.234 ± 0.05 um", "—" for a null figure; `scale` turns SI into the unit shown.
std::string shown(const Estimate& estimate, double scale, const std::string& unit) {
    if (!estimate.value) return "—";
    std::string text = fmt::format("{:.4g}", *estimate.value * scale);
    if (estimate.standard_error) text += fmt::format(" ± {:.2g}", *estimate.standard_error * std::abs(scale));
    return text + " " + unit;
}

struct Units {
    double length_scale;
    std::string length;
    double stiffness_scale;
    std::string stiffness;
    std::string force;
};

Units display_units(bool rotary) {
    constexpr double degree = 3.14159265358979323846 / 180.0;
    if (rotary) return {1e3 / degree, "mdeg", degree / 1e3, "N*m/mdeg", "N*m"};
    return {1e6, "um", 1e-6, "N/um", "N"};
}

void print_figure(const std::string& name, const DirectionalEstimate& estimate, double scale, const std::string& unit) {
    fmt::print("  {:<16} {:<24} forward {:<24} reverse {}\n", name, shown(estimate.both, scale, unit),
               shown(estimate.forward, scale, unit), shown(estimate.reverse, scale, unit));
    if (!estimate.reason.empty()) fmt::print("  {:<16} ({})\n", "", terminal_message(estimate.reason));
}

void print(const Trace& trace, const FingerprintResult& result) {
    const Units u = display_units(result.rotary);
    fmt::print("{}: mechanical fingerprint ({}; reversals: {} into +, {} into -)\n", terminal_text(trace.source_path),
               result.two_measuring_systems ? "scale and motor encoder" : "one measuring system",
               result.reversals_forward, result.reversals_reverse);
    print_figure("lost motion", result.lost_motion, u.length_scale, u.length);
    fmt::print("  {:<16} {}\n", "backlash", shown(result.backlash, u.length_scale, u.length));
    if (!result.backlash_reason.empty()) fmt::print("  {:<16} ({})\n", "", terminal_message(result.backlash_reason));
    print_figure("stiffness", result.stiffness, u.stiffness_scale, u.stiffness);
    if (result.deflection_per_signal) {
        fmt::print("  {:<16} {:.4g} {} per {}\n", "deflection", *result.deflection_per_signal * u.length_scale,
                   u.length, result.signal_unit);
    }
    print_figure("reversal error", result.reversal_error, u.length_scale, u.length);
    print_figure("breakaway", result.breakaway, 1.0, u.force);
    for (const auto& diagnostic : result.diagnostics) fmt::print("  - {}\n", terminal_message(diagnostic));
}

struct FingerprintCommand {
    TraceArguments trace_arguments;
    DriveArguments drive_arguments;
    FingerprintOptions options;
    RecordArguments record;
    std::string json_path;
    std::string report_path;

    // What shapes the figures, stored with a recorded run: the same trace fingerprinted alike is recorded once.
    [[nodiscard]] nlohmann::json options_document() const {
        const DriveConstants& drive = options.drive;
        return {{"settle_s", options.settle_s},
                {"reversal_window_s", options.reversal_window_s},
                {"contact_fraction", options.contact_fraction},
                {"force_constant", drive.force_constant ? nlohmann::json(*drive.force_constant) : nlohmann::json()},
                {"channels", trace_arguments.channel_assignments},
                {"units", trace_arguments.unit_assignments}};
    }

    int run() {
        auto inputs = trace_arguments.inputs();
        if (record.enabled()) inputs.push_back({"the --record history database", record.database, true});
        require_separate_outputs({{"--json", json_path}, {"--report", report_path}}, inputs);
        record.check(trace_arguments.axis);
        const Trace trace = read_trace_for_drive(trace_arguments, drive_arguments);
        options.drive = drive_arguments.constants();
        const FingerprintResult result = fingerprint(trace, options);
        nlohmann::json document = fingerprint_document(result);
        document["feedid_version"] = feedid::version;
        document["trace"] = {{"path", trace.source_path}, {"samples", trace.samples()}};
        document["options"] = options_document();
        if (!json_path.empty()) write_json(document, json_path);
        if (json_path != "-") print(trace, result);
        if (!report_path.empty()) {
            write_output(report_path, report::fingerprint_report_html(document, result.curves, trace.source_path));
            if (report_path != "-") fmt::print(stderr, "feedid: wrote {}\n", terminal_text(report_path));
        }
        if (record.enabled()) record.record(document, trace_arguments.file, trace_arguments.axis, document["options"]);
        return 0;
    }
};

}  // namespace

Action add_fingerprint_command(CLI::App& app) {
    auto command = std::make_shared<FingerprintCommand>();
    auto* sub = app.add_subcommand(
        "fingerprint",
        "The axis's mechanical fingerprint: lost motion, backlash, stiffness, reversal error and breakaway force per "
        "direction, from the scale (position) and the motor encoder (motor_position)");
    command->trace_arguments.add_to(*sub);
    command->drive_arguments.add_to(*sub);
    sub->add_option("--json", command->json_path, "Write the fingerprint document to PATH ('-' for stdout)");
    sub->add_option("--report", command->report_path,
                    "Write an HTML page with the encoder difference against position and the force against "
                    "deflection to PATH");
    command->record.add_to(*sub);
    sub->add_option("--settle", command->options.settle_s,
                    "How long the reference must hold its speed before a sample counts as settled [s] (default 0.05)")
        ->check(allowed_range(0.0, 10.0, "s"));
    sub->footer(
        "Example:\n  feedid fingerprint ../shared/data/sinumerik-trace/X_BK300_1.xml\n"
        "  feedid fingerprint reversal.csv --kt 1.444 --lead 20 --json fingerprint.json\n"
        "  feedid fingerprint reversal.csv --kt 1.444 --lead 20 --report x.html --record shop.db --machine DMU50 "
        "--axis X\n"
        "Without a motor encoder only the reversal error (from the following error) and the breakaway force (from the "
        "drive signal) are given; the others are null with the reason.");
    return [command] { return command->run(); };
}

}  // namespace feedid::cli
