// Run records from result documents (checked against the result document's schema, text cut to the store's limits),
// their JSON for `feedid history --json`, and the time stamps of the history.
#include <chrono>
#include <ctime>
#include <fstream>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/history/store.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/result_document.hpp"

namespace feedid::history {
namespace {

/// Cuts `text` to at most `limit` bytes at a UTF-8 character boundary and marks the cut; true when it cut.
bool cut_text(std::string& text, std::size_t limit) {
    if (text.size() <= limit) return false;
    const std::size_t original = text.size();
    std::size_t end = limit;
    while (end > 0 && (static_cast<unsigned char>(text[end]) & 0xC0u) == 0x80u) --end;  // not inside a character
    text.resize(end);
    text += fmt::format(" … [cut: {} of {} bytes kept]", end, original);
    return true;
}

/// Cuts every string of a document (at any depth) to the limit; the number of strings cut.
std::size_t cut_strings(nlohmann::json& document, std::size_t limit) {
    std::size_t cut = 0;
    if (document.is_string()) return cut_text(document.get_ref<std::string&>(), limit) ? 1 : 0;
    if (document.is_object() || document.is_array())
        for (auto& element : document) cut += cut_strings(element, limit);
    return cut;
}

/// The diagnostics as stored: each cut to the limit, at most `count` of them; findings say what was cut.
std::vector<std::string> stored_diagnostics(const std::vector<std::string>& diagnostics, const StoredTextLimits& limits,
                                            std::vector<std::string>& findings) {
    std::vector<std::string> kept;
    std::size_t cut = 0;
    for (const auto& line : diagnostics) {
        if (kept.size() + 1 == limits.diagnostics && diagnostics.size() > limits.diagnostics) {
            kept.push_back(fmt::format("… {} more diagnostics not stored", diagnostics.size() - kept.size()));
            findings.push_back(fmt::format("the result has {} diagnostics; the first {} are stored", diagnostics.size(),
                                           limits.diagnostics - 1));
            break;
        }
        kept.push_back(line);
        if (cut_text(kept.back(), limits.line_bytes)) ++cut;
    }
    if (cut > 0)
        findings.push_back(
            fmt::format("{} diagnostic(s) longer than {} bytes were cut to that length", cut, limits.line_bytes));
    return kept;
}

/// The result document as the store keeps it: without the RLS history, strings cut, the diagnostics as stored.
nlohmann::json stored_result(const nlohmann::json& result, const std::vector<std::string>& diagnostics,
                             const std::string& source, const StoredTextLimits& limits,
                             std::vector<std::string>& findings) {
    nlohmann::json stored = result;
    if (stored.contains("rls") && stored["rls"].is_object()) stored["rls"].erase("history");
    stored["diagnostics"] = diagnostics;
    if (const std::size_t cut = cut_strings(stored, limits.line_bytes); cut > 0)
        findings.push_back(
            fmt::format("{} text(s) of the result document (notes, reasons) longer than {} bytes were "
                        "cut to that length",
                        cut, limits.line_bytes));
    if (const std::size_t size = stored.dump().size(); size > limits.document_bytes)
        throw InputError(
            fmt::format("{}: the result document is {} bytes without its RLS history, more than the {} "
                        "a run may store",
                        source, size, limits.document_bytes));
    return stored;
}

std::optional<double> optional_number(const nlohmann::json& object, const char* key) {
    if (object.is_object() && object.contains(key) && object[key].is_number()) return object[key].get<double>();
    return std::nullopt;
}

std::string format_utc(std::int64_t milliseconds) {
    const std::time_t seconds = static_cast<std::time_t>(milliseconds / 1000);
    std::tm utc{};
    gmtime_r(&seconds, &utc);
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z", utc.tm_year + 1900, utc.tm_mon + 1, utc.tm_mday,
                       utc.tm_hour, utc.tm_min, utc.tm_sec, static_cast<int>(milliseconds % 1000));
}

nlohmann::json optional_json(const std::optional<double>& value) {
    return value && std::isfinite(*value) ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

// What a fingerprint run stores: the figures and their per-direction values, in both kinds' units.
constexpr std::pair<const char*, const char*> fingerprint_figures[] = {
    {"lost_motion", "m"}, {"backlash", "m"}, {"stiffness", "N_per_m"}, {"reversal_error", "m"}};

std::string rotary_unit(std::string_view unit) { return unit == "N_per_m" ? "Nm_per_rad" : "rad"; }

// An entry of the fingerprint document's "fingerprint": {"value": number|null, "stderr": number|null}.
StoredEstimate fingerprint_entry(const nlohmann::json& entry, const std::string& key, const std::string& source) {
    const auto bad = [&](const std::string& why) {
        return InputError(fmt::format("{}: not a feedid fingerprint document (fingerprint.{}: {})", source, key, why));
    };
    if (!entry.is_object()) throw bad("not an object with value and stderr");
    for (const char* field : {"value", "stderr"})
        if (!entry.contains(field) || !(entry[field].is_null() || entry[field].is_number()))
            throw bad(fmt::format("\"{}\" is not a number or null", field));
    return {optional_number(entry, "value"), optional_number(entry, "stderr")};
}

// The document's figures the run stores (fingerprint_parameter_keys), checked; whether they are a rotary axis's.
std::map<std::string, StoredEstimate> fingerprint_parameters(const nlohmann::json& figures, const std::string& source,
                                                             bool& rotary) {
    std::map<std::string, StoredEstimate> parameters;
    rotary = figures.contains("backlash_rad");
    for (const auto& [name, linear_unit] : fingerprint_figures) {
        const std::string unit = rotary ? rotary_unit(linear_unit) : std::string(linear_unit);
        const bool directional = std::string_view(name) != "backlash";
        for (const char* side : {"", "_forward", "_reverse"}) {
            if (!directional && *side != '\0') continue;
            const std::string key = fmt::format("{}{}_{}", name, side, unit);
            if (!figures.contains(key))
                throw InputError(
                    fmt::format("{}: not a feedid fingerprint document (it has no fingerprint.{})", source, key));
            parameters[key] = fingerprint_entry(figures[key], key, source);
        }
    }
    return parameters;
}

}  // namespace

bool is_fingerprint_run(const RunRecord& run) { return run.model == fingerprint_model; }

std::vector<std::string> fingerprint_parameter_keys() {
    std::vector<std::string> keys;
    for (const bool rotary : {false, true})
        for (const auto& [name, linear_unit] : fingerprint_figures)
            for (const char* side : {"", "_forward", "_reverse"}) {
                if (std::string_view(name) == "backlash" && *side != '\0') continue;
                keys.push_back(fmt::format("{}{}_{}", name, side, rotary ? rotary_unit(linear_unit) : linear_unit));
            }
    return keys;
}

RunRecord run_from_fingerprint(const nlohmann::json& document, const std::string& source,
                               const StoredTextLimits& limits) {
    if (!document.is_object() || !document.contains("fingerprint") || !document["fingerprint"].is_object())
        throw InputError(fmt::format("{}: not a feedid fingerprint document (no \"fingerprint\" object)", source));
    RunRecord run;
    run.model = std::string(fingerprint_model);
    bool rotary = false;
    run.parameters = fingerprint_parameters(document["fingerprint"], source, rotary);
    run.axis_kind = rotary ? "rotary" : "linear";
    if (document.contains("feedid_version") && document["feedid_version"].is_string())
        run.feedid_version = document["feedid_version"].get<std::string>();
    if (document.contains("trace") && document["trace"].is_object() && document["trace"].contains("path") &&
        document["trace"]["path"].is_string())
        run.trace_path = document["trace"]["path"].get<std::string>();
    run.fit_figures.samples_used = optional_number(document, "samples_used");
    if (run.fit_figures.samples_used) run.fit = {{"samples_used", *run.fit_figures.samples_used}};
    std::vector<std::string> diagnostics;
    if (document.contains("diagnostics") && document["diagnostics"].is_array())
        for (const auto& line : document["diagnostics"])
            if (line.is_string()) diagnostics.push_back(line.get<std::string>());
    run.diagnostics = stored_diagnostics(diagnostics, limits, run.recording_findings);
    nlohmann::json stored = document;
    stored.erase("curves");  // the samples of the report's plots: the trace has them
    run.result = stored_result(stored, run.diagnostics, source, limits, run.recording_findings);
    if (document.contains("options") && document["options"].dump().size() > limits.options_bytes)
        throw InputError(
            fmt::format("{}: options: larger than the {} bytes a run may store", source, limits.options_bytes));
    return run;
}

std::string axis_kind_of(const std::map<std::string, StoredEstimate>& parameters) {
    for (const auto& [key, estimate] : parameters) {
        if (const auto parsed = parse_parameter_key(key); parsed && parsed->rotary) return "rotary";
    }
    return "linear";
}

RunRecord run_from_result(const nlohmann::json& result, const std::string& source, const StoredTextLimits& limits) {
    const auto not_a_result = [&](const std::string& why) {
        return InputError(fmt::format("{}: not a feedid identify result document ({})", source, why));
    };
    if (!result.is_object()) throw not_a_result("it is not a JSON object");
    if (result.contains("fingerprint")) return run_from_fingerprint(result, source, limits);
    if (!result.contains("parameters") || !result["parameters"].is_object())
        throw not_a_result("it has no \"parameters\" object");
    if (!result.contains("model") || !result["model"].is_string()) throw not_a_result("it has no \"model\"");
    // The whole document read as the readers read it: a value of the wrong type is refused here, naming its key,
    // rather than stored and found when the report reads it back.
    IdentifyResult checked;
    try {
        from_json(result, checked);
    } catch (const InputError& e) {
        throw InputError(fmt::format("{}: {}", source, e.what()));
    }
    RunRecord run;
    run.model = result["model"].get<std::string>();
    for (const auto& [key, entry] : result["parameters"].items()) {
        run.parameters[key] = {optional_number(entry, "value"), optional_number(entry, "stderr"),
                               optional_number(entry, "systematic"), optional_number(entry, "uncertainty")};
    }
    run.feedid_version = checked.feedid_version;
    if (result.contains("status")) run.status = to_string(checked.status);
    run.trace_path = checked.trace.path;
    if (result.contains("fit") && result["fit"].is_object()) run.fit = result["fit"];
    run.fit_figures = {optional_number(run.fit, "relative_error_pct"), optional_number(run.fit, "condition_number"),
                       optional_number(run.fit, "samples_used")};
    run.axis_kind = ParameterNaming{checked.rotary}.axis_kind();
    run.diagnostics = stored_diagnostics(checked.diagnostics, limits, run.recording_findings);
    run.result = stored_result(result, run.diagnostics, source, limits, run.recording_findings);
    if (result.contains("options") && result["options"].dump().size() > limits.options_bytes)
        throw InputError(
            fmt::format("{}: options: larger than the {} bytes a run may store", source, limits.options_bytes));
    if (!run.recording_findings.empty()) {
        const std::string note = "recording: " + run.recording_findings.front() +
                                 (run.recording_findings.size() > 1 ? " (and more cuts)" : "");
        run.diagnostics.push_back(note);
        run.result["diagnostics"].push_back(note);
    }
    return run;
}

nlohmann::json to_json(const RunRecord& run) {
    nlohmann::json parameters = nlohmann::json::object();
    for (const auto& [key, estimate] : run.parameters)
        parameters[key] = {{"value", optional_json(estimate.value)},
                           {"stderr", optional_json(estimate.standard_error)},
                           {"systematic", optional_json(estimate.systematic)},
                           {"uncertainty", optional_json(estimate.uncertainty)}};
    return {{"id", run.id},
            {"machine", run.machine},
            {"axis", run.axis},
            {"location", run.location},
            {"recorded_at", run.recorded_at},
            {"trace", {{"path", run.trace_path}, {"sha256", run.trace_sha256}}},
            {"feedid_version", run.feedid_version},
            {"model", run.model},
            {"axis_kind", run.axis_kind},
            {"status", run.status},
            {"options", run.options},
            {"parameters", parameters},
            {"fit", run.fit},
            {"diagnostics", run.diagnostics},
            {"stored_at", run.stored_at}};
}

bool looks_like_sqlite(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    char header[16] = {};
    in.read(header, sizeof header);
    return in.gcount() == sizeof header &&
           std::string_view(header, sizeof header) == std::string_view("SQLite format 3\0", 16);
}

std::string file_modification_time_utc(const std::filesystem::path& path) {
    std::error_code error;
    const auto file_time = std::filesystem::last_write_time(path, error);
    if (error) throw InputError(fmt::format("{}: cannot read the file's modification time", path.string()));
    const auto system_time = std::chrono::file_clock::to_sys(file_time);
    return format_utc(std::chrono::duration_cast<std::chrono::milliseconds>(system_time.time_since_epoch()).count());
}

std::string now_utc() {
    return format_utc(
        std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count());
}

}  // namespace feedid::history
