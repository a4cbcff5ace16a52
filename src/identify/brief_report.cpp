#include "feedid/identify/brief_report.hpp"

#include <cmath>
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

/// The drive signal's delay behind the position where identify applied it, as a line; "" where it did not.
std::string timing_line(const IdentifyResult& result) {
    if (!result.model_choice || !result.model_choice->delay_applied || !result.model_choice->delay_s) return {};
    const ModelChoice& choice = *result.model_choice;
    const double delay = *choice.delay_s;
    return fmt::format("timing: the drive signal {} the position by {:.3g} ms{} ({}): read {}\n",
                       delay >= 0.0 ? "lags" : "leads", std::abs(delay) * 1e3,
                       choice.delay_standard_error ? fmt::format(" +/- {:.2g}", *choice.delay_standard_error * 1e3)
                                                   : std::string(),
                       choice.delay_source, delay >= 0.0 ? "that much later" : "that much earlier");
}

std::string brief_report(const IdentifyResult& result) {
    const std::string trace = result.trace.path.empty() ? std::string("trace") : terminal_text(result.trace.path);
    const bool chosen = result.model_choice && result.model_choice->automatic;
    return fmt::format("{} ({} samples, {:.6g} s)\nmodel: {}{}{}, status: {}\n{}\n{}", trace, result.trace.samples,
                       result.trace.duration_s, result.model_name(), result.offset ? " with offset" : "",
                       chosen ? " (chosen from the data)" : "", to_string(result.status), timing_line(result),
                       parameter_table_text(result));
}

}  // namespace feedid
