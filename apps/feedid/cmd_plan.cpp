// feedid plan: design the axis test, write it as a part program and as a reference trajectory, and predict what the
// data will identify.
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/plan/reversal_test.hpp"
#include "feedid/core/error.hpp"
#include "feedid/plan/gcode_writer.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/plan/test_plan.hpp"

namespace feedid::cli {

namespace {

// A comma-separated list option, one value per occurrence (write --centers=-300,0,300): CLI11 splits it.
CLI::Option* add_list_option(CLI::App& app, const std::string& name, std::vector<std::string>& entries,
                             const std::string& description) {
    return app.add_option(name, entries, description)
        ->delimiter(',')
        ->expected(1)
        ->allow_extra_args(false)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

void print_summary(std::FILE* out, const TestPlan& plan, const IdentifiabilityPrediction& prediction,
                   const PredictionOptions& nominal) {
    const auto& o = plan.options;
    const ParameterNaming naming{o.units().rotary};
    std::size_t slow = 0;
    for (const auto& pass : plan.passes) slow += pass.slow ? 1 : 0;
    fmt::print(out,
               "feedid plan: axis {}, {} centre(s), {} passes ({} slow), {} blocks, predicted duration {:.1f} s "
               "({:.1f} min)\n",
               o.axis, o.centers.size(), plan.passes.size(), slow, plan.moves.size(), plan.duration,
               plan.duration / 60.0);
    const auto& branch = nominal.drive.friction.forward;
    const std::string force = naming.unit(Term::coulomb);
    fmt::print(out,
               "identifiability from a nominal drive (M {} {}, B {} {}, F_C {} {}, F_B {} {}, v_s {} {}; {} noise {} "
               "{}):\n",
               nominal.drive.mass, naming.unit(Term::mass), branch.viscous, naming.unit(Term::viscous), branch.coulomb,
               force, branch.breakaway.value_or(0.0), force,
               branch.stribeck_velocity.value_or(0.0) * naming.display_velocity_scale(), naming.display_velocity_unit(),
               naming.rotary ? "torque" : "force", nominal.force_noise, force);
    fmt::print(out, "  step 1: condition number {:.3g} over {} samples; step 2: {} constant-velocity friction levels\n",
               prediction.step1_condition_number, prediction.step1_samples, prediction.step2_levels);
    for (const auto& p : prediction.parameters) {
        if (std::isfinite(p.standard_error)) {
            fmt::print(out, "  {:<4} {:>10.4g} {:<11} +- {:<10.3g} ({:6.3g} %)  {}\n", p.symbol, p.nominal, p.unit,
                       p.standard_error, 100.0 * p.standard_error / std::abs(p.nominal),
                       p.identifiable ? "identifiable" : "NOT identifiable");
        } else {
            fmt::print(out, "  {:<4} {:>10.4g} {:<11} +- {:<10}            {}\n", p.symbol, p.nominal, p.unit, "inf",
                       "NOT identifiable");
        }
    }
    for (const auto& note : plan.notes) fmt::print(out, "note: {}\n", note);
    for (const auto& diagnostic : prediction.diagnostics) fmt::print(out, "diagnostic: {}\n", diagnostic);
}

}  // namespace

// The help's statement of a default: a number as %g ("30", "0.001", "5000").
std::string shown(double value) {
    return fmt::format("{:g}", value);
}

// The defaults of TestPlanOptions and PredictionOptions as the command line writes them: lengths and feeds in mm
// and mm/min (the rotary defaults are the same numbers in degrees), the encoder in um, and where an option's
// default depends on the axis kind, the linear and the rotary one ("69.1 kg, 2 kg*m^2").
struct PlanDefaults {
    PlanUnits linear{false};
    PlanUnits rotary{true};
    TestPlanOptions plan{default_plan_options("X")};
    TestPlanOptions rotary_plan{default_plan_options("A")};
    PredictionOptions prediction{default_prediction_options(false)};
    PredictionOptions rotary_prediction{default_prediction_options(true)};

    [[nodiscard]] std::string slow_feeds() const {
        if (plan.slow_feeds.empty()) return "none";
        return fmt::format("{}:{}:{}", shown(plan.slow_feeds.front() / linear.feed()),
                           shown(plan.slow_feeds.back() / linear.feed()), plan.slow_feeds.size());
    }
    [[nodiscard]] std::string ladder() const {
        std::string text;
        for (const double feed : plan.feeds) text += (text.empty() ? "" : ",") + shown(feed / linear.feed());
        return text;
    }
    // "default 69.1 kg, 2 kg*m^2": one value of the linear and the rotary nominal drive
    template <class Get>
    [[nodiscard]] std::string both(Get&& get, double linear_scale, double rotary_scale, const char* linear_unit,
                                   const char* rotary_unit) const {
        return fmt::format("default {} {}, {} {}", shown(get(prediction) * linear_scale), linear_unit,
                           shown(get(rotary_prediction) * rotary_scale), rotary_unit);
    }
};

/// The options of `feedid plan`, as given; the library turns them into a plan and a prediction. Lengths and feeds are
/// in mm and mm/min, or in degrees and deg/min on a rotary axis (A, B, C); the nominal drive in the SI units of the
/// axis's parameters (kg or kg*m^2, N or N*m), its Stribeck velocity in mm/s or rad/s as identify prints it. An
/// option not given keeps the library's default (default_plan_options, default_prediction_options).
struct PlanArguments {
    std::string axis{TestPlanOptions{}.axis};
    std::string travel;
    std::vector<std::string> centers;
    std::optional<double> stroke;
    std::vector<std::string> feeds;
    std::vector<std::string> slow_feeds;
    std::optional<double> max_pass_time_s;
    std::optional<int> cycles;
    std::optional<double> acceleration;
    std::optional<double> jerk;
    std::optional<double> dwell_s;
    std::optional<double> sample_time_s;
    std::optional<double> max_feed;
    std::optional<double> positioning_feed;
    std::optional<double> start;
    std::string dialect{"iso"};
    std::string test{"friction"};
    std::optional<double> micro_step_um;
    std::optional<int> micro_steps;
    std::string output;
    std::string reference;
    std::string json;
    // nominal drive: the demo drive of the axis's kind where not given
    std::optional<double> mass;
    std::optional<double> viscous;
    std::optional<double> coulomb;
    std::optional<double> breakaway;
    std::optional<double> stribeck_velocity;
    std::optional<double> force_noise;
    std::optional<double> level_error;
    std::optional<double> resolution;

    void add_to(CLI::App& sub) {
        add_plan_options(sub);
        add_prediction_options(sub);
    }

    void add_plan_options(CLI::App& sub) {
        const PlanDefaults d;
        sub.add_option("--axis", axis,
                       "Axis name as the NC knows it (X, Y, Z, A, ...; X1 on SINUMERIK); A, B and C are rotary: their "
                       "lengths in deg, feeds in deg/min")
            ->capture_default_str();
        sub.add_option("--travel", travel, "Travel limits MIN:MAX [mm; deg] (write --travel=-400:400)")->required();
        add_list_option(sub, "--centers", centers,
                        "Centres of the strokes C1,C2,... [mm; deg] (write --centers=-300,0,300)")
            ->required()
            ->check(allowed_range(-1e6, 1e6, "mm or deg"));
        sub.add_option("--stroke", stroke, "Stroke of the ladder passes [mm; deg]")
            ->default_str(shown(d.plan.stroke / d.linear.length()))
            ->check(allowed_range(0.01, 1e5, "mm or deg"));
        add_list_option(sub, "--feeds", feeds,
                        "Ladder feedrates F1,F2,... [mm/min; deg/min]; default the paper's " + d.ladder())
            ->check(allowed_range(1e-3, 1e6, "mm/min or deg/min"));
        add_list_option(sub, "--slow-feeds", slow_feeds,
                        "Slow Stribeck passes: LO:HI[:N] log-spaced, F1,F2,... [mm/min; deg/min], or none")
            ->default_str(d.slow_feeds());
        sub.add_option("--max-pass-time", max_pass_time_s, "Longest slow pass; its stroke is shortened to fit [s]")
            ->default_str(shown(d.plan.max_pass_time))
            ->check(allowed_range(0.01, 3600.0, "s"));
        sub.add_option("--cycles", cycles, "Back-and-forth cycles per feedrate")
            ->default_str(std::to_string(d.plan.cycles))
            ->check(allowed_range(1, 100, "cycles"));
        sub.add_option("--acceleration", acceleration,
                       fmt::format("Axis acceleration (machine data) [m/s^2; deg/s^2]; default {} m/s^2, {} deg/s^2",
                                   shown(d.plan.acceleration / d.linear.acceleration()),
                                   shown(d.rotary_plan.acceleration / d.rotary.acceleration())))
            ->check(allowed_range(1e-3, 1e6, "m/s^2 or deg/s^2"));
        sub.add_option("--jerk", jerk, "Jerk limit [m/s^3; deg/s^3] (SINUMERIK SOFT); default none (BRISK)")
            ->check(allowed_range(1e-3, 1e9, "m/s^3 or deg/s^3"));
        sub.add_option("--dwell", dwell_s, "Dwell at every reversal [s]")
            ->default_str(shown(d.plan.dwell))
            ->check(allowed_range(0.0, 60.0, "s"));
        sub.add_option("--sample-time", sample_time_s, "Trace sample time [s] (the reference file's step)")
            ->default_str(shown(d.plan.sample_time))
            ->check(allowed_range(1e-6, 1.0, "s"));
        sub.add_option("--max-feed", max_feed, "Feedrate limit of the axis [mm/min; deg/min]; refuse moves above it")
            ->check(allowed_range(1e-3, 1e6, "mm/min or deg/min"));
        sub.add_option("--positioning-feed", positioning_feed, "Feedrate between passes [mm/min; deg/min]")
            ->default_str(shown(d.plan.positioning_feed / d.linear.feed()))
            ->check(allowed_range(1e-3, 1e6, "mm/min or deg/min"));
        sub.add_option("--start", start, "Where the axis stands at the program start [mm; deg]; default the first pass")
            ->check(allowed_range(-1e6, 1e6, "mm or deg"));
        sub.add_option("--test", test,
                       "Which test: friction (the strokes and feedrate ladder for identify) or reversal (micro-steps "
                       "through reversals and slow strokes for fingerprint)")
            ->check(CLI::IsMember({"friction", "reversal"}))
            ->capture_default_str();
        sub.add_option("--micro-step", micro_step_um, "--test reversal: one micro-step [um; mdeg] (default 1)")
            ->check(allowed_range(1e-3, 1000.0, "um or mdeg"));
        sub.add_option("--micro-steps", micro_steps, "--test reversal: micro-steps each way (default 10)")
            ->check(allowed_range(1, 1000, "steps"));
        sub.add_option("--dialect", dialect, "Part-program dialect")
            ->check(CLI::IsMember({"iso", "sinumerik", "linuxcnc"}))
            ->capture_default_str();
        sub.add_option("-o,--out", output, "Write the part program here ('-' for stdout)");
        sub.add_option("--reference", reference,
                       "Write the reference trajectory (CSV: t [s], x_ref [m; rad on a rotary axis]) here");
        sub.add_option("--json", json, "Write the plan and its prediction as JSON ('-' for stdout)");
    }

    void add_prediction_options(CLI::App& sub) {
        const PlanDefaults d;
        const auto mass = [](const PredictionOptions& o) { return o.drive.mass; };
        const auto viscous = [](const PredictionOptions& o) { return o.drive.friction.forward.viscous; };
        const auto coulomb = [](const PredictionOptions& o) { return o.drive.friction.forward.coulomb; };
        const auto breakaway = [](const PredictionOptions& o) {
            return o.drive.friction.forward.breakaway.value_or(0.0);
        };
        const auto stribeck = [](const PredictionOptions& o) {
            return o.drive.friction.forward.stribeck_velocity.value_or(0.0);
        };
        const auto noise = [](const PredictionOptions& o) { return o.force_noise; };
        const auto level = [](const PredictionOptions& o) { return o.level_error; };
        const double mm_per_s = ParameterNaming{false}.display_velocity_scale();
        const double rad_per_s = ParameterNaming{true}.display_velocity_scale();
        sub.add_option("--mass", this->mass,
                       "Nominal mass [kg; inertia kg*m^2]; " + d.both(mass, 1.0, 1.0, "kg", "kg*m^2") +
                           " (the demo drives)")
            ->check(allowed_range(1e-6, 1e6, "kg or kg*m^2"));
        sub.add_option("--viscous", this->viscous,
                       "Nominal viscous friction [N*s/m; N*m*s/rad]; " +
                           d.both(viscous, 1.0, 1.0, "N*s/m", "N*m*s/rad"))
            ->check(allowed_range(0.0, 1e7, "N*s/m or N*m*s/rad"));
        sub.add_option("--coulomb", this->coulomb,
                       "Nominal Coulomb friction [N; N*m]; " + d.both(coulomb, 1.0, 1.0, "N", "N*m"))
            ->check(allowed_range(0.0, 1e7, "N or N*m"));
        sub.add_option("--breakaway", this->breakaway,
                       "Nominal breakaway friction [N; N*m]; " + d.both(breakaway, 1.0, 1.0, "N", "N*m"))
            ->check(allowed_range(0.0, 1e7, "N or N*m"));
        sub.add_option("--stribeck-velocity", stribeck_velocity,
                       "Nominal Stribeck velocity [mm/s; rad/s]; " +
                           d.both(stribeck, mm_per_s, rad_per_s, "mm/s", "rad/s"))
            ->check(allowed_range(1e-6, 1e4, "mm/s or rad/s"));
        sub.add_option("--force-noise", force_noise,
                       "Expected force noise per sample [N; N*m]; " + d.both(noise, 1.0, 1.0, "N", "N*m"))
            ->check(allowed_range(1e-9, 1e9, "N or N*m"));
        sub.add_option("--level-error", level_error,
                       "Expected error of one pass's friction level [N; N*m]; " + d.both(level, 1.0, 1.0, "N", "N*m"))
            ->check(allowed_range(1e-9, 1e9, "N or N*m"));
        sub.add_option("--position-resolution", resolution, "Position measurement resolution [um; millidegree]")
            ->default_str(shown(d.prediction.position_resolution * 1e6))
            ->check(allowed_range(1e-6, 1e4, "um or mdeg"));
    }

    [[nodiscard]] PlanUnits units() const { return {is_rotary_axis(axis)}; }

    [[nodiscard]] TestPlanOptions plan_options() const {
        const PlanUnits u = units();
        TestPlanOptions options = default_plan_options(axis);
        std::tie(options.travel_min, options.travel_max) = parse_travel(travel, u);
        options.centers = parse_number_list(centers, "--centers", u.length());
        if (stroke) options.stroke = *stroke * u.length();
        if (!feeds.empty()) options.feeds = parse_feeds(feeds, u);
        if (!slow_feeds.empty()) options.slow_feeds = parse_slow_feeds(slow_feeds, u);
        if (max_pass_time_s) options.max_pass_time = *max_pass_time_s;
        if (cycles) options.cycles = *cycles;
        if (acceleration) options.acceleration = *acceleration * u.acceleration();
        if (jerk) options.jerk = *jerk * u.acceleration();
        if (dwell_s) options.dwell = *dwell_s;
        if (sample_time_s) options.sample_time = *sample_time_s;
        if (max_feed) options.max_feed = *max_feed * u.feed();
        if (positioning_feed) options.positioning_feed = *positioning_feed * u.feed();
        if (start) options.start_position = *start * u.length();
        return options;
    }

    [[nodiscard]] PredictionOptions prediction_options() const {
        const bool rotary = units().rotary;
        const ParameterNaming naming{rotary};
        PredictionOptions nominal = default_prediction_options(rotary);
        FrictionBranch branch = nominal.drive.friction.forward;
        if (viscous) branch.viscous = *viscous;
        if (coulomb) branch.coulomb = *coulomb;
        if (breakaway) branch.breakaway = *breakaway;
        if (stribeck_velocity) branch.stribeck_velocity = *stribeck_velocity / naming.display_velocity_scale();
        if (mass) nominal.drive.mass = *mass;
        nominal.drive.friction = Friction::symmetric(branch);
        if (force_noise) nominal.force_noise = *force_noise;
        if (level_error) nominal.level_error = *level_error;
        // um -> m; millidegree -> rad
        if (resolution)
            nominal.position_resolution = rotary ? *resolution * 1e-3 * std::numbers::pi / 180.0 : *resolution * 1e-6;
        return nominal;
    }

    [[nodiscard]] ReversalTestOptions reversal_options() const {
        const PlanUnits u = units();
        ReversalTestOptions options = default_reversal_options(axis);
        std::tie(options.travel_min, options.travel_max) = parse_travel(travel, u);
        options.centers = parse_number_list(centers, "--centers", u.length());
        if (stroke) options.stroke = *stroke * u.length();
        if (!feeds.empty()) options.feeds = parse_feeds(feeds, u);
        if (cycles) options.cycles = *cycles;
        if (acceleration) options.acceleration = *acceleration * u.acceleration();
        if (dwell_s) options.dwell = *dwell_s;
        if (sample_time_s) options.sample_time = *sample_time_s;
        if (positioning_feed) options.positioning_feed = *positioning_feed * u.feed();
        if (micro_step_um) options.micro_step = *micro_step_um * 1e-3 * u.length();
        if (micro_steps) options.micro_steps = *micro_steps;
        return options;
    }

    // --test reversal: the fingerprint's measurement program; no identifiability prediction.
    [[nodiscard]] int run_reversal() const {
        for (const auto& [given, option] :
             {std::pair{!slow_feeds.empty(), "--slow-feeds"}, std::pair{max_pass_time_s.has_value(), "--max-pass-time"},
              std::pair{jerk.has_value(), "--jerk"}, std::pair{max_feed.has_value(), "--max-feed"},
              std::pair{start.has_value(), "--start"}}) {
            if (given) throw InputError(fmt::format("plan --test reversal: {} does not apply", option));
        }
        const TestPlan plan = make_reversal_plan(reversal_options());
        const auto part_program_dialect = parse_dialect(dialect).value_or(Dialect::iso);
        if (!output.empty()) write_output(output, emit_part_program(plan, part_program_dialect));
        if (!reference.empty()) write_output(reference, write_csv(reference_trajectory(plan)));
        if (!json.empty()) {
            write_json({{"test", "reversal"}, {"axis", plan.options.axis}, {"duration_s", plan.duration},
                        {"blocks", plan.moves.size()}, {"description", plan.description}},
                       json);
        }
        const bool stdout_taken = output == "-" || reference == "-" || json == "-";
        std::FILE* stream = stdout_taken ? stderr : stdout;
        for (const auto& line : plan.description) fmt::print(stream, "{}\n", line);
        fmt::print(stream, "duration {:.1f} s, {} blocks\n", plan.duration, plan.moves.size());
        return 0;
    }

    [[nodiscard]] int run() const {
        require_separate_outputs({{"-o", output}, {"--reference", reference}, {"--json", json}}, {});
        if (test == "reversal") return run_reversal();
        if (micro_step_um || micro_steps)
            throw InputError("plan: --micro-step and --micro-steps go with --test reversal");
        const TestPlan plan = make_test_plan(plan_options());
        const PredictionOptions nominal = prediction_options();
        const auto prediction = predict_identifiability(plan, nominal);
        const auto part_program_dialect = parse_dialect(dialect).value_or(Dialect::iso);
        if (!output.empty()) write_output(output, emit_part_program(plan, part_program_dialect));
        if (!reference.empty()) write_output(reference, write_csv(reference_trajectory(plan)));
        if (!json.empty()) write_json(plan_document(plan, prediction), json);
        const bool stdout_taken = output == "-" || reference == "-" || json == "-";
        print_summary(stdout_taken ? stderr : stdout, plan, prediction, nominal);
        return 0;
    }
};

Action add_plan_command(CLI::App& app) {
    auto* sub = app.add_subcommand("plan", "Design the axis test and write it as a part program and a reference");
    sub->footer(
        "The test (after the paper's test procedure): at each centre, back-and-forth strokes at every feedrate, the\n"
        "slow Stribeck passes first (strokes shortened to --max-pass-time), then the ladder. Every move ends at rest\n"
        "(exact stop) with a dwell. A plan that leaves the travel or exceeds --max-feed is refused (exit 2) with the\n"
        "move named. The summary predicts which parameters the data will identify, from a nominal drive.\n"
        "\n"
        "Example (a LinuxCNC program for three places along X, and the reference for `feedid synth`):\n"
        "  feedid plan --axis X --travel=-400:400 --centers=-300,0,300 --dialect linuxcnc -o test.ngc \\\n"
        "      --reference ref.csv\n"
        "  feedid synth --reference ref.csv --out synth.csv        # a dry run of the test\n"
        "  feedid identify synth.csv --force-constant force_constant_N_per_A --by-location\n"
        "The paper's ladder alone (no slow passes; F_B and v_s come out not identifiable):\n"
        "  feedid plan --travel=-400:400 --centers=-300 --slow-feeds none --dialect sinumerik -o TEST.MPF\n"
        "A rotary table (degrees, deg/min; the rotary demo drive as the nominal):\n"
        "  feedid plan --axis C --travel=-360:360 --centers=0,120,240 --dialect linuxcnc -o c.ngc --reference c.csv\n"
        "  feedid synth --rotary --reference c.csv --out c-synth.csv && feedid identify c-synth.csv --kt 2\n"
        "The reversal test for the mechanical fingerprint (record the scale and the motor encoder):\n"
        "  feedid plan --test reversal --travel=-400:400 --centers=-300,0,300 --dialect sinumerik -o REV.MPF \\\n"
        "      --reference rev.csv\n"
        "  feedid synth --reference rev.csv --backlash 8 --stiffness 150 --out rev-synth.csv\n"
        "  feedid fingerprint rev-synth.csv --force-constant force_constant_N_per_A");

    auto arguments = std::make_shared<PlanArguments>();
    arguments->add_to(*sub);
    return [arguments] { return arguments->run(); };
}

}  // namespace feedid::cli
