// Opening a history by its location (store.hpp): a PostgreSQL URI or a SQLite file; copying one history into another.
#include <algorithm>
#include <map>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/history/store.hpp"

namespace feedid::history {

bool is_postgresql_location(std::string_view location) {
    return location.starts_with("postgresql://") || location.starts_with("postgres://");
}

bool postgresql_supported() {
#ifdef FEEDID_HAVE_POSTGRESQL
    return true;
#else
    return false;
#endif
}

std::string shown_location(const std::string& location) {
    if (!is_postgresql_location(location)) return location;
    // postgresql://[user[:password]@][host][:port][/dbname][?param=value&...]
    const std::size_t authority = location.find("://") + 3;
    const std::size_t authority_end = std::min(location.find_first_of("/?", authority), location.size());
    std::string shown = location.substr(0, authority);
    std::string host_part = location.substr(authority, authority_end - authority);
    if (const std::size_t at = host_part.rfind('@'); at != std::string::npos) {
        const std::string user = host_part.substr(0, at);
        shown += user.substr(0, user.find(':')) + host_part.substr(at);
    } else {
        shown += host_part;
    }
    std::string rest = location.substr(authority_end);
    // drop a password=... parameter of the query string
    const std::size_t query = rest.find('?');
    if (query == std::string::npos) return shown + rest;
    std::string kept = rest.substr(0, query);
    std::string parameters;
    std::size_t start = query + 1;
    while (start <= rest.size()) {
        const std::size_t end = std::min(rest.find('&', start), rest.size());
        const std::string parameter = rest.substr(start, end - start);
        if (!parameter.empty() && !parameter.starts_with("password="))
            parameters += (parameters.empty() ? "" : "&") + parameter;
        start = end + 1;
    }
    return shown + kept + (parameters.empty() ? "" : "?" + parameters);
}

bool location_has_password(const std::string& location) {
    if (!is_postgresql_location(location)) return false;
    const std::size_t authority = location.find("://") + 3;
    const std::size_t authority_end = std::min(location.find_first_of("/?", authority), location.size());
    const std::string host_part = location.substr(authority, authority_end - authority);
    if (const std::size_t at = host_part.rfind('@');
        at != std::string::npos && host_part.substr(0, at).find(':') != std::string::npos)
        return true;
    const std::size_t query = location.find('?', authority);
    if (query == std::string::npos) return false;
    for (std::size_t start = query + 1; start <= location.size();) {
        const std::size_t end = std::min(location.find('&', start), location.size());
        if (location.compare(start, 9, "password=") == 0) return true;
        start = end + 1;
    }
    return false;
}

#ifndef FEEDID_HAVE_POSTGRESQL
std::unique_ptr<HistoryStore> open_postgres_store(const std::string& location, const OpenOptions&) {
    throw InputError(
        fmt::format("{}: this feedid was built without the PostgreSQL backend (libpq and its headers, Debian's "
                    "libpq-dev, were not found when it was built); use a SQLite file or a build with libpq-dev",
                    shown_location(location)));
}
#endif

std::unique_ptr<HistoryStore> open_store(const std::string& location, const OpenOptions& options) {
    if (is_postgresql_location(location)) {
        if (postgresql_supported() && location_has_password(location))
            throw InputError(fmt::format(
                "{}: a password in the location is refused (it would show in ps and in logs); put it in ~/.pgpass, "
                "a file named by PGPASSFILE, a service file (PGSERVICEFILE) or PGPASSWORD",
                shown_location(location)));
        return open_postgres_store(location, options);
    }
    SqliteOpenOptions sqlite;
    sqlite.read_only = options.read_only;
    sqlite.create = options.create;
    return open_sqlite_store(location, sqlite);
}

CopyOutcome copy_history(const HistoryStore& from, HistoryStore& to) {
    // In the order they were stored, so that an empty destination numbers them as the source does; a page at a
    // time, so that a history of any size is copied in bounded memory (the documents are most of it).
    constexpr std::size_t page = 500;
    CopyOutcome outcome;
    std::map<std::int64_t, std::int64_t> ids;
    for (std::int64_t after = 0;;) {
        const auto runs = from.runs_in_storage_order(after, page);
        for (const auto& run : runs) {
            const AddOutcome added = to.add_run(run);
            ids[run.id] = added.id;
            ++(added.inserted ? outcome.copied : outcome.already_there);
        }
        if (runs.size() < page) break;
        after = runs.back().id;
    }
    std::map<std::pair<std::string, std::string>, std::int64_t> pinned;
    for (const auto& pin : to.pins()) pinned[{pin.machine, pin.axis}] = pin.run_id;
    for (const auto& pin : from.pins()) {
        const auto found = ids.find(pin.run_id);
        if (found == ids.end()) continue;  // a pin of a run the listing did not give: nothing to pin it to
        const auto there = pinned.find({pin.machine, pin.axis});
        if (there != pinned.end() && there->second == found->second) continue;
        to.pin_baseline(pin.machine, pin.axis, found->second);
        ++outcome.pins;
    }
    return outcome;
}

}  // namespace feedid::history
