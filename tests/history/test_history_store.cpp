// The history store: round trip, duplicates, migrations, durability under a forced abort between statements,
// and two processes recording at the same time. The tests of the store's contract run on both backends (SQLite and
// PostgreSQL, postgres_testing.hpp); those of the SQLite file itself (migrations of older files, its integrity check)
// on SQLite.

#include <gtest/gtest.h>

#include <sqlite3.h>

#include <algorithm>
#include <csignal>
#include <functional>
#include <map>
#include <set>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/history/sha256.hpp"
#include "feedid/history/store.hpp"
#include "feedid/history/trend.hpp"
#include "history_testing.hpp"
#include "postgres_testing.hpp"
#include "testing.hpp"

namespace {

using namespace feedid::testing;
namespace history = feedid::history;

history::RunRecord sample_run(const std::string& sha, double coulomb) {
    history::RunRecord run;
    run.machine = "DMU 50";
    run.axis = "X";
    run.location = "Aachen";
    run.recorded_at = "2026-03-01T06:00:00.000Z";
    run.trace_path = "x.csv";
    run.trace_sha256 = sha;
    run.feedid_version = "0.1.0";
    run.model = "symmetric";
    run.status = "partial";
    run.options = {{"model", "symmetric"}};
    run.parameters["coulomb_N"] = {coulomb, 0.4};
    run.parameters["mass_kg"] = {69.1, 0.3};
    run.parameters["breakaway_N"] = {std::nullopt, std::nullopt};
    run.fit = {{"relative_error_pct", 1.7}};
    run.diagnostics = {"Stribeck: no slow passes"};
    run.result = {{"friction_curve", {{"forward", {{"velocity_m_per_s", {0.01, 0.1}}, {"force_N", {750.0, 752.0}}}}}}};
    return run;
}

/// PRAGMA integrity_check of a file, through SQLite itself (read-only).
std::string integrity(const std::filesystem::path& path) {
    sqlite3* db = nullptr;
    if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
        sqlite3_close(db);
        return "cannot open";
    }
    sqlite3_stmt* statement = nullptr;
    std::string result = "cannot check";
    if (sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &statement, nullptr) == SQLITE_OK &&
        sqlite3_step(statement) == SQLITE_ROW)
        result = reinterpret_cast<const char*>(sqlite3_column_text(statement, 0));
    sqlite3_finalize(statement);
    sqlite3_close(db);
    return result;
}

class HistoryStoreOn : public HistoryBackendTest {};
INSTANTIATE_TEST_SUITE_P(Backends, HistoryStoreOn, ::testing::Values(Backend::sqlite, Backend::postgresql),
                         backend_name);

TEST_P(HistoryStoreOn, RoundTripKeepsEveryField) {
    const auto location = new_location();
    {
        auto store = open(location);
        EXPECT_EQ(store->schema_version(),
                  postgresql() ? history::postgres_schema_version : history::sqlite_schema_version);
        const auto outcome = store->add_run(sample_run("aa", 742.0));
        EXPECT_TRUE(outcome.inserted);
    }
    const auto store = open(location, true);
    const auto runs = store->runs();
    ASSERT_EQ(runs.size(), 1u);
    const auto& run = runs[0];
    EXPECT_EQ(run.machine, "DMU 50");
    EXPECT_EQ(run.axis, "X");
    EXPECT_EQ(run.location, "Aachen");
    EXPECT_EQ(run.recorded_at, "2026-03-01T06:00:00.000Z");
    EXPECT_EQ(run.trace_sha256, "aa");
    EXPECT_EQ(run.status, "partial");
    EXPECT_EQ(run.options, (nlohmann::json{{"model", "symmetric"}}));
    ASSERT_EQ(run.parameters.size(), 3u);
    EXPECT_DOUBLE_EQ(*run.parameters.at("coulomb_N").value, 742.0);
    EXPECT_DOUBLE_EQ(*run.parameters.at("coulomb_N").standard_error, 0.4);
    EXPECT_FALSE(run.parameters.at("breakaway_N").value);
    EXPECT_FALSE(run.parameters.at("breakaway_N").standard_error);
    EXPECT_EQ(run.fit["relative_error_pct"], 1.7);
    EXPECT_EQ(run.diagnostics, std::vector<std::string>{"Stribeck: no slow passes"});
    EXPECT_EQ(run.result["friction_curve"]["forward"]["force_N"][1], 752.0);
    EXPECT_FALSE(run.stored_at.empty());
    EXPECT_THROW(store->add_run(sample_run("bb", 1.0)), feedid::InputError);  // opened read-only
}

TEST_P(HistoryStoreOn, SameTraceWithSameOptionsIsNotAddedTwice) {
    auto store = open(new_location());
    const auto first = store->add_run(sample_run("aa", 742.0));
    const auto again = store->add_run(sample_run("aa", 742.0));
    EXPECT_FALSE(again.inserted);
    EXPECT_EQ(again.id, first.id);
    auto other_options = sample_run("aa", 742.0);
    other_options.options = {{"model", "asymmetric"}};
    EXPECT_TRUE(store->add_run(other_options).inserted);
    EXPECT_EQ(store->runs().size(), 2u);
}

TEST_P(HistoryStoreOn, PinsCheckMachineAndAxis) {
    auto store = open(new_location());
    const auto id = store->add_run(sample_run("aa", 742.0)).id;
    EXPECT_THROW(store->pin_baseline("DMU 50", "Y", id), feedid::InputError);
    EXPECT_THROW(store->pin_baseline("DMU 50", "X", id + 100), feedid::InputError);
    store->pin_baseline("DMU 50", "X", id);
    ASSERT_EQ(store->pins().size(), 1u);
    EXPECT_EQ(store->pins()[0].run_id, id);
}

TEST(HistoryStore, MigratesAnOlderFileAndKeepsItsRuns) {
    const auto folder = temp_dir();
    const auto path = folder / "h.db";
    {
        history::SqliteOpenOptions old;
        old.target_schema_version = 2;
        auto store = history::open_sqlite_store(path, old);
        EXPECT_EQ(store->schema_version(), 2);
        store->add_run(sample_run("aa", 742.0));
        EXPECT_TRUE(store->runs()[0].result.empty());  // schema 2 keeps no result document
    }
    {
        history::SqliteOpenOptions read_only;
        read_only.read_only = true;
        const auto store = history::open_sqlite_store(path, read_only);  // reading does not migrate
        EXPECT_EQ(store->schema_version(), 2);
        EXPECT_EQ(store->runs().size(), 1u);
    }
    auto store = history::open_sqlite_store(path);
    EXPECT_EQ(store->schema_version(), history::sqlite_schema_version);
    store->add_run(sample_run("bb", 743.0));
    const auto runs = store->runs();
    ASSERT_EQ(runs.size(), 2u);
    EXPECT_DOUBLE_EQ(*runs[0].parameters.at("coulomb_N").value, 742.0);
    EXPECT_TRUE(runs[0].result.empty());
    EXPECT_EQ(runs[1].result["friction_curve"]["forward"]["force_N"][0], 750.0);
    EXPECT_EQ(integrity(path), "ok");
}

// Schema 5 moves the documents out of the runs table and gives the fit's figures and each parameter's systematic
// error and uncertainty typed columns; runs stored before keep everything, their figures taken from fit_json.
TEST(HistoryStore, MigrationToSchemaFiveKeepsEveryDocumentAndTypesTheFit) {
    const auto folder = temp_dir();
    const auto path = folder / "h.db";
    {
        history::SqliteOpenOptions old;
        old.target_schema_version = 4;
        auto store = history::open_sqlite_store(path, old);
        auto run = sample_run("aa", 742.0);
        run.fit = {{"relative_error_pct", 1.7}, {"condition_number", 26.0}, {"samples_used", 2066}};
        store->add_run(run);
    }
    {
        history::SqliteOpenOptions read_only;
        read_only.read_only = true;
        const auto store = history::open_sqlite_store(path, read_only);  // reading does not migrate
        EXPECT_EQ(store->schema_version(), 4);
        const auto summary = store->runs({}, history::RunDetail::summary);
        EXPECT_EQ(summary[0].fit_figures.condition_number, 26.0);  // from fit_json, in SQL
    }
    history::SqliteOpenOptions to_five;  // this migration alone (schema 6 has its own test)
    to_five.target_schema_version = 5;
    auto store = history::open_sqlite_store(path, to_five);
    EXPECT_EQ(store->schema_version(), 5);
    auto second = sample_run("bb", 743.0);
    second.parameters["coulomb_N"] = {743.0, 0.4, 1.5, 1.6};
    store->add_run(second);
    const auto runs = store->runs();
    ASSERT_EQ(runs.size(), 2u);
    EXPECT_EQ(runs[0].fit_figures.relative_error_pct, 1.7);
    EXPECT_EQ(runs[0].fit_figures.condition_number, 26.0);
    EXPECT_EQ(runs[0].fit_figures.samples_used, 2066.0);
    EXPECT_EQ(runs[0].fit["condition_number"], 26.0);
    EXPECT_EQ(runs[0].diagnostics, std::vector<std::string>{"Stribeck: no slow passes"});
    EXPECT_EQ(runs[0].result["friction_curve"]["forward"]["force_N"][1], 752.0);
    EXPECT_EQ(store->result_document(runs[0].id), runs[0].result);
    EXPECT_FALSE(runs[0].parameters.at("coulomb_N").systematic);
    EXPECT_EQ(runs[1].parameters.at("coulomb_N").systematic, 1.5);
    EXPECT_EQ(runs[1].parameters.at("coulomb_N").uncertainty, 1.6);
    EXPECT_EQ(runs[1].fit_figures.relative_error_pct, 1.7);  // a record made by hand: from its fit object
    EXPECT_TRUE(store->verify().empty());
    EXPECT_EQ(integrity(path), "ok");
}

// The compact series the trend reads hold what the full listing holds, and give the same trend.
TEST_P(HistoryStoreOn, SeriesHoldWhatTheListingHolds) {
    auto store = open(new_location());
    for (int i = 0; i < 30; ++i) {
        auto run = sample_run(fmt::format("sha-{}", i), 742.0 + (i >= 20 ? 5.0 : 0.1 * (i % 3)));
        run.machine = i % 3 == 0 ? "B" : "A";
        run.axis = i % 2 == 0 ? "X" : "Y";
        run.recorded_at = fmt::format("2026-03-{:02}T06:00:00.000Z", 1 + (i * 7) % 28);  // not in insertion order
        if (i % 5 == 0) run.parameters.erase("mass_kg");
        if (i == 7) run.options = {{"model", "asymmetric"}};
        store->add_run(run);
    }
    const auto series = store->series();
    const auto from_runs = history::series_of(store->runs({}, history::RunDetail::summary));
    ASSERT_EQ(series.size(), 4u);
    ASSERT_EQ(series.size(), from_runs.size());
    for (std::size_t s = 0; s < series.size(); ++s) {
        SCOPED_TRACE(series[s].machine + " " + series[s].axis);
        EXPECT_EQ(series[s].machine, from_runs[s].machine);
        EXPECT_EQ(series[s].axis, from_runs[s].axis);
        EXPECT_EQ(series[s].run_ids, from_runs[s].run_ids);
        EXPECT_EQ(series[s].recorded_at, from_runs[s].recorded_at);
        EXPECT_EQ(series[s].keys, from_runs[s].keys);
        for (std::size_t k = 0; k < series[s].keys.size(); ++k)
            for (std::size_t i = 0; i < series[s].size(); ++i)
                EXPECT_EQ(series[s].estimates[k][i].value, from_runs[s].estimates[k][i].value);
    }
    history::TrendOptions options;
    options.baseline_runs = 4;
    const auto a = history::analyse_trends(series, store->pins(), options);
    const auto b = history::analyse_trends(from_runs, store->pins(), options);
    options.keep_points = false;
    const auto c = history::analyse_trends(series, store->pins(), options);
    std::size_t alarms = 0;
    for (std::size_t s = 0; s < a.size(); ++s) {
        EXPECT_EQ(history::to_json(a[s]), history::to_json(b[s]));
        EXPECT_EQ(history::to_json(a[s])["alarms"], history::to_json(c[s])["alarms"]);
        EXPECT_EQ(history::to_json(a[s])["notes"], history::to_json(c[s])["notes"]);
        alarms += a[s].alarms.size();
    }
    EXPECT_GT(alarms, 0u);  // the step at run 20 is found
}

// Reading in pages (copy_history's bounded memory): every run once, in id order, with what the listing gives.
TEST_P(HistoryStoreOn, PagesInStorageOrderHoldWhatTheListingHolds) {
    auto store = open(new_location());
    for (int i = 0; i < 7; ++i) {
        auto run = sample_run(fmt::format("sha-{}", i), 742.0 + i);
        run.recorded_at = fmt::format("2026-03-{:02}T06:00:00.000Z", 10 - i);  // the listing's order is the reverse
        if (i == 3) run.parameters.erase("mass_kg");
        store->add_run(run);
    }
    std::map<std::int64_t, history::RunRecord> listed;
    for (auto& run : store->runs()) listed[run.id] = run;
    std::vector<std::int64_t> paged;
    std::size_t pages = 0;
    for (std::int64_t after = 0;; ++pages) {
        const auto page = store->runs_in_storage_order(after, 3);
        for (const auto& run : page) {
            paged.push_back(run.id);
            const auto& same = listed.at(run.id);
            EXPECT_EQ(history::to_json(run), history::to_json(same)) << "run #" << run.id;
            EXPECT_EQ(run.result, same.result);
        }
        if (page.empty()) break;
        after = page.back().id;
    }
    EXPECT_EQ(pages, 3u);
    ASSERT_EQ(paged.size(), 7u);
    EXPECT_TRUE(std::is_sorted(paged.begin(), paged.end()));
    EXPECT_EQ(paged.front(), listed.begin()->first);
}

/// sample_run as a rotary table's run: its parameters under the rotary keys.
history::RunRecord rotary_run(const std::string& sha) {
    auto run = sample_run(sha, 0.0);
    run.parameters.clear();
    run.parameters["inertia_kgm2"] = {0.0007, 1e-6};
    run.parameters["coulomb_Nm"] = {2.36, 0.001};
    run.axis_kind = "rotary";
    return run;
}

// What one backend refuses, none takes: a name or text that is not valid UTF-8, or holds a NUL (PostgreSQL refuses
// both), is refused on SQLite too, naming the field, and nothing is written; so both backends hold the same runs and
// `history --copy` never meets a run it cannot copy.
TEST_P(HistoryStoreOn, TextThatNotEveryBackendStoresIsRefusedOnBoth) {
    auto store = open(new_location());
    const auto refused = [&](const std::function<void(history::RunRecord&)>& change, const std::string& field) {
        auto run = sample_run("aa", 742.0);
        change(run);
        try {
            (void)store->add_run(run);
            ADD_FAILURE() << field << " was stored";
        } catch (const feedid::InputError& e) {
            EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
        }
    };
    refused([](auto& run) { run.machine = std::string("DMU\0 50", 7); }, "machine");
    refused([](auto& run) { run.machine = "DMU \xff"; }, "machine");
    refused([](auto& run) { run.axis = "X\xc3"; }, "axis");
    refused([](auto& run) { run.location = std::string("Aa\0chen", 7); }, "location");
    refused([](auto& run) { run.trace_path = "x\xed\xa0\x80.csv"; }, "trace path");
    refused([](auto& run) { run.diagnostics = {"bad \xff"}; }, "diagnostics");
    refused([](auto& run) { run.parameters["coulomb\xff"] = {1.0, 0.1}; }, "parameter key");
    EXPECT_TRUE(store->runs().empty());
    EXPECT_TRUE(store->add_run(sample_run("aa", 742.0)).inserted);  // and the store goes on
}

TEST_P(HistoryStoreOn, AnAxisHoldsRunsOfOneAxisKind) {
    auto store = open(new_location());
    const auto linear = store->add_run(sample_run("aa", 742.0));  // no axis_kind given: its keys say linear
    try {
        (void)store->add_run(rotary_run("bb"));
        ADD_FAILURE() << "a rotary run was recorded on a linear axis";
    } catch (const feedid::InputError& e) {
        const std::string message = e.what();
        for (const std::string& part :
             std::vector<std::string>{"machine 'DMU 50'", "axis 'X'", "is a linear axis",
                                      fmt::format("run #{}", linear.id), "this run is of a rotary axis"})
            EXPECT_NE(message.find(part), std::string::npos) << part << " in " << message;
    }
    EXPECT_EQ(store->runs().size(), 1u);  // nothing written
    auto on_c = rotary_run("bb");
    on_c.axis = "C";
    EXPECT_TRUE(store->add_run(on_c).inserted);
    EXPECT_TRUE(store->add_run(sample_run("cc", 743.0)).inserted);  // X stays linear
    auto linear_on_c = sample_run("dd", 742.0);
    linear_on_c.axis = "C";
    EXPECT_THROW((void)store->add_run(linear_on_c), feedid::InputError);
    const auto runs = store->runs();
    ASSERT_EQ(runs.size(), 3u);
    EXPECT_EQ(runs[0].axis_kind, "linear");
    EXPECT_EQ(runs[1].axis_kind, "rotary");
    EXPECT_EQ(runs[2].axis_kind, "linear");
}

TEST(HistoryStore, MigrationGivesEarlierRunsTheirAxisKind) {
    const auto folder = temp_dir();
    const auto path = folder / "h.db";
    {
        history::SqliteOpenOptions old;
        old.target_schema_version = 3;
        auto store = history::open_sqlite_store(path, old);
        store->add_run(sample_run("aa", 742.0));
        auto rotary = rotary_run("bb");
        rotary.axis = "C";
        store->add_run(rotary);
    }
    auto store = history::open_sqlite_store(path);
    EXPECT_EQ(store->schema_version(), history::sqlite_schema_version);
    const auto runs = store->runs();
    ASSERT_EQ(runs.size(), 2u);
    EXPECT_EQ(runs[0].axis_kind, "linear");
    EXPECT_EQ(runs[1].axis_kind, "rotary");
    EXPECT_THROW((void)store->add_run(rotary_run("cc")), feedid::InputError);  // X was linear before the migration
    EXPECT_EQ(integrity(path), "ok");
}

/// small_result() of a rotary axis: the same figures under the rotary keys, "rotary": true.
nlohmann::json small_rotary_result(const std::filesystem::path& trace) {
    auto document = small_result(trace, 2.36);
    nlohmann::json parameters;
    const std::map<std::string, std::string> rotary_keys{{"mass_kg", "inertia_kgm2"},
                                                         {"viscous_Ns_per_m", "viscous_Nms_per_rad"},
                                                         {"coulomb_N", "coulomb_Nm"},
                                                         {"breakaway_N", "breakaway_Nm"},
                                                         {"stribeck_velocity_m_per_s", "stribeck_velocity_rad_per_s"}};
    for (const auto& [key, entry] : document["parameters"].items()) parameters[rotary_keys.at(key)] = entry;
    document["parameters"] = parameters;
    document["rotary"] = true;
    return document;
}

TEST(HistoryStore, TheAxisKindComesFromTheResult) {
    auto document = small_result("x.csv", 742.0);
    EXPECT_EQ(history::run_from_result(document, "r.json").axis_kind, "linear");
    auto rotary = small_rotary_result("x.csv");
    EXPECT_EQ(history::run_from_result(rotary, "r.json").axis_kind, "rotary");
    rotary.erase("rotary");  // older documents: the keys say it
    EXPECT_EQ(history::run_from_result(rotary, "r.json").axis_kind, "rotary");
    // "rotary": true over linear keys is no document feedid writes (nor reads back): refused, naming the key
    document["rotary"] = true;
    try {
        (void)history::run_from_result(document, "r.json");
        ADD_FAILURE() << "a rotary document with linear keys was taken";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("r.json: parameter \"breakaway_N\""), std::string::npos) << e.what();
    }
}

class HistoryCliOn : public HistoryBackendTest {};
INSTANTIATE_TEST_SUITE_P(Backends, HistoryCliOn, ::testing::Values(Backend::sqlite, Backend::postgresql), backend_name);

TEST_P(HistoryCliOn, ARotaryRunOnALinearAxisIsExitTwo) {
    const auto folder = folder_;
    const auto results = write_small_results(folder, "run", 2);
    auto rotary = small_rotary_result(folder / "run-2.csv");
    write_text(results[1], rotary.dump());
    const auto database = new_location();
    const auto command = [&](const std::filesystem::path& result) {
        return run_shell(
            fmt::format("{} history '{}' --record {} --machine M1 --axis X", cli(), database, quoted(result)), folder);
    };
    ASSERT_EQ(command(results[0]).exit_code, 0);
    const auto refused = command(results[1]);
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_EQ(count_lines(refused.err), 1) << refused.err;
    for (const std::string part : {"machine 'M1'", "axis 'X'", "linear", "rotary"})
        EXPECT_NE(refused.err.find(part), std::string::npos) << part << " in " << refused.err;
}

TEST(HistoryStore, ResultDocumentIsStoredWithoutTheRlsHistory) {
    auto document = small_result("x.csv", 742.0);
    document["rls"] = {{"variant", "directional"},
                       {"forgetting_factor", 0.99995},
                       {"initial_covariance", 1e6},
                       {"final", {{"coulomb_N", 742.0}}},
                       {"averaged", {{"coulomb_N", 741.0}}},
                       {"settled", true},
                       {"transient_end_s", 0.5},
                       {"history", {{"time_s", {0.0, 0.1}}, {"coulomb_N", {700.0, 742.0}}}}};
    const auto run = history::run_from_result(document, "r.json");
    EXPECT_TRUE(run.result["rls"].contains("final"));
    EXPECT_FALSE(run.result["rls"].contains("history"));
    EXPECT_EQ(run.parameters.size(), 5u);
}

/// Records `results` one command each into `database`; expects success.
void record_all(const std::filesystem::path& folder, const std::string& database,
                const std::vector<std::filesystem::path>& results) {
    for (std::size_t i = 0; i < results.size(); ++i) {
        const auto r = run_shell(fmt::format("{} history {} --record {} --machine M1 --axis X "
                                             "--recorded-at 2026-03-{:02}T06:00:00Z",
                                             cli(), quoted(database), quoted(results[i]), i + 1),
                                 folder);
        ASSERT_EQ(r.exit_code, 0) << r.err;
    }
}

class HistoryDurabilityOn : public HistoryBackendTest {};
INSTANTIATE_TEST_SUITE_P(Backends, HistoryDurabilityOn, ::testing::Values(Backend::sqlite, Backend::postgresql),
                         backend_name);

// A process killed between any two statements of --record (FEEDID_TEST_ABORT_AFTER_STATEMENT=N aborts right after
// the N-th write statement: BEGIN, the run, its documents, each parameter (on PostgreSQL: all parameters in one),
// COMMIT) leaves a history that opens, holds every earlier run whole, and holds the interrupted run whole (aborted
// after COMMIT) or not at all.
TEST_P(HistoryDurabilityOn, AbortBetweenStatementsLeavesEveryEarlierRunAndTheNewOneWholeOrAbsent) {
    const auto folder = folder_;
    const auto results = write_small_results(folder, "run", 4);
    int aborted = 0;
    int whole = 0;
    for (int n = 1;; ++n) {
        ASSERT_LE(n, 30) << "the abort hook never let --record finish";
        const auto database = new_location(fmt::format("abort-{}", n));
        record_all(folder, database, {results[0], results[1], results[2]});
        const auto r = run_shell(fmt::format("FEEDID_TEST_ABORT_AFTER_STATEMENT={} {} history {} --record {} --machine "
                                             "M1 --axis X --recorded-at 2026-03-04T06:00:00Z",
                                             n, cli(), quoted(database), quoted(results[3])),
                                 folder);
        if (r.exit_code == 0) break;  // n is past the last statement: the recording ran to its end
        ASSERT_EQ(r.exit_code, 128 + SIGABRT) << "n = " << n << ": " << r.err;
        ++aborted;

        // The file opens (through feedid and through SQLite's own check) ...
        if (!postgresql()) {
            EXPECT_EQ(integrity(database), "ok") << "n = " << n;
        }
        const auto listing = run_shell(fmt::format("{} history {} --json -", cli(), quoted(database)), folder);
        ASSERT_EQ(listing.exit_code, 0) << "n = " << n << ": " << listing.err;
        const auto document = nlohmann::json::parse(listing.out);
        // ... with every earlier run, whole ...
        const auto& runs = document["runs"];
        ASSERT_GE(runs.size(), 3u) << "n = " << n;
        ASSERT_LE(runs.size(), 4u) << "n = " << n;
        for (std::size_t i = 0; i < runs.size(); ++i) {
            EXPECT_EQ(runs[i]["parameters"].size(), 5u) << "n = " << n << ", run " << i + 1;
            EXPECT_DOUBLE_EQ(runs[i]["parameters"]["coulomb_N"]["value"].get<double>(), 740.0 + 0.1 * (i + 1.0));
        }
        // ... and the interrupted one whole (counted) or absent.
        if (runs.size() == 4u) ++whole;
        // It can still be recorded afterwards (or is found to be there already).
        const auto again = run_shell(fmt::format("{} history {} --record {} --machine M1 --axis X "
                                                 "--recorded-at 2026-03-04T06:00:00Z",
                                                 cli(), quoted(database), quoted(results[3])),
                                     folder);
        EXPECT_EQ(again.exit_code, 0) << again.err;
        const auto after = run_shell(fmt::format("{} history {} --json -", cli(), quoted(database)), folder);
        EXPECT_EQ(nlohmann::json::parse(after.out)["runs"].size(), 4u) << "n = " << n;
    }
    // BEGIN, the run's row, its documents' row, five parameters (PostgreSQL: one statement) and COMMIT: 9 (5) places
    // to die; only the abort after COMMIT keeps the run.
    EXPECT_EQ(aborted, postgresql() ? 5 : 9);
    EXPECT_EQ(whole, 1);
}

// Two processes, each recording 50 runs (one command per run) into the same file at the same time, starting without
// the file: both create and migrate it, then contend for the write lock 50 times each.
TEST_P(HistoryDurabilityOn, TwoProcessesRecordingAtOnceLoseNothing) {
    const auto folder = folder_;
    const auto first = write_small_results(folder, "a", 50);
    const auto second = write_small_results(folder, "b", 50);
    const auto database = new_location("shared");
    const auto loop = [&](const std::string& stem) {
        return fmt::format(
            "fail=0; for i in $(seq 1 50); do {} history {} --record {}/{}-$i.json --machine M1 --axis "
            "X || fail=1; done; exit $fail",
            cli(), quoted(database), quoted(folder), stem);
    };
    const auto r = run_shell(fmt::format("( {} ) & a=$!; ( {} ) & b=$!; wait $a; ra=$?; wait $b; rb=$?; "
                                         "echo \"$ra $rb\"; [ $ra -eq 0 ] && [ $rb -eq 0 ]",
                                         loop("a"), loop("b")),
                             folder);
    EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
    if (!postgresql()) {
        EXPECT_EQ(integrity(database), "ok");
    }
    const auto runs = open(database, true)->runs();
    ASSERT_EQ(runs.size(), 100u);
    std::set<std::string> traces;
    for (const auto& run : runs) {
        EXPECT_EQ(run.parameters.size(), 5u);
        traces.insert(run.trace_path);
    }
    EXPECT_EQ(traces.size(), 100u);
}

// The same with each process recording its 50 runs in one command (50 transactions back to back).
TEST_P(HistoryDurabilityOn, TwoProcessesWithFiftyRunsPerCommandLoseNothing) {
    const auto folder = folder_;
    write_small_results(folder, "a", 50);
    write_small_results(folder, "b", 50);
    const auto database = new_location("shared");
    const auto command = [&](const std::string& stem) {
        std::string files;
        for (int i = 1; i <= 50; ++i) files += " --record " + quoted(folder / fmt::format("{}-{}.json", stem, i));
        return fmt::format("{} history {} --machine M1 --axis X{}", cli(), quoted(database), files);
    };
    const auto r = run_shell(fmt::format("{} & a=$!; {} & b=$!; wait $a; ra=$?; wait $b; rb=$?; "
                                         "[ $ra -eq 0 ] && [ $rb -eq 0 ]",
                                         command("a"), command("b")),
                             folder);
    EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
    EXPECT_EQ(open(database, true)->runs().size(), 100u);
    if (!postgresql()) {
        EXPECT_EQ(integrity(database), "ok");
    }
}

}  // namespace

namespace {

// feedid identify --record files the run as it is made; the result document it writes carries the options, so that
// recording that document again (feedid history --record) is recognised as the same run.
class HistoryRecordOn : public HistoryBackendTest {};
INSTANTIATE_TEST_SUITE_P(Backends, HistoryRecordOn, ::testing::Values(Backend::sqlite, Backend::postgresql),
                         backend_name);

TEST_P(HistoryRecordOn, IdentifyRecordsAndHistoryRecognisesTheSameRun) {
    const auto folder = folder_;
    const auto drive = folder / "drive.json";
    write_text(drive, R"({"seed": 9, "slow_passes": false, "test": {"feedrates_mm_per_min": [1500, 3000, 4500, 6000],
                          "stroke_mm": 20}})");
    const auto trace = folder / "x.csv";
    ASSERT_EQ(
        run_shell(fmt::format("{} synth --drive {} --out {}", cli(), quoted(drive), quoted(trace)), folder).exit_code,
        0);
    const auto database = new_location("shop");
    const auto result = folder / "result.json";
    const auto identify = run_shell(fmt::format("{} identify {} --force-constant force_constant_N_per_A --json {} "
                                                "--record {} --machine 'DMU 50' --axis X --location Aachen "
                                                "--recorded-at 2026-03-01T06:00:00Z",
                                                cli(), quoted(trace), quoted(result), quoted(database)),
                                    folder);
    ASSERT_EQ(identify.exit_code, 0) << identify.err;
    EXPECT_NE(identify.err.find("recorded as run #1 of machine 'DMU 50' axis 'X'"), std::string::npos) << identify.err;

    auto runs = open(database, true)->runs();
    ASSERT_EQ(runs.size(), 1u);
    const auto document = nlohmann::json::parse(read_text(result));
    EXPECT_EQ(runs[0].location, "Aachen");
    EXPECT_EQ(runs[0].recorded_at, "2026-03-01T06:00:00Z");
    EXPECT_EQ(runs[0].trace_sha256, history::sha256_file(trace));
    EXPECT_EQ(runs[0].options, document["options"]);
    EXPECT_EQ(runs[0].options["drive"]["force_constant"], "force_constant_N_per_A");
    EXPECT_DOUBLE_EQ(*runs[0].parameters.at("coulomb_N").value,
                     document["parameters"]["coulomb_N"]["value"].get<double>());
    EXPECT_TRUE(runs[0].result.contains("friction_curve"));

    const auto again = run_shell(
        fmt::format("{} history {} --record {} --machine 'DMU 50' --axis X", cli(), quoted(database), quoted(result)),
        folder);
    EXPECT_EQ(again.exit_code, 0) << again.err;
    EXPECT_NE(again.err.find("already recorded as run #1"), std::string::npos) << again.err;
    EXPECT_EQ(open(database, true)->runs().size(), 1u);

    // Other options make another run of the same trace.
    const auto other = run_shell(fmt::format("{} identify {} --force-constant force_constant_N_per_A --offset "
                                             "--record {} --machine 'DMU 50' --axis X",
                                             cli(), quoted(trace), quoted(database)),
                                 folder);
    EXPECT_EQ(other.exit_code, 0) << other.err;
    EXPECT_EQ(open(database, true)->runs().size(), 2u);
}

// In WAL mode a connection opened with SQLITE_OPEN_READONLY creates DB-wal and DB-shm and may not delete them when it
// closes: read-only commands left two empty files beside the database. Every read-only command now leaves the
// folder, and the database file, as it found them.
TEST(HistoryStore, ReadOnlyCommandsLeaveTheFolderAsTheyFoundIt) {
    const auto folder = temp_dir();
    const auto scratch = folder / "scratch";  // results, report and captured output live outside the listed folder
    const auto shop = folder / "shop";
    std::filesystem::create_directories(scratch);
    std::filesystem::create_directories(shop);
    const auto results = write_small_results(scratch, "run", 2);
    const auto database = shop / "shop.db";
    const auto recorded = run_shell(fmt::format("{} history {} --record {} --record {} --machine M --axis X", cli(),
                                                quoted(database), quoted(results[0]), quoted(results[1])),
                                    scratch);
    ASSERT_EQ(recorded.exit_code, 0) << recorded.err;
    auto listing = [&] {
        std::set<std::string> names;
        for (const auto& entry : std::filesystem::directory_iterator(shop)) {
            names.insert(fmt::format("{} ({} bytes)", entry.path().filename().string(), entry.file_size()));
        }
        return names;
    };
    const auto before = listing();
    ASSERT_EQ(before.size(), 1U) << *before.begin();
    const std::string bytes_before = read_text(database);

    for (const std::string& arguments :
         {fmt::format("history {}", quoted(database)), fmt::format("history {} --json -", quoted(database)),
          fmt::format("history {} --csv - --machine M --axis X", quoted(database)),
          fmt::format("history {} --check", quoted(database)),
          fmt::format("report {} --out {}", quoted(database), quoted(scratch / "report.html"))}) {
        SCOPED_TRACE(arguments);
        const auto result = run_shell(cli() + " " + arguments, scratch);
        EXPECT_EQ(result.exit_code, 0) << result.err;
        EXPECT_EQ(listing(), before);
    }
    // the library's reader too, and a reader that closes while another connection still has the file open
    history::SqliteOpenOptions read_only;
    read_only.read_only = true;
    {
        const auto writer = history::open_sqlite_store(database);
        EXPECT_EQ(history::open_sqlite_store(database, read_only)->runs().size(), 2U);
    }
    EXPECT_EQ(history::open_sqlite_store(database, read_only)->runs().size(), 2U);
    EXPECT_EQ(listing(), before);
    EXPECT_EQ(read_text(database), bytes_before);

    // a reader still cannot write
    EXPECT_THROW(history::open_sqlite_store(database, read_only)->add_run(history::RunRecord{}), feedid::InputError);
}

}  // namespace
