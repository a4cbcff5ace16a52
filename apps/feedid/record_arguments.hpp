#pragma once
// `--record DB --machine NAME [--location SITE] [--recorded-at TIME]`: record a result in the history as it is made
// (feedid identify ... --record shop.db --machine DMU50 --axis X).

#include <CLI/CLI.hpp>

#include <string>

#include <nlohmann/json.hpp>

namespace feedid::cli {

struct RecordArguments {
    std::string database;
    std::string machine;
    std::string location;
    std::string recorded_at;

    void add_to(CLI::App& app);
    [[nodiscard]] bool enabled() const { return !database.empty(); }
    /// Checks the names, the time stamp and an existing database before the (long) identification runs, so that bad
    /// input costs nothing and a failed command never touches the file. `axis` is the --axis of the trace.
    void check(const std::string& axis) const;
    /// Records the result document of `trace` (with the identification options) as one run; says on stderr what it
    /// did. InputError when the database cannot take it.
    void record(const nlohmann::json& result, const std::string& trace, const std::string& axis,
                const nlohmann::json& options) const;
};

}  // namespace feedid::cli
