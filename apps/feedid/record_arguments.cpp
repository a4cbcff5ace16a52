#include "record_arguments.hpp"

#include <cstdio>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/history/record.hpp"
#include "feedid/history/store.hpp"
#include "feedid/core/terminal_text.hpp"

namespace feedid::cli {

namespace {
// The names and the time stamp of --record as a record context (no trace yet).
history::RecordContext record_context(const RecordArguments& arguments, const std::string& axis) {
    history::RecordContext context;
    context.machine = arguments.machine;
    context.axis = axis;
    context.location = arguments.location;
    context.recorded_at = arguments.recorded_at;
    return context;
}
}  // namespace

void RecordArguments::add_to(CLI::App& app) {
    auto* group = app.add_option_group("History");
    group->add_option("--record", database,
                      "Record the result as a run in this history database (a SQLite file, created when missing, or "
                      "postgresql://user@host:port/db); needs --machine and --axis");
    group->add_option("--machine", machine, "With --record: the machine the axis belongs to");
    group->add_option("--location", location, "With --record: the site, for tests at several centres");
    group->add_option("--recorded-at", recorded_at,
                      "With --record: when the trace was recorded, ISO 8601 UTC (default: the trace file's "
                      "modification time)");
}

void RecordArguments::check(const std::string& axis) const {
    if (!enabled()) {
        if (!machine.empty() || !location.empty() || !recorded_at.empty())
            throw InputError("--machine, --location and --recorded-at go with --record DB");
        return;
    }
    if (const auto problem = record_context(*this, axis).validate("--record"); !problem.empty())
        throw InputError(problem);
    history::check_recordable(database);
}

void RecordArguments::record(const nlohmann::json& result, const std::string& trace, const std::string& axis,
                             const nlohmann::json& options) const {
    history::RecordContext context = record_context(*this, axis);
    context.trace = trace;
    context.options = options;
    const auto run = history::prepare_run(result, trace, context);
    const auto outcome = history::open_store(database)->add_run(run);
    if (outcome.inserted)
        fmt::print(stderr, "feedid: recorded as run #{} of machine '{}' axis '{}' in {}\n", outcome.id,
                   terminal_text(machine), terminal_text(axis), terminal_text(history::shown_location(database)));
    else
        fmt::print(stderr, "feedid: already recorded as run #{} in {} (same trace, same options); not added\n",
                   outcome.id, terminal_text(history::shown_location(database)));
}

}  // namespace feedid::cli
