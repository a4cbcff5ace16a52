// The history at plant scale, timed as users run it: each iteration starts the feedid binary (or Python) afresh
// and waits for it; wall time per run, peak resident memory of the process (wait4's ru_maxrss), the alarms it
// printed and, for the report, the size of the HTML file. Targets (issue 14):
//   - `feedid history DB --check` on 100,000 runs in under 0.5x the time of the same check written with Python's
//     sqlite3 and pandas (bench/history_check.py, run here side by side on the same file), under 200 MB peak;
//   - `feedid report DB -o r.html` on 10,000 runs in under 1 s and under 3 MB of HTML (one machine's 3 axes, and four
//     machines' 12 axes).
// The histories are recorded through the store itself (HistoryStore::add_run, one transaction per run as `feedid
// history --record` does) from one real identify result (the demo drive, synthesised and identified here), each run
// with its own values: noise of 0.2 % and, on every tenth axis, Coulomb friction rising over the last tenth of its
// runs. They are kept in the build tree (bench-data/) and made once: 100,000 runs take a few minutes to record.
// Issue 18: the same `--check` on the 120-axis history of 100,000 runs in PostgreSQL, within 2x of SQLite's. The
// server is started as the tests start theirs (tests/support/postgres_server.hpp), its cluster kept in bench-data/pg so that
// the database is recorded once, through the same store interface.
#include <benchmark/benchmark.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "feedid/history/store.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/sim/synth.hpp"
#include "postgres_server.hpp"
#include "run_program.hpp"

namespace {

namespace fs = std::filesystem;
namespace history = feedid::history;
using feedid::bench::Outcome;
using feedid::bench::run;

/// A history to benchmark: machines x axes, each with its share of the runs.
struct Composition {
    std::string name;
    int machines{1};
    int axes{1};
    int runs{0};

    [[nodiscard]] fs::path path() const {
        return fs::path(FEEDID_BENCH_DATA) / fmt::format("history-{}-{}x{}.db", runs, machines, axes);
    }
};

const Composition plant{"plant", 40, 3, 100'000};       // 120 axes of 833 or 834 runs each
const Composition one_axis{"one-axis", 1, 1, 100'000};  // the worst case for memory: one series of 100,000
const Composition machine{"machine", 1, 3, 10'000};     // one machine's report: 3 axes of 3,333 or 3,334 runs
const Composition workshop{"workshop", 4, 3, 10'000};   // four machines: 12 axes of 833 or 834 runs

/// The run record of a real identify result: the demo drive's trace synthesised and identified.
history::RunRecord template_run() {
    const feedid::Trace trace = feedid::synthesize(feedid::demo_spec());
    feedid::IdentifyOptions options;
    options.drive.force_constant_name = "force_constant_N_per_A";
    feedid::IdentifyResult result = feedid::identify(trace, options);
    result.options = feedid::identify_options_document(options, nlohmann::json::object());
    const nlohmann::json document = result;
    return history::run_from_result(document, "bench");
}

std::string day_stamp(int day, int minute) {
    using namespace std::chrono;
    const year_month_day date{sys_days{year{2020} / January / 1} + days{day}};
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:00.000Z", static_cast<int>(date.year()),
                       static_cast<unsigned>(date.month()), static_cast<unsigned>(date.day()), minute / 60,
                       minute % 60);
}

/// Records the composition's runs into an empty store, one transaction each.
void record_composition(history::HistoryStore& store, const Composition& composition) {
    const history::RunRecord base = template_run();
    std::mt19937 generator(14);
    std::normal_distribution<double> noise(0.0, 0.002);
    const int series = composition.machines * composition.axes;
    for (int s = 0; s < series; ++s) {
        const int count = composition.runs / series + (s < composition.runs % series ? 1 : 0);
        for (int i = 0; i < count; ++i) {
            history::RunRecord run = base;
            run.machine = fmt::format("M{:02}", s / composition.axes + 1);
            run.axis = std::string(1, "XYZABC"[s % composition.axes]);
            run.recorded_at = day_stamp(i, s);
            run.trace_path = fmt::format("traces/{}-{}-{}.csv", run.machine, run.axis, i);
            run.trace_sha256 = fmt::format("{:064x}", static_cast<unsigned long long>(s) * 1'000'000u + i);
            const bool drifting = s % 10 == 3 && i > count * 9 / 10;
            for (auto& [key, estimate] : run.parameters) {
                if (!estimate.value) continue;
                double factor = 1.0 + noise(generator);
                if (drifting && key.starts_with("coulomb")) factor += 0.0005 * (i - count * 9 / 10);
                *estimate.value *= factor;
            }
            store.add_run(run);
        }
    }
}

/// The runs a history holds (0 when it cannot be read).
std::size_t recorded_runs(const std::string& location) {
    std::size_t recorded = 0;
    try {
        for (const auto& series : history::open_store(location, {true, false})->series()) recorded += series.size();
    } catch (const std::exception&) {
        return 0;
    }
    return recorded;
}

/// Records the composition's history through the store (once: an existing file with all its runs is kept).
const fs::path& history_file(const Composition& composition) {
    static std::map<std::string, fs::path> made;
    if (const auto found = made.find(composition.name); found != made.end()) return found->second;
    const fs::path path = composition.path();
    fs::create_directories(path.parent_path());
    if (!fs::exists(path) || recorded_runs(path.string()) != static_cast<std::size_t>(composition.runs)) {
        fs::remove(path);
        fmt::print(stderr, "bench_history: recording {} runs into {} (once) ...\n", composition.runs, path.string());
        record_composition(*history::open_sqlite_store(path), composition);
    }
    return made.emplace(composition.name, path).first->second;
}

/// The benchmark's PostgreSQL server (kept in bench-data/pg between runs), started on first use.
feedid::testing::PostgresServer& bench_server() {
    static feedid::testing::PostgresServer server(fs::path(FEEDID_BENCH_DATA) / "pg", true);
    return server;
}

/// The composition's history in a database of the benchmark's server (recorded once, as history_file does). "" when
/// no server can run here.
std::string history_database(const Composition& composition) {
    static std::map<std::string, std::string> made;
    if (const auto found = made.find(composition.name); found != made.end()) return found->second;
    if (!bench_server().available()) return {};
    const std::string name = fmt::format("history_{}_{}x{}", composition.runs, composition.machines, composition.axes);
    std::string location = bench_server().database(name);
    if (recorded_runs(location) != static_cast<std::size_t>(composition.runs)) {
        bench_server().execute("DROP DATABASE " + name);
        location = bench_server().database(name);
        fmt::print(stderr, "bench_history: recording {} runs into {} (once) ...\n", composition.runs, location);
        record_composition(*history::open_store(location), composition);
    }
    return made.emplace(composition.name, location).first->second;
}

/// The lines that start with "drift alarm:" (feedid's and the Python check's alarm lines).
int alarm_lines(const std::string& out) {
    int alarms = out.starts_with("drift alarm:") ? 1 : 0;
    for (std::size_t at = out.find("\ndrift alarm:"); at != std::string::npos; at = out.find("\ndrift alarm:", at + 1))
        ++alarms;
    return alarms;
}

/// Times a program over the benchmark's iterations; counters: peak memory (largest), alarms printed.
void time_program(benchmark::State& state, const std::vector<std::string>& argv, int expected_exit) {
    double peak = 0.0;
    int alarms = 0;
    for (auto _ : state) {
        const Outcome outcome = run(argv);
        if (outcome.exit_code != expected_exit && outcome.exit_code != 0) {
            state.SkipWithError(fmt::format("{} exited with {}", argv[0], outcome.exit_code).c_str());
            return;
        }
        state.SetIterationTime(outcome.seconds);
        peak = std::max(peak, outcome.peak_megabytes);
        alarms = alarm_lines(outcome.out);
    }
    state.counters["peak_MB"] = peak;
    state.counters["alarms"] = alarms;
}

void BM_HistoryCheck_feedid(benchmark::State& state, const Composition& composition) {
    time_program(state, {FEEDID_CLI, "history", history_file(composition).string(), "--check"}, 1);
}

void BM_HistoryCheck_feedid_postgresql(benchmark::State& state, const Composition& composition) {
    const std::string location = history_database(composition);
    if (location.empty()) {
        state.SkipWithError(("no PostgreSQL server: " + bench_server().why_not()).c_str());
        return;
    }
    time_program(state, {FEEDID_CLI, "history", location, "--check"}, 1);
}

void BM_HistoryCheck_python(benchmark::State& state, const Composition& composition) {
    if (run({"/usr/bin/python3", "-c", "import pandas"}).exit_code != 0) {
        state.SkipWithError("the Python check needs python3-pandas (scripts/setup.sh --extra installs it)");
        return;
    }
    time_program(state,
                 {"/usr/bin/python3", FEEDID_SOURCE_DIR "/bench/history_check.py", history_file(composition).string()},
                 1);
}

void BM_Report(benchmark::State& state, const Composition& composition) {
    const fs::path html = fs::path(FEEDID_BENCH_DATA) / fmt::format("report-{}.html", composition.name);
    time_program(state, {FEEDID_CLI, "report", history_file(composition).string(), "-o", html.string()}, 0);
    state.counters["html_MB"] = static_cast<double>(fs::file_size(html)) / 1e6;
    state.counters.erase("alarms");  // a report prints none
}

// Python first, then feedid, for each history: side by side in one run of this program.
BENCHMARK_CAPTURE(BM_HistoryCheck_python, plant_100k, plant)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(10);
BENCHMARK_CAPTURE(BM_HistoryCheck_feedid, plant_100k, plant)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(10);
BENCHMARK_CAPTURE(BM_HistoryCheck_feedid_postgresql, plant_100k, plant)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(10);
BENCHMARK_CAPTURE(BM_HistoryCheck_python, one_axis_100k, one_axis)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(10);
BENCHMARK_CAPTURE(BM_HistoryCheck_feedid, one_axis_100k, one_axis)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(10);
BENCHMARK_CAPTURE(BM_Report, machine_10k, machine)->UseManualTime()->Unit(benchmark::kMillisecond)->Iterations(10);
BENCHMARK_CAPTURE(BM_Report, workshop_10k, workshop)->UseManualTime()->Unit(benchmark::kMillisecond)->Iterations(10);

}  // namespace

BENCHMARK_MAIN();
