#pragma once
// The report of one identification: one self-contained HTML file (no script, no font, no stylesheet from the network)
// with the parameter table, the diagnostics and SVG plots (svg_plot.hpp) of an identify result document: the RLS
// estimates over time with the detected transient (the paper's Fig. 3 and 4) and the measured friction against speed
// with the fitted curve per direction (Fig. 5). With a simulate document (feedid simulate --json): the tracking error
// of machine and model and the modelling error over time (the paper's Fig. 6) and the validation figures.

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/report/svg_plot.hpp"

namespace feedid::report {

/// Human name and unit of a result-document parameter key: "coulomb_forward_N" -> {"Coulomb friction F_C+", "N"};
/// of a fingerprint figure in the unit people read it in: "lost_motion_forward_m" -> {"Lost motion+ (forward)", "µm",
/// 1e6}.
struct ParameterLabel {
    std::string name;
    std::string unit;
    double scale{1.0};  ///< the value in `unit` per SI value of the key
};
ParameterLabel parameter_label(const std::string& key);

/// Plots of an identify result document: RLS histories (one per parameter, with the transient end and the batch
/// value) and the friction curve. InputError naming `source` when the document is not an identify result.
std::vector<Plot> result_plots(const nlohmann::json& result, const std::string& source);

/// A simulate document (feedid simulate --json) and the file it came from.
struct SimulationDocument {
    nlohmann::json document;
    std::string source;
};

/// Plots of a simulate document, the paper's Fig. 6: the tracking errors of machine and model over time, and the
/// modelling error over time. InputError naming `source` (and the key) when it is not a simulate document with a
/// well-formed "series".
std::vector<Plot> simulation_plots(const nlohmann::json& simulation, const std::string& source);

/// The whole HTML page of an identify result document (parameter table, diagnostics, plots), with the validation by
/// simulation (figures and Fig. 6) when a simulate document is given. InputError when either document is of the
/// wrong kind.
std::string result_report_html(const nlohmann::json& result, const std::string& source,
                               const std::optional<SimulationDocument>& simulation = std::nullopt);

}  // namespace feedid::report
