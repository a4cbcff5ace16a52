#pragma once
// Helpers shared by the tests: where the reference data lives, running the feedid CLI, temporary files.

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <vector>

namespace feedid::testing {

/// ../shared/data (a CMake cache variable); tests that need it skip with a message when it is absent.
inline std::filesystem::path shared_data() {
    return FEEDID_SHARED_DATA;
}

#define FEEDID_REQUIRE_SHARED(relative)                                                                     \
    do {                                                                                                    \
        if (!std::filesystem::exists(::feedid::testing::shared_data() / (relative)))                        \
            GTEST_SKIP() << "reference data not found: " << (::feedid::testing::shared_data() / (relative)) \
                         << " (set -DFEEDID_SHARED_DATA=...)";                                              \
    } while (0)

struct CliResult {
    int exit_code{-1};
    std::string out;
    std::string err;
};

/// The folder of this build's test files (build/test-files): never shared with another build's test run.
inline std::filesystem::path test_files_root() {
    return std::filesystem::path(FEEDID_TEST_TMP);
}

/// The test folders this process made, removed when it exits if every test it ran passed (a failing test's files
/// stay for a look). The disk of a CI machine is not large: a suite that synthesizes production traces writes
/// gigabytes, and ctest runs over 600 test processes one after the other.
class TestFolders {
public:
    static TestFolders& instance() {
        static TestFolders folders;
        return folders;
    }
    void add(const std::filesystem::path& dir) {
        if (std::find(dirs_.begin(), dirs_.end(), dir) == dirs_.end()) dirs_.push_back(dir);
    }
    TestFolders(const TestFolders&) = delete;
    TestFolders& operator=(const TestFolders&) = delete;

private:
    TestFolders() = default;
    ~TestFolders() {
        // gtest's UnitTest was made before the first test folder, so it is destroyed after this
        const auto* unit = ::testing::UnitTest::GetInstance();
        if (unit == nullptr || !unit->Passed()) return;
        for (const auto& dir : dirs_) {
            std::error_code error;
            std::filesystem::remove_all(dir, error);
        }
    }
    std::vector<std::filesystem::path> dirs_;
};

/// A fresh folder for the running test's files, named after the test.
inline std::filesystem::path temp_dir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    auto dir = test_files_root() / (std::string(info->test_suite_name()) + "." + info->name());
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    TestFolders::instance().add(dir);
    return dir;
}

/// LinuxCNC's rs274 interpreter (Debian's linuxcnc-uspace: /usr/bin/rs274, or on PATH); empty when absent.
inline std::filesystem::path find_rs274() {
    for (const char* candidate : {"/usr/bin/rs274", "/usr/local/bin/rs274"}) {
        if (std::filesystem::exists(candidate)) return candidate;
    }
    if (const char* path = std::getenv("PATH")) {
        std::string folders(path);
        for (std::size_t start = 0, end; start <= folders.size(); start = end + 1) {
            end = std::min(folders.find(':', start), folders.size());
            const auto candidate = std::filesystem::path(folders.substr(start, end - start)) / "rs274";
            if (end > start && std::filesystem::exists(candidate)) return candidate;
        }
    }
    return {};
}

/// Runs `rs274 -g PROGRAM` in `dir` (out.txt, err.txt there) and returns its wait status. HOME is `dir` too: rs274
/// maps its tool table at $HOME/.tool.mmap, truncated by every run, so two at once in one HOME kill each other with
/// a bus error (ctest runs tests in parallel processes).
inline int run_rs274(const std::filesystem::path& rs274, const std::filesystem::path& program,
                     const std::filesystem::path& dir) {
    const std::string command = "cd '" + dir.string() + "' && HOME='" + dir.string() + "' '" + rs274.string() +
                                "' -g '" + program.string() + "' >out.txt 2>err.txt </dev/null";
    return std::system(command.c_str());
}

/// A folder for files a test suite shares between its tests, of this process only: ctest runs each test in its own
/// process, in parallel, and a file one process rewrites while another reads it (mapped) is a crash, not a test.
inline std::filesystem::path suite_dir(const std::string& name) {
    auto dir = test_files_root() / (name + "-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    TestFolders::instance().add(dir);
    return dir;
}

inline std::string read_text(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

inline void write_text(const std::filesystem::path& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    out << text;
}

/// Runs the feedid binary with a shell-quoted argument string; captures stdout, stderr and the exit code.
inline CliResult run_cli(const std::string& arguments) {
    // beside the tests' folders, never inside one: a test's files must survive the commands it runs
    const auto dir = test_files_root() / "cli-capture";
    std::filesystem::create_directories(dir);
    static int counter = 0;
    const auto out_path = dir / ("out" + std::to_string(::getpid()) + "_" + std::to_string(counter) + ".txt");
    const auto err_path = dir / ("err" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + ".txt");
    const std::string command = std::string("'") + FEEDID_CLI + "' " + arguments + " >'" + out_path.string() + "' 2>'" +
                                err_path.string() + "' </dev/null";
    const int status = std::system(command.c_str());
    CliResult result;
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    result.out = read_text(out_path);
    result.err = read_text(err_path);
    std::filesystem::remove(out_path);
    std::filesystem::remove(err_path);
    return result;
}

/// Counts the lines of a message (a "one clear message" is one line).
inline int count_lines(const std::string& text) {
    int lines = 0;
    for (const char c : text) lines += c == '\n';
    return lines;
}

}  // namespace feedid::testing
