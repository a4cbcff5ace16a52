// feedid: the command line. A thin main over the library; each subcommand lives in its own file.
#include <cstdio>
#include <exception>
#include <filesystem>
#include <map>

#include <malloc.h>

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
// memory is kept; the peak resident set is the same. (Setting GLIBC_TUNABLES=glibc.malloc.hugetlb=1 in the
// environment also backs the heap by huge pages: fewer faults still; docs/performance.md has the figures.)
void reuse_freed_columns() {
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
    mallopt(M_TOP_PAD, 64 << 20);
}

}  // namespace

int main(int argc, char** argv) {
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
