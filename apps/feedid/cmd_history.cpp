// feedid history: list the recorded runs, their trends against the baseline, and check for drift (nightly job).
#include <algorithm>
#include <cstdio>
#include <map>
#include <set>
#include <tuple>
#include <unordered_set>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/history/record.hpp"
#include "feedid/history/store.hpp"
#include "feedid/history/trend.hpp"
#include "feedid/core/progress.hpp"
#include "feedid/core/terminal_text.hpp"

namespace feedid::cli {
namespace {

struct HistoryArguments {
    std::string database;
    history::RunFilter filter;
    std::string json_path;
    std::string csv_path;
    bool check{false};
    bool verify{false};
    std::vector<std::string> add;
    std::string trace;
    std::string recorded_at;
    std::optional<std::int64_t> pin;
    std::optional<std::int64_t> baseline_from;
    std::vector<std::string> copy;  ///< --copy FROM TO
    history::TrendOptions trend;
};

std::string format_estimate(const history::StoredEstimate& estimate) {
    if (!estimate.value) return "null";
    if (!estimate.standard_error) return fmt::format("{:.5g}", *estimate.value);
    return fmt::format("{:.5g} ± {:.2g}", *estimate.value, *estimate.standard_error);
}

std::string csv_field(const std::string& text) {
    if (text.find_first_of(",\"\n") == std::string::npos) return text;
    std::string quoted = "\"";
    for (const char c : text) {
        if (c == '"') quoted += '"';
        quoted += c;
    }
    return quoted + "\"";
}

/// Wide CSV: one row per run, two columns (value, stderr) per parameter key found in any listed run.
std::string runs_csv(const std::vector<history::RunRecord>& runs) {
    std::set<std::string> keys;
    for (const auto& run : runs)
        for (const auto& [key, estimate] : run.parameters) keys.insert(key);
    std::string text = "run,recorded_at,machine,axis,location,model,status,feedid_version,trace_sha256,trace_path";
    for (const auto& key : keys) text += fmt::format(",{},{}_stderr", key, key);
    text += ",relative_error_pct,condition_number,samples_used\n";
    const auto number = [](const std::optional<double>& value) {
        return value ? fmt::format("{:.10g}", *value) : std::string();
    };
    for (const auto& run : runs) {
        text += fmt::format("{},{},{},{},{},{},{},{},{},{}", run.id, run.recorded_at, csv_field(run.machine),
                            csv_field(run.axis), csv_field(run.location), run.model, run.status, run.feedid_version,
                            run.trace_sha256, csv_field(run.trace_path));
        for (const auto& key : keys) {
            const auto found = run.parameters.find(key);
            if (found == run.parameters.end())
                text += ",,";
            else
                text += fmt::format(",{},{}", number(found->second.value), number(found->second.standard_error));
        }
        text += fmt::format(",{},{},{}\n", number(run.fit_figures.relative_error_pct),
                            number(run.fit_figures.condition_number), number(run.fit_figures.samples_used));
    }
    return text;
}

/// The runs of one series in alarm, per parameter key.
std::map<std::string, std::unordered_set<std::int64_t>> runs_in_alarm(const history::SeriesTrend& series) {
    std::map<std::string, std::unordered_set<std::int64_t>> in_alarm;
    for (const auto& parameter : series.parameters)
        for (const auto& point : parameter.points)
            if (point.alarm) in_alarm[parameter.key].insert(point.run_id);
    return in_alarm;
}

void print_table(const std::vector<history::RunRecord>& runs, const std::vector<history::SeriesTrend>& trends) {
    // a series per axis and kind: its identifications, and its fingerprint runs apart
    std::map<std::tuple<std::string, std::string, bool>, std::vector<const history::RunRecord*>> by_series;
    for (const auto& run : runs)
        by_series[{run.machine, run.axis, history::is_fingerprint_run(run)}].push_back(&run);
    for (const auto& series : trends) {
        const bool fingerprint = series.kind == "fingerprint";
        const auto& series_runs = by_series[{series.machine, series.axis, fingerprint}];
        std::set<std::string> keys;
        for (const auto* run : series_runs)
            for (const auto& [key, estimate] : run->parameters) keys.insert(key);
        fmt::print("machine '{}' axis '{}'{}: {} run(s); baseline: ", terminal_text(series.machine),
                   terminal_text(series.axis), fingerprint ? " (fingerprint)" : "", series_runs.size());
        if (series.baseline_run_ids.empty())
            fmt::print("none\n");
        else
            fmt::print("run(s) #{}..#{}{}\n", series.baseline_run_ids.front(), series.baseline_run_ids.back(),
                       series.pinned_run ? fmt::format(" (pinned at #{})", *series.pinned_run) : "");
        fmt::print("{:>5}  {:<24} {:<10}", "run", "recorded_at", "model");
        for (const auto& key : keys) fmt::print("  {:>24}", key);
        fmt::print("\n");
        const auto in_alarm = runs_in_alarm(series);
        for (const auto* run : series_runs) {
            fmt::print("{:>5}  {:<24} {:<10}", fmt::format("#{}", run->id), terminal_text(run->recorded_at),
                       terminal_text(run->model));
            for (const auto& key : keys) {
                const auto found = run->parameters.find(key);
                std::string cell = found == run->parameters.end() ? "-" : format_estimate(found->second);
                // Mark values in alarm with '!' so that a glance finds them.
                if (const auto alarms = in_alarm.find(key); alarms != in_alarm.end() && alarms->second.count(run->id))
                    cell += " !";
                fmt::print("  {:>24}", terminal_text(cell));
            }
            fmt::print("\n");
        }
        for (const auto& note : series.notes) fmt::print("note: {}\n", terminal_message(note));
        for (const auto& alarm : series.alarms) fmt::print("{}\n", terminal_text(alarm.message()));
        fmt::print("\n");
    }
}

/// The --add results, read and checked before the database is opened for writing, so that a failed command leaves
/// the file as it was.
std::vector<history::RunRecord> prepare_runs(const HistoryArguments& arguments) {
    std::vector<history::RunRecord> prepared;
    if (arguments.add.empty()) return prepared;
    if (arguments.filter.machine.empty() || arguments.filter.axis.empty())
        throw InputError("--add needs --machine NAME and --axis X to file the run under");
    Progress progress("reading results", arguments.add.size());
    for (std::size_t i = 0; i < arguments.add.size(); ++i) {
        const auto& path = arguments.add[i];
        const nlohmann::json result = read_json(path);
        history::RecordContext context;
        context.machine = arguments.filter.machine;
        context.axis = arguments.filter.axis;
        context.location = arguments.filter.location;
        context.trace =
            arguments.trace.empty() ? history::trace_of_result(result, path) : std::filesystem::path(arguments.trace);
        context.recorded_at = arguments.recorded_at;
        if (result.contains("options") && result["options"].is_object()) context.options = result["options"];
        prepared.push_back(history::prepare_run(result, path, context));
        for (const auto& finding : prepared.back().recording_findings)
            fmt::print(stderr, "feedid: warning: {}: {}\n", terminal_text(path), terminal_message(finding));
        progress.update(i + 1);
    }
    return prepared;
}

void record_runs(history::HistoryStore& store, const std::vector<history::RunRecord>& prepared,
                 const HistoryArguments& arguments) {
    Progress progress("recording runs", prepared.size());
    for (std::size_t i = 0; i < prepared.size(); ++i) {
        const auto outcome = store.add_run(prepared[i]);
        if (outcome.inserted)
            fmt::print(stderr, "feedid: recorded {} as run #{}\n", terminal_text(arguments.add[i]), outcome.id);
        else
            fmt::print(stderr, "feedid: {} is already recorded as run #{} (same trace, same options); not added\n",
                       terminal_text(arguments.add[i]), outcome.id);
        progress.update(i + 1);
    }
}

void pin_baseline(history::HistoryStore& store, const HistoryArguments& arguments) {
    for (const auto& series : store.series({})) {
        if (std::find(series.run_ids.begin(), series.run_ids.end(), *arguments.pin) == series.run_ids.end()) continue;
        store.pin_baseline(series.machine, series.axis, *arguments.pin);
        fmt::print(stderr, "feedid: the baseline of machine '{}' axis '{}' now starts at run #{}\n",
                   terminal_text(series.machine), terminal_text(series.axis), *arguments.pin);
        return;
    }
    throw InputError(
        fmt::format("{}: there is no run #{}", history::shown_location(arguments.database), *arguments.pin));
}

nlohmann::json history_document(const history::HistoryStore& store, const std::vector<history::RunRecord>& runs,
                                const std::vector<history::SeriesTrend>& trends, std::size_t alarms,
                                const HistoryArguments& arguments) {
    nlohmann::json document;
    document["database"] = history::shown_location(arguments.database);
    document["schema_version"] = store.schema_version();
    document["runs"] = nlohmann::json::array();
    for (const auto& run : runs) document["runs"].push_back(history::to_json(run));
    document["trends"] = nlohmann::json::array();
    for (const auto& series : trends) document["trends"].push_back(history::to_json(series));
    document["trend_options"] = {{"baseline_runs", arguments.trend.baseline_runs},
                                 {"cusum_k", arguments.trend.cusum_k},
                                 {"cusum_h", arguments.trend.cusum_h}};
    document["alarm"] = alarms > 0;
    return document;
}

// What --check checked when no alarm fired: the runs compared with a complete baseline (as the listing marks them),
// and the axes whose baseline is still forming, where nothing is checked yet.
std::string check_summary(const std::vector<history::SeriesTrend>& trends, const history::TrendOptions& options) {
    std::size_t checked_runs = 0;
    std::set<std::pair<std::string, std::string>> checked_axes;
    std::string forming;
    for (const auto& series : trends) {
        if (!series.baseline_complete) {
            forming += fmt::format("{}machine '{}' axis '{}'{}: {} of {} runs", forming.empty() ? "" : ", ",
                                   terminal_text(series.machine), terminal_text(series.axis),
                                   series.kind == "fingerprint" ? " (fingerprint)" : "",
                                   series.baseline_run_ids.size(), options.baseline_runs);
            continue;
        }
        checked_runs += series.checked_runs;
        if (series.checked_runs > 0) checked_axes.emplace(series.machine, series.axis);
    }
    if (trends.empty()) return "no drift alarm, but nothing checked: no runs recorded";
    if (checked_runs == 0) {
        return forming.empty()
                   ? std::string("no drift alarm, but nothing checked yet: no run after the baseline")
                   : "no drift alarm, but nothing checked yet: the baseline is still forming (" + forming + ")";
    }
    std::string summary = fmt::format("no drift alarm: {} run(s) of {} axis/axes checked against their baseline",
                                      checked_runs, checked_axes.size());
    if (!forming.empty()) summary += "; not checked yet, the baseline still forming: " + forming;
    return summary;
}

/// --verify: SQLite's full integrity check (on PostgreSQL: every table read) and every stored document; exit 0 when
/// sound, 2 with the problems.
int verify(const HistoryArguments& arguments) {
    history::OpenOptions read_only;
    read_only.read_only = true;
    const auto problems = history::open_store(arguments.database, read_only)->verify();
    const std::string shown = terminal_text(history::shown_location(arguments.database));
    if (problems.empty()) {
        fmt::print(
            "{}: ok ({}, every stored document readable)\n", shown,
            history::is_postgresql_location(arguments.database) ? "every table read" : "SQLite's integrity check");
        return 0;
    }
    for (const auto& problem : problems) fmt::print("{}\n", terminal_text(problem));
    fmt::print(stderr, "feedid: {}: the history database is damaged ({} problem(s), listed on stdout)\n", shown,
               problems.size());
    return 2;
}

/// --copy FROM TO: every run of FROM (and its pinned baselines) into TO, created when missing; idempotent.
int copy(const HistoryArguments& arguments) {
    const std::string& from = arguments.copy[0];
    const std::string& to = arguments.copy[1];
    if (from == to) throw InputError(fmt::format("--copy {} {}: the same history twice", from, to));
    history::OpenOptions read_only;
    read_only.read_only = true;
    const auto source = history::open_store(from, read_only);
    const auto destination = history::open_store(to);
    const auto outcome = history::copy_history(*source, *destination);
    fmt::print(stderr, "feedid: copied {} run(s) from {} to {} ({} already there), {} baseline pin(s)\n",
               outcome.copied, terminal_text(history::shown_location(from)), terminal_text(history::shown_location(to)),
               outcome.already_there, outcome.pins);
    return 0;
}

/// --check alone: the trend from the compact series, alarms only.
int check_only(const history::HistoryStore& store, const HistoryArguments& arguments) {
    history::TrendOptions options = arguments.trend;
    options.keep_points = false;
    const auto series = store.series(arguments.filter);
    const auto trends = history::analyse_trends(series, store.pins(), options);
    std::size_t alarms = 0;
    for (const auto& trend : trends)
        for (const auto& alarm : trend.alarms) {
            fmt::print("{}\n", terminal_text(alarm.message()));
            ++alarms;
        }
    if (alarms == 0) fmt::print("{}\n", check_summary(trends, arguments.trend));
    return alarms > 0 ? 1 : 0;
}

void check_arguments(const HistoryArguments& arguments) {
    if (const auto problem = arguments.trend.validate(); !problem.empty()) throw InputError(problem);
    if (!arguments.copy.empty()) {
        if (!arguments.database.empty() || !arguments.add.empty() || arguments.pin || arguments.check ||
            arguments.verify || !arguments.json_path.empty() || !arguments.csv_path.empty())
            throw InputError("--copy goes alone: feedid history --copy FROM TO");
        return;
    }
    if (arguments.database.empty())
        throw InputError("history needs DB: the history database (a SQLite file or postgresql://user@host:port/db)");
    if (!arguments.trace.empty() && arguments.add.size() != 1)
        throw InputError("--trace goes with exactly one --add RESULT.json");
    if (!arguments.recorded_at.empty() && arguments.add.size() != 1)
        throw InputError("--recorded-at goes with exactly one --add RESULT.json");
    if (arguments.verify && (!arguments.add.empty() || arguments.pin || arguments.check ||
                             !arguments.json_path.empty() || !arguments.csv_path.empty()))
        throw InputError("--verify goes alone: feedid history DB --verify");
    const bool server = history::is_postgresql_location(arguments.database);
    std::vector<GuardedFile> inputs{{"the history database", server ? std::string() : arguments.database, true},
                                    {"the --trace file", arguments.trace}};
    for (const auto& path : arguments.add) inputs.push_back({"a --record document", path});
    require_separate_outputs({{"--json", arguments.json_path}, {"--csv", arguments.csv_path}}, inputs);
}

int run_history(HistoryArguments& arguments) {
    check_arguments(arguments);
    if (arguments.baseline_from) arguments.trend.pinned_run = arguments.baseline_from;
    if (!arguments.copy.empty()) return copy(arguments);
    if (arguments.verify) return verify(arguments);
    const bool writes = !arguments.add.empty() || arguments.pin;
    const std::vector<history::RunRecord> prepared = prepare_runs(arguments);

    history::OpenOptions open_options;
    open_options.read_only = !writes;
    open_options.create = !arguments.add.empty();  // --pin names a run: a missing file has none, and is not made
    auto store = history::open_store(arguments.database, open_options);
    record_runs(*store, prepared, arguments);
    if (arguments.pin) pin_baseline(*store, arguments);
    const bool listing = arguments.json_path.empty() && arguments.csv_path.empty() && !writes;
    // What was recorded is committed: reading the history afterwards is only for outputs asked for.
    if (!listing && !arguments.check && arguments.json_path.empty() && arguments.csv_path.empty()) return 0;
    if (arguments.check && arguments.json_path.empty() && arguments.csv_path.empty())
        return check_only(*store, arguments);

    const auto detail = arguments.json_path.empty() ? history::RunDetail::summary : history::RunDetail::documents;
    const auto runs = store->runs(arguments.filter, detail);
    // a CSV listing needs no trend
    const bool trended = !arguments.json_path.empty() || arguments.check || listing;
    const auto trends = trended ? history::analyse_trends(runs, store->pins(), arguments.trend)
                                : std::vector<history::SeriesTrend>{};
    std::size_t alarms = 0;
    for (const auto& series : trends) alarms += series.alarms.size();
    if (!arguments.json_path.empty())
        write_json(history_document(*store, runs, trends, alarms, arguments), arguments.json_path);
    if (!arguments.csv_path.empty()) write_output(arguments.csv_path, runs_csv(runs));

    if (arguments.check) {
        if (arguments.json_path != "-" && arguments.csv_path != "-") {
            for (const auto& series : trends)
                for (const auto& alarm : series.alarms) fmt::print("{}\n", terminal_text(alarm.message()));
            if (alarms == 0) fmt::print("{}\n", check_summary(trends, arguments.trend));
        }
        return alarms > 0 ? 1 : 0;
    }
    if (listing) {
        if (runs.empty())
            fmt::print("no runs recorded{}\n", arguments.filter.machine.empty() && arguments.filter.axis.empty()
                                                   ? ""
                                                   : " for this machine/axis");
        print_table(runs, trends);
    }
    return 0;
}

}  // namespace

Action add_history_command(CLI::App& app) {
    auto arguments = std::make_shared<HistoryArguments>();
    auto* sub = app.add_subcommand("history", "List, record and check the parameter history of machines and axes");
    sub->add_option("DB", arguments->database,
                    "The history database: a SQLite file or a PostgreSQL database (postgresql://user@host:port/db; "
                    "libpq's PG* environment variables and service files fill in the rest)");
    sub->add_option("--machine", arguments->filter.machine,
                    "Only this machine (with --add: the machine to file under)");
    sub->add_option("--axis", arguments->filter.axis, "Only this axis (with --add: the axis to file under)");
    sub->add_option("--location", arguments->filter.location, "Only this location / site (with --add: its site)");
    auto* json = sub->add_option("--json", arguments->json_path,
                                 "Write runs and trends as JSON to PATH (- or no value: "
                                 "stdout)")
                     ->expected(0, 1);
    auto* csv = sub->add_option("--csv", arguments->csv_path,
                                "Write the runs as CSV, one row per run, to PATH (- or no "
                                "value: stdout)")
                    ->expected(0, 1);
    sub->add_flag("--check", arguments->check,
                  "Check for drift: print every alarm (machine, axis, parameter, run) and exit 1 when there is one, 0 "
                  "otherwise");
    sub->add_flag("--verify", arguments->verify,
                  "Check the whole file: SQLite's full integrity check (every index against its table) and every "
                  "stored document; exit 0 when sound, 2 listing the problems");
    sub->add_option("--add,--record", arguments->add,
                    "Record identify result documents (feedid identify --json) as runs, each in one transaction; needs "
                    "--machine and --axis")
        ->take_all()
        ->allow_extra_args(false);
    sub->add_option("--copy", arguments->copy,
                    "Copy every run and pinned baseline of the history FROM into the history TO (created when "
                    "missing); runs TO holds already are skipped, so copying again adds nothing")
        ->expected(2)
        ->type_name("FROM TO");
    sub->add_option("--trace", arguments->trace, "With --add: the trace file (default: the path in the result)");
    sub->add_option("--recorded-at", arguments->recorded_at,
                    "With --add: when the trace was recorded, ISO 8601 UTC (default: the trace file's modification "
                    "time)");
    sub->add_option("--pin", arguments->pin,
                    "Store a new baseline for the run's machine and axis starting at run ID (e.g. after maintenance)");
    sub->add_option("--baseline-from", arguments->baseline_from,
                    "For this listing only: the baseline starts at run ID");
    sub->add_option("--baseline-runs", arguments->trend.baseline_runs, "Runs in the baseline")
        ->capture_default_str()
        ->check(allowed_range(1, 1000, "runs"));
    sub->add_option("--cusum-k", arguments->trend.cusum_k, "CUSUM allowance [combined standard errors]")
        ->capture_default_str()
        ->check(allowed_range(0.0, 100.0, "combined standard errors"));
    sub->add_option("--cusum-h", arguments->trend.cusum_h, "CUSUM alarm threshold [combined standard errors]")
        ->capture_default_str()
        ->check(allowed_range(1e-3, 1000.0, "combined standard errors"));
    sub->footer(
        "Trend: each run's change against the baseline (mean of the first --baseline-runs runs of the axis, or of the\n"
        "runs from a pinned one) in units of the combined standard error, where a run's error is the larger of its\n"
        "reported standard error and the baseline runs' own scatter; a two-sided CUSUM per parameter raises the "
        "alarm.\n"
        "Examples:\n"
        "  feedid identify x.csv --json - --record shop.db --machine DMU50 --axis X\n"
        "  feedid history shop.db --add result.json --machine DMU50 --axis X --recorded-at 2026-11-23T09:00:00Z\n"
        "  feedid history shop.db --machine DMU50 --axis X\n"
        "  feedid history shop.db --check          # nightly: exit 1 and name machine, axis, parameter, run on drift\n"
        "  feedid history shop.db --pin 42        # after maintenance: baseline starts again at run 42\n"
        "  feedid history shop.db --verify        # the whole file: SQLite's integrity check, every stored document\n"
        "  feedid history --copy cell7.db postgresql://feedid@plant-db/history   # the edge device's runs upward");
    return [arguments, json, csv] {
        if (json->count() > 0 && arguments->json_path.empty()) arguments->json_path = "-";
        if (csv->count() > 0 && arguments->csv_path.empty()) arguments->csv_path = "-";
        return run_history(*arguments);
    };
}

}  // namespace feedid::cli
