// feedid: the command line. A thin main over the library; each subcommand lives in its own file.
#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>

#include <malloc.h>
#include <unistd.h>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/core/terminal_text.hpp"
#include "feedid/core/version.hpp"

namespace {

// Columns of millions of samples are allocated and freed many times over an identification (every preprocessing run
// filters, differentiates and thresholds several). By default glibc maps each block above its threshold afresh and
// trims freed memory back to the kernel, so each allocation is faulted in again page by page, and on a virtual machine
// a page fault costs microseconds: on the million-sample trace a third of identify's time went to faults. Blocks up to
// the largest threshold glibc allows (32 MiB, 4 million samples) now come from the heap and are reused, and freed
// memory is kept; the peak resident set is the same.
void reuse_freed_columns() {
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
    mallopt(M_TOP_PAD, 64 << 20);
}

// Huge pages for the heap: a column of a million samples is 2,000 pages of 4 KiB, each faulted in on first touch
// and each a TLB entry; in 2 MiB pages it is four. Linux gives transparent huge pages to a process that asks for them
// (the default mode, "madvise"), and glibc asks where its tunable glibc.malloc.hugetlb=1 says so; glibc reads its
// tunables once, at start. The commands that crunch whole traces therefore start again once, as the same process,
// with the tunable added: on the million-sample trace identify takes 2,000 page faults instead of 31,000 and 40 %
// less CPU time (docs/performance.md). A tunable the user set stands; FEEDID_HEAP_TUNED marks the second start (and
// set to anything beforehand keeps the first); where /proc is missing, the command simply runs on.
void restart_with_huge_pages(int argc, char** argv) {
    static constexpr std::array<std::string_view, 6> batch{"info", "identify", "gains", "simulate", "scan", "synth"};
    if (argc < 2 || std::find(batch.begin(), batch.end(), std::string_view(argv[1])) == batch.end()) return;
    if (std::getenv("FEEDID_HEAP_TUNED") != nullptr) return;
    const char* tunables = std::getenv("GLIBC_TUNABLES");
    const std::string given = tunables != nullptr ? tunables : "";
    if (given.find("glibc.malloc.hugetlb") != std::string::npos) return;
    const std::string value = given.empty() ? "glibc.malloc.hugetlb=1" : given + ":glibc.malloc.hugetlb=1";
    if (setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0 || setenv("FEEDID_HEAP_TUNED", "1", 1) != 0) return;
    execv("/proc/self/exe", argv);
    unsetenv("FEEDID_HEAP_TUNED");  // not restarted: on as started
    if (tunables != nullptr) setenv("GLIBC_TUNABLES", tunables, 1); else unsetenv("GLIBC_TUNABLES");
}

}  // namespace

int main(int argc, char** argv) {
    restart_with_huge_pages(argc, argv);
    reuse_freed_columns();
    using namespace feedid::cli;
    CLI::App app{"feedid: rapid parameter estimation and health monitoring of CNC feed drives", "feedid"};
    app.set_version_flag("--version", std::string(feedid::version));
    app.require_subcommand(1);
    app.footer(
        "Exit codes: 0 success, 1 the analysis failed (the message says why), 2 bad usage or bad input.\n"
        "Run `feedid SUBCOMMAND --help` for a subcommand's options and an example.");

    std::map<CLI::App*, Action> actions;
    const auto add = [&](Action (*add_command)(CLI::App&)) {
        const std::size_t before = app.get_subcommands({}).size();
        Action action = add_command(app);
        actions[app.get_subcommands({}).at(before)] = std::move(action);
    };
    add(add_info_command);
    add(add_identify_command);
    add(add_scan_command);
    add(add_gains_command);
    add(add_fingerprint_command);
    add(add_simulate_command);
    add(add_synth_command);
    add(add_plan_command);
    add(add_history_command);
    add(add_report_command);
    add(add_watch_command);
    add(add_publish_command);

    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        fmt::print(stderr, "feedid: {}\n", feedid::terminal_message(e.what()));
        return 2;
    }

    try {
        for (auto* sub : app.get_subcommands()) {
            return actions.at(sub)();
        }
        return 2;
    } catch (const feedid::InputError& e) {
        fmt::print(stderr, "feedid: {}\n", feedid::terminal_message(e.what()));
        return 2;
    } catch (const feedid::AnalysisError& e) {
        fmt::print(stderr, "feedid: {}\n", feedid::terminal_message(e.what()));
        return 1;
    } catch (const std::filesystem::filesystem_error& e) {
        // a path that cannot be looked at (a folder without search permission, a loop of symbolic links): bad input
        fmt::print(stderr, "feedid: {}: {}\n", feedid::terminal_text(e.path1().string()),
                   feedid::terminal_text(e.code().message()));
        return 2;
    } catch (const std::bad_alloc&) {
        fmt::print(stderr, "feedid: out of memory\n");
        return 2;
    } catch (const std::exception& e) {
        fmt::print(stderr, "feedid: internal error: {}\n", feedid::terminal_message(e.what()));
        return 1;
    }
}
