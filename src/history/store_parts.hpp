#pragma once
// What both history backends (sqlite_store.cpp: SQLite, postgres_store.cpp: PostgreSQL) compute alike from a run record.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/core/terminal_text.hpp"
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

/// Refuses (InputError naming `where`, the run and the field) a run with a text that not every backend stores: not
/// valid UTF-8, or holding a NUL (PostgreSQL refuses both; a SQLite file would take them, and `history --copy` could
/// then not copy it).
inline void require_storable_text(const RunRecord& run, std::string_view where) {
    const std::pair<const char*, const std::string*> fields[] = {{"machine", &run.machine},
                                                                 {"axis", &run.axis},
                                                                 {"location", &run.location},
                                                                 {"recorded_at", &run.recorded_at},
                                                                 {"trace path", &run.trace_path},
                                                                 {"trace hash", &run.trace_sha256},
                                                                 {"feedid version", &run.feedid_version},
                                                                 {"model", &run.model},
                                                                 {"status", &run.status},
                                                                 {"axis kind", &run.axis_kind}};
    for (const auto& [name, text] : fields)
        if (!is_storable_text(*text))
            throw InputError(
                fmt::format("{}: the run's {} '{}' is not valid UTF-8 without NUL, which every history "
                            "backend needs",
                            where, name, terminal_text(*text)));
    for (const auto& [key, estimate] : run.parameters)
        if (!is_storable_text(key))
            throw InputError(
                fmt::format("{}: the parameter key '{}' is not valid UTF-8 without NUL", where, terminal_text(key)));
}

/// The text a run is stored as; a run larger than the store takes, or with a text not every backend stores, is
/// refused (InputError naming `where`) before anything is written.
inline StoredText stored_text_of(const RunRecord& run, std::string_view where) {
    const StoredTextLimits limits;
    require_storable_text(run, where);
    const auto dump = [&](const nlohmann::json& document, const char* what) {
        try {
            return document.dump();
        } catch (const nlohmann::json::type_error&) {  // a string of it is not UTF-8
            throw InputError(fmt::format("{}: the run's {} holds text that is not valid UTF-8", where, what));
        }
    };
    StoredText text{dump(run.options, "options"), run.fit.is_object() ? dump(run.fit, "fit") : std::string("{}"),
                    dump(nlohmann::json(run.diagnostics), "diagnostics"),
                    run.result.is_object() ? dump(run.result, "result document") : std::string("{}"),
                    run.stored_at.empty() ? now_utc() : run.stored_at};
    if (text.result_json.size() > limits.document_bytes || text.options_json.size() > limits.options_bytes)
        throw InputError(
            fmt::format("{}: the run's result document or options are larger than a run may store", where));
    return text;
}

/// Marks the run just appended to `series` as a fingerprint run or not (SeriesRuns::fingerprint stays empty while
/// no run is one).
inline void note_kind(SeriesRuns& series, bool fingerprint) {
    if (!fingerprint && series.fingerprint.empty()) return;
    series.fingerprint.resize(series.size(), 0);
    series.fingerprint.back() = fingerprint ? 1 : 0;
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
