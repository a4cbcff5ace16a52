// feedid report (placeholder until its issue lands: it says so and exits 2).
#include <cstdio>

#include <fmt/core.h>

#include "cli.hpp"

namespace feedid::cli {

Action add_report_command(CLI::App& app) {
    auto* sub = app.add_subcommand("report", "(not yet available)");
    sub->allow_extras();
    return [] {
        fmt::print(stderr, "feedid: 'report' is not available in this build yet\n");
        return 2;
    };
}

}  // namespace feedid::cli
