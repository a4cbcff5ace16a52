// feedid report RESULT.json|DB -o report.html: one self-contained HTML file with the plots people look at.
#include <algorithm>
#include <cstdio>
#include <map>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/history/store.hpp"
#include "feedid/history/trend.hpp"
#include "feedid/io/json_input.hpp"
#include "feedid/report/history_report.hpp"
#include "feedid/report/result_report.hpp"

namespace feedid::cli {
namespace {

struct ReportArguments {
    std::string input;
    std::string out_path;
    std::string simulation_path;
    history::RunFilter filter;
    history::TrendOptions trend;
};

/// The stored result documents the report's friction curves come from: per axis the latest run's, or the latest of
/// the last `latest_runs` runs whose result holds a friction curve.
void attach_latest_results(const history::HistoryStore& store, std::vector<history::RunRecord>& runs) {
    constexpr std::size_t latest_runs = 20;
    std::map<std::pair<std::string, std::string>, std::vector<history::RunRecord*>> by_axis;
    for (auto& run : runs) by_axis[{run.machine, run.axis}].push_back(&run);
    for (auto& [axis, members] : by_axis) {
        std::stable_sort(members.begin(), members.end(), [](const auto* a, const auto* b) {
            return a->recorded_at != b->recorded_at ? a->recorded_at < b->recorded_at : a->id < b->id;
        });
        for (std::size_t n = 0; n < latest_runs && n < members.size(); ++n) {
            auto* run = members[members.size() - 1 - n];
            run->result = store.result_document(run->id);
            if (run->result.contains("friction_curve")) break;
        }
    }
}

int run_report(const ReportArguments& arguments) {
    if (const auto problem = arguments.trend.validate(); !problem.empty()) throw InputError(problem);
    const bool server = history::is_postgresql_location(arguments.input);
    if (!server && !std::filesystem::is_regular_file(arguments.input))
        throw InputError(
            fmt::format("{}: no such file (give an identify result document or a history database)", arguments.input));
    // A history database is guarded with its -wal and -shm files; a result document alone.
    const bool database = server || history::looks_like_sqlite(arguments.input);
    require_separate_outputs({{"-o", arguments.out_path}}, {{database ? "the history database" : "the result document",
                                                             server ? std::string() : arguments.input, database},
                                                            {"the --simulation document", arguments.simulation_path}});
    std::string html;
    if (database) {
        // A simulation validates one run; a history holds many.
        if (!arguments.simulation_path.empty())
            throw InputError(
                fmt::format("--simulation {}: goes with an identify result document, not with a history "
                            "database ({})",
                            arguments.simulation_path, history::shown_location(arguments.input)));
        history::OpenOptions options;
        options.read_only = true;
        const auto store = history::open_store(arguments.input, options);
        // The typed columns of every run; of the stored documents only those the friction curves need.
        auto runs = store->runs(arguments.filter, history::RunDetail::summary);
        attach_latest_results(*store, runs);
        if (runs.empty())
            throw InputError(fmt::format(
                "{}: no runs recorded{}", history::shown_location(arguments.input),
                arguments.filter.machine.empty() && arguments.filter.axis.empty() ? "" : " for this machine/axis"));
        const auto trends = history::analyse_trends(runs, store->pins(), arguments.trend);
        html = report::history_report_html(runs, trends, arguments.trend, history::shown_location(arguments.input));
    } else {
        nlohmann::json document;
        try {
            document = read_json(arguments.input);
        } catch (const JsonSyntaxError&) {
            throw InputError(
                fmt::format("{}: neither an identify result document (JSON) nor a history database "
                            "(SQLite)",
                            arguments.input));
        }
        std::optional<report::SimulationDocument> simulation;
        if (!arguments.simulation_path.empty())
            simulation = report::SimulationDocument{read_json(arguments.simulation_path), arguments.simulation_path};
        html = report::result_report_html(document, arguments.input, simulation);
    }
    write_output(arguments.out_path, html);
    if (arguments.out_path != "-") fmt::print(stderr, "feedid: wrote {}\n", arguments.out_path);
    return 0;
}

}  // namespace

Action add_report_command(CLI::App& app) {
    auto arguments = std::make_shared<ReportArguments>();
    auto* sub = app.add_subcommand("report",
                                   "Write one self-contained HTML report with plots of an identify result or "
                                   "of a parameter history");
    sub->add_option("INPUT", arguments->input,
                    "An identify result document (feedid identify --json) or a history database (SQLite file)")
        ->required();
    sub->add_option("-o,--out", arguments->out_path, "Where to write the HTML file ('-' for stdout)")->required();
    sub->add_option("--simulation", arguments->simulation_path,
                    "With a result: the simulate document (feedid simulate --json) for the tracking-error plots "
                    "(Fig. 6)");
    sub->add_option("--machine", arguments->filter.machine, "History: only this machine");
    sub->add_option("--axis", arguments->filter.axis, "History: only this axis");
    sub->add_option("--location", arguments->filter.location, "History: only this location / site");
    sub->add_option("--baseline-runs", arguments->trend.baseline_runs, "History: runs in the baseline")
        ->capture_default_str()
        ->check(allowed_range(1, 1000, "runs"));
    sub->add_option("--cusum-k", arguments->trend.cusum_k, "History: CUSUM allowance [combined standard errors]")
        ->capture_default_str()
        ->check(allowed_range(0.0, 100.0, "combined standard errors"));
    sub->add_option("--cusum-h", arguments->trend.cusum_h, "History: CUSUM alarm threshold [combined standard errors]")
        ->capture_default_str()
        ->check(allowed_range(1e-3, 1000.0, "combined standard errors"));
    sub->footer(
        "From a result: the RLS estimates over time with the end of the transient, and the friction curve per\n"
        "direction; with --simulation, the tracking error of machine and model and the modelling error over time.\n"
        "From a history: per axis and parameter, each run's value with its uncertainty band, the baseline,\n"
        "the alarm limits and the CUSUM, and the latest run's friction curve. The file needs no network to view.\n"
        "Examples:\n"
        "  feedid identify x.csv --json result.json && feedid report result.json -o x.html\n"
        "  feedid simulate x.csv --result result.json --json sim.json && \\\n"
        "      feedid report result.json --simulation sim.json -o x.html\n"
        "  feedid report shop.db --machine DMU50 -o health.html");
    return [arguments] { return run_report(*arguments); };
}

}  // namespace feedid::cli
