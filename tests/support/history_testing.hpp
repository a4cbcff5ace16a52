#pragma once
// Helpers of the history and report tests: a thread-safe way to run the CLI, and identify-result documents.

#include <atomic>
#include <filesystem>
#include <string>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "testing.hpp"

namespace feedid::testing {

/// Runs a shell command line (the feedid binary is FEEDID_CLI); safe to call from several threads at once.
inline CliResult run_shell(const std::string& command_line, const std::filesystem::path& scratch) {
    static std::atomic<int> counter{0};
    const int n = counter++;
    const auto out_path = scratch / fmt::format("shell-out-{}-{}.txt", ::getpid(), n);
    const auto err_path = scratch / fmt::format("shell-err-{}-{}.txt", ::getpid(), n);
    // The shell's own streams are redirected too, so that its note about a child killed by a signal (the durability
    // test's forced abort) lands in the captured stderr, not in the test's output.
    const std::string command =
        "exec >'" + out_path.string() + "' 2>'" + err_path.string() + "' </dev/null; " + command_line;
    const int status = std::system(command.c_str());
    CliResult result;
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    result.out = read_text(out_path);
    result.err = read_text(err_path);
    std::filesystem::remove(out_path);
    std::filesystem::remove(err_path);
    return result;
}

/// The feedid binary, quoted for a shell.
inline std::string cli() {
    return std::string("'") + FEEDID_CLI + "'";
}

/// A path quoted for a shell.
inline std::string quoted(const std::filesystem::path& path) {
    return "'" + path.string() + "'";
}
/// A location (a path or a postgresql:// URI) quoted for a shell (a better match than std::quoted for a string).
inline std::string quoted(const std::string& location) {
    return "'" + location + "'";
}

/// A small identify result document (docs/documents.md's shape) naming `trace`: the store tests need
/// many distinct runs quickly, not the identification itself.
inline nlohmann::json small_result(const std::filesystem::path& trace, double coulomb) {
    const auto estimate = [](double value, double error) {
        return nlohmann::json{{"value", value}, {"stderr", error}};
    };
    return {{"feedid_version", "0.1.0"},
            {"trace", {{"path", trace.string()}, {"samples", 5000}, {"sample_time_s", 0.001}, {"duration_s", 5.0}}},
            {"model", "symmetric"},
            {"status", "partial"},
            {"parameters",
             {{"mass_kg", estimate(69.1, 0.2)},
              {"viscous_Ns_per_m", estimate(54.2, 1.5)},
              {"coulomb_N", estimate(coulomb, 0.8)},
              {"breakaway_N", {{"value", nullptr}, {"stderr", nullptr}}},
              {"stribeck_velocity_m_per_s", {{"value", nullptr}, {"stderr", nullptr}}}}},
            {"fit", {{"relative_error_pct", 3.1}, {"condition_number", 12.0}, {"samples_used", 4000}}},
            {"diagnostics", {"Stribeck: no slow passes"}}};
}

/// Writes `count` trace files and result documents named `<stem>-<i>.csv` / `<stem>-<i>.json` (i from 1) into
/// `folder`; every trace has its own content (so its own hash).
inline std::vector<std::filesystem::path> write_small_results(const std::filesystem::path& folder,
                                                              const std::string& stem, int count) {
    std::vector<std::filesystem::path> results;
    for (int i = 1; i <= count; ++i) {
        const auto trace = folder / fmt::format("{}-{}.csv", stem, i);
        write_text(trace, fmt::format("# {}\nt [s],x [mm]\n0,{}\n0.001,{}\n", trace.filename().string(), i, i + 1));
        const auto result = folder / fmt::format("{}-{}.json", stem, i);
        write_text(result, small_result(trace, 740.0 + 0.1 * i).dump(1));
        results.push_back(result);
    }
    return results;
}

}  // namespace feedid::testing
