// feedid: the command line. A thin main over the library; each subcommand lives in its own file.
#include <cstdio>
#include <exception>
#include <filesystem>
#include <map>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/core/terminal_text.hpp"
#include "feedid/core/version.hpp"

int main(int argc, char** argv) {
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
