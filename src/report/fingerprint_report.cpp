// The page of one mechanical fingerprint: its figures and the two plots that show where they come from.
#include "feedid/report/fingerprint_report.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "html_page.hpp"

namespace feedid::report {
namespace {

constexpr const char* blue = "#1f77b4";
constexpr const char* orange = "#ff7f0e";
constexpr const char* light_grey = "#bbbbbb";

// How the page shows lengths, positions and stiffness: µm, mm, N/µm (rotary: mdeg, deg, N·m/mdeg).
struct Shown {
    double length_scale;
    std::string length;
    double position_scale;
    std::string position;
    double stiffness_scale;
    std::string stiffness;
    std::string force;
};

Shown shown_units(bool rotary) {
    constexpr double degree = std::numbers::pi / 180.0;
    if (rotary) return {1e3 / degree, "mdeg", 1.0 / degree, "deg", degree / 1e3, "N·m/mdeg", "N·m"};
    return {1e6, "µm", 1e3, "mm", 1e-6, "N/µm", "N"};
}

Series points(const std::string& name, const std::string& colour) {
    Series series;
    series.name = name;
    series.style = Series::Style::points;
    series.colour = colour;
    return series;
}

Plot deflection_plot(const FingerprintCurves& curves, const Shown& u) {
    Plot plot;
    plot.id = "fingerprint-deflection-position";
    plot.title = "Encoder difference against position, per direction of the move";
    plot.x_label = fmt::format("scale position x_load [{}]", u.position);
    plot.y_label = fmt::format("motor encoder − scale d [{}]", u.length);
    Series forward = points("moving + (after a reversal into +)", blue);
    Series reverse = points("moving − (after a reversal into −)", orange);
    for (std::size_t k = 0; k < curves.position.size(); ++k) {
        if (curves.direction[k] == 0) continue;
        Series& series = curves.direction[k] > 0 ? forward : reverse;
        series.x.push_back(curves.position[k] * u.position_scale);
        series.y.push_back(curves.deflection[k] * u.length_scale);
    }
    plot.series = {std::move(forward), std::move(reverse)};
    return plot;
}

// F = (d - a) / c over the deflections of the fit's samples of one direction.
Series fitted_line(const FingerprintCurves& curves, int direction, double intercept, const Shown& u,
                   double force_scale) {
    Series line;
    line.name = direction > 0 ? "fit, pushing forward: d = a₊ + F/k" : "fit, pulling back: d = a₋ + F/k";
    line.colour = direction > 0 ? blue : orange;
    double low = INFINITY, high = -INFINITY;
    for (std::size_t k = 0; k < curves.deflection.size(); ++k) {
        if (!curves.in_fit[k] || curves.direction[k] != direction) continue;
        low = std::min(low, curves.deflection[k]);
        high = std::max(high, curves.deflection[k]);
    }
    if (!(low < high) || !curves.compliance || *curves.compliance == 0.0) return line;
    for (const double d : {low, high}) {
        line.x.push_back(d * u.length_scale);
        line.y.push_back((d - intercept) / *curves.compliance * force_scale);
    }
    return line;
}

Plot force_plot(const FingerprintCurves& curves, const Shown& u, const std::string& force_unit) {
    Plot plot;
    plot.id = "fingerprint-force-deflection";
    plot.title = "Drive force against the encoder difference";
    plot.x_label = fmt::format("motor encoder − scale d [{}]", u.length);
    plot.y_label = fmt::format("drive {} [{}]", force_unit == u.force ? "force F" : "signal", force_unit);
    Series other = points("other samples (moving off the line: accelerating, in the dead band)", light_grey);
    Series forward = points("in the fit, pushing forward", blue);
    Series reverse = points("in the fit, pulling back", orange);
    for (std::size_t k = 0; k < curves.drive.size(); ++k) {
        Series& series = !curves.in_fit[k] ? other : curves.direction[k] > 0 ? forward : reverse;
        series.x.push_back(curves.deflection[k] * u.length_scale);
        series.y.push_back(curves.drive[k]);
    }
    plot.series = {std::move(other), std::move(forward), std::move(reverse)};
    if (curves.intercept_forward) plot.series.push_back(fitted_line(curves, 1, *curves.intercept_forward, u, 1.0));
    if (curves.intercept_reverse) plot.series.push_back(fitted_line(curves, -1, *curves.intercept_reverse, u, 1.0));
    std::erase_if(plot.series, [](const Series& s) { return s.x.empty(); });
    return plot;
}

std::string cell(const nlohmann::json& entry, double scale, const std::string& unit) {
    if (!entry.is_object() || !entry.contains("value") || !entry["value"].is_number()) return "—";
    std::string text = fmt::format("{:.4g}", entry["value"].get<double>() * scale);
    if (entry.contains("stderr") && entry["stderr"].is_number())
        text += fmt::format(" ± {:.2g}", entry["stderr"].get<double>() * std::abs(scale));
    return text + " " + unit;
}

// The figures per direction, a null as "—" and the reason under the table.
std::string figures_table(const nlohmann::json& document, const Shown& u, bool rotary) {
    const auto& figures = document["fingerprint"];
    const std::string length = rotary ? "rad" : "m";
    struct Row {
        const char* name;
        const char* stem;
        std::string unit_key;
        double scale;
        std::string unit;
        bool directional;
    };
    const Row rows[] = {{"lost motion", "lost_motion", length, u.length_scale, u.length, true},
                        {"backlash", "backlash", length, u.length_scale, u.length, false},
                        {"stiffness", "stiffness", rotary ? "Nm_per_rad" : "N_per_m", u.stiffness_scale, u.stiffness,
                         true},
                        {"reversal error", "reversal_error", length, u.length_scale, u.length, true},
                        {"breakaway force", "breakaway", rotary ? "Nm" : "N", 1.0, u.force, true}};
    std::string html =
        "<table>\n<tr><th class=\"text\">figure</th><th>both directions</th><th>forward (into +)</th>"
        "<th>reverse (into −)</th></tr>\n";
    for (const auto& row : rows) {
        const auto entry = [&](const char* side) {
            const std::string key = fmt::format("{}{}_{}", row.stem, side, row.unit_key);
            return figures.contains(key) ? figures[key] : nlohmann::json();
        };
        html += fmt::format("<tr><td class=\"text\">{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n", row.name,
                            escape_xml(cell(entry(""), row.scale, row.unit)),
                            row.directional ? escape_xml(cell(entry("_forward"), row.scale, row.unit)) : "",
                            row.directional ? escape_xml(cell(entry("_reverse"), row.scale, row.unit)) : "");
    }
    html += "</table>\n";
    const auto& reasons = document["reasons"];
    if (reasons.is_object() && !reasons.empty()) {
        html += "<p>Why a figure is null (—):</p>\n<ul>\n";
        for (const auto& [figure, reason] : reasons.items())
            if (reason.is_string())
                html += fmt::format("<li><b>{}</b>: {}</li>\n", escape_xml(figure),
                                    escape_xml(reason.get<std::string>()));
        html += "</ul>\n";
    }
    return html;
}

}  // namespace

std::vector<Plot> fingerprint_plots(const FingerprintCurves& curves, bool rotary, const std::string& signal_unit) {
    const Shown u = shown_units(rotary);
    std::vector<Plot> plots;
    if (!curves.position.empty()) plots.push_back(deflection_plot(curves, u));
    if (!curves.drive.empty()) plots.push_back(force_plot(curves, u, signal_unit.empty() ? u.force : signal_unit));
    return plots;
}

std::string fingerprint_report_html(const nlohmann::json& document, const FingerprintCurves& curves,
                                    const std::string& source) {
    if (!document.is_object() || !document.contains("fingerprint") || !document["fingerprint"].is_object())
        throw InputError(fmt::format("{}: not a feedid fingerprint document (no \"fingerprint\" object)", source));
    const bool rotary = document["fingerprint"].contains("backlash_rad");
    const Shown u = shown_units(rotary);
    std::string signal_unit;
    if (document.contains("deflection_per_signal") && document["deflection_per_signal"].contains("unit")) {
        const auto unit = document["deflection_per_signal"]["unit"].get<std::string>();
        signal_unit = unit.substr(unit.find('/') + 1);  // "m/A": the drive signal's unit
    }
    const auto& reversals = document.contains("reversals") ? document["reversals"] : nlohmann::json::object();
    std::string body = fmt::format(
        "<p>Trace <code>{}</code>: {}; reversals into +: {}, into −: {}; samples in the force-deflection fit: "
        "{}.</p>\n",
        escape_xml(source),
        document.value("two_measuring_systems", false) ? "scale (position) and motor encoder (motor_position)"
                                                       : "one measuring system",
        reversals.value("forward", 0), reversals.value("reverse", 0), document.value("samples_used", 0));
    body += figures_table(document, u, rotary);
    if (document.contains("diagnostics") && document["diagnostics"].is_array() && !document["diagnostics"].empty()) {
        body += "<ul>\n";
        for (const auto& line : document["diagnostics"])
            if (line.is_string()) body += fmt::format("<li>{}</li>\n", escape_xml(line.get<std::string>()));
        body += "</ul>\n";
    }
    for (const auto& plot : fingerprint_plots(curves, rotary, signal_unit)) {
        const bool deflection = plot.id == "fingerprint-deflection-position";
        body += html_figure(
            plot, deflection
                      ? "The transmission's deflection d = x_motor − x_load at every sample, by the direction of the "
                        "last commanded move: the gap between the two bands is the lost motion; its slope along the "
                        "axis a pitch error of the screw or the scale."
                      : "Where the axis stands or moves at constant speed, d = a± + F/k: the slope of the fitted "
                        "lines is 1/k, the gap a₊ − a₋ between them at F = 0 the backlash.");
    }
    return html_page(fmt::format("feedid fingerprint: {}", std::filesystem::path(source).filename().string()), body);
}

}  // namespace feedid::report
