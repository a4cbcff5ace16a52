// From an identify result document to a history record.
#include "feedid/history/record.hpp"

#include <regex>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/terminal_text.hpp"
#include "feedid/core/version.hpp"
#include "feedid/history/sha256.hpp"
#include "sqlite_access.hpp"

namespace feedid::history {

bool is_iso8601_utc(const std::string& text) {
    static const std::regex pattern(R"(^\d{4}-\d{2}-\d{2}([T ]\d{2}:\d{2}(:\d{2}(\.\d{1,9})?)?Z?)?$)");
    return std::regex_match(text, pattern);
}

std::string RecordContext::validate(std::string_view requester) const {
    if (machine.empty()) return fmt::format("{} needs the machine's name (--machine NAME)", requester);
    if (axis.empty()) return fmt::format("{} needs the axis (--axis X)", requester);
    // what one history backend refuses, none takes: SQLite and PostgreSQL hold the same runs
    for (const auto& [option, name] :
         {std::pair{"--machine", &machine}, std::pair{"--axis", &axis}, std::pair{"--location", &location}})
        if (!is_storable_text(*name))
            return fmt::format("{} '{}': not valid UTF-8 (every history backend stores names as UTF-8)", option,
                               terminal_text(*name));
    if (!recorded_at.empty() && !is_iso8601_utc(recorded_at))
        return fmt::format("--recorded-at '{}': not an ISO 8601 UTC time (e.g. 2026-11-23T09:30:00Z)", recorded_at);
    return {};
}

RunRecord prepare_run(const nlohmann::json& result, const std::string& source, const RecordContext& context) {
    if (const auto problem = context.validate(); !problem.empty()) throw InputError(problem);
    if (context.trace.empty()) throw InputError(fmt::format("{}: recording a run needs its trace file", source));
    RunRecord run = run_from_result(result, source);
    if (!std::filesystem::is_regular_file(context.trace))
        throw InputError(
            fmt::format("{}: the trace file is not found (needed for its content hash)", context.trace.string()));
    run.machine = context.machine;
    run.axis = context.axis;
    run.location = context.location;
    run.trace_path = context.trace.string();
    run.trace_sha256 = sha256_file(context.trace);
    run.recorded_at = context.recorded_at.empty() ? file_modification_time_utc(context.trace) : context.recorded_at;
    run.options = context.options.is_object() ? context.options : nlohmann::json::object();
    if (run.feedid_version.empty()) run.feedid_version = feedid::version;
    return run;
}

std::filesystem::path trace_of_result(const nlohmann::json& result, const std::string& source) {
    const bool names_trace = result.is_object() && result.contains("trace") && result["trace"].is_object() &&
                             result["trace"].contains("path") && result["trace"]["path"].is_string();
    if (!names_trace) (void)run_from_result(result, source);  // the clearer message for a wrong document
    std::filesystem::path trace;
    if (names_trace) trace = result["trace"]["path"].get<std::string>();
    // A relative trace path is relative to where identify ran; fall back to the result's folder.
    if (!trace.empty() && trace.is_relative() && !std::filesystem::exists(trace))
        trace = std::filesystem::path(source).parent_path() / trace;
    if (trace.empty())
        throw InputError(fmt::format("{}: the result names no trace file; give it with --trace FILE", source));
    return trace;
}

void check_recordable(const std::string& database) {
    if (is_postgresql_location(database)) {
        // Connect, authenticate and look at the schema without writing: a database without feedid's tables is fine
        // (the first run creates them).
        OpenOptions read_only;
        read_only.read_only = true;
        try {
            (void)open_store(database, read_only);
        } catch (const InputError& e) {
            if (std::string_view(e.what()).find("(no run recorded yet)") == std::string_view::npos) throw;
        }
        return;
    }
    // Where a writer may not write (permission, a read-only mount, the folder), say so now, not after identifying.
    const OpenPlan plan = plan_open(database, SqliteOpenOptions{});
    (void)plan;
    std::error_code error;
    if (!std::filesystem::exists(database, error)) return;
    SqliteOpenOptions read_only;
    read_only.read_only = true;
    try {
        (void)open_sqlite_store(database, read_only);
    } catch (const InputError&) {
        // An existing but empty file is fine: the store creates its tables.
        if (std::filesystem::is_regular_file(database, error) && std::filesystem::file_size(database, error) == 0)
            return;
        throw;
    }
}

}  // namespace feedid::history
