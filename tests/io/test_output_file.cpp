// Output files: replaced whole or not at all (a failed write, a full disk, a kill at any moment leave the old file and
// no temporary), and never written over an input or the history database.

#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <random>
#include <set>
#include <thread>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/io/output_file.hpp"
#include "history_testing.hpp"
#include "testing.hpp"

extern char** environ;

namespace {

using namespace feedid::testing;
namespace fs = std::filesystem;

/// The names in a folder.
std::set<std::string> names_in(const fs::path& folder) {
    std::set<std::string> names;
    for (const auto& entry : fs::directory_iterator(folder)) names.insert(entry.path().filename().string());
    return names;
}

/// The names in a folder that are feedid's temporaries (".NAME.feedid-PID.tmp").
std::vector<std::string> temporaries_in(const fs::path& folder) {
    std::vector<std::string> found;
    for (const auto& name : names_in(folder))
        if (name.find(".feedid-") != std::string::npos && name.ends_with(".tmp")) found.push_back(name);
    return found;
}

TEST(OutputFile, WritesANewFileAndReplacesAnOldOneKeepingItsPermissions) {
    const auto folder = temp_dir();
    const auto path = folder / "out.txt";
    feedid::write_output_file(path, "first\n");
    EXPECT_EQ(read_text(path), "first\n");
    fs::permissions(path, fs::perms::owner_read | fs::perms::owner_write);
    feedid::write_output_file(path, std::string(100000, 'x'));
    EXPECT_EQ(read_text(path), std::string(100000, 'x'));
    EXPECT_EQ(fs::status(path).permissions() & fs::perms::all, fs::perms::owner_read | fs::perms::owner_write);
    EXPECT_EQ(names_in(folder), std::set<std::string>{"out.txt"});
}

TEST(OutputFile, WritesThroughASymbolicLinkToItsTarget) {
    const auto folder = temp_dir();
    feedid::write_output_file(folder / "target.txt", "old\n");
    fs::create_symlink("target.txt", folder / "link.txt");
    feedid::write_output_file(folder / "link.txt", "new\n");
    EXPECT_TRUE(fs::is_symlink(folder / "link.txt"));
    EXPECT_EQ(read_text(folder / "target.txt"), "new\n");
}

TEST(OutputFile, AFailureNamesThePathAndTheReasonAndLeavesNothing) {
    const auto folder = temp_dir();
    try {
        feedid::write_output_file(folder / "missing-folder" / "out.txt", "x");
        ADD_FAILURE() << "wrote into a folder that does not exist";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(
            std::string(e.what()).find("missing-folder/out.txt: cannot write the file: No such file or directory"),
            std::string::npos)
            << e.what();
    }
    EXPECT_THROW(feedid::write_output_file(folder, "x"), feedid::InputError);  // a folder
    EXPECT_TRUE(names_in(folder).empty());
}

// A kill between naming the temporary and the rename can leave `.NAME.feedid-PID.tmp`; the next write removes it
// when its process is gone, and leaves a running writer's alone.
TEST(OutputFile, TheNextWriteRemovesTemporariesOfDeadProcesses) {
    const auto folder = temp_dir();
    const auto path = folder / "out.txt";
    pid_t dead = fork();
    if (dead == 0) _exit(0);
    waitpid(dead, nullptr, 0);
    write_text(folder / fmt::format(".out.txt.feedid-{}.tmp", dead), "left by a killed writer");
    write_text(folder / fmt::format(".out.txt.feedid-{}.tmp", getppid()), "a running writer's");
    feedid::write_output_file(path, "new\n");
    EXPECT_EQ(names_in(folder), (std::set<std::string>{"out.txt", fmt::format(".out.txt.feedid-{}.tmp", getppid())}));
}

TEST(OutputFile, AnOutputThatIsAnInputOrTheDatabaseIsRefused) {
    const auto folder = temp_dir();
    write_text(folder / "shop.db", "a database");
    write_text(folder / "trace.csv", "t,x\n");
    fs::create_hard_link(folder / "shop.db", folder / "hard.db");
    fs::create_symlink("shop.db", folder / "soft.db");
    fs::create_directories(folder / "sub");
    const std::vector<feedid::GuardedFile> guarded{{"the trace", (folder / "trace.csv").string()},
                                                   {"the history database", (folder / "shop.db").string(), true}};
    const auto refused = [&](const fs::path& output, const std::string& says) {
        try {
            feedid::require_separate_outputs({{"--json", output.string()}}, guarded);
            ADD_FAILURE() << output << " was allowed";
        } catch (const feedid::InputError& e) {
            EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
        }
    };
    refused(folder / "shop.db", "is the history database");
    refused(folder / "hard.db", "is the history database");  // the same inode
    refused(folder / "soft.db", "is the history database");  // a link to it
    refused(folder / "sub" / ".." / "trace.csv", "is the trace");
    refused(folder / "shop.db-wal", "companion file of the history database");  // not there yet: by path
    EXPECT_NO_THROW(
        feedid::require_separate_outputs({{"--json", (folder / "result.json").string()}, {"-o", "-"}}, guarded));
    EXPECT_NO_THROW(feedid::require_separate_outputs({{"--json", "/dev/null"}}, {{"the trace", "/dev/null"}}));
    EXPECT_THROW(feedid::require_separate_outputs(
                     {{"--json", (folder / "a.json").string()}, {"--out", (folder / "a.json").string()}}, {}),
                 feedid::InputError);
    EXPECT_EQ(read_text(folder / "shop.db"), "a database");
}

// The reproduced cases of the issue: each command that named the database as its output destroyed it.
TEST(OutputFileCli, NoCommandWritesOverTheHistoryDatabase) {
    const auto folder = temp_dir();
    const auto results = write_small_results(folder, "run", 2);
    const auto database = folder / "shop.db";
    const std::string db = quoted(database);
    ASSERT_EQ(
        run_shell(fmt::format("{} history {} --record {} --machine M --axis X", cli(), db, quoted(results[0])), folder)
            .exit_code,
        0);
    const std::string before = read_text(database);
    for (const std::string& arguments :
         {fmt::format("history {0} --json {0}", db), fmt::format("history {0} --csv {0}", db),
          fmt::format("report {0} -o {0}", db), fmt::format("report {} -o {}", quoted(results[1]), quoted(results[1])),
          fmt::format("history {} --record {} --machine M --axis X --json {}", db, quoted(results[1]),
                      quoted(results[1])),
          fmt::format("identify {} --force-constant 1 --record {} --machine M --axis X --json {}",
                      quoted(folder / "run-1.csv"), db, db),
          fmt::format("identify {0} --json {0}", quoted(folder / "run-1.csv"))}) {
        SCOPED_TRACE(arguments);
        const std::string results_before = read_text(results[1]);
        const auto r = run_shell(cli() + " " + arguments, folder);
        EXPECT_EQ(r.exit_code, 2) << r.err;
        EXPECT_EQ(count_lines(r.err), 1) << r.err;
        EXPECT_NE(r.err.find("refusing to overwrite it"), std::string::npos) << r.err;
        EXPECT_TRUE(read_text(database) == before) << "the database changed";
        EXPECT_EQ(read_text(results[1]), results_before);
    }
}

TEST(OutputFileCli, AWriteToAFullDeviceIsExitTwoNamingIt) {
    const auto folder = temp_dir();
    const auto results = write_small_results(folder, "run", 1);
    const auto database = folder / "shop.db";
    ASSERT_EQ(run_shell(fmt::format("{} history {} --record {} --machine M --axis X", cli(), quoted(database),
                                    quoted(results[0])),
                        folder)
                  .exit_code,
              0);
    for (const std::string& arguments : {fmt::format("history {} --csv /dev/full", quoted(database)),
                                         fmt::format("history {} --json /dev/full", quoted(database)),
                                         fmt::format("report {} -o /dev/full", quoted(database))}) {
        SCOPED_TRACE(arguments);
        const auto r = run_shell(cli() + " " + arguments, folder);
        EXPECT_EQ(r.exit_code, 2) << r.err;
        EXPECT_NE(r.err.find("/dev/full: cannot write the file: No space left on device"), std::string::npos) << r.err;
    }
}

// A write that fails half-way (here: beyond the file-size limit, EFBIG) leaves the old file as it was.
TEST(OutputFileCli, AWriteThatFailsHalfWayLeavesTheOldFileWhole) {
    const auto folder = temp_dir();
    const auto results = write_small_results(folder, "run", 1);
    const auto report = folder / "report.html";
    write_text(report, "the old report\n");
    // ulimit -f counts 1024-byte blocks; SIGXFSZ ignored, so the write returns EFBIG instead of killing
    const auto r = run_shell(
        fmt::format("trap '' XFSZ; ulimit -f 1; {} report {} -o {}", cli(), quoted(results[0]), quoted(report)),
        folder);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find(report.string() + ": cannot write the file: File too large"), std::string::npos) << r.err;
    EXPECT_EQ(read_text(report), "the old report\n");
    // a new file that cannot be written whole is not made at all (it was left empty)
    const auto fresh = folder / "new.html";
    const auto r2 = run_shell(
        fmt::format("trap '' XFSZ; ulimit -f 1; {} report {} -o {}", cli(), quoted(results[0]), quoted(fresh)), folder);
    EXPECT_EQ(r2.exit_code, 2) << r2.err;
    EXPECT_FALSE(fs::exists(fresh));
    EXPECT_TRUE(temporaries_in(folder).empty());
}

// On a full file system (a 256 kB tmpfs in a mount namespace of its own) an existing report stays whole.
TEST(OutputFileCli, AFullDiskLeavesTheOldFileWhole) {
    const auto folder = temp_dir();
    const auto results = write_small_results(folder, "run", 1);
    const auto database = folder / "shop.db";
    ASSERT_EQ(run_shell(fmt::format("{} history {} --record {} --machine M --axis X", cli(), quoted(database),
                                    quoted(results[0])),
                        folder)
                  .exit_code,
              0);
    const auto script = folder / "full-disk.sh";
    write_text(script, fmt::format(R"(set -e
disk={0}/disk
mkdir -p "$disk"
mount -t tmpfs -o size=256k tmpfs "$disk" || exit 77
printf 'the old report\n' > "$disk/report.html"
head -c 262144 /dev/zero > "$disk/filler" 2>/dev/null || true
set +e
{1} report {2} -o "$disk/report.html"
echo "exit $?"
{1} history {3} --csv "$disk/new.csv"
echo "csv exit $?"
cat "$disk/report.html"
ls -a "$disk"
)",
                                   folder.string(), cli(), quoted(results[0]), quoted(database)));
    const auto r = run_shell(fmt::format("unshare -m sh {}", quoted(script)), folder);
    if (r.exit_code == 77 || r.out.find("exit") == std::string::npos)
        GTEST_SKIP() << "cannot mount a tmpfs here (needs CAP_SYS_ADMIN): " << r.err;
    EXPECT_NE(r.out.find("exit 2"), std::string::npos) << r.out << r.err;
    EXPECT_NE(r.err.find("report.html: cannot write the file: No space left on device"), std::string::npos) << r.err;
    EXPECT_NE(r.out.find("the old report\n"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("csv exit 2"), std::string::npos) << r.out << r.err;
    EXPECT_EQ(r.out.find("new.csv"), std::string::npos) << "an empty file was left: " << r.out;
    EXPECT_EQ(r.out.find(".feedid-"), std::string::npos) << "a temporary was left: " << r.out;
}

// A file the user may write in a folder they may not: it is not overwritten in place (that would not be atomic);
// the message says which folder.
TEST(OutputFileCli, AFolderThatIsNotWritableIsNamed) {
    if (::geteuid() != 0 || !fs::exists("/usr/bin/setpriv"))
        GTEST_SKIP() << "needs root and setpriv to run feedid as another user (uid 65534)";
    const auto folder = temp_dir();
    const auto results = write_small_results(folder, "run", 1);
    const auto locked = folder / "locked";
    fs::create_directories(locked);
    const auto report = locked / "report.html";
    write_text(report, "the old report\n");
    fs::permissions(report, fs::perms::all);  // anyone may write the file, only root the folder
    fs::permissions(folder, fs::perms::all);  // the captured output lands here
    const auto r =
        run_shell(fmt::format("/usr/bin/setpriv --reuid=65534 --regid=65534 --clear-groups {} report {} -o {}", cli(),
                              quoted(results[0]), quoted(report)),
                  folder);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("cannot write the file: the folder " + locked.string() + " is not writable"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(read_text(report), "the old report\n");
}

/// Starts the feedid binary with `arguments` (stdout and stderr to /dev/null); its pid.
pid_t spawn_cli(const std::vector<std::string>& arguments) {
    std::vector<std::string> argv_text{FEEDID_CLI};
    argv_text.insert(argv_text.end(), arguments.begin(), arguments.end());
    std::vector<char*> argv;
    for (auto& a : argv_text) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
    pid_t pid = -1;
    const int error = posix_spawn(&pid, FEEDID_CLI, &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    EXPECT_EQ(error, 0);
    return pid;
}

/// One command that rewrites an existing output: its arguments, the output, and the output's two complete versions.
struct Rewrite {
    std::string name;
    std::vector<std::string> arguments;
    fs::path output;
    std::string old_text;
    std::string new_text;
    double seconds{0.0};  // how long a run takes to its end
};

/// Runs a command to its end and returns how long it took.
double run_to_end(const std::vector<std::string>& arguments) {
    const auto start = std::chrono::steady_clock::now();
    const pid_t pid = spawn_cli(arguments);
    int status = 0;
    waitpid(pid, &status, 0);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// 100 SIGKILLs at random moments of report, identify --json and synth --out, each over an existing complete output:
// afterwards the output is always the old file or the new one, byte for byte, never empty or cut; and no temporary
// is left (a kill in the instant between naming the finished temporary and the rename may leave one: the next run's
// write removes it, which the end of the test checks).
TEST(OutputFileKill, AKilledCommandLeavesTheOldOutputOrTheNewOneWhole) {
    const auto folder = temp_dir();
    const auto inputs = folder / "inputs";
    const auto outputs = folder / "outputs";
    fs::create_directories(inputs);
    fs::create_directories(outputs);
    const auto trace = inputs / "trace.csv";
    const auto result = inputs / "result.json";
    ASSERT_EQ(run_to_end({"synth", "--seed", "3", "--out", trace.string()}) > 0.0, true);
    ASSERT_GT(run_to_end({"identify", trace.string(), "--force-constant", "force_constant_N_per_A", "--json",
                          result.string()}),
              0.0);
    std::vector<Rewrite> rewrites{{"report",
                                   {"report", result.string(), "-o", (outputs / "report.html").string()},
                                   outputs / "report.html",
                                   "",
                                   "",
                                   0.0},
                                  {"identify",
                                   {"identify", trace.string(), "--force-constant", "force_constant_N_per_A", "--json",
                                    (outputs / "result.json").string()},
                                   outputs / "result.json",
                                   "",
                                   "",
                                   0.0},
                                  {"synth",
                                   {"synth", "--seed", "4", "--out", (outputs / "synth.csv").string()},
                                   outputs / "synth.csv",
                                   "",
                                   "",
                                   0.0}};
    for (auto& rewrite : rewrites) {
        rewrite.seconds = run_to_end(rewrite.arguments);
        rewrite.new_text = read_text(rewrite.output);
        rewrite.old_text = "the old " + rewrite.name + " output, complete\n" + std::string(50000, '.') + "\n";
        ASSERT_GT(rewrite.new_text.size(), 1000u) << rewrite.name;
    }
    std::mt19937 generator(14);
    int kills = 0;
    int old_kept = 0;
    int new_found = 0;
    int temporaries_seen = 0;
    for (int k = 0; k < 100; ++k) {
        const auto& rewrite = rewrites[static_cast<std::size_t>(k) % rewrites.size()];
        write_text(rewrite.output, rewrite.old_text);
        // a moment anywhere in the run, now and then just after it
        std::uniform_real_distribution<double> moment(0.0, 1.5 * rewrite.seconds);
        const pid_t pid = spawn_cli(rewrite.arguments);
        std::this_thread::sleep_for(std::chrono::duration<double>(moment(generator)));
        kill(pid, SIGKILL);
        int status = 0;
        waitpid(pid, &status, 0);
        kills += WIFSIGNALED(status) ? 1 : 0;
        const std::string text = read_text(rewrite.output);
        const bool old_file = text == rewrite.old_text;
        const bool new_file = text == rewrite.new_text;
        EXPECT_TRUE(old_file || new_file) << rewrite.name << ", kill " << k << ": " << text.size() << " bytes";
        old_kept += old_file ? 1 : 0;
        new_found += new_file ? 1 : 0;
        temporaries_seen += static_cast<int>(temporaries_in(outputs).size());
    }
    // each command once more to its end: whatever a kill left is gone
    for (const auto& rewrite : rewrites) run_to_end(rewrite.arguments);
    EXPECT_TRUE(temporaries_in(outputs).empty());
    EXPECT_EQ(names_in(outputs), (std::set<std::string>{"report.html", "result.json", "synth.csv"}));
    // the kills landed before, during and after the writes
    EXPECT_GE(kills, 30);
    EXPECT_GE(old_kept, 10);
    EXPECT_GE(new_found, 3);
    std::cout << kills << " processes killed; the old output kept " << old_kept << " times, the new one complete "
              << new_found << " times; temporaries seen right after a kill: " << temporaries_seen << "\n";
}

}  // namespace
