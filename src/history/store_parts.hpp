#pragma once
// What both history backends (store.cpp: SQLite, postgres_store.cpp: PostgreSQL) compute alike from a run record.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>

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
