#pragma once
// From an identify result document to a run record of the history: where the run comes from (machine, axis, trace,
// time) and the checks that it can be recorded, made once here for identify --record and history --add.

#include <filesystem>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "feedid/history/store.hpp"

namespace feedid::history {

/// Where a run comes from, for prepare_run.
struct RecordContext {
    std::string machine;  ///< required
    std::string axis;     ///< required
    std::string location;
    std::filesystem::path trace;                        ///< the trace file (hashed); required
    std::string recorded_at;                            ///< ISO 8601 UTC; default: the trace file's modification time
    nlohmann::json options = nlohmann::json::object();  ///< the identification options used

    /// What is wrong with the names and the time stamp ("" when nothing): the machine and the axis are required, the
    /// names valid UTF-8 (what every history backend stores), and recorded_at, when given, is ISO 8601 UTC. `requester`
    /// opens the messages about a missing name ("--record" for identify's option). Does not look at the trace
    /// (prepare_run does).
    [[nodiscard]] std::string validate(std::string_view requester = "recording a run") const;
};

/// A run record from an identify result document and its context: hashes the trace, checks the names and the time
/// stamp. InputError naming what is missing or malformed.
RunRecord prepare_run(const nlohmann::json& result, const std::string& source, const RecordContext& context);

/// The trace file an identify result document read from `source` names (its trace.path): relative paths are taken
/// from the working directory or, when no such file is there, from the folder of `source`. InputError naming
/// `source` when the document is not an identify result or names no trace file.
std::filesystem::path trace_of_result(const nlohmann::json& result, const std::string& source);

/// Checks, before a long computation and without writing, that a run can be recorded in `database` (a SQLite file or
/// a PostgreSQL location, as open_store takes): a missing or empty file, or a database without feedid's tables, is
/// fine (the store creates its tables); an existing one must open as a feedid history, and a server must accept the
/// connection. InputError naming the file or the database otherwise.
void check_recordable(const std::string& database);

/// True for "2026-11-23", "2026-11-23T09:30", "2026-11-23T09:30:21", "2026-11-23T09:30:21.250Z" and the like.
bool is_iso8601_utc(const std::string& text);

}  // namespace feedid::history
