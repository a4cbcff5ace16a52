#pragma once
// The frame every report page shares (html_report.cpp): the page with its style, and a figure with its caption.
#include <string>

#include "feedid/report/svg_plot.hpp"

namespace feedid::report {

/// A self-contained HTML page: its title as <title> and <h1>, the body, the feedid version at the end.
std::string html_page(const std::string& title, const std::string& body);
/// The plot as an SVG figure with its caption.
std::string html_figure(const Plot& plot, const std::string& caption);

}  // namespace feedid::report
