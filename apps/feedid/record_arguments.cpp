#include "record_arguments.hpp"

#include <cstdio>
#include <filesystem>

#include <fmt/core.h>

#include "feedid/error.hpp"
#include "feedid/history/record.hpp"
#include "feedid/history/store.hpp"

namespace feedid::cli {

void RecordArguments::add_to(CLI::App& app) {
    auto* group = app.add_option_group("History");
    group->add_option("--record", database,
                      "Record the result as a run in this history database (SQLite; created when missing); needs "
                      "--machine and --axis");
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
    if (machine.empty()) throw InputError("--record needs the machine's name (--machine NAME)");
    if (axis.empty()) throw InputError("--record needs the axis (--axis X)");
    if (!recorded_at.empty() && !history::is_iso8601_utc(recorded_at))
        throw InputError(
            fmt::format("--recorded-at '{}': not an ISO 8601 UTC time (e.g. 2026-11-23T09:30:00Z)", recorded_at));
    if (std::filesystem::exists(database)) {
        history::SqliteOpenOptions read_only;
        read_only.read_only = true;
        try {
            (void)history::open_sqlite_store(database, read_only);
        } catch (const InputError& e) {
            // An existing but empty file is fine: the store creates its tables.
            if (std::filesystem::is_regular_file(database) && std::filesystem::file_size(database) == 0) return;
            throw;
        }
    }
}

void RecordArguments::record(const nlohmann::json& result, const std::string& trace, const std::string& axis,
                             const nlohmann::json& options) const {
    history::RecordContext context;
    context.machine = machine;
    context.axis = axis;
    context.location = location;
    context.trace = trace;
    context.recorded_at = recorded_at;
    context.options = options;
    const auto run = history::prepare_run(result, trace, context);
    const auto outcome = history::open_sqlite_store(database)->add_run(run);
    if (outcome.inserted)
        fmt::print(stderr, "feedid: recorded as run #{} of machine '{}' axis '{}' in {}\n", outcome.id, machine, axis,
                   database);
    else
        fmt::print(stderr, "feedid: already recorded as run #{} in {} (same trace, same options); not added\n",
                   outcome.id, database);
}

}  // namespace feedid::cli
