// How the history file is opened: readers that may not write create nothing and lock nobody out; permission, a
// read-only mount, a full disk, a folder that cannot be searched, a loop of symbolic links, a FIFO or a device are
// named as such (exit 2, never "corrupt", never an internal error); --pin creates no file; --verify runs the full
// integrity check; text from the file is escaped on the terminal; overlong stored text is cut with a finding.

#include <gtest/gtest.h>

#include <sqlite3.h>

#include <sys/stat.h>
#include <unistd.h>

#include <set>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "history_testing.hpp"
#include "testing.hpp"

namespace {

using namespace feedid::testing;
namespace fs = std::filesystem;

std::set<std::string> listing(const fs::path& folder) {
    std::set<std::string> names;
    for (const auto& entry : fs::directory_iterator(folder)) names.insert(entry.path().filename().string());
    return names;
}

/// Executes SQL on a file through SQLite itself (to damage a history as a disk or another program might).
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

/// Skips the test unless it runs as root with setpriv: the permission tests act as user 65534 (nobody), and only
/// root may switch to it (as root, every permission check passes).
#define REQUIRE_ANOTHER_USER()                                                                  \
    do {                                                                                        \
        if (::geteuid() != 0 || !fs::exists("/usr/bin/setpriv"))                                \
            GTEST_SKIP() << "needs root and setpriv to run feedid as another user (uid 65534)"; \
    } while (0)

/// The feedid command line run as user 65534.
std::string as_nobody(const std::string& arguments) {
    return "/usr/bin/setpriv --reuid=65534 --regid=65534 --clear-groups " + cli() + " " + arguments;
}

class HistoryAccess : public ::testing::Test {
protected:
    void SetUp() override {
        folder_ = temp_dir();
        scratch_ = folder_ / "scratch";  // captured output, results, reports: writable by everyone
        shop_ = folder_ / "shop";
        fs::create_directories(scratch_);
        fs::create_directories(shop_);
        fs::permissions(scratch_, fs::perms::all);
        results_ = write_small_results(scratch_, "run", 3);
        database_ = shop_ / "shop.db";
        record(results_[0]);
        record(results_[1]);
    }

    void record(const fs::path& result) {
        const auto r = run_shell(
            fmt::format("{} history {} --record {} --machine M --axis X", cli(), quoted(database_), quoted(result)),
            scratch_);
        ASSERT_EQ(r.exit_code, 0) << r.err;
    }

    CliResult shell(const std::string& command) { return run_shell(command, scratch_); }

    fs::path folder_;
    fs::path scratch_;
    fs::path shop_;
    fs::path database_;
    std::vector<fs::path> results_;
};

// The issue: --check as another user left DB-wal and DB-shm owned by that user, and the owner could no longer write.
TEST_F(HistoryAccess, AReaderThatMayNotWriteCreatesNothingAndLocksNobodyOut) {
    REQUIRE_ANOTHER_USER();
    for (const auto mode : {fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                                fs::perms::others_read | fs::perms::others_exec,  // 0755: the folder is not theirs
                            fs::perms::all | fs::perms::sticky_bit}) {            // 1777: like /tmp
        fs::permissions(shop_, mode);
        const auto before = listing(shop_);
        const std::string bytes = read_text(database_);
        for (const std::string& arguments :
             {fmt::format("history {}", quoted(database_)), fmt::format("history {} --check", quoted(database_)),
              fmt::format("history {} --json -", quoted(database_)),
              fmt::format("history {} --csv -", quoted(database_)),
              fmt::format("report {} -o {}", quoted(database_), quoted(scratch_ / "report.html"))}) {
            SCOPED_TRACE(arguments);
            const auto r = shell(as_nobody(arguments));
            EXPECT_EQ(r.exit_code, 0) << r.err;
            EXPECT_EQ(listing(shop_), before);
        }
        EXPECT_TRUE(read_text(database_) == bytes);
    }
    record(results_[2]);  // the owner still writes
}

TEST_F(HistoryAccess, AWriterWithoutPermissionIsToldWhyAndNothingChanges) {
    REQUIRE_ANOTHER_USER();
    const std::string bytes = read_text(database_);
    const auto refused = [&](const std::string& arguments, const std::string& says) {
        SCOPED_TRACE(arguments);
        const auto r = shell(as_nobody(arguments));
        EXPECT_EQ(r.exit_code, 2) << r.err;
        EXPECT_EQ(count_lines(r.err), 1) << r.err;
        EXPECT_NE(r.err.find(says), std::string::npos) << r.err;
        EXPECT_EQ(r.err.find("corrupt"), std::string::npos) << r.err;
        EXPECT_TRUE(read_text(database_) == bytes);
        EXPECT_EQ(listing(shop_), std::set<std::string>{"shop.db"});
    };
    const std::string record =
        fmt::format("history {} --record {} --machine M --axis X", quoted(database_), quoted(results_[2]));
    // the file is not theirs to write (the folder is)
    fs::permissions(shop_, fs::perms::all);
    refused(record, "cannot record: no permission to write the file");
    refused(fmt::format("history {} --pin 1", quoted(database_)), "cannot record: no permission to write the file");
    refused(
        fmt::format("identify {} --record {} --machine M --axis X", quoted(scratch_ / "run-1.csv"), quoted(database_)),
        "cannot record: no permission to write the file");
    // the file is, the folder is not: SQLite could not create DB-wal (this was reported as "corrupt")
    fs::permissions(shop_, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                               fs::perms::others_read | fs::perms::others_exec);
    fs::permissions(database_, fs::perms::all);
    refused(record, "no permission to write in the folder " + shop_.string());
}

TEST_F(HistoryAccess, AFolderThatCannotBeSearchedIsNamed) {
    REQUIRE_ANOTHER_USER();
    fs::permissions(shop_, fs::perms::owner_all);
    for (const std::string& arguments :
         {fmt::format("history {}", quoted(database_)), fmt::format("history {} --check", quoted(database_)),
          fmt::format("report {} -o {}", quoted(database_), quoted(scratch_ / "report.html"))}) {
        SCOPED_TRACE(arguments);
        const auto r = shell(as_nobody(arguments));
        EXPECT_EQ(r.exit_code, 2) << r.err;
        EXPECT_NE(r.err.find("ermission denied"), std::string::npos) << r.err;
        EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
    }
}

// A read-only mount (a tmpfs in a mount namespace of its own): readers read, a writer is told why; and the same
// file system full: the record is refused and the file stays whole.
TEST_F(HistoryAccess, AReadOnlyMountAndAFullDiskAreNamed) {
    const auto script = scratch_ / "mounts.sh";
    write_text(script, fmt::format(R"(disk={0}/disk
mkdir -p "$disk"
mount -t tmpfs -o size=2m tmpfs "$disk" || exit 77
cp {1} "$disk/shop.db"
mount -o remount,ro "$disk" || exit 77
{2} history "$disk/shop.db" --check; echo "check $?"
{2} history "$disk/shop.db" --record {3} --machine M --axis X; echo "record $?"
ls -a "$disk"
mount -o remount,rw,size=80k "$disk" || exit 77
head -c 200000 /dev/zero > "$disk/filler" 2>/dev/null
{2} history "$disk/shop.db" --record {3} --machine M --axis X; echo "full $?"
rm -f "$disk/filler"
{2} history "$disk/shop.db" --verify; echo "verify $?"
{2} history "$disk/shop.db" --json - | grep -c '"id"'
)",
                                   scratch_.string(), quoted(database_), cli(), quoted(results_[2])));
    const auto r = shell(fmt::format("unshare -m sh {}", quoted(script)));
    if (r.exit_code == 77 || r.out.find("check") == std::string::npos)
        GTEST_SKIP() << "cannot mount a tmpfs here (needs CAP_SYS_ADMIN): " << r.err;
    EXPECT_NE(r.out.find("check 0"), std::string::npos) << r.out << r.err;
    EXPECT_NE(r.out.find("record 2"), std::string::npos) << r.out;
    EXPECT_NE(r.err.find("cannot record: the file system is mounted read-only"), std::string::npos) << r.err;
    EXPECT_EQ(r.out.find("shop.db-"), std::string::npos) << "a file was created: " << r.out;
    EXPECT_NE(r.out.find("full 2"), std::string::npos) << r.out;
    EXPECT_NE(r.err.find("the disk is full"), std::string::npos) << r.err;
    EXPECT_NE(r.out.find("verify 0"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("\n2\n"), std::string::npos) << "the two runs, no more: " << r.out;
}

TEST_F(HistoryAccess, WhatIsNotAFileIsNamedAndNothingIsCreated) {
    const auto fifo = shop_ / "fifo.db";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
    fs::create_symlink("loop-b.db", shop_ / "loop-a.db");
    fs::create_symlink("loop-a.db", shop_ / "loop-b.db");
    const std::vector<std::pair<std::string, std::string>> cases{
        {fifo.string(), "is not a regular file (a FIFO, a device or a socket)"},
        {"/dev/null", "is not a regular file"},
        {(shop_ / "loop-a.db").string(), "a loop of symbolic links"},
        {shop_.string(), "is a folder"},
        {(shop_ / "shop.db" / "x.db").string(), "a part of the path is not a folder"},
    };
    for (const auto& [text, says] : cases) {
        const fs::path path = text;
        for (const std::string& arguments :
             {fmt::format("history {}", quoted(path)), fmt::format("history {} --check", quoted(path)),
              fmt::format("history {} --record {} --machine M --axis X", quoted(path), quoted(results_[2])),
              fmt::format("history {} --pin 1", quoted(path))}) {
            SCOPED_TRACE(arguments);
            const auto r = shell("timeout 20 " + cli() + " " + arguments);
            EXPECT_EQ(r.exit_code, 2) << r.err;
            EXPECT_NE(r.err.find(says), std::string::npos) << r.err;
        }
    }
    // --pin names a run of an existing history: a missing file is not created (it was, with 32 kB, before exit 2)
    const auto missing = shop_ / "new.db";
    const auto r = shell(fmt::format("{} history {} --pin 3", cli(), quoted(missing)));
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("no such history database"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(missing));
}

// An index that lost its rows: quick_check (a reader's) does not see it; a writer's full check does, and so does
// --verify.
TEST_F(HistoryAccess, VerifyAndWritersFindABrokenIndex) {
    const auto good = shell(fmt::format("{} history {} --verify", cli(), quoted(database_)));
    EXPECT_EQ(good.exit_code, 0) << good.err;
    EXPECT_NE(good.out.find(": ok"), std::string::npos) << good.out;
    // the index emptied (made as a partial index of no row), then declared whole again
    execute(database_,
            "DROP INDEX runs_by_axis;"
            "CREATE INDEX runs_by_axis ON runs (machine, axis, recorded_at) WHERE 0;"
            "PRAGMA writable_schema = ON;"
            "UPDATE sqlite_master SET sql = 'CREATE INDEX runs_by_axis ON runs (machine, axis, recorded_at)' "
            "WHERE name = 'runs_by_axis';"
            "PRAGMA writable_schema = OFF;");
    const std::string bytes = read_text(database_);
    const auto verify = shell(fmt::format("{} history {} --verify", cli(), quoted(database_)));
    EXPECT_EQ(verify.exit_code, 2);
    EXPECT_NE(verify.out.find("row 1 missing from index runs_by_axis"), std::string::npos) << verify.out;
    EXPECT_NE(verify.err.find("the history database is damaged"), std::string::npos) << verify.err;
    const auto recorded = shell(
        fmt::format("{} history {} --record {} --machine M --axis X", cli(), quoted(database_), quoted(results_[2])));
    EXPECT_EQ(recorded.exit_code, 2);
    EXPECT_NE(recorded.err.find("corrupt (SQLite's check: row 1 missing from index runs_by_axis"), std::string::npos)
        << recorded.err;
    EXPECT_TRUE(read_text(database_) == bytes);
}

// Names and text from files are escaped on the terminal: a machine named with escape sequences retitles or clears
// no terminal, and bytes that are not UTF-8 show as \xNN.
TEST_F(HistoryAccess, TextFromInputsIsEscapedOnTheTerminal) {
    const auto database = shop_ / "escapes.db";
    const std::string machine = R"x("$(printf 'M\033]0;T\007\033[2J')")x";
    // a baseline of 8 steady runs, then Coulomb friction 5 % up: the alarm names the machine
    for (int i = 1; i <= 12; ++i) {
        const auto trace = scratch_ / fmt::format("e-{}.csv", i);
        write_text(trace, fmt::format("t [s],x [mm]\n0,{}\n0.001,{}\n", i, i + 1));
        auto result = small_result(trace, (i <= 9 ? 740.0 : 777.0) + 0.3 * (i % 3));
        write_text(scratch_ / fmt::format("e-{}.json", i), result.dump());
        const auto r =
            shell(fmt::format("{} history {} --record {} --machine {} --axis X --recorded-at "
                              "2026-01-{:02}T06:00:00Z",
                              cli(), quoted(database), quoted(scratch_ / fmt::format("e-{}.json", i)), machine, i));
        ASSERT_EQ(r.exit_code, 0) << r.err;
    }
    const auto table = shell(fmt::format("{} history {}", cli(), quoted(database)));
    const auto check = shell(fmt::format("{} history {} --check", cli(), quoted(database)));
    EXPECT_EQ(check.exit_code, 1) << check.out << check.err;
    for (const auto* output : {&table.out, &check.out}) {
        EXPECT_EQ(output->find('\033'), std::string::npos) << *output;
        EXPECT_EQ(output->find('\007'), std::string::npos) << *output;
        EXPECT_NE(output->find(R"(machine 'M\x1b]0;T\x07\x1b[2J')"), std::string::npos) << *output;
    }
    // the JSON listing keeps the name as it is (JSON escapes it its own way)
    const auto json = shell(fmt::format("{} history {} --json -", cli(), quoted(database)));
    EXPECT_EQ(nlohmann::json::parse(json.out)["runs"][0]["machine"], "M\033]0;T\007\033[2J");
    // a message quoting a damaged file's bytes
    write_text(scratch_ / "bad.csv", "t [s],x [m\xffm]\n0,1\n0.1,2\n");
    const auto info = shell(fmt::format("{} info {}", cli(), quoted(scratch_ / "bad.csv")));
    EXPECT_EQ(info.exit_code, 2);
    EXPECT_NE(info.err.find(R"(unknown unit 'm\xffm')"), std::string::npos) << info.err;
    EXPECT_EQ(info.err.find('\xff'), std::string::npos);
}

// Diagnostics of 10 MB (a document under the 64 MiB input limit) are stored cut, with a finding; 100 MB are refused.
TEST_F(HistoryAccess, OverlongTextIsCutWithAFindingAndHugeDocumentsRefused) {
    auto result = small_result(scratch_ / "run-3.csv", 740.3);
    result["diagnostics"] = {std::string(10'000'000, 'd'), "a short one"};
    write_text(scratch_ / "long.json", result.dump());
    const auto recorded = shell(fmt::format("{} history {} --record {} --machine M --axis X", cli(), quoted(database_),
                                            quoted(scratch_ / "long.json")));
    EXPECT_EQ(recorded.exit_code, 0) << recorded.err.substr(0, 500);
    EXPECT_NE(recorded.err.find("warning:"), std::string::npos) << recorded.err.substr(0, 500);
    EXPECT_NE(recorded.err.find("cut to that length"), std::string::npos) << recorded.err.substr(0, 500);
    EXPECT_LT(fs::file_size(database_), 1'000'000u);
    const auto json = shell(fmt::format("{} history {} --json -", cli(), quoted(database_)));
    const auto diagnostics = nlohmann::json::parse(json.out)["runs"][2]["diagnostics"];
    ASSERT_EQ(diagnostics.size(), 3u) << diagnostics.dump().substr(0, 300);
    EXPECT_LT(diagnostics[0].get<std::string>().size(), 4200u);
    EXPECT_NE(diagnostics[0].get<std::string>().find("[cut: 4096 of 10000000 bytes kept]"), std::string::npos);
    EXPECT_EQ(diagnostics[1], "a short one");
    EXPECT_NE(diagnostics[2].get<std::string>().find("recording: "), std::string::npos);

    result["diagnostics"] = {std::string(100'000'000, 'd')};
    write_text(scratch_ / "huge.json", result.dump());
    const std::string bytes = read_text(database_);
    const auto refused = shell(fmt::format("{} history {} --record {} --machine M --axis X", cli(), quoted(database_),
                                           quoted(scratch_ / "huge.json")));
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_NE(refused.err.find("larger than 64 MiB, the limit for a JSON document"), std::string::npos) << refused.err;
    EXPECT_TRUE(read_text(database_) == bytes);
}

}  // namespace
