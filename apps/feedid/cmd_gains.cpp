// feedid gains FILE: the position and velocity loop gains of the NC's P-PI controller, identified by RLS.
#include <cmath>
#include <cstdio>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/core/terminal_text.hpp"
#include "gain_arguments.hpp"

namespace feedid::cli {

namespace {

// "1.23 %", or "—" for a figure that is not a finite number.
std::string percent(double value) {
    return std::isfinite(value) ? fmt::format("{:.3g} %", value) : std::string("—");
}

std::string format_estimate(const Estimate& estimate, const std::string& unit, double scale = 1.0) {
    if (!estimate.value || !std::isfinite(*estimate.value * scale)) return "—";
    std::string text = fmt::format("{:.6g}", *estimate.value * scale);
    if (estimate.standard_error && std::isfinite(*estimate.standard_error)) {
        text += fmt::format(" ± {:.2g}", *estimate.standard_error * std::abs(scale));
    }
    return text + " " + unit;
}

}  // namespace

namespace {

struct GainsCommand {
    TraceArguments trace_arguments;
    DriveArguments drive_arguments;
    GainArguments gain_arguments;
    std::string json_path;

    int run() const {
        require_separate_outputs({{"--json", json_path}}, trace_arguments.inputs());
        const Trace trace = read_trace_for_drive(trace_arguments, drive_arguments);
        const DriveConstants drive = drive_arguments.constants();
        const std::vector<double> force = drive_force(trace, drive);
        const std::vector<double> injection = injection_force(trace, drive);
        const GainOptions options = gain_arguments.options(trace, drive);
        GainResult result = identify_gains(trace, force, options, injection);
        for (auto& warning : drive.warnings()) result.diagnostics.push_back(std::move(warning));
        if (!json_path.empty()) write_json(gains_document(result, options, trace), json_path);
        if (json_path != "-") print(trace, result, options);
        if (result.status == Status::failed) {
            fmt::print(stderr, "feedid: {}\n", terminal_message(result.diagnostics.front()));
            return 1;
        }
        return 0;
    }

    static void print(const Trace& trace, const GainResult& result, const GainOptions& options) {
        fmt::print(
            "{}: controller gains ({}, {}{})\n", trace.source_path,
            result.samples_used == 0 ? std::string("not fitted") : fmt::format("{} samples", result.samples_used),
            result.method == "velocity_command" ? "position and velocity loop each from the logged velocity command"
                                                : "from reference, position and drive signal",
            result.injection_subtracted ? "; the injected signal taken out of the drive signal" : "");
        const ParameterNaming naming{trace.rotary};
        fmt::print("  position loop  K_v   {:<28}", format_estimate(result.position_gain_per_s, "1/s"));
        if (!trace.rotary) {
            fmt::print(" ({})",
                       format_estimate(result.position_gain_per_s, "(m/min)/mm", m_per_min_per_mm_per_1_per_s));
        }
        fmt::print("\n");
        if (result.position_gain_within_model_stderr && result.position_gain_per_s.standard_error &&
            *result.position_gain_per_s.standard_error > *result.position_gain_within_model_stderr) {
            fmt::print("                       (± with the choice between a P and a P+FF position loop; within the "
                       "{} loop ± {:.2g} 1/s)\n",
                       result.velocity_feedforward.value ? "P+FF" : "P", *result.position_gain_within_model_stderr);
        }
        if (result.velocity_feedforward.value) {
            fmt::print("                 k_ff  {}\n", format_estimate(result.velocity_feedforward, ""));
        }
        if (result.effective_position_gain_per_s.value) {
            fmt::print("                 (a P-only fit gives {}: an effective gain of the loop with its feed-forward, "
                       "not its K_v)\n",
                       format_estimate(result.effective_position_gain_per_s, "1/s"));
        }
        fmt::print("  velocity loop  K_p   {:<28}",
                   format_estimate(result.velocity_gain_N_s_per_m, naming.velocity_gain_unit()));
        if (options.force_per_signal != 0.0) {
            fmt::print(" ({})", format_estimate(result.velocity_gain_N_s_per_m,
                                                naming.signal_velocity_gain_unit(options.signal_unit),
                                                1.0 / options.force_per_signal));
        }
        fmt::print("\n");
        if (result.velocity_integral_gain_N_per_m.value) {
            fmt::print("                 K_i   {}\n",
                       format_estimate(result.velocity_integral_gain_N_per_m, naming.velocity_integral_gain_unit()));
            fmt::print("                 T_n   {}\n", format_estimate(result.reset_time_s, "ms", 1000.0));
        } else if (result.status != Status::failed) {
            fmt::print("                 K_i   — (P-only velocity loop)\n");
        }
        if (result.samples_used == 0) return print_notes(result);  // nothing was fitted
        const std::string cycle = result.fit_kind == "output_error"
                                      ? fmt::format("T_s, the velocity loop at {:.6g} Hz", result.servo_rate_hz)
                                      : std::string("T");
        fmt::print(
            "  structure      velocity measured as (x_k - x_k-{0})/({0}*{3}); reference delay {1} samples; "
            "current-loop lag {2:.3g} ms\n",
            result.velocity_difference_samples, result.reference_delay_samples, result.current_lag_s * 1e3, cycle);
        if (result.setpoint_delay_s.value) {
            fmt::print("  setpoint       reaches the position loop {} after it is logged\n",
                       format_estimate(result.setpoint_delay_s, "ms", 1000.0));
        }
        if (result.injection_gain.value) {
            std::string gain = format_estimate(result.injection_gain, "");
            while (!gain.empty() && gain.back() == ' ') gain.pop_back();  // a gain has no unit
            fmt::print("  injection      enters the drive with gain {} ({})\n", gain,
                       result.injection_gain.standard_error ? "fitted" : "taken as 1: the data cannot tell it");
        }
        fmt::print("  fit            relative error {} (velocity loop; {} not noise)",
                   percent(result.relative_error_pct), percent(result.systematic_error_pct));
        if (result.method == "velocity_command") {
            fmt::print(", {} (position loop)", percent(result.position_loop_relative_error_pct));
        }
        fmt::print("\n");
        print_notes(result);
    }

    static void print_notes(const GainResult& result) {
        if (result.status == Status::failed)
            fmt::print("  status         failed: the gains above are not to be trusted\n");
        for (const auto& diagnostic : result.diagnostics) fmt::print("  note: {}\n", diagnostic);
    }
};

}  // namespace

Action add_gains_command(CLI::App& app) {
    auto command = std::make_shared<GainsCommand>();
    auto* sub = app.add_subcommand(
        "gains", "Identify the P-PI controller gains (position loop K_v, velocity loop K_p and K_i) by RLS");
    command->trace_arguments.add_to(*sub);
    command->drive_arguments.add_to(*sub);
    command->gain_arguments.add_to(*sub);
    sub->add_option("--json", command->json_path, "Write the gains document to PATH ('-' for stdout)");
    sub->footer(
        "Needs the reference position, the position and the drive signal; with a logged velocity command each loop is "
        "identified on its own, otherwise the known structure F = K_p*(K_v*(x_ref - x) - v) [+ K_i*integral] is "
        "fitted. A test signal added to the controller's output (--channel injection=NAME, in the drive signal's "
        "units) is taken out of the drive signal first. A fit that leaves more than " +
        fmt::format("{:g}", gain_fit_error_limit_pct) +
        " % of the drive signal unexplained fails (exit 1): the gains are not to be trusted.\n"
        "Examples:\n"
        "  feedid gains ../shared/data/emps/DATA_EMPS.mat --channel position=qm --channel reference_position=qg \\\n"
        "      --channel current=vir --force-constant gtau --json -\n"
        "  feedid gains synth.csv --force-constant force_constant_N_per_A\n"
        "  feedid gains injected.csv --force-constant force_constant_N_per_A --channel injection=injection");
    return [command] { return command->run(); };
}

}  // namespace feedid::cli
