// Fingerprint runs in the history: feedid synth --backlash (the truth), feedid fingerprint --record beside the
// identifications, feedid history --check. Eight runs at 4 um of backlash form the baseline; then it grows by 2 um per
// run to 12 um and stays there: the backlash alarm fires at the first grown run, the lost motion (its scatter over the
// reversals' speeds is wider) before the series ends, the stiffness (unchanged, 200 N/um) never; the same series at a
// constant 4 um raises nothing. A history of schema 5 opens, takes fingerprint runs and keeps the two kinds' trends
// apart.

#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <map>
#include <thread>
#include <vector>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/history/store.hpp"
#include "feedid/history/trend.hpp"
#include "feedid/identify/fingerprint.hpp"
#include "feedid/sim/synth.hpp"
#include "feedid/sim/transmission_synth.hpp"
#include "history_testing.hpp"
#include "postgres_testing.hpp"
#include "testing.hpp"

namespace {

using namespace feedid;
using namespace feedid::testing;

constexpr double stiffness_N_per_um = 200.0;

/// Backlash of run i (1-based) [um]: 4 for the baseline's eight runs, then 6, 8, 10, 12, 12, 12.
double growing_backlash(int i) { return i <= 8 ? 4.0 : std::min(12.0, 4.0 + 2.0 * (i - 8)); }

constexpr int runs_per_series = 14;

/// Synthesises the trace of run i of the series kept in `database`.
std::filesystem::path record_run(const std::filesystem::path& folder, const std::filesystem::path& database, int i,
                                 double backlash_um) {
    const auto trace = folder / fmt::format("{}-{:02}.csv", database.stem().string(), i);
    const auto synth = run_shell(fmt::format("{} synth --backlash {} --stiffness {} --seed {} --out {}", cli(),
                                             backlash_um, stiffness_N_per_um, 100 + i, quoted(trace)),
                                 folder);
    EXPECT_EQ(synth.exit_code, 0) << synth.err;
    return trace;
}

struct Series {
    std::filesystem::path database;
    nlohmann::json history;  // feedid history --json
    int check_exit{0};
};

Series record_series(const std::filesystem::path& folder, const std::string& name, bool growing) {
    Series series;
    series.database = folder / (name + ".db");
    std::vector<std::filesystem::path> traces(runs_per_series);
    std::vector<std::thread> workers;
    for (int w = 0; w < 2; ++w)
        workers.emplace_back([&, w] {
            for (int i = 1 + w; i <= runs_per_series; i += 2)
                traces[static_cast<std::size_t>(i - 1)] =
                    record_run(folder, series.database, i, growing ? growing_backlash(i) : 4.0);
        });
    for (auto& worker : workers) worker.join();
    for (int i = 1; i <= runs_per_series; ++i) {  // recorded in order: one day each
        const auto recorded = run_shell(
            fmt::format("{} fingerprint {} --force-constant force_constant_N_per_A --axis X --record {} --machine "
                        "'DMU 50' --recorded-at 2026-11-{:02}T06:00:00Z",
                        cli(), quoted(traces[static_cast<std::size_t>(i - 1)]), quoted(series.database), i),
            folder);
        EXPECT_EQ(recorded.exit_code, 0) << recorded.err;
        EXPECT_NE(recorded.err.find(fmt::format("recorded as run #{}", i)), std::string::npos) << recorded.err;
    }
    const auto check = run_shell(fmt::format("{} history {} --check", cli(), quoted(series.database)), folder);
    series.check_exit = check.exit_code;
    const auto listing = run_shell(fmt::format("{} history {} --json -", cli(), quoted(series.database)), folder);
    EXPECT_EQ(listing.exit_code, 0) << listing.err;
    series.history = nlohmann::json::parse(listing.out);
    return series;
}

/// The first alarm of each parameter: parameter -> alarm document.
std::map<std::string, nlohmann::json> first_alarms(const nlohmann::json& trend) {
    std::map<std::string, nlohmann::json> first;
    for (const auto& alarm : trend["alarms"]) first.emplace(alarm["parameter"].get<std::string>(), alarm);
    return first;
}

}  // namespace

TEST(FingerprintHistory, GrowingBacklashRaisesTheAlarmAndAConstantOneDoesNot) {
    const auto folder = temp_dir();
    const Series growing = record_series(folder, "growing", true);
    const Series constant = record_series(folder, "constant", false);

    // Every run is a fingerprint run of the axis, its backlash within 10 % and 4 standard errors of the truth.
    ASSERT_EQ(growing.history["runs"].size(), static_cast<std::size_t>(runs_per_series));
    for (const auto& run : growing.history["runs"]) {
        EXPECT_EQ(run["model"], "fingerprint");
        const int i = run["id"].get<int>();
        const double truth = growing_backlash(i) * 1e-6;
        const auto& backlash = run["parameters"]["backlash_m"];
        ASSERT_TRUE(backlash["value"].is_number()) << "run " << i;
        const double error = std::abs(backlash["value"].get<double>() - truth);
        EXPECT_LE(error, 0.10 * truth) << "run " << i;
        EXPECT_LE(error, 4.0 * backlash["stderr"].get<double>()) << "run " << i;
        const double stiffness = run["parameters"]["stiffness_N_per_m"]["value"].get<double>();
        EXPECT_NEAR(stiffness, stiffness_N_per_um * 1e6, 0.10 * stiffness_N_per_um * 1e6) << "run " << i;
    }

    ASSERT_EQ(growing.history["trends"].size(), 1u);
    const auto& trend = growing.history["trends"][0];
    EXPECT_EQ(trend["kind"], "fingerprint");
    EXPECT_EQ(growing.check_exit, 1);
    const auto alarms = first_alarms(trend);
    ASSERT_TRUE(alarms.count("backlash_m")) << trend["alarms"].dump();
    const auto& backlash = alarms.at("backlash_m");
    EXPECT_EQ(backlash["run"], 9);  // the first grown run: 2 um on a standard error of nanometres
    EXPECT_EQ(backlash["direction"], "up");
    EXPECT_NEAR(backlash["change"].get<double>(), 2e-6, 0.2e-6);
    EXPECT_GT(backlash["sigma"].get<double>(), 0.0);
    EXPECT_LT(backlash["sigma"].get<double>(), 0.1e-6);
    EXPECT_EQ(backlash["baseline_runs"], nlohmann::json({1, 2, 3, 4, 5, 6, 7, 8}));
    const std::string message = backlash["message"].get<std::string>();
    for (const char* part : {"machine 'DMU 50' axis 'X' parameter backlash_m at run #9", "rose by +",
                             " ± ", "from the baseline of runs #1..#8"})
        EXPECT_NE(message.find(part), std::string::npos) << part << " not in: " << message;
    // The lost motion grows with the backlash and alarms too, later: its per-run standard error is the scatter over
    // the reversals at 20 to 2000 mm/min (about 1.5 um), not the noise.
    ASSERT_TRUE(alarms.count("lost_motion_m")) << trend["alarms"].dump();
    EXPECT_GT(alarms.at("lost_motion_m")["run"].get<int>(), 9);
    EXPECT_EQ(alarms.at("lost_motion_m")["direction"], "up");
    for (const char* unchanged : {"stiffness_N_per_m", "stiffness_forward_N_per_m", "stiffness_reverse_N_per_m"})
        EXPECT_FALSE(alarms.count(unchanged)) << unchanged << ": " << trend["alarms"].dump();

    EXPECT_EQ(constant.check_exit, 0);
    ASSERT_EQ(constant.history["trends"].size(), 1u);
    EXPECT_TRUE(constant.history["trends"][0]["alarms"].empty()) << constant.history["trends"][0]["alarms"].dump();
}

namespace {

/// A fingerprint run of a synthetic axis, recorded by hand (the library's path of --record).
history::RunRecord fingerprint_run(const std::string& sha) {
    SynthSpec spec = demo_spec();
    spec.seed = 3;
    TransmissionModel transmission;
    transmission.backlash_m = 6e-6;
    const Trace trace = synthesize_with_transmission(spec, transmission);
    FingerprintOptions options;
    options.drive.force_constant = spec.force_constant_N_per_A();
    nlohmann::json document = fingerprint_document(fingerprint(trace, options));
    document["trace"] = {{"path", "rev.csv"}};
    auto run = history::run_from_result(document, "rev.json");  // a fingerprint document goes its own way
    run.machine = "DMU 50";
    run.axis = "X";
    run.recorded_at = "2026-03-02T06:00:00Z";
    run.trace_sha256 = sha;
    return run;
}

history::RunRecord identification_run(const std::string& sha) {
    history::RunRecord run;
    run.machine = "DMU 50";
    run.axis = "X";
    run.recorded_at = "2026-03-01T06:00:00Z";
    run.trace_path = "x.csv";
    run.trace_sha256 = sha;
    run.feedid_version = "0.1.0";
    run.model = "symmetric";
    run.parameters["coulomb_N"] = {742.0, 0.4};
    run.parameters["breakaway_N"] = {946.0, 2.0};
    return run;
}

}  // namespace

TEST(FingerprintHistory, AnOlderHistoryOpensTakesFingerprintRunsAndKeepsTheKindsApart) {
    const auto path = temp_dir() / "h.db";
    {
        history::SqliteOpenOptions old;
        old.target_schema_version = 5;
        auto store = history::open_sqlite_store(path, old);
        EXPECT_EQ(store->schema_version(), 5);
        store->add_run(identification_run("aa"));
    }
    {
        history::SqliteOpenOptions read_only;
        read_only.read_only = true;
        const auto store = history::open_sqlite_store(path, read_only);  // reading does not migrate
        EXPECT_EQ(store->schema_version(), 5);
        EXPECT_EQ(store->runs().size(), 1u);
    }
    auto store = history::open_sqlite_store(path);
    EXPECT_EQ(store->schema_version(), 6);
    const auto fingerprint = fingerprint_run("bb");
    EXPECT_EQ(fingerprint.model, "fingerprint");
    EXPECT_EQ(fingerprint.axis_kind, "linear");
    EXPECT_FALSE(fingerprint.parameters.count("breakaway_N"));  // the identification's key: not stored
    ASSERT_TRUE(fingerprint.parameters.at("backlash_m").value);
    EXPECT_NEAR(*fingerprint.parameters.at("backlash_m").value, 6e-6, 0.6e-6);
    EXPECT_TRUE(store->add_run(fingerprint).inserted);
    EXPECT_FALSE(store->add_run(fingerprint).inserted);  // the same trace fingerprinted alike: once

    const auto runs = store->runs();
    ASSERT_EQ(runs.size(), 2u);
    EXPECT_FALSE(history::is_fingerprint_run(runs[0]));
    EXPECT_TRUE(history::is_fingerprint_run(runs[1]));
    EXPECT_EQ(store->result_document(runs[1].id)["reversals"]["forward"], fingerprint.result["reversals"]["forward"]);

    // Both readings of the trend (the store's series, the listing's runs) give two series: the identification's
    // without fingerprint figures, the fingerprint's without friction.
    for (const auto& trends : {history::analyse_trends(store->series(), store->pins(), {}),
                               history::analyse_trends(runs, store->pins(), {})}) {
        ASSERT_EQ(trends.size(), 2u);
        EXPECT_EQ(trends[0].kind, "identification");
        EXPECT_EQ(trends[1].kind, "fingerprint");
        EXPECT_EQ(trends[0].baseline_run_ids, std::vector<std::int64_t>{runs[0].id});
        EXPECT_EQ(trends[1].baseline_run_ids, std::vector<std::int64_t>{runs[1].id});
        for (const auto& parameter : trends[0].parameters) EXPECT_EQ(parameter.key.find("backlash"), std::string::npos);
        for (const auto& parameter : trends[1].parameters) EXPECT_EQ(parameter.key.find("coulomb"), std::string::npos);
    }
    // A pin on the identification run starts the fingerprint's baseline at its first run from then on.
    store->pin_baseline("DMU 50", "X", runs[0].id);
    const auto pinned = history::analyse_trends(store->series(), store->pins(), {});
    ASSERT_EQ(pinned.size(), 2u);
    EXPECT_EQ(pinned[1].pinned_run, runs[1].id);
    EXPECT_TRUE(pinned[1].notes.empty() || pinned[1].notes[0].find("not among") == std::string::npos);
}

TEST(FingerprintHistory, ADocumentThatIsNotAFingerprintIsRefusedNamingTheKey) {
    nlohmann::json document = {{"fingerprint", {{"lost_motion_m", {{"value", "wide"}, {"stderr", nullptr}}}}}};
    try {
        (void)history::run_from_result(document, "odd.json");
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("odd.json"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("fingerprint"), std::string::npos) << e.what();
    }
}

// Both backends store fingerprint runs beside the identifications and read them back as two trends; PostgreSQL's
// dashboards get a series view per fingerprint figure (schema 3).
class FingerprintHistoryOn : public HistoryBackendTest {};
INSTANTIATE_TEST_SUITE_P(Backends, FingerprintHistoryOn, ::testing::Values(Backend::sqlite, Backend::postgresql),
                         backend_name);

TEST_P(FingerprintHistoryOn, FingerprintRunsAreStoredBesideIdentificationsAndTrendApart) {
    const auto location = new_location();
    auto store = open(location);
    EXPECT_EQ(store->schema_version(),
              postgresql() ? history::postgres_schema_version : history::sqlite_schema_version);
    store->add_run(identification_run("aa"));
    const auto fingerprint = fingerprint_run("bb");
    EXPECT_TRUE(store->add_run(fingerprint).inserted);
    const auto trends = history::analyse_trends(store->series(), store->pins(), {});
    ASSERT_EQ(trends.size(), 2u);
    EXPECT_EQ(trends[0].kind, "identification");
    EXPECT_EQ(trends[1].kind, "fingerprint");
    const auto runs = store->runs();
    ASSERT_EQ(runs.size(), 2u);
    EXPECT_EQ(runs[1].parameters.at("backlash_m").value, fingerprint.parameters.at("backlash_m").value);
    if (postgresql()) {
        const auto database = location.substr(location.rfind('/') + 1);
        for (const auto& key : history::fingerprint_parameter_keys()) {
            std::string view = "series_" + key;
            for (auto& c : view) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
            const bool linear_key = fingerprint.parameters.count(key) > 0;
            EXPECT_EQ(test_server().value(fmt::format("SELECT count(*) FROM {}", view), database),
                      linear_key ? "1" : "0")
                << view;
        }
        EXPECT_NEAR(std::stod(test_server().value("SELECT value FROM series_backlash_m", database)),
                    *fingerprint.parameters.at("backlash_m").value, 1e-15);
    }
}
