// feedid simulate FILE --result RESULT.json: the identified axis in closed loop on the recorded reference (the
// paper's validation): tracking errors of model and machine side by side, the modelling error, and the EMPS relative
// errors of position, velocity, acceleration and force.
#include <cmath>
#include <cstdio>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/sim/simulate.hpp"
#include "feedid/sim/twin.hpp"
#include "feedid/core/terminal_text.hpp"
#include "gain_arguments.hpp"

namespace feedid::cli {

namespace {

// A figure to 4 significant digits, or "—" when it is not a finite number (a diverged simulation's).
std::string figure(double value, const char* unit = "") {
    return std::isfinite(value) ? fmt::format("{:.4g}{}", value, unit) : std::string("—");
}

struct SimulateCommand {
    TraceArguments trace_arguments;
    DriveArguments drive_arguments;
    GainArguments gain_arguments;
    std::string result_path;
    std::string gains_path;
    std::string json_path;
    std::string out_path;
    int substeps{SimulationOptions{}.substeps};

    int run() const {
        std::vector<GuardedFile> inputs = trace_arguments.inputs();
        inputs.push_back({"the --result document", result_path});
        inputs.push_back({"the --gains document", gains_path});
        require_separate_outputs({{"--out", out_path}, {"--json", json_path}}, inputs);
        // The documents first: a wrong path fails before the trace is read.
        const nlohmann::json result_document = read_json(result_path);
        const std::optional<nlohmann::json> gains_document =
            gains_path.empty() ? std::nullopt : std::optional<nlohmann::json>(read_json(gains_path));
        const Trace trace = read_trace_for_drive(trace_arguments, drive_arguments);
        TwinOptions options;
        options.drive = drive_arguments.constants();
        options.gains = gain_arguments.given();
        options.saturation = gain_arguments.saturation;
        options.simulation.substeps = substeps;
        const Twin twin = run_twin(
            trace, {result_document, result_path},
            gains_document ? std::optional<TwinDocument>({*gains_document, gains_path}) : std::nullopt, options);

        if (!out_path.empty())
            write_output(out_path, write_csv(simulation_trace(twin.simulation.output, trace.rotary)));
        if (!json_path.empty()) write_json(twin_document(trace, twin), json_path);
        if (json_path != "-") print(trace, twin);
        if (twin.status == Status::failed) {
            fmt::print(stderr, "feedid: {}\n", terminal_message(twin.failure));
            return 1;
        }
        return 0;
    }

    static void print(const Trace& trace, const Twin& twin) {
        const TwinController& controller = twin.controller;
        const TraceSimulation& simulation = twin.simulation;
        const ValidationMetrics& metrics = simulation.metrics;
        const std::string unit = ParameterNaming{trace.rotary}.display_small_length_unit();
        fmt::print("{}: closed-loop simulation of the identified axis on the recorded reference ({} samples)\n",
                   trace.source_path, trace.samples());
        for (const auto& note : controller.notes) fmt::print("  {}\n", note);
        fmt::print("  {:<32} {:>12} {:>12}\n", "", "model", "machine");
        fmt::print("  {:<32} {:>12} {:>12}   {}\n", "mean absolute tracking error",
                   figure(metrics.tracking_error_mae_model_m * 1e3), figure(metrics.tracking_error_mae_machine_m * 1e3),
                   unit);
        fmt::print("  {:<32} {:>12} {:>12}   {}\n", "largest tracking error",
                   figure(metrics.tracking_error_max_model_m * 1e3), figure(metrics.tracking_error_max_machine_m * 1e3),
                   unit);
        fmt::print("  {:<32} {:>12}   {}   (e_m = x_machine - x_model; largest {} {})\n",
                   "mean absolute modelling error", figure(metrics.modelling_error_mae_m * 1e3), unit,
                   figure(metrics.modelling_error_max_m * 1e3), unit);
        fmt::print("  relative error 100*||y - y_sim||/||y||: position {}, velocity {}, acceleration {}, force {}\n",
                   figure(metrics.position_relative_error_pct, " %"), figure(metrics.velocity_relative_error_pct, " %"),
                   figure(metrics.acceleration_relative_error_pct, " %"),
                   figure(metrics.force_relative_error_pct, " %"));
        if (simulation.injected) fmt::print("  the injected signal added to the simulated controller output\n");
        if (twin.status == Status::failed) {
            fmt::print(
                "  status         failed: the simulation validates nothing (— marks a figure that is not a "
                "finite number)\n");
        }
        for (const auto& diagnostic : simulation.diagnostics) fmt::print("  note: {}\n", diagnostic);
    }
};

}  // namespace

Action add_simulate_command(CLI::App& app) {
    auto command = std::make_shared<SimulateCommand>();
    auto* sub = app.add_subcommand(
        "simulate",
        "Simulate the identified axis in closed loop on the trace's reference and compare with the machine");
    command->trace_arguments.add_to(*sub);
    command->drive_arguments.add_to(*sub);
    command->gain_arguments.add_to(*sub);
    sub->add_option("--result", command->result_path, "The identification result (feedid identify --json)")->required();
    sub->add_option("--gains", command->gains_path,
                    "The controller gains (feedid gains --json); default: identified from this trace");
    sub->add_option("--json", command->json_path, "Write the validation document to PATH ('-' for stdout)");
    sub->add_option("--out", command->out_path, "Write the simulated signals as CSV");
    sub->add_option("--substeps", command->substeps, "Integration steps per sample")
        ->capture_default_str()
        ->check(allowed_range(1, 1000, "steps"));
    sub->footer(
        "Examples:\n"
        "  feedid identify DATA_EMPS.mat --channel position=qm --channel current=vir --force-constant gtau --offset "
        "\\\n"
        "      --json result.json\n"
        "  feedid simulate DATA_EMPS.mat --channel position=qm --channel reference_position=qg --channel current=vir "
        "\\\n"
        "      --force-constant gtau --saturation 10 --result result.json\n"
        "  feedid simulate synth.csv --force-constant force_constant_N_per_A --result result.json --gains gains.json "
        "--out sim.csv\n"
        "A test signal injected at the controller's output (--channel injection=NAME) is added to the simulated "
        "controller's output too. A simulation that diverges (values not finite, or farther from the machine than "
        "the trace's whole travel) or does not follow the machine (farther from it on average than the machine's own "
        "tracking error), or gains identified here from a fit too poor to trust, exit 1. A result whose axis kind (or "
        "a gains document's) "
        "is not the trace's, or whose forces do not fit the trace's drive force (units, sign, another axis), exits "
        "2.");
    return [command] { return command->run(); };
}

}  // namespace feedid::cli
