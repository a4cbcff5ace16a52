// Bad input to feedid history and feedid report: a corrupt database, a database of a newer schema, another
// application's SQLite file, a result file of the wrong kind. Each gives exit code 2 and one clear line on stderr, and
// the database file is byte for byte what it was before the command.

#include <gtest/gtest.h>

#include <sqlite3.h>

#include <fmt/core.h>

#include "history_testing.hpp"
#include "testing.hpp"

namespace {

using namespace feedid::testing;
namespace fs = std::filesystem;

/// Executes SQL on a file through SQLite itself (to make files feedid must reject).
void execute(const fs::path& path, const std::string& sql) {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    char* message = nullptr;
    const int code = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &message);
    const std::string text = message ? message : "";
    sqlite3_free(message);
    sqlite3_close(db);
    ASSERT_EQ(code, SQLITE_OK) << text;
}

class HistoryBadInput : public ::testing::Test {
protected:
    void SetUp() override {
        folder_ = temp_dir();
        results_ = write_small_results(folder_, "run", 4);
        good_ = folder_ / "good.db";
        for (int i = 0; i < 3; ++i) {
            const auto r =
                run_shell(fmt::format("{} history {} --record {} --machine M1 --axis X "
                                      "--recorded-at 2026-03-0{}T06:00:00Z",
                                      cli(), quoted(good_), quoted(results_[static_cast<std::size_t>(i)]), i + 1),
                          folder_);
            ASSERT_EQ(r.exit_code, 0) << r.err;
        }
        ASSERT_FALSE(fs::exists(good_.string() + "-wal")) << "the WAL is checkpointed when the last writer closes";
    }

    /// A copy of the good database under another name.
    fs::path copy_of_good(const std::string& name) {
        const auto path = folder_ / name;
        fs::copy_file(good_, path, fs::copy_options::overwrite_existing);
        return path;
    }

    /// Runs a feedid command line (arguments after the binary) that must fail with exit 2 and one line naming `names`
    /// and saying `says`; the database is byte-identical afterwards and no report is written.
    void expect_rejected(const std::string& arguments, const fs::path& database, const std::string& names,
                         const std::string& says) {
        const std::string before = read_text(database);
        const auto report = folder_ / "report.html";
        fs::remove(report);
        const auto r = run_shell(cli() + " " + arguments, folder_);
        EXPECT_EQ(r.exit_code, 2) << arguments << "\n" << r.err;
        EXPECT_EQ(count_lines(r.err), 1) << arguments << "\n" << r.err;
        EXPECT_EQ(r.err.rfind("feedid: ", 0), 0u) << r.err;
        EXPECT_NE(r.err.find(names), std::string::npos) << arguments << "\n" << r.err;
        EXPECT_NE(r.err.find(says), std::string::npos) << arguments << "\n" << r.err;
        EXPECT_TRUE(read_text(database) == before) << arguments << ": the database file changed";
        EXPECT_FALSE(fs::exists(report)) << arguments << ": a report was written";
    }

    /// Every command that reads or writes a history, run against `database`.
    void expect_every_command_rejected(const fs::path& database, const std::string& says) {
        const std::string db = quoted(database);
        const std::string name = database.string();
        expect_rejected(fmt::format("history {}", db), database, name, says);
        expect_rejected(fmt::format("history {} --check", db), database, name, says);
        expect_rejected(fmt::format("history {} --json -", db), database, name, says);
        expect_rejected(fmt::format("history {} --csv -", db), database, name, says);
        expect_rejected(fmt::format("history {} --record {} --machine M1 --axis X", db, quoted(results_[3])), database,
                        name, says);
        expect_rejected(fmt::format("history {} --pin 1", db), database, name, says);
        expect_rejected(fmt::format("report {} -o {}", db, quoted(folder_ / "report.html")), database, name, says);
        // identify --record checks the database before it identifies (the trace here is not even read).
        expect_rejected(fmt::format("identify {} --record {} --machine M1 --axis X", quoted(folder_ / "run-1.csv"), db),
                        database, name, says);
    }

    fs::path folder_;
    fs::path good_;
    std::vector<fs::path> results_;
};

TEST_F(HistoryBadInput, CorruptDatabaseIsRejectedUntouched) {
    const auto path = copy_of_good("corrupt.db");
    // Overwrite the second and third pages (table and index b-trees) with a pattern; the header stays valid.
    std::string bytes = read_text(path);
    ASSERT_GE(bytes.size(), 3u * 4096u);
    for (std::size_t i = 4096; i < 3 * 4096; ++i) bytes[i] = static_cast<char>(0xA5);
    write_text(path, bytes);
    expect_every_command_rejected(path, "corrupt");
}

TEST_F(HistoryBadInput, TruncatedDatabaseIsRejectedUntouched) {
    const auto path = copy_of_good("truncated.db");
    const std::string bytes = read_text(path);
    write_text(path, bytes.substr(0, 4096 + 1000));
    expect_every_command_rejected(path, "corrupt");
}

TEST_F(HistoryBadInput, FileThatIsNotSqliteIsRejectedUntouched) {
    const auto path = folder_ / "notes.db";
    write_text(path, "machine notes, not a database\n");
    expect_rejected(fmt::format("history {}", quoted(path)), path, path.string(), "not a feedid history database");
    expect_rejected(fmt::format("history {} --record {} --machine M1 --axis X", quoted(path), quoted(results_[3])),
                    path, path.string(), "not a feedid history database");
    expect_rejected(fmt::format("report {} -o {}", quoted(path), quoted(folder_ / "report.html")), path, path.string(),
                    "neither");
}

TEST_F(HistoryBadInput, NewerSchemaIsRejectedUntouched) {
    const auto path = copy_of_good("newer.db");
    execute(path, "PRAGMA user_version = 99");
    expect_every_command_rejected(path, "schema version 99, newer than this feedid");
}

TEST_F(HistoryBadInput, AnotherApplicationsSqliteFileIsRejectedUntouched) {
    const auto path = folder_ / "other.db";
    execute(path, "CREATE TABLE invoices (id INTEGER PRIMARY KEY, amount REAL); INSERT INTO invoices VALUES (1, 9.5)");
    expect_every_command_rejected(path, "another application");
}

TEST_F(HistoryBadInput, ResultOfTheWrongKindIsRejectedAndTheDatabaseUntouched) {
    // A trace (CSV) and a gains document (JSON, but not an identify result) where a result belongs.
    const auto csv = folder_ / "run-4.csv";
    const auto gains = folder_ / "gains.json";
    write_text(gains, R"({"gains": {"position_gain_per_s": {"value": 160.2, "stderr": 0.1}}, "diagnostics": []})");
    const auto empty = folder_ / "empty.json";
    write_text(empty, "");
    const std::string db = quoted(good_);
    expect_rejected(fmt::format("history {} --record {} --machine M1 --axis X", db, quoted(csv)), good_, csv.string(),
                    "not a JSON document");
    expect_rejected(fmt::format("history {} --record {} --machine M1 --axis X", db, quoted(gains)), good_,
                    gains.string(), "not a feedid identify result document");
    expect_rejected(fmt::format("history {} --record {} --machine M1 --axis X", db, quoted(empty)), good_,
                    empty.string(), "not a JSON document");
    // One bad file among good ones: nothing is recorded.
    expect_rejected(
        fmt::format("history {} --record {} --record {} --machine M1 --axis X", db, quoted(results_[3]), quoted(gains)),
        good_, gains.string(), "not a feedid identify result document");
    // The report of a wrong document.
    expect_rejected(fmt::format("report {} -o {}", quoted(csv), quoted(folder_ / "report.html")), good_, csv.string(),
                    "neither");
    expect_rejected(fmt::format("report {} -o {}", quoted(gains), quoted(folder_ / "report.html")), good_,
                    gains.string(), "not a feedid identify result document");
    // Missing names and a malformed time: rejected before the database is opened.
    expect_rejected(fmt::format("history {} --record {} --axis X", db, quoted(results_[3])), good_, "--machine",
                    "--machine");
    expect_rejected(
        fmt::format("history {} --record {} --machine M1 --axis X --recorded-at yesterday", db, quoted(results_[3])),
        good_, "yesterday", "not an ISO 8601");
    // A name PostgreSQL would refuse is refused on SQLite too (both backends hold the same runs)
    expect_rejected(
        fmt::format("history {} --record {} --machine \"$(printf 'M\\377')\" --axis X", db, quoted(results_[3])), good_,
        "--machine", "not valid UTF-8");
}

TEST_F(HistoryBadInput, AGoodDatabaseStillWorksAfterwards) {
    const auto r = run_shell(fmt::format("{} history {} --check", cli(), quoted(good_)), folder_);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    const auto report =
        run_shell(fmt::format("{} report {} -o {}", cli(), quoted(good_), quoted(folder_ / "good.html")), folder_);
    EXPECT_EQ(report.exit_code, 0) << report.err;
    EXPECT_TRUE(fs::exists(folder_ / "good.html"));
}

}  // namespace
