// feedid plan: design the axis test, write it as a part program and as a reference trajectory, and predict what the
// data will identify.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/error.hpp"
#include "feedid/gcode.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/testplan.hpp"

namespace feedid::cli {

namespace {

constexpr double mm = 1e-3;
constexpr double mm_per_min = 1e-3 / 60.0;

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
    std::size_t slow = 0;
    for (const auto& pass : plan.passes) slow += pass.slow ? 1 : 0;
    fmt::print(out,
               "feedid plan: axis {}, {} centre(s), {} passes ({} slow), {} blocks, predicted duration {:.1f} s "
               "({:.1f} min)\n",
               o.axis, o.centers.size(), plan.passes.size(), slow, plan.moves.size(), plan.duration,
               plan.duration / 60.0);
    const auto& branch = nominal.drive.friction.forward;
    fmt::print(out,
               "identifiability from a nominal drive (M {} kg, B {} N*s/m, F_C {} N, F_B {} N, v_s {} mm/s; force "
               "noise {} N):\n",
               nominal.drive.mass, branch.viscous, branch.coulomb, branch.breakaway.value_or(0.0),
               branch.stribeck_velocity.value_or(0.0) / mm, nominal.force_noise);
    fmt::print(out, "  step 1: condition number {:.3g} over {} samples; step 2: {} constant-velocity friction levels\n",
               prediction.step1_condition_number, prediction.step1_samples, prediction.step2_levels);
    for (const auto& p : prediction.parameters) {
        if (std::isfinite(p.standard_error)) {
            fmt::print(out, "  {:<4} {:>10.4g} {:<6} +- {:<10.3g} ({:6.3g} %)  {}\n", p.symbol, p.nominal, p.unit,
                       p.standard_error, 100.0 * p.standard_error / std::abs(p.nominal),
                       p.identifiable ? "identifiable" : "NOT identifiable");
        } else {
            fmt::print(out, "  {:<4} {:>10.4g} {:<6} +- {:<10}            {}\n", p.symbol, p.nominal, p.unit, "inf",
                       "NOT identifiable");
        }
    }
    for (const auto& note : plan.notes) fmt::print(out, "note: {}\n", note);
    for (const auto& diagnostic : prediction.diagnostics) fmt::print(out, "diagnostic: {}\n", diagnostic);
}

void write_text_file(const std::string& path, const std::string& text) {
    if (path == "-") {
        std::fwrite(text.data(), 1, text.size(), stdout);
        return;
    }
    std::ofstream out(path, std::ios::binary);
    if (!out) throw InputError(fmt::format("cannot write '{}'.", path));
    out << text;
    if (!out) throw InputError(fmt::format("cannot write '{}'.", path));
}

}  // namespace

/// The options of `feedid plan`, as given; the library turns them into a plan and a prediction.
struct PlanArguments {
    std::string axis{"X"};
    std::string travel;
    std::vector<std::string> centers;
    double stroke_mm{30.0};
    std::vector<std::string> feeds;
    std::vector<std::string> slow_feeds{"10:1000:7"};
    double max_pass_time_s{8.0};
    int cycles{2};
    double acceleration{1.0};
    std::optional<double> jerk;
    double dwell_s{0.2};
    double sample_time_s{0.001};
    std::optional<double> max_feed_mm_per_min;
    double positioning_feed_mm_per_min{5000.0};
    std::optional<double> start_mm;
    std::string dialect{"iso"};
    std::string output;
    std::string reference;
    std::string json;
    // nominal drive
    double mass{69.1};
    double viscous{54.2};
    double coulomb{742.8};
    double breakaway{946.2};
    double stribeck_mm_per_s{5.0};
    double force_noise{10.0};
    double level_error{5.0};
    double resolution_um{1.0};

    void add_to(CLI::App& sub) {
        sub.add_option("--axis", axis, "Axis name as the NC knows it (X, Y, Z, A, ...; X1 on SINUMERIK)")
            ->default_val("X");
        sub.add_option("--travel", travel, "Travel limits MIN:MAX [mm] (write --travel=-400:400)")->required();
        add_list_option(sub, "--centers", centers, "Centres of the strokes C1,C2,... [mm] (write --centers=-300,0,300)")
            ->required()
            ->check(allowed_range(-1e6, 1e6, "mm"));
        sub.add_option("--stroke", stroke_mm, "Stroke of the ladder passes [mm]")
            ->default_val(30.0)
            ->check(allowed_range(0.01, 1e5, "mm"));
        add_list_option(sub, "--feeds", feeds,
                        "Ladder feedrates F1,F2,... [mm/min]; default the paper's 1250,2600,3950,5300,6650,8000,9350")
            ->check(allowed_range(1e-3, 1e6, "mm/min"));
        add_list_option(sub, "--slow-feeds", slow_feeds,
                        "Slow Stribeck passes: LO:HI[:N] log-spaced, F1,F2,... [mm/min], or none")
            ->default_val("10:1000:7");
        sub.add_option("--max-pass-time", max_pass_time_s, "Longest slow pass; its stroke is shortened to fit [s]")
            ->default_val(8.0)
            ->check(allowed_range(0.01, 3600.0, "s"));
        sub.add_option("--cycles", cycles, "Back-and-forth cycles per feedrate")
            ->default_val(2)
            ->check(allowed_range(1, 100, "cycles"));
        sub.add_option("--acceleration", acceleration, "Axis acceleration (machine data) [m/s^2]")
            ->default_val(1.0)
            ->check(allowed_range(1e-3, 1e3, "m/s^2"));
        sub.add_option("--jerk", jerk, "Jerk limit [m/s^3] (SINUMERIK SOFT); default none (BRISK)")
            ->check(allowed_range(1e-3, 1e6, "m/s^3"));
        sub.add_option("--dwell", dwell_s, "Dwell at every reversal [s]")
            ->default_val(0.2)
            ->check(allowed_range(0.0, 60.0, "s"));
        sub.add_option("--sample-time", sample_time_s, "Trace sample time [s] (the reference file's step)")
            ->default_val(0.001)
            ->check(allowed_range(1e-6, 1.0, "s"));
        sub.add_option("--max-feed", max_feed_mm_per_min, "Feedrate limit of the axis [mm/min]; refuse moves above it")
            ->check(allowed_range(1e-3, 1e6, "mm/min"));
        sub.add_option("--positioning-feed", positioning_feed_mm_per_min, "Feedrate between passes [mm/min]")
            ->default_val(5000.0)
            ->check(allowed_range(1e-3, 1e6, "mm/min"));
        sub.add_option("--start", start_mm, "Where the axis stands at the program start [mm]; default the first pass")
            ->check(allowed_range(-1e6, 1e6, "mm"));
        sub.add_option("--dialect", dialect, "Part-program dialect")
            ->check(CLI::IsMember({"iso", "sinumerik", "linuxcnc"}))
            ->default_val("iso");
        sub.add_option("-o,--out", output, "Write the part program here ('-' for stdout)");
        sub.add_option("--reference", reference, "Write the reference trajectory (CSV: t [s], x_ref [m]) here");
        sub.add_option("--json", json, "Write the plan and its prediction as JSON ('-' for stdout)");
        sub.add_option("--mass", mass, "Nominal mass for the prediction [kg]")
            ->default_val(69.1)
            ->check(allowed_range(1e-3, 1e6, "kg"));
        sub.add_option("--viscous", viscous, "Nominal viscous friction [N*s/m]")
            ->default_val(54.2)
            ->check(allowed_range(0.0, 1e7, "N*s/m"));
        sub.add_option("--coulomb", coulomb, "Nominal Coulomb friction [N]")
            ->default_val(742.8)
            ->check(allowed_range(0.0, 1e7, "N"));
        sub.add_option("--breakaway", breakaway, "Nominal breakaway friction [N]")
            ->default_val(946.2)
            ->check(allowed_range(0.0, 1e7, "N"));
        sub.add_option("--stribeck-velocity", stribeck_mm_per_s, "Nominal Stribeck velocity [mm/s]")
            ->default_val(5.0)
            ->check(allowed_range(1e-3, 1e4, "mm/s"));
        sub.add_option("--force-noise", force_noise, "Expected force noise per sample [N]")
            ->default_val(10.0)
            ->check(allowed_range(1e-9, 1e9, "N"));
        sub.add_option("--level-error", level_error, "Expected error of one pass's friction level [N]")
            ->default_val(5.0)
            ->check(allowed_range(1e-9, 1e9, "N"));
        sub.add_option("--position-resolution", resolution_um, "Position measurement resolution [um]")
            ->default_val(1.0)
            ->check(allowed_range(1e-6, 1e4, "um"));
    }

    [[nodiscard]] TestPlanOptions plan_options() const {
        TestPlanOptions options;
        options.axis = axis;
        std::tie(options.travel_min, options.travel_max) = parse_travel(travel);
        options.centers = parse_number_list(centers, "--centers", mm);
        options.stroke = stroke_mm * mm;
        if (!feeds.empty()) options.feeds = parse_feeds(feeds);
        options.slow_feeds = parse_slow_feeds(slow_feeds);
        options.max_pass_time = max_pass_time_s;
        options.cycles = cycles;
        options.acceleration = acceleration;
        options.jerk = jerk;
        options.dwell = dwell_s;
        options.sample_time = sample_time_s;
        if (max_feed_mm_per_min) options.max_feed = *max_feed_mm_per_min * mm_per_min;
        options.positioning_feed = positioning_feed_mm_per_min * mm_per_min;
        if (start_mm) options.start_position = *start_mm * mm;
        return options;
    }

    [[nodiscard]] PredictionOptions prediction_options() const {
        PredictionOptions nominal;
        FrictionBranch branch;
        branch.viscous = viscous;
        branch.coulomb = coulomb;
        branch.breakaway = breakaway;
        branch.stribeck_velocity = stribeck_mm_per_s * mm;
        nominal.drive.mass = mass;
        nominal.drive.friction = Friction::symmetric(branch);
        nominal.force_noise = force_noise;
        nominal.level_error = level_error;
        nominal.position_resolution = resolution_um * 1e-6;
        return nominal;
    }

    [[nodiscard]] int run() const {
        const TestPlan plan = make_test_plan(plan_options());
        const PredictionOptions nominal = prediction_options();
        const auto prediction = predict_identifiability(plan, nominal);
        const auto part_program_dialect = parse_dialect(dialect).value_or(Dialect::iso);
        if (!output.empty()) write_text_file(output, emit_part_program(plan, part_program_dialect));
        if (!reference.empty()) write_text_file(reference, write_csv(reference_trajectory(plan)));
        if (!json.empty()) write_json(plan_document(plan, prediction), json);
        const bool stdout_taken = output == "-" || reference == "-" || json == "-";
        print_summary(stdout_taken ? stderr : stdout, plan, prediction, nominal);
        return 0;
    }
};

Action add_plan_command(CLI::App& app) {
    auto* sub = app.add_subcommand("plan", "Design the axis test and write it as a part program and a reference");
    sub->footer(
        "The test (after the paper, METHOD.md step 5): at each centre, back-and-forth strokes at every feedrate, the\n"
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
        "  feedid plan --travel=-400:400 --centers=-300 --slow-feeds none --dialect sinumerik -o TEST.MPF");

    auto arguments = std::make_shared<PlanArguments>();
    arguments->add_to(*sub);
    return [arguments] { return arguments->run(); };
}

}  // namespace feedid::cli
