#pragma once
// The report of one mechanical fingerprint (fingerprint.hpp): one self-contained HTML page with the figures and their
// standard errors (a null with its reason), the encoder difference d = x_motor - x_load against the scale's position
// per direction of the move (the lost motion is the gap between the two), and the drive force against d with the
// fitted lines of the force-deflection fit (their slope is the stiffness, their offset the backlash).
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/identify/fingerprint.hpp"
#include "feedid/report/svg_plot.hpp"

namespace feedid::report {

/// The plots of a fingerprint: the encoder difference against position (none with one measuring system) and the
/// force against deflection (none without a drive signal); lengths in µm (mdeg), positions in mm (deg).
std::vector<Plot> fingerprint_plots(const FingerprintCurves& curves, bool rotary, const std::string& signal_unit);

/// The whole page from the fingerprint document (fingerprint_document(), with "trace") and the result's curves.
/// InputError naming `source` when the document is not a fingerprint document.
std::string fingerprint_report_html(const nlohmann::json& document, const FingerprintCurves& curves,
                                    const std::string& source);

}  // namespace feedid::report
