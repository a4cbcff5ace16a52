// The history on PostgreSQL beyond the contract both backends share (test_history_store.cpp and the others run that
// on both): a hundred writers at once, writers killed in the middle of a run, a lost connection retried, the messages
// for authentication, permission and an unreachable server, another application's tables, the dashboards' views, and
// --copy between a SQLite file and PostgreSQL. Every test uses the program's own server (postgres_testing.hpp) and a
// database of its own; skipped, with the reason, where no server can run.

#include <gtest/gtest.h>

#include <sqlite3.h>

#include <cctype>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <set>
#include <sstream>
#include <thread>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/history/sha256.hpp"
#include "feedid/history/store.hpp"
#include "history_testing.hpp"
#include "postgres_testing.hpp"
#include "testing.hpp"

namespace {

using namespace feedid::testing;
namespace history = feedid::history;

class HistoryPostgres : public ::testing::Test {
protected:
    void SetUp() override {
        folder_ = temp_dir();
        if (!server().available()) GTEST_SKIP() << "PostgreSQL: " << server().why_not();
    }
    static PostgresServer& server() { return test_server(); }
    /// The database name of a location made by create_database().
    static std::string database_of(const std::string& location) { return location.substr(location.rfind('/') + 1); }
    /// A query's first value on the database of `location`.
    static std::string value(const std::string& location, const std::string& sql) {
        return server().value(sql, database_of(location));
    }
    std::filesystem::path folder_;
};

/// The runs' integrity in SQL: runs, runs without their documents row, runs whose parameter count is not `keys`.
struct Integrity {
    int runs{0};
    int without_documents{0};
    int partial_parameters{0};
    int distinct_traces{0};
};

Integrity integrity_of(const std::string& location, int keys) {
    const auto number = [&](const std::string& sql) {
        return std::stoi(test_server().value(sql, location.substr(location.rfind('/') + 1)));
    };
    Integrity found;
    found.runs = number("SELECT count(*) FROM runs");
    found.without_documents =
        number("SELECT count(*) FROM runs r WHERE NOT EXISTS (SELECT 1 FROM documents d WHERE d.run_id = r.id)");
    found.partial_parameters = number(fmt::format(
        "SELECT count(*) FROM runs r WHERE (SELECT count(*) FROM parameters p WHERE p.run_id = r.id) != {}", keys));
    found.distinct_traces = number("SELECT count(DISTINCT trace_sha256) FROM runs");
    return found;
}

// 100 processes start at once on an empty database (all of them migrate it: one does, the others wait for the
// advisory lock and find it done), each recording 20 runs (one transaction each): 2,000 runs, none lost, none twice.
// Then 10 processes record the same 20 runs at once: the content hash keeps one of each.
TEST_F(HistoryPostgres, HundredWritersStoreTwoThousandRunsNoneLostNoneTwice) {
    const auto location = server().create_database();
    constexpr int writers = 100;
    constexpr int runs_each = 20;
    std::string script = "pids=''; ";
    for (int w = 0; w < writers; ++w) {
        write_small_results(folder_, fmt::format("w{}", w), runs_each);
        std::string records;
        for (int i = 1; i <= runs_each; ++i)
            records += " --record " + quoted(folder_ / fmt::format("w{}-{}.json", w, i));
        script += fmt::format("{} history '{}' --machine M{} --axis X{} 2>>{} & pids=\"$pids $!\"; ", cli(), location,
                              w % 10, records, quoted(folder_ / fmt::format("w{}.err", w)));
    }
    script += "fail=0; for p in $pids; do wait $p || fail=$((fail+1)); done; echo \"failed: $fail\"; [ $fail -eq 0 ]";
    write_text(folder_ / "writers.sh", script);  // longer than one argument of sh -c may be
    const auto started = std::chrono::steady_clock::now();
    const auto r = run_shell("sh " + quoted(folder_ / "writers.sh"), folder_);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    EXPECT_EQ(r.exit_code, 0) << r.out << read_text(folder_ / "w0.err");
    int errors = 0;
    for (int w = 0; w < writers; ++w) {
        const auto err = read_text(folder_ / fmt::format("w{}.err", w));
        for (std::size_t at = 0; (at = err.find("feedid: ", at)) != std::string::npos; ++at)
            if (err.compare(at, 17, "feedid: recorded ") != 0) ++errors;
    }
    EXPECT_EQ(errors, 0) << "a writer said something other than 'recorded'";
    const auto found = integrity_of(location, 5);
    EXPECT_EQ(found.runs, writers * runs_each);
    EXPECT_EQ(found.distinct_traces, writers * runs_each);
    EXPECT_EQ(found.without_documents, 0);
    EXPECT_EQ(found.partial_parameters, 0);
    EXPECT_EQ(history::open_store(location, {true, false})->runs({}, history::RunDetail::summary).size(),
              static_cast<std::size_t>(writers * runs_each));
    fmt::print("100 writers x 20 runs: {:.1f} s\n", seconds);

    // the same 20 runs from 10 processes at once
    const auto same = server().create_database();
    write_small_results(folder_, "same", runs_each);
    std::string records;
    for (int i = 1; i <= runs_each; ++i) records += " --record " + quoted(folder_ / fmt::format("same-{}.json", i));
    std::string race = "pids=''; ";
    for (int w = 0; w < 10; ++w)
        race += fmt::format("{} history '{}' --machine M --axis X{} 2>/dev/null & pids=\"$pids $!\"; ", cli(), same,
                            records);
    race += "fail=0; for p in $pids; do wait $p || fail=1; done; [ $fail -eq 0 ]";
    EXPECT_EQ(run_shell(race, folder_).exit_code, 0);
    const auto raced = integrity_of(same, 5);
    EXPECT_EQ(raced.runs, runs_each);
    EXPECT_EQ(raced.partial_parameters, 0);
}

// 20 writers, each recording its 20 runs one command per run; one command of each writer is SIGKILLed in the middle
// of its transaction (FEEDID_TEST_PAUSE_AFTER_STATEMENT holds it after its BEGIN, its run row, its documents or its
// parameters until the kill). Every run whose command exited 0 is there, whole; the killed runs are not there at all.
TEST_F(HistoryPostgres, WritersKilledMidWriteLeaveEveryConfirmedRunAndNoPartialOne) {
    const auto location = server().create_database();
    ASSERT_EQ(run_shell(fmt::format("{} history '{}' --verify", cli(), location), folder_).exit_code, 2);  // empty
    constexpr int writers = 20;
    constexpr int runs_each = 20;
    // one writer: its runs one command each, the exit status of each logged; the command to be killed writes its pid
    // (sh's, which exec makes feedid's) first
    const auto writer = folder_ / "writer.sh";
    write_text(writer,
               "dir=$1; w=$2; n=$3; k=$4; p=$5; loc=$6; cli=$7; i=1\n"
               "while [ $i -le $n ]; do\n"
               "  if [ $i -eq $k ]; then\n"
               "    sh -c 'echo $$ > \"$1\"; exec env FEEDID_TEST_PAUSE_AFTER_STATEMENT=\"$2\" \"$3\" history \"$4\" "
               "--record \"$5\" --machine M --axis \"$6\"' _ \"$dir/k$w-$i.pid\" \"$p\" \"$cli\" \"$loc\" "
               "\"$dir/k$w-$i.json\" \"X$w\" 2>/dev/null\n"
               "  else\n"
               "    \"$cli\" history \"$loc\" --record \"$dir/k$w-$i.json\" --machine M --axis \"X$w\" 2>/dev/null\n"
               "  fi\n"
               "  echo \"$i $?\" >> \"$dir/k$w.log\"\n"
               "  i=$((i+1))\n"
               "done\n");
    std::string script = "pids=''; ";
    for (int w = 0; w < writers; ++w) {
        write_small_results(folder_, fmt::format("k{}", w), runs_each);
        const int killed_run = 1 + (w * 7) % runs_each;
        const int pause_after = 1 + w % 4;  // BEGIN, the run, its documents, its parameters
        script += fmt::format("sh {} {} {} {} {} {} '{}' {} & pids=\"$pids $!\"; ", quoted(writer), quoted(folder_), w,
                              runs_each, killed_run, pause_after, location, cli());
    }
    script += "for p in $pids; do wait $p; done";
    std::thread killer([&] {
        // every paused command: wait for its pid file, give it time to reach the pause, SIGKILL it
        for (int w = 0; w < writers; ++w) {
            const int killed_run = 1 + (w * 7) % runs_each;
            const auto pid_file = folder_ / fmt::format("k{}-{}.pid", w, killed_run);
            for (int wait = 0; wait < 1200 && !std::filesystem::exists(pid_file); ++wait)
                std::this_thread::sleep_for(std::chrono::milliseconds(50));
            std::this_thread::sleep_for(std::chrono::milliseconds(300));
            const int pid = std::atoi(read_text(pid_file).c_str());
            if (pid > 0) ::kill(pid, SIGKILL);
        }
    });
    const auto started = std::chrono::steady_clock::now();
    run_shell(script, folder_);
    killer.join();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();

    int confirmed = 0;
    int killed = 0;
    std::set<std::string> confirmed_traces;
    for (int w = 0; w < writers; ++w) {
        std::istringstream log(read_text(folder_ / fmt::format("k{}.log", w)));
        int run = 0;
        int code = 0;
        while (log >> run >> code) {
            if (code == 0) {
                ++confirmed;
                confirmed_traces.insert(history::sha256_hex(
                    read_text(folder_ / fmt::format("k{}-{}.csv", w, run))));  // the trace's content hash
            } else {
                EXPECT_EQ(code, 128 + SIGKILL) << "writer " << w << " run " << run;
                EXPECT_EQ(run, 1 + (w * 7) % runs_each) << "writer " << w;
                ++killed;
            }
        }
    }
    EXPECT_EQ(killed, writers);
    EXPECT_EQ(confirmed, writers * (runs_each - 1));
    const auto found = integrity_of(location, 5);
    EXPECT_EQ(found.runs, confirmed);  // the killed ones are absent, every confirmed one present
    EXPECT_EQ(found.without_documents, 0);
    EXPECT_EQ(found.partial_parameters, 0);
    std::set<std::string> stored;
    for (const auto& run : history::open_store(location, {true, false})->runs()) stored.insert(run.trace_sha256);
    EXPECT_EQ(stored, confirmed_traces);
    EXPECT_EQ(run_shell(fmt::format("{} history '{}' --verify", cli(), location), folder_).exit_code, 0);
    fmt::print("20 writers x 20 runs, 20 killed mid-write: {} confirmed runs stored, {:.1f} s\n", found.runs, seconds);
}

// The store's session is ended by the server just before each write statement in turn (BEGIN, the run, its
// documents, its parameters, COMMIT): the write is retried on a new connection and the run is stored once, whole.
TEST_F(HistoryPostgres, ALostConnectionIsRetriedWithoutDuplicates) {
    const auto results = write_small_results(folder_, "run", 2);
    for (int n = 1; n <= 6; ++n) {
        SCOPED_TRACE(fmt::format("connection ended before write statement {}", n));
        const auto location = server().create_database();
        ASSERT_EQ(run_shell(fmt::format("{} history '{}' --record {} --machine M --axis X", cli(), location,
                                        quoted(results[0])),
                            folder_)
                      .exit_code,
                  0);
        const auto r = run_shell(fmt::format("FEEDID_TEST_DROP_CONNECTION_AT_STATEMENT={} {} history '{}' --record {} "
                                             "--machine M --axis X",
                                             n, cli(), location, quoted(results[1])),
                                 folder_);
        EXPECT_EQ(r.exit_code, 0) << r.err;
        EXPECT_NE(r.err.find("recorded"), std::string::npos) << r.err;
        const auto found = integrity_of(location, 5);
        EXPECT_EQ(found.runs, 2);
        EXPECT_EQ(found.partial_parameters, 0);
        EXPECT_EQ(found.without_documents, 0);
    }
}

// Authentication, permission and an unreachable server: exit 2, one line naming the host and the database, never
// the password (given in the URI or in PGPASSWORD).
TEST_F(HistoryPostgres, ConnectionFailuresAreOneLineNamingHostAndDatabaseNeverThePassword) {
    const auto results = write_small_results(folder_, "run", 1);
    const auto owned = fmt::format("owned_{}", ::getpid());
    ASSERT_EQ(server().execute(fmt::format("CREATE DATABASE {} OWNER feedid_password", owned)), "");
    const auto expect_refused = [&](const std::string& environment, const std::string& location,
                                    const std::vector<std::string>& parts) {
        SCOPED_TRACE(location);
        const auto r = run_shell(fmt::format("{} {} history '{}' --record {} --machine M --axis X", environment, cli(),
                                             location, quoted(results[0])),
                                 folder_);
        EXPECT_EQ(r.exit_code, 2) << r.err;
        EXPECT_EQ(count_lines(r.err), 1) << r.err;
        for (const auto& part : parts) EXPECT_NE(r.err.find(part), std::string::npos) << part << " in " << r.err;
        for (const char* secret : {"Wrong-Guess-7", test_password})
            EXPECT_EQ(r.err.find(secret), std::string::npos) << "the password is shown: " << r.err;
        return r.err;
    };
    const std::string host = fmt::format("127.0.0.1:{}", server().port());
    // a password in the URI is refused before any connection (it would show in ps); a wrong one in the environment
    expect_refused("", fmt::format("postgresql://feedid_password:Wrong-Guess-7@{}/{}", host, owned),
                   {"127.0.0.1", owned, "a password in the location is refused", "PGPASSFILE"});
    expect_refused("PGPASSWORD=Wrong-Guess-7", fmt::format("postgresql://feedid_password@{}/{}", host, owned),
                   {"127.0.0.1", owned, "authentication failed"});
    // no password at all
    expect_refused("PGPASSFILE=/nonexistent", fmt::format("postgres://feedid_password@{}/{}", host, owned),
                   {"127.0.0.1", owned, "authentication failed"});
    // the right one records (the role owns the database)
    const auto right = run_shell(fmt::format("PGPASSWORD='{}' {} history 'postgresql://feedid_password@{}/{}' --record "
                                             "{} --machine M --axis X",
                                             test_password, cli(), host, owned, quoted(results[0])),
                                 folder_);
    EXPECT_EQ(right.exit_code, 0) << right.err;
    EXPECT_EQ(right.err.find(test_password), std::string::npos) << right.err;
    // a role without rights: may not create feedid's tables in a database it does not own, nor read them
    const auto fresh = server().create_database();
    expect_refused("", server().location(database_of(fresh), "feedid_reader"),
                   {"127.0.0.1", database_of(fresh), "permission denied"});
    const auto listing =
        run_shell(fmt::format("{} history '{}'", cli(), server().location(owned, "feedid_reader")), folder_);
    EXPECT_EQ(listing.exit_code, 2) << listing.err;
    EXPECT_NE(listing.err.find("permission denied"), std::string::npos) << listing.err;
    EXPECT_EQ(count_lines(listing.err), 1) << listing.err;
    // nothing listening on the port, and a host that does not resolve
    expect_refused("", fmt::format("postgresql://feedid_admin@127.0.0.1:1/{}", owned),
                   {"127.0.0.1", owned, "unreachable"});
    expect_refused("", fmt::format("postgresql://feedid_admin@no-such-host.invalid/{}", owned),
                   {"no-such-host.invalid", owned, "unreachable"});
    // a database that does not exist
    expect_refused("", server().location("no_such_database"), {"127.0.0.1", "no_such_database", "does not exist"});
}

// The password comes from a file (PGPASSFILE, ~/.pgpass) or a service file, never from the command line: it is not
// in `ps`, and no message shows it.
TEST_F(HistoryPostgres, ThePasswordComesFromAPasswordFileNeverFromTheLocation) {
    const auto results = write_small_results(folder_, "run", 1);
    const auto owned = fmt::format("pgpass_{}", ::getpid());
    ASSERT_EQ(server().execute(fmt::format("CREATE DATABASE {} OWNER feedid_password", owned)), "");
    write_text(folder_ / "pgpass",
               fmt::format("127.0.0.1:{}:{}:feedid_password:{}\n", server().port(), owned, test_password));
    std::filesystem::permissions(folder_ / "pgpass",
                                 std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
    const auto location = fmt::format("postgresql://feedid_password@127.0.0.1:{}/{}", server().port(), owned);
    const auto r = run_shell(fmt::format("PGPASSFILE={} {} history '{}' --record {} --machine M --axis X",
                                         quoted(folder_ / "pgpass"), cli(), location, quoted(results[0])),
                             folder_);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ((r.out + r.err).find(test_password), std::string::npos);
    EXPECT_EQ(value(location, "SELECT count(*) FROM runs"), "1");
    for (const std::string& given :
         {fmt::format("postgresql://feedid_password:{}@127.0.0.1:{}/{}", test_password, server().port(), owned),
          fmt::format("postgresql://feedid_password@127.0.0.1:{}/{}?password={}", server().port(), owned,
                      test_password)}) {
        const auto refused = run_shell(fmt::format("{} history '{}'", cli(), given), folder_);
        EXPECT_EQ(refused.exit_code, 2) << refused.err;
        EXPECT_EQ(count_lines(refused.err), 1) << refused.err;
        EXPECT_NE(refused.err.find("a password in the location is refused"), std::string::npos) << refused.err;
        EXPECT_EQ((refused.out + refused.err).find(test_password), std::string::npos) << refused.err;
    }
}

// A SQLite history written before names were checked may hold one that PostgreSQL refuses (a NUL, bytes that are not
// UTF-8): --copy says which run and stops, exit 2, at once (it once waited forever).
TEST_F(HistoryPostgres, CopyStopsAtARunPostgresqlCannotHoldNamingIt) {
    const auto source = (folder_ / "old.db").string();
    const auto results = write_small_results(folder_, "run", 2);
    for (const auto& result : results) {
        const auto r = run_shell(
            fmt::format("{} history {} --record {} --machine M --axis X", cli(), quoted(source), quoted(result)),
            folder_);
        ASSERT_EQ(r.exit_code, 0) << r.err;
    }
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(source.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(
        sqlite3_exec(db, "UPDATE runs SET machine = CAST(X'4DFF' AS TEXT) WHERE id = 2", nullptr, nullptr, nullptr),
        SQLITE_OK);
    sqlite3_close(db);
    const auto plant = server().create_database();
    const auto started = std::chrono::steady_clock::now();
    const auto r =
        run_shell(fmt::format("timeout 60 {} history --copy {} '{}'", cli(), quoted(source), plant), folder_);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_LT(seconds, 30.0);
    EXPECT_NE(r.err.find("machine"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("not valid UTF-8 without NUL"), std::string::npos) << r.err;
    EXPECT_EQ(value(plant, "SELECT count(*) FROM runs"), "1");  // the run before it
}

// What the URI leaves out comes from libpq's environment variables and service files, as for psql.
TEST_F(HistoryPostgres, EnvironmentVariablesAndServiceFilesFillInTheLocation) {
    const auto results = write_small_results(folder_, "run", 2);
    const auto location = server().create_database();
    const auto database = database_of(location);
    const auto by_environment = run_shell(
        fmt::format("PGHOST=127.0.0.1 PGPORT={} PGUSER=feedid_admin PGDATABASE={} {} history postgresql:// --record {} "
                    "--machine M --axis X",
                    server().port(), database, cli(), quoted(results[0])),
        folder_);
    EXPECT_EQ(by_environment.exit_code, 0) << by_environment.err;
    write_text(
        folder_ / "pg_service.conf",
        fmt::format("[plant]\nhost=127.0.0.1\nport={}\nuser=feedid_admin\ndbname={}\n", server().port(), database));
    const auto by_service = run_shell(fmt::format("PGSERVICEFILE={} {} history 'postgresql:///?service=plant' --record "
                                                  "{} --machine M --axis X",
                                                  quoted(folder_ / "pg_service.conf"), cli(), quoted(results[1])),
                                      folder_);
    EXPECT_EQ(by_service.exit_code, 0) << by_service.err;
    EXPECT_EQ(value(location, "SELECT count(*) FROM runs"), "2");
}

// Another application's tables of the same names, a newer feedid schema and an empty database: refused (exit 2),
// nothing written.
TEST_F(HistoryPostgres, ForeignTablesNewerSchemasAndEmptyDatabasesAreRefusedUntouched) {
    const auto results = write_small_results(folder_, "run", 1);
    const auto record = [&](const std::string& location) {
        return run_shell(
            fmt::format("{} history '{}' --record {} --machine M --axis X", cli(), location, quoted(results[0])),
            folder_);
    };
    const auto foreign = server().create_database();
    ASSERT_EQ(server().execute("CREATE TABLE runs (x integer); INSERT INTO runs VALUES (7)", database_of(foreign)), "");
    auto r = record(foreign);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("not a feedid history database"), std::string::npos) << r.err;
    EXPECT_EQ(value(foreign, "SELECT string_agg(x::text, ',') FROM runs"), "7");
    EXPECT_EQ(value(foreign, "SELECT count(*) FROM pg_tables WHERE schemaname = 'public'"), "1");

    const auto newer = server().create_database();
    ASSERT_EQ(record(newer).exit_code, 0);
    ASSERT_EQ(server().execute("INSERT INTO feedid_schema VALUES (99, 'later')", database_of(newer)), "");
    r = record(newer);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("newer than this feedid understands"), std::string::npos) << r.err;

    const auto empty = server().create_database();
    for (const std::string arguments : {"", " --check", " --json -", " --verify"}) {
        r = run_shell(fmt::format("{} history '{}'{}", cli(), empty, arguments), folder_);
        EXPECT_EQ(r.exit_code, 2) << arguments;
        EXPECT_NE(r.err.find("empty"), std::string::npos) << r.err;
    }
    EXPECT_EQ(value(empty, "SELECT count(*) FROM pg_tables WHERE schemaname = 'public'"),
              "0");  // reading wrote nothing
}

// The views a dashboard reads: one per parameter series, with the time as timestamptz and every stored figure.
TEST_F(HistoryPostgres, DashboardViewsGiveEachParameterSeries) {
    const auto location = server().create_database();
    const auto results = write_small_results(folder_, "run", 3);
    for (std::size_t i = 0; i < results.size(); ++i)
        ASSERT_EQ(run_shell(fmt::format("{} history '{}' --add {} --machine 'DMU 50' --axis X --recorded-at "
                                        "2026-03-0{}T06:00:00Z",
                                        cli(), location, quoted(results[i]), i + 1),
                            folder_)
                      .exit_code,
                  0);
    EXPECT_EQ(value(location, "SELECT count(*) FROM series_coulomb_n"), "3");
    EXPECT_EQ(value(location, "SELECT count(*) FROM series_mass_kg WHERE value = 69.1 AND stderr = 0.2"), "3");
    EXPECT_EQ(value(location, "SELECT count(*) FROM series_breakaway_n WHERE value IS NULL"), "3");
    // write_small_results: coulomb 740 + 0.1 i; the time of run 3 as a time stamp
    EXPECT_EQ(value(location,
                    "SELECT abs(value - 740.3) < 1e-9 FROM series_coulomb_n WHERE machine = 'DMU 50' AND "
                    "axis = 'X' ORDER BY time DESC LIMIT 1"),
              "t");
    EXPECT_EQ(value(location, "SELECT max(time) AT TIME ZONE 'UTC' FROM parameter_series"), "2026-03-03 06:00:00");
    EXPECT_EQ(value(location, "SELECT runs FROM axes WHERE machine = 'DMU 50' AND axis = 'X'"), "3");
    EXPECT_EQ(value(location, "SELECT count(*) FROM fit_series WHERE relative_error_pct = 3.1"), "3");
}

/// Every key ParameterNaming gives, enumerated from it: linear and rotary, symmetric and per direction, offset.
std::set<std::string> every_parameter_key() {
    std::set<std::string> keys;
    for (const bool rotary : {false, true})
        for (const auto term : feedid::all_terms)
            for (const auto direction : feedid::all_directions)
                keys.insert(feedid::ParameterNaming{rotary}.key(term, direction));
    return keys;
}

/// The series view of a key, as PostgreSQL folds its unquoted name.
std::string series_view(std::string key) {
    for (auto& c : key) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return "series_" + key;
}

// Each parameter key has its series view, and the view gives that key's values: a value stored under each key (into
// the run's parameters table) comes out of its view, and only there. A database made by schema 1 (whose hand-written
// list of views missed the per-direction Stribeck velocities) gains the missing views on its next write.
TEST_F(HistoryPostgres, SeriesViewsCoverEveryParameterKey) {
    const auto location = server().create_database();
    const auto results = write_small_results(folder_, "run", 2);
    const auto record = [&](const std::filesystem::path& result) {
        return run_shell(
            fmt::format("{} history '{}' --record {} --machine M --axis X", cli(), location, quoted(result)), folder_);
    };
    ASSERT_EQ(record(results[0]).exit_code, 0);
    const auto keys = every_parameter_key();
    // 2 axis kinds x (mass, offset, and 4 friction terms each symmetric, forward, reverse)
    EXPECT_EQ(keys.size(), 28u);
    const std::string run = value(location, "SELECT min(id) FROM runs");
    const auto check_views = [&] {
        double stored = 1.0;
        for (const auto& key : keys) {
            ASSERT_EQ(server().execute(fmt::format("INSERT INTO parameters (run_id, key, value) VALUES ({}, '{}', {}) "
                                                   "ON CONFLICT (run_id, key) DO UPDATE SET value = EXCLUDED.value",
                                                   run, key, stored),
                                       database_of(location)),
                      "");
            EXPECT_EQ(value(location, fmt::format("SELECT count(*) FROM {} WHERE run_id = {} AND value = {}",
                                                  series_view(key), run, stored)),
                      "1")
                << series_view(key) << " misses " << key;
            stored += 1.0;
        }
        // no view gives another key's values: each holds the one row of its key
        for (const auto& key : keys)
            EXPECT_EQ(value(location, fmt::format("SELECT count(*) FROM {}", series_view(key))), "1") << key;
    };
    check_views();

    // As schema 1 left it: without the per-direction Stribeck views, at version 1.
    const std::string stribeck_forward =
        series_view(feedid::ParameterNaming{}.key(feedid::Term::stribeck_velocity, feedid::Direction::forward));
    ASSERT_EQ(
        server().execute(fmt::format("DROP VIEW {}; DELETE FROM feedid_schema WHERE version > 1", stribeck_forward),
                         database_of(location)),
        "");
    ASSERT_EQ(value(location, fmt::format("SELECT to_regclass('{}') IS NULL", stribeck_forward)), "t");
    ASSERT_EQ(record(results[1]).exit_code, 0);
    EXPECT_EQ(value(location, "SELECT max(version) FROM feedid_schema"),
              std::to_string(history::postgres_schema_version));
    EXPECT_EQ(value(location, fmt::format("SELECT to_regclass('{}') IS NOT NULL", stribeck_forward)), "t");
    ASSERT_EQ(server().execute(fmt::format("DELETE FROM parameters WHERE run_id != {}", run), database_of(location)),
              "");
    check_views();
}

/// The outputs of the history commands that must not depend on where the history is.
std::vector<std::string> outputs_of(const std::string& location, const std::filesystem::path& folder) {
    std::vector<std::string> outputs;
    for (const std::string arguments : {"", " --check", " --csv -", " --json -", " --machine B --axis Y"}) {
        const auto r = run_shell(fmt::format("{} history '{}'{}", cli(), location, arguments), folder);
        EXPECT_TRUE(r.exit_code == 0 || r.exit_code == 1) << arguments << ": " << r.err;
        if (arguments == " --json -") {
            auto document = nlohmann::json::parse(r.out);
            document.erase("database");        // names the location
            document.erase("schema_version");  // each backend's own numbering
            outputs.push_back(document.dump(1));
        } else {
            outputs.push_back(fmt::format("exit {}\n{}", r.exit_code, r.out));
        }
    }
    return outputs;
}

// SQLite -> PostgreSQL -> SQLite: the listing, the check, the CSV and the JSON document are identical; copying again
// adds nothing.
TEST_F(HistoryPostgres, CopyRoundTripLeavesIdenticalListingAndCheck) {
    const auto source = (folder_ / "edge.db").string();
    {
        auto store = history::open_store(source);
        // 6 series (2 machines' A X/Y, B X/Y ... by i % 3 and i % 2) of 10 runs; runs 6 and 12 (one series) recorded
        // in the reverse order of their ids; Coulomb friction steps up by 6 N (15 standard errors) from run 48
        for (int i = 0; i < 60; ++i) {
            history::RunRecord run;
            run.machine = i % 3 == 0 ? "B" : "A";
            run.axis = i % 2 == 0 ? "X" : "Y";
            const int hour = i == 6 ? 12 : i == 12 ? 6 : i;
            run.recorded_at = fmt::format("2026-03-{:02}T{:02}:00:00.000Z", 1 + hour / 24, hour % 24);
            run.trace_path = fmt::format("t{}.csv", i);
            run.trace_sha256 = history::sha256_hex(run.trace_path);
            run.feedid_version = "0.1.0";
            run.model = "symmetric";
            run.status = i % 4 == 0 ? "partial" : "ok";
            run.options = {{"model", i == 5 ? "asymmetric" : "symmetric"}};
            run.parameters["coulomb_N"] = {742.0 + (i >= 48 ? 6.0 : 0.1 * (i % 3)), 0.4, 0.05, 0.41};
            run.parameters["mass_kg"] = {69.1 + 0.01 * i, 0.3};
            if (i % 5 == 0) run.parameters["breakaway_N"] = {std::nullopt, std::nullopt};
            run.fit = {{"relative_error_pct", 1.0 + 0.1 * i}, {"samples_used", 4000 + i}};
            run.diagnostics = {fmt::format("note {}", i)};
            run.result = {{"friction_curve", {{"forward", {{"force_N", {750.0, 752.0 + i}}}}}}};
            store->add_run(run);
        }
        store->pin_baseline("A", "Y", store->series({"A", "Y", ""})[0].run_ids[2]);
    }
    const auto plant = server().create_database();
    const auto back = (folder_ / "back.db").string();
    const auto copy = [&](const std::string& from, const std::string& to) {
        const auto r = run_shell(fmt::format("{} history --copy '{}' '{}'", cli(), from, to), folder_);
        EXPECT_EQ(r.exit_code, 0) << r.err;
        return r.err;
    };
    EXPECT_NE(copy(source, plant).find("copied 60 run(s)"), std::string::npos);
    EXPECT_NE(copy(source, plant).find("copied 0 run(s)"), std::string::npos);  // idempotent
    EXPECT_NE(copy(plant, back).find("copied 60 run(s)"), std::string::npos);
    EXPECT_NE(copy(plant, back).find("copied 0 run(s) from"), std::string::npos);
    const auto original = outputs_of(source, folder_);
    const auto on_server = outputs_of(plant, folder_);
    const auto returned = outputs_of(back, folder_);
    ASSERT_EQ(original.size(), 5u);
    EXPECT_NE(original[1].find("exit 1"), std::string::npos) << "the step from run 48 raises alarms: " << original[1];
    EXPECT_NE(original[0].find("(pinned at #"), std::string::npos) << original[0];
    for (std::size_t k = 0; k < original.size(); ++k) {
        EXPECT_EQ(on_server[k], original[k]) << "output " << k;
        EXPECT_EQ(returned[k], original[k]) << "output " << k;
    }
    EXPECT_EQ(integrity_of(plant, 3).runs, 60);
    // the report reads the plant database as it reads a file
    const auto report =
        run_shell(fmt::format("{} report '{}' -o {}", cli(), plant, quoted(folder_ / "plant.html")), folder_);
    EXPECT_EQ(report.exit_code, 0) << report.err;
    EXPECT_NE(read_text(folder_ / "plant.html").find("coulomb_N"), std::string::npos);
}

// A build without libpq (cmake -DFEEDID_WITH_POSTGRESQL=OFF, or no libpq-dev) still reads and writes SQLite files,
// and a PostgreSQL location is exit 2 naming what is missing (and never the password).
TEST(HistoryLocation, WithoutTheBackendAPostgresqlLocationIsExitTwoNamingWhatIsMissing) {
    if (feedid::history::postgresql_supported()) GTEST_SKIP() << "this build has the PostgreSQL backend";
    const auto r = run_cli("history postgresql://alice:Pw-1@plant-db/history --check");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_EQ(count_lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find("postgresql://alice@plant-db/history"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("libpq-dev"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("Pw-1"), std::string::npos) << r.err;
}

// Messages name a PostgreSQL location without its password, wherever it was given.
TEST(HistoryLocation, APasswordIsNeverShown) {
    EXPECT_TRUE(history::is_postgresql_location("postgresql://h/db"));
    EXPECT_TRUE(history::is_postgresql_location("postgres://h/db"));
    EXPECT_FALSE(history::is_postgresql_location("shop.db"));
    EXPECT_FALSE(history::is_postgresql_location("./postgresql://x"));
    EXPECT_EQ(history::shown_location("postgresql://alice:Pw-1@plant-db:5432/history"),
              "postgresql://alice@plant-db:5432/history");
    EXPECT_EQ(history::shown_location("postgres://alice:Pw-1@plant-db/history?sslmode=require&password=Pw-1&x=1"),
              "postgres://alice@plant-db/history?sslmode=require&x=1");
    EXPECT_EQ(history::shown_location("postgresql:///history?service=plant"), "postgresql:///history?service=plant");
    EXPECT_EQ(history::shown_location("shop.db"), "shop.db");
}

}  // namespace
