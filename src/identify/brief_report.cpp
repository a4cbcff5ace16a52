#include "feedid/identify/brief_report.hpp"

#include <optional>

#include <fmt/core.h>

#include "feedid/core/status.hpp"
#include "feedid/core/terminal_text.hpp"

namespace feedid {

namespace {

std::string figure(const std::optional<double>& value) {
    return value ? fmt::format("{:.3g}", *value) : std::string("—");
}

}  // namespace

std::string parameter_table_text(const IdentifyResult& result) {
    std::string text =
        fmt::format("  {:<6} {:>14}   {:<12} {:<12} {:<10}\n", "", "value", "std. error", "uncertainty", "unit");
    for (const auto& p : result.parameters) {
        if (p.estimate.value) {
            text += fmt::format("  {:<6} {:>14.6g} ± {:<12} {:<12} {:<10}\n", p.symbol, *p.estimate.value,
                                figure(p.estimate.standard_error), figure(p.estimate.uncertainty), p.unit);
        } else {
            text += fmt::format("  {:<6} {:>14}   {:<12} {:<12} {:<10}\n", p.symbol, "—", "", "", p.unit);
        }
    }
    return text;
}

std::string brief_report(const IdentifyResult& result) {
    const std::string trace = result.trace.path.empty() ? std::string("trace") : terminal_text(result.trace.path);
    return fmt::format("{} ({} samples, {:.6g} s)\nmodel: {}{}, status: {}\n\n{}", trace, result.trace.samples,
                       result.trace.duration_s, result.model_name(), result.offset ? " with offset" : "",
                       to_string(result.status), parameter_table_text(result));
}

}  // namespace feedid
