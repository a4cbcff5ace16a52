// feedid identify FILE: mass and friction of the axis, with uncertainty (the paper's two-step RLS, done right).
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <optional>
#include <string_view>
#include <cstdio>
#include <memory>
#include <vector>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/identify/brief_report.hpp"
#include "feedid/identify/friction_map.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/identify/option_names.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/core/terminal_text.hpp"
#include "record_arguments.hpp"

namespace feedid::cli {

namespace {

struct IdentifyCommand {
    TraceArguments trace_arguments;
    DriveArguments drive_arguments;
    IdentifyOptions options;  // the defaults: the library's
    // "auto" (the library's default, ModelSelectionOptions::automatic) or a forced friction model
    std::string model{options.model_selection.automatic ? automatic_model_name
                                                        : name_of(friction_model_names, options.model)};
    bool no_offset{false};
    std::string delay;
    std::string differentiation{name_of(differentiation_names, options.preprocess.differentiation)};
    std::string velocity_source{name_of(velocity_source_names, options.preprocess.velocity_source)};
    std::string rls_variant{name_of(rls_variant_names, options.step1.rls.variant)};
    bool no_stribeck{false};
    std::string json_path;
    bool by_location{false};
    bool no_systematic{false};
    std::vector<double> centers_mm;
    RecordArguments record;

    void add_to(CLI::App& sub) {
        trace_arguments.add_to(sub);
        drive_arguments.add_to(sub);
        auto* model_group = sub.add_option_group("Model");
        std::vector<std::string> models{automatic_model_name};
        for (const auto& name : names_of(friction_model_names)) models.push_back(name);
        model_group
            ->add_option("--model", model,
                         "Friction model: auto (chosen from the data with the offset and the drive signal's delay), "
                         "symmetric (the paper's eq. 11) or asymmetric (per direction); symmetric or asymmetric "
                         "forces the model")
            ->check(CLI::IsMember(models))
            ->capture_default_str();
        auto* offset_flag = model_group->add_flag(
            "--offset", options.offset,
            "Force a constant force offset F_0 into the model (a weight, a sensor's zero); without --offset, --no-offset "
            "or --model, the data decide");
        model_group
            ->add_flag("--no-offset", no_offset, "Force the model without an offset")
            ->excludes(offset_flag);
        model_group
            ->add_option("--delay", delay,
                         "The drive signal's delay behind the position: auto (estimated, applied where significant; "
                         "the default with an automatic model), none (the default with a forced model, which only "
                         "says a significant one), or a known one, e.g. 0.5ms")
            ->check([](const std::string& text) { return delay_problem(text); });
        sub.add_flag("--no-stribeck", no_stribeck, "Skip step 2 (breakaway friction and Stribeck velocity)");
        sub.add_option("--json", json_path, "Write the result document to PATH ('-' for stdout)");
        record.add_to(sub);
        auto* location = sub.add_option_group("Friction along the axis");
        location->add_flag("--by-location", by_location,
                           "Cut a multi-centre test (feedid plan --centers ...) by centre and identify each segment on "
                           "its own: a friction map, in which a worn stretch of the screw stands out");
        location
            ->add_option("--centers", centers_mm,
                         "Centres of the strokes C1,C2,... [mm; deg on a rotary axis] for --by-location (write "
                         "--centers=-300,0,300); default: found from the strokes in the trace")
            ->delimiter(',')
            ->check(allowed_range(-1e9, 1e9, "mm (deg on a rotary axis)"));
        auto* pre = sub.add_option_group("Preprocessing");
        pre->add_option("--differentiation", differentiation,
                        "How velocity and acceleration are obtained from position: butterworth (zero-phase low-pass, "
                        "then central differences), central (the paper), savitzky-golay")
            ->check(CLI::IsMember(names_of(differentiation_names)))
            ->capture_default_str();
        pre->add_option("--velocity-source", velocity_source,
                        "Where velocity comes from: position (differentiated), velocity (the logged velocity channel, "
                        "filtered like the position; acceleration is its derivative) or auto (the logged velocity "
                        "when there is no position or it is too coarse)")
            ->check(CLI::IsMember(names_of(velocity_source_names)))
            ->capture_default_str();
        pre->add_option("--filter-order", options.preprocess.filter_order, "Butterworth order")
            ->capture_default_str()
            ->check(allowed_range(1, 12, ""));
        pre->add_flag("--no-systematic", no_systematic,
                      "Skip the family of preprocessing choices (cut-off halved and doubled, the other "
                      "differentiation method, the split speed raised by half) that gives each parameter its "
                      "systematic uncertainty: standard errors only, about 5x faster");
        pre->add_option("--threads", options.threads,
                        "Threads the family of preprocessing choices runs on at most (default 0: one per core; reruns go in "
                        "parallel only while they fit identify's memory budget of 100 bytes per sample)")
            ->check(allowed_range(0, 1024, ""));
        pre->add_option("--cutoff", options.preprocess.cutoff_hz,
                        "Butterworth cut-off [Hz] (default: min(100 Hz, sample rate / 10))")
            ->check(allowed_range(1e-3, 1e6, "Hz"));
        pre->add_option("--sg-window", options.preprocess.savitzky_golay_window,
                        "Savitzky-Golay window [samples, odd] (default: about 20 ms)")
            ->check(allowed_range(5, 1e6, "samples"));
        pre->add_option("--sg-order", options.preprocess.savitzky_golay_order, "Savitzky-Golay polynomial order")
            ->capture_default_str()
            ->check(allowed_range(2, 6, ""));
        pre->add_option("--decimate", options.preprocess.decimation,
                        "Decimate every regressor column and the force by this factor (order-8 Chebyshev anti-alias "
                        "filter, forwards and backwards; default 1 = none)")
            ->check(allowed_range(0, 1000, ""));
        pre->add_option("--edge-samples", options.preprocess.edge_samples,
                        "Samples dropped at each end after filtering (default: 2.5 filter periods, fs/cutoff*2.5)")
            ->check(allowed_range(0, 1e9, "samples"));
        auto* select = sub.add_option_group("Data selection");
        select->add_option("--from", options.preprocess.from_s, "Start of the analysis window [s]")
            ->check(allowed_range(-1e12, 1e12, "s"));
        select->add_option("--to", options.preprocess.to_s, "End of the analysis window [s]")
            ->check(allowed_range(-1e12, 1e12, "s"));
        select
            ->add_option("--split-velocity", options.selection.split_velocity,
                         "Step 1 uses |v| above, step 2 the quasi-static samples below [m/s or rad/s] (default: a "
                         "tenth of the typical constant-velocity speed)")
            ->check(allowed_range(0.0, 1e4, "m/s or rad/s"));
        select
            ->add_option("--moving-threshold", options.selection.moving_threshold,
                         "|v| above which a sample counts as moving [m/s] (default: 5x the velocity noise floor)")
            ->check(allowed_range(0.0, 1e4, "m/s or rad/s"));
        auto* rls = sub.add_option_group("RLS");
        rls->add_option("--lambda", options.step1.rls.forgetting_factor, "Forgetting factor")
            ->capture_default_str()
            ->check(allowed_range(1e-6, 1.0, ""));
        rls->add_option("--p0", options.step1.rls.initial_covariance, "Initial covariance P(0) = p0 * I")
            ->capture_default_str()
            ->check(allowed_range(1e-12, 1e12, ""));
        rls->add_option("--rls", rls_variant,
                        "RLS variant: directional (forgetting only where the data excites; robust) or paper "
                        "(exponential forgetting, eq. 7-9)")
            ->check(CLI::IsMember(names_of(rls_variant_names)))
            ->capture_default_str();
    }

    IdentifyOptions resolved() const {
        IdentifyOptions o = options;
        o.drive = drive_arguments.constants();
        // the names were checked while parsing (IsMember)
        if (model != automatic_model_name) o.model = value_named(friction_model_names, model).value_or(o.model);
        // any of --model symmetric|asymmetric, --offset, --no-offset forces the whole model
        o.model_selection.automatic = model == automatic_model_name && !options.offset && !no_offset;
        if (delay == "auto")
            o.model_selection.delay = ModelSelectionOptions::Delay::estimate;
        else if (delay == "none")
            o.model_selection.delay = ModelSelectionOptions::Delay::none;
        else if (!delay.empty())
            o.model_selection.known_delay_s = parse_delay(delay);
        o.preprocess.differentiation =
            value_named(differentiation_names, differentiation).value_or(o.preprocess.differentiation);
        o.preprocess.velocity_source =
            value_named(velocity_source_names, velocity_source).value_or(o.preprocess.velocity_source);
        o.step1.rls.variant = value_named(rls_variant_names, rls_variant).value_or(o.step1.rls.variant);
        o.stribeck = !no_stribeck;
        o.systematic = !no_systematic;
        return o;
    }

    /// What only the command line knows of the options that shape the result (as given, for the history).
    nlohmann::json command_line_options() const {
        const auto optional = [](const auto& value) {
            return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
        };
        nlohmann::json document{{"drive",
                                 {{"kt_Nm_per_A", optional(drive_arguments.kt)},
                                  {"lead_mm", optional(drive_arguments.lead_mm)},
                                  {"gear_ratio", drive_arguments.gear_ratio},
                                  {"force_constant", drive_arguments.force_constant}}},
                                {"channels", trace_arguments.channel_assignments},
                                {"units", trace_arguments.unit_assignments},
                                {"axis", trace_arguments.axis},
                                {"format", trace_arguments.format},
                                {"rated", trace_arguments.rated.empty() ? nlohmann::json(nullptr) : nlohmann::json(trace_arguments.rated)}};
        // a second recording and tares shape the result too; absent when not used (older documents lack them)
        if (!trace_arguments.join.empty()) document["join"] = trace_arguments.join;
        if (!trace_arguments.tare.empty()) document["tare"] = trace_arguments.tare;
        if (!trace_arguments.invert.empty()) document["invert"] = trace_arguments.invert;
        return document;
    }

    int run() const {
        const IdentifyOptions o = resolved();
        if (const auto problem = o.validate(); !problem.empty()) throw InputError(problem);
        if (!centers_mm.empty() && !by_location) throw InputError("--centers needs --by-location");
        if (by_location && record.enabled()) throw InputError("--record takes one result; not with --by-location");
        std::vector<GuardedFile> inputs = trace_arguments.inputs();
        inputs.push_back({"the --record history database", record.database, true});
        require_separate_outputs({{"--json", json_path}}, inputs);
        record.check(trace_arguments.axis);
        const Trace trace = read_trace_for_drive(trace_arguments, drive_arguments);
        if (by_location) return run_by_location(trace, o);
        IdentifyResult result = identify(trace, o);
        // The options go into the document too, so that recording it later (feedid history --record) gives the
        // same run as --record here.
        result.options = identify_options_document(o, command_line_options());
        const nlohmann::json document = result;
        if (!json_path.empty()) write_json(document, json_path);
        if (json_path != "-") print_table(result);
        if (result.status == Status::failed) {
            for (const auto& d : result.diagnostics) fmt::print(stderr, "feedid: {}\n", terminal_message(d));
            return 1;
        }
        if (record.enabled()) record.record(document, trace_arguments.file, trace_arguments.axis, document["options"]);
        if (json_path == "-") {
            for (const auto& d : result.diagnostics) fmt::print(stderr, "feedid: {}\n", terminal_message(d));
        }
        return 0;
    }

    int run_by_location(const Trace& trace, const IdentifyOptions& o) const {
        FrictionMapOptions map_options;
        map_options.identify = o;
        // --centers is in mm, or in deg on a rotary axis: positions as the friction map shows them
        const ParameterNaming naming{trace.rotary};
        for (const double c : centers_mm) map_options.centers.push_back(c / naming.display_position_scale());
        const FrictionMap map = friction_map(trace, map_options);
        if (!json_path.empty()) write_json(map.document, json_path);
        const bool any = std::any_of(map.locations.begin(), map.locations.end(),
                                     [](const LocationResult& l) { return l.result.status != Status::failed; });
        if (json_path != "-") print_map(trace, map);
        if (!any) {
            std::string why;
            for (const auto& location : map.locations) {
                const std::string reason = location.error                        ? *location.error
                                           : location.result.diagnostics.empty() ? std::string("not identified")
                                                                                 : location.result.diagnostics.front();
                why += fmt::format("{}centre {:.3f} {}: {}", why.empty() ? "" : "; ",
                                   location.center * naming.display_position_scale(), naming.display_position_unit(),
                                   reason);
            }
            fmt::print(stderr, "feedid: no location could be identified ({})\n", terminal_message(why));
            return 1;
        }
        return 0;
    }

    static void print_map(const Trace& trace, const FrictionMap& map) {
        fmt::print("{}: friction along the axis, {} location{} ({})\n", trace.source_path, map.locations.size(),
                   map.locations.size() == 1 ? "" : "s",
                   map.centers_detected ? "centres found from the strokes" : "centres as given");
        // Columns: every parameter that some location identified, in the pipeline's order.
        std::vector<const Parameter*> columns;
        for (const auto& location : map.locations) {
            for (const auto& p : location.result.parameters) {
                const bool seen =
                    std::any_of(columns.begin(), columns.end(), [&](const Parameter* c) { return c->key == p.key; });
                if (!seen) columns.push_back(&p);
            }
        }
        const ParameterNaming naming{map.rotary};
        fmt::print("\n  {:>12} {:>17}", fmt::format("centre [{}]", naming.display_position_unit()), "time [s]");
        for (const auto* c : columns) fmt::print(" {:>14}", fmt::format("{} [{}]", c->symbol, c->unit));
        fmt::print("\n");
        for (std::size_t l = 0; l < map.locations.size(); ++l) {
            const auto& location = map.locations[l];
            const auto& outstanding = map.document["locations"][l]["stands_out"];
            fmt::print("  {:>12.3f} {:>17}", location.center * naming.display_position_scale(),
                       fmt::format("{:.1f}..{:.1f}", location.from_s, location.to_s));
            for (const auto* c : columns) {
                const auto* p = location.result.find(c->key);
                std::string cell = "—";
                if (p != nullptr && p->estimate.value) {
                    const bool marked = std::find(outstanding.begin(), outstanding.end(), c->key) != outstanding.end();
                    cell = fmt::format("{:.5g}{}", *p->estimate.value, marked ? " *" : "");
                }
                fmt::print(" {:>14}", cell);
            }
            if (location.error) fmt::print("   ({})", *location.error);
            fmt::print("\n");
        }
        fmt::print("\n");
        if (map.findings.empty()) {
            fmt::print("  no location stands out from the others\n");
        } else {
            for (const auto& finding : map.findings) fmt::print("  * {}\n", finding);
        }
    }

    static void print_table(const IdentifyResult& result) {
        fmt::print("{}", brief_report(result));
        if (result.step1) {
            fmt::print("\n  step-1 batch QR: relative error {:.3f} %, condition number {:.3g}, {} samples\n",
                       result.step1->relative_error_pct, result.step1->condition_number, result.step1->samples_used);
        }
        if (result.rls) print_rls(*result.rls);
        if (result.selection) {
            fmt::print("  data:\n");
            for (const auto& note : result.selection->notes) fmt::print("    - {}\n", terminal_message(note));
        }
        if (!result.diagnostics.empty() && result.status != Status::failed) {
            fmt::print("  diagnostics:\n");
            for (const auto& d : result.diagnostics) fmt::print("    - {}\n", terminal_message(d));
        }
    }

    static void print_rls(const RlsReport& rls) {
        const char* variant = rls.options.variant == RlsVariant::exponential ? "exponential" : "directional";
        if (rls.settled) {
            fmt::print("  RLS ({}): settled at {:.3g} s\n", variant, rls.transient_end_s);
        } else {
            fmt::print(
                "  RLS ({}): did not settle before the last tenth of the data (within tolerance of the final values "
                "only from {:.3g} s on); averaged = final\n",
                variant, rls.transient_end_s);
        }
        std::vector<std::size_t> order(rls.keys.size());  // by key, as the document lists them
        for (std::size_t c = 0; c < order.size(); ++c) order[c] = c;
        std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return rls.keys[a] < rls.keys[b]; });
        for (const auto c : order) {
            fmt::print("    {:<28} final {:>12.6g}   averaged {:>12.6g}\n", rls.keys[c], rls.final_estimate[c],
                       rls.averaged[c]);
        }
    }
};

}  // namespace

Action add_identify_command(CLI::App& app) {
    auto command = std::make_shared<IdentifyCommand>();
    auto* sub = app.add_subcommand("identify",
                                   "Estimate mass, viscous, Coulomb and breakaway friction and Stribeck "
                                   "velocity, each with a standard error");
    command->add_to(*sub);
    sub->footer(
        "Examples:\n"
        "  feedid identify ../shared/data/emps/DATA_EMPS.mat --channel position=qm --channel current=vir \\\n"
        "      --force-constant gtau --offset --json -\n"
        "  feedid identify trace.csv --kt 1.45 --lead 10 --model asymmetric\n"
        "  feedid identify x.csv --kt 1.45 --lead 10 --record shop.db --machine DMU50 --axis X   # weekly test\n"
        "  feedid identify multi-centre.csv --kt 1.45 --lead 10 --by-location --json map.json\n"
        "Exit codes: 0 identified (possibly with some parameters null: see diagnostics), 1 the data cannot identify "
        "the model (the message says why and what data would), 2 bad usage or bad input.");
    return [command] { return command->run(); };
}

}  // namespace feedid::cli
