#pragma once
// What both history backends (sqlite_store.cpp: SQLite, postgres_store.cpp: PostgreSQL) compute alike from a run record.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/history/store.hpp"

namespace feedid::history {

/// The fit's figures of a run: as given, or (a record made by hand) from its "fit" object.
inline FitFigures fit_figures_of(const RunRecord& run) {
    const FitFigures& given = run.fit_figures;
    if (given.relative_error_pct || given.condition_number || given.samples_used) return given;
    const auto number = [&](const char* key) -> std::optional<double> {
        if (run.fit.is_object() && run.fit.contains(key) && run.fit[key].is_number()) return run.fit[key].get<double>();
        return std::nullopt;
    };
    return {number("relative_error_pct"), number("condition_number"), number("samples_used")};
}

/// A run's JSON columns and its storage time, as written.
struct StoredText {
    std::string options_json;
    std::string fit_json;
    std::string diagnostics_json;
    std::string result_json;
    std::string stored_at;
};

/// The text a run is stored as; a run larger than the store takes is refused (InputError naming `where`) before
/// anything is written.
inline StoredText stored_text_of(const RunRecord& run, std::string_view where) {
    const StoredTextLimits limits;
    StoredText text{run.options.dump(), run.fit.is_object() ? run.fit.dump() : std::string("{}"),
                    nlohmann::json(run.diagnostics).dump(),
                    run.result.is_object() ? run.result.dump() : std::string("{}"),
                    run.stored_at.empty() ? now_utc() : run.stored_at};
    if (text.result_json.size() > limits.document_bytes || text.options_json.size() > limits.options_bytes)
        throw InputError(
            fmt::format("{}: the run's result document or options are larger than a run may store", where));
    return text;
}

/// Numbers each distinct options text of one listing: runs with equal options get equal groups.
class OptionsGroups {
public:
    std::int64_t of(std::string_view text) {
        const auto found = groups_.find(std::string(text));
        if (found != groups_.end()) return found->second;
        const auto group = static_cast<std::int64_t>(groups_.size()) + 1;
        groups_.emplace(std::string(text), group);
        return group;
    }

private:
    std::unordered_map<std::string, std::int64_t> groups_;
};

}  // namespace feedid::history
