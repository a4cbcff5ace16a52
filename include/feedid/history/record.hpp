#pragma once
// From an identify result document to a run record of the history: where the run comes from (machine, axis, trace,
// time) and the checks that it can be recorded.

#include <filesystem>
#include <string>

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
};

/// A run record from an identify result document and its context: hashes the trace, checks the names and the time
/// stamp. InputError naming what is missing or malformed.
RunRecord prepare_run(const nlohmann::json& result, const std::string& source, const RecordContext& context);

/// True for "2026-11-23", "2026-11-23T09:30", "2026-11-23T09:30:21", "2026-11-23T09:30:21.250Z" and the like.
bool is_iso8601_utc(const std::string& text);

}  // namespace feedid::history
