// From an identify result document to a history record.
#include "feedid/history/record.hpp"

#include <regex>

#include <fmt/core.h>

#include "feedid/error.hpp"
#include "feedid/history/sha256.hpp"
#include "feedid/version.hpp"

namespace feedid::history {

bool is_iso8601_utc(const std::string& text) {
    static const std::regex pattern(R"(^\d{4}-\d{2}-\d{2}([T ]\d{2}:\d{2}(:\d{2}(\.\d{1,9})?)?Z?)?$)");
    return std::regex_match(text, pattern);
}

RunRecord prepare_run(const nlohmann::json& result, const std::string& source, const RecordContext& context) {
    if (context.machine.empty()) throw InputError("recording a run needs the machine's name (--machine NAME)");
    if (context.axis.empty()) throw InputError("recording a run needs the axis (--axis X)");
    if (context.trace.empty()) throw InputError(fmt::format("{}: recording a run needs its trace file", source));
    if (!context.recorded_at.empty() && !is_iso8601_utc(context.recorded_at))
        throw InputError(fmt::format("--recorded-at '{}': not an ISO 8601 UTC time (e.g. 2026-11-23T09:30:00Z)",
                                     context.recorded_at));
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

}  // namespace feedid::history
