// feedid synth --out FILE: a synthetic NC trace of a known drive in closed loop, with realistic sensors.
#include <algorithm>
#include <charconv>
#include <cstdio>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/plan/gcode_reader.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/sim/production_synth.hpp"
#include "feedid/sim/synth.hpp"
#include "feedid/sim/transmission_synth.hpp"

namespace feedid::cli {

namespace {

// The reference from a file (columns time and reference position, e.g. `feedid plan --reference`), resampled
// linearly onto the synthetic trace's sample grid.
std::vector<double> read_reference(const std::string& path, double sample_time_s) {
    ImportOptions options;
    Trace trace = read_trace(path, options);
    const Channel* reference = trace.find(Role::reference_position);
    if (reference == nullptr) reference = trace.find(Role::position);
    if (reference == nullptr) {
        throw InputError(
            fmt::format("{}: no reference position column (name it x_ref, with its unit, e.g. 'x_ref [mm]')", path));
    }
    const auto time = trace.column(Role::time);
    const double start = time.front();
    const double duration = time.back() - start;
    const auto samples = static_cast<std::size_t>(std::floor(duration / sample_time_s)) + 1;
    if (samples > 100'000'000) throw InputError(fmt::format("{}: the reference is too long to synthesise", path));
    std::vector<double> out(samples);
    std::size_t j = 0;
    for (std::size_t k = 0; k < samples; ++k) {
        const double t = start + static_cast<double>(k) * sample_time_s;
        while (j + 2 < time.size() && time[j + 1] <= t) ++j;
        const double span = time[j + 1] - time[j];
        const double fraction = std::clamp((t - time[j]) / span, 0.0, 1.0);
        out[k] = reference->values[j] + fraction * (reference->values[j + 1] - reference->values[j]);
    }
    return out;
}

// A number followed by an optional unit ("300N", "0.5Hz", "300"), nullopt when it is not one.
std::optional<double> number_with_unit(std::string_view text, std::string_view unit) {
    if (text.ends_with(unit)) text.remove_suffix(unit.size());
    double value = 0.0;
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (error != std::errc() || end != text.data() + text.size() || text.empty()) return std::nullopt;
    return value;
}

// --injection AMPLITUDE@FREQUENCY, e.g. 300N@1Hz: a square wave of 300 N (then 0 N) at 1 Hz.
SquareWaveInjection parse_injection(std::string_view text) {
    const auto at = text.find('@');
    const auto amplitude = number_with_unit(text.substr(0, at), "N");
    const auto frequency = at == std::string_view::npos ? std::nullopt : number_with_unit(text.substr(at + 1), "Hz");
    if (!amplitude || !frequency) {
        throw InputError(fmt::format("--injection {}: expected AMPLITUDE@FREQUENCY, e.g. 300N@1Hz", text));
    }
    return {*amplitude, *frequency};
}

// The demo drive's values (demo_spec), for the help.
std::string demo_drive_text() {
    const SynthSpec demo = demo_spec();
    const FrictionBranch& friction = demo.axis.friction.forward;
    const ControllerModel& c = demo.controller;
    const SensorModel& sensors = demo.sensors;
    return fmt::format(
        "The default drive: the paper's M {:g} kg, B {:g} N*s/m, F_C {:g} N, F_B {:g} N, v_s {:g} mm/s; K_v {:g} "
        "(m/min)/mm, K_p {:g} N*s/m, T_n {:g} ms, current lag {:g} ms; {:g} kHz, {:g} nm encoder, current noise "
        "{:g} A, quantum {:g} mA.",
        demo.axis.mass, friction.viscous, friction.coulomb, friction.breakaway.value_or(0.0),
        friction.stribeck_velocity.value_or(0.0) * 1e3, c.position_gain_per_s / position_gain_from_kv(1.0),
        c.velocity_gain_N_s_per_m, c.velocity_gain_N_s_per_m / c.velocity_integral_gain_N_per_m * 1e3,
        c.current_lag_s * 1e3, 1e-3 / sensors.sample_time_s, sensors.position_resolution_m * 1e9,
        sensors.current_noise_A, sensors.current_resolution_A * 1e3);
}

struct SynthCommand {
    std::string out_path;
    std::string drive_path;
    std::string reference_path;
    std::optional<std::uint64_t> seed;
    std::string injection;
    bool no_slow_passes{false};
    bool print_drive{false};
    bool rotary{false};
    std::string preset;
    std::string program_path;
    std::string machine_path;
    std::optional<double> cutting_force;
    std::optional<double> feedforward;
    std::optional<double> setpoint_delay_ms;
    // the transmission (a second encoder, backlash, finite stiffness): feedid fingerprint's truth
    std::optional<double> backlash_um;
    std::optional<double> stiffness_N_per_um;
    std::optional<double> scale_noise_nm;
    bool one_encoder{false};

    [[nodiscard]] bool with_transmission() const {
        return backlash_um || stiffness_N_per_um || scale_noise_nm || one_encoder;
    }

    // --backlash/--stiffness: the two-mass axis with both encoders, on the reversal test unless --reference.
    int run_transmission(const SynthSpec& spec) const {
        if (!injection.empty() || !preset.empty())
            throw InputError("synth --backlash/--stiffness: --injection and --preset do not apply");
        TransmissionModel transmission;
        const double length = spec.axis.rotary ? 3.14159265358979323846 / 180.0 * 1e-3 : 1e-6;  // um, or mdeg
        if (backlash_um) transmission.backlash_m = *backlash_um * length;
        if (stiffness_N_per_um) transmission.stiffness_N_per_m = *stiffness_N_per_um / length;
        if (scale_noise_nm) transmission.scale_noise_m = *scale_noise_nm * length * 1e-3;
        transmission.log_motor_position = !one_encoder;
        std::optional<std::vector<double>> reference;
        if (!reference_path.empty()) reference = read_reference(reference_path, spec.sensors.sample_time_s);
        const Trace trace = synthesize_with_transmission(spec, transmission, reference);
        write_output(out_path, write_csv(trace));
        const auto base = trace.time_base();
        fmt::print(stderr, "feedid: wrote {} ({} samples, {:.4g} s at {:.4g} ms; seed {})\n", out_path, trace.samples(),
                   base.duration_s, base.sample_time_s * 1e3, spec.seed);
        return 0;
    }

    // --program: the machine runs a part program; one multi-axis trace.
    int run_program() const {
        require_separate_outputs({{"--out", out_path}},
                                 {{"the --program file", program_path}, {"the --machine file", machine_path}});
        for (const auto& [given, option] :
             {std::pair{!drive_path.empty(), "--drive"}, std::pair{!reference_path.empty(), "--reference"},
              std::pair{!injection.empty(), "--injection"}, std::pair{no_slow_passes, "--no-slow-passes"},
              std::pair{print_drive, "--print-drive"}, std::pair{rotary, "--rotary"},
              std::pair{!preset.empty(), "--preset"}, std::pair{feedforward.has_value(), "--feedforward"},
              std::pair{setpoint_delay_ms.has_value(), "--setpoint-delay"}}) {
            if (given)
                throw InputError(
                    fmt::format("synth --program: {} does not apply (give the drives in --machine)", option));
        }
        if (out_path.empty()) throw InputError("synth: --out FILE is required (where to write the trace)");
        const MachineSpec machine = machine_path.empty() ? default_machine() : read_machine(machine_path);
        ProductionOptions options;
        if (seed) options.seed = *seed;
        if (cutting_force) options.cutting_force_fraction = *cutting_force;
        if (auto problem = options.validate(); !problem.empty()) throw InputError("--cutting-force: " + problem);
        const GcodeProgram program = read_gcode_file(program_path);
        for (const auto& note : program.notes) fmt::print(stderr, "feedid: {}\n", note);
        const Trace trace = synthesize_production(program, machine, options);
        write_output(out_path, write_csv(trace));
        const auto base = trace.time_base();
        fmt::print(stderr, "feedid: wrote {} ({} samples, {:.4g} s at {:.4g} ms; axes X, Y, Z; seed {})\n", out_path,
                   trace.samples(), base.duration_s, base.sample_time_s * 1e3, options.seed);
        return 0;
    }

    int run() const {
        if (!program_path.empty()) return run_program();
        if (!machine_path.empty() || cutting_force)
            throw InputError("synth: --machine and --cutting-force go with --program (a part program to run)");
        require_separate_outputs({{"--out", out_path}},
                                 {{"the --drive file", drive_path}, {"the --reference file", reference_path}});
        SynthSpec spec = rotary ? rotary_demo_spec() : demo_spec();
        if (!drive_path.empty()) spec = read_spec(drive_path);
        if (rotary && !spec.axis.rotary) {
            throw InputError(
                fmt::format("synth --rotary: the drive file {} describes a linear axis (give "
                            "axis.{}, or leave out --rotary)",
                            drive_path, ParameterNaming{true}.key(Term::mass)));
        }
        if (preset == "sinumerik") apply_sinumerik_recording(spec);
        if (seed) spec.seed = *seed;
        if (no_slow_passes) spec.test.slow_passes = false;
        if (feedforward) spec.controller.velocity_feedforward = *feedforward;
        if (setpoint_delay_ms) spec.controller.setpoint_delay_s = *setpoint_delay_ms * 1e-3;
        if (feedforward || setpoint_delay_ms) {
            if (const auto problem = spec.validate(); !problem.empty())
                throw InputError("--feedforward/--setpoint-delay: " + problem);
        }
        if (!injection.empty()) {
            spec.injection = parse_injection(injection);
            if (const auto problem = spec.validate(); !problem.empty()) throw InputError("--injection: " + problem);
        }
        if (print_drive) {
            write_json(spec_to_json(spec), "-");
            if (out_path.empty()) return 0;
        }
        if (out_path.empty()) throw InputError("synth: --out FILE is required (where to write the trace)");
        if (with_transmission()) return run_transmission(spec);
        std::optional<std::vector<double>> reference;
        if (!reference_path.empty()) reference = read_reference(reference_path, spec.sensors.sample_time_s);
        Trace trace = synthesize(spec, reference);
        const std::string text = write_csv(in_recording_units(trace, spec.recording));
        write_output(out_path, text);
        const auto base = trace.time_base();
        fmt::print(stderr, "feedid: wrote {} ({} samples, {:.4g} s at {:.4g} ms; seed {})\n", out_path, trace.samples(),
                   base.duration_s, base.sample_time_s * 1e3, spec.seed);
        return 0;
    }
};

}  // namespace

Action add_synth_command(CLI::App& app) {
    auto command = std::make_shared<SynthCommand>();
    auto* sub = app.add_subcommand(
        "synth", "Generate the trace an NC would record for a known drive, controller and test (with sensor models)");
    sub->add_option("--out", command->out_path, "Where to write the trace (CSV with `name [unit]` headers)");
    sub->add_option(
        "--drive", command->drive_path,
        "Drive file, JSON or TOML (*.toml): axis, controller, drive, sensors, test, seed; missing keys keep the "
        "demo values");
    sub->add_option("--seed", command->seed, "Seed of the sensor noise (default: the drive file's, or 1)");
    sub->add_option("--reference", command->reference_path,
                    "A reference position to follow instead of the test: a file with time and x_ref columns (e.g. "
                    "from feedid plan --reference)");
    sub->add_option("--injection", command->injection,
                    "Add a test signal to the controller's output, a square wave AMPLITUDE@FREQUENCY (e.g. 300N@1Hz: "
                    "300 N for the first half of each period, 0 N for the second), logged as the channel 'injection' "
                    "in the drive signal's unit (A; N or N*m with --preset sinumerik's torque); read it back with "
                    "--channel injection=injection");
    sub->add_option("--program", command->program_path,
                    "Run a LinuxCNC part program (G-code) on a 3-axis machine instead of the test: one trace with "
                    "t, X_x_ref, X_x, X_i, Y_..., Z_..., spindle_load [%], spindle_speed [rpm]; cutting forces act on "
                    "cutting moves");
    sub->add_option("--machine", command->machine_path,
                    "With --program: the machine file (JSON or TOML: limits, per-axis drives, cutting; see the "
                    "README); default: the built-in machining centre");
    sub->add_option("--cutting-force", command->cutting_force,
                    fmt::format("With --program: the peak cutting force as a fraction of the drive force "
                                "(default {:g}; 0 = no cutting force)",
                                ProductionOptions{}.cutting_force_fraction));
    sub->add_option("--feedforward", command->feedforward,
                    "The position loop's velocity feed-forward k_ff [-] (drive file: controller.velocity_feedforward)")
        ->check(allowed_range(0.0, 2.0, ""));
    sub->add_option("--setpoint-delay", command->setpoint_delay_ms,
                    "The position setpoint reaches the position loop this late [ms], its feed-forward too (drive "
                    "file: controller.setpoint_delay_ms); e.g. 0.375 = 3 cycles of an 8 kHz servo")
        ->check(allowed_range(0.0, 1000.0, "ms"));
    sub->add_flag("--no-slow-passes", command->no_slow_passes,
                  "Leave out the slow passes: the paper's feedrate ladder (1250..9350 mm/min) alone");
    sub->add_option("--backlash", command->backlash_um,
                    "A transmission with this dead band between motor and load [um; mdeg on a rotary axis], logged "
                    "with the motor encoder (x_motor) beside the scale (x); without --reference the reversal test of "
                    "`feedid plan --test reversal` is run")
        ->check(allowed_range(0.0, 10000.0, "um"));
    sub->add_option("--stiffness", command->stiffness_N_per_um,
                    "The transmission's stiffness [N/um; N*m/mdeg on a rotary axis] (default 200)")
        ->check(allowed_range(1e-3, 1e6, "N/um"));
    sub->add_option("--scale-noise", command->scale_noise_nm,
                    "White noise of the scale with --backlash/--stiffness [nm; udeg] (default 5)")
        ->check(allowed_range(0.0, 1e6, "nm"));
    sub->add_flag("--one-encoder", command->one_encoder,
                  "With --backlash/--stiffness: log the scale only (one measuring system)");
    sub->add_flag("--print-drive", command->print_drive, "Print the drive file in use (every key) as JSON");
    sub->add_flag("--rotary", command->rotary,
                  "A rotary axis: the rotary demo drive (a rotary table, SI rad, kg*m^2, N*m), or check that the "
                  "drive file's axis is rotary");
    sub->add_option("--preset", command->preset,
                    "Record as a control does: 'sinumerik' = a SINUMERIK servo trace (2 ms time base; position, "
                    "reference, velocity command and actual velocity every 4 ms, held; torque (rotary) or current "
                    "every 2 ms; positions in deg or mm, velocities in rpm or mm/min)")
        ->check(CLI::IsMember({"sinumerik"}));
    sub->footer(
        demo_drive_text() +
        "\nThe trace carries the drive constants (force_constant_N_per_A, kt_Nm_per_A, lead_m) and the true values as "
        "`# name = value` lines.\n"
        "Examples:\n"
        "  feedid synth --out synth.csv\n"
        "  feedid synth --injection 300N@1Hz --out injected.csv\n"
        "  feedid synth --print-drive > drive.json      # then edit, and:\n"
        "  feedid synth --drive drive.json --seed 7 --out synth.csv\n"
        "  feedid synth --drive drive.toml --no-slow-passes --out ladder.csv   # drive.toml, for instance:\n"
        "      seed = 3\n"
        "      [axis]\n"
        "      mass_kg = 120.0\n"
        "      viscous_Ns_per_m = 800.0\n"
        "      coulomb_forward_N = 300.0\n"
        "      coulomb_reverse_N = 340.0\n"
        "      offset_N = 0.0\n"
        "      [controller]\n"
        "      kv_m_per_min_per_mm = 2.5\n"
        "      velocity_gain_N_s_per_m = 40000.0\n"
        "      tn_ms = 15.0\n"
        "      servo_rate_hz = 8000.0     # the loops at 8 kHz, logged at the sample rate\n"
        "      [recording]\n"
        "      drive_delay_ms = 0.5       # the current logged 0.5 ms late\n"
        "      [test]\n"
        "      one_way = false            # true: every stroke forward\n"
        "      [process_force]            # bursts of cutting force on the moves\n"
        "      rate_per_s = 0.3\n"
        "      amplitude_fraction = [0.1, 0.5]   # of the Coulomb friction\n"
        "  feedid identify synth.csv --force-constant force_constant_N_per_A\n"
        "  feedid synth --rotary --preset sinumerik --out rotary.csv      # deg, rpm, N*m; 2 ms and 4 ms signals\n"
        "  feedid synth --program examples/programs/pocket.ngc --seed 3 --out pocket.csv\n"
        "  feedid identify pocket.csv --axis X --force-constant X_force_constant_N_per_A\n"
        "  feedid identify rotary.csv");
    return [command] { return command->run(); };
}

}  // namespace feedid::cli
