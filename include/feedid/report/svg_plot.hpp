#pragma once
// The report's plots: SVG written by feedid itself, one self-contained element per plot (no script, no font, no
// stylesheet from the network). The result report (result_report.hpp) and the history report (history_report.hpp)
// lay their figures out as these plots.
//
// Every plot has a title and both axes labelled with their unit; each SVG is well-formed XML on its own. Nothing is
// clipped: the image grows to hold wrapped titles and labels, tick labels and the legend (text widths estimated at
// 0.65 em per character, 0.72 em in bold: DejaVu Sans, the sans-serif of Debian's browsers, measures at most 0.64 and
// 0.70 em for digits, its widest common characters). Data that lies beyond the y axis (a start-up transient, a
// diverged simulation) is clipped at the frame and marked there with a triangle.

#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace feedid::report {

/// One data series of a plot.
struct Series {
    enum class Style { line, points, line_and_points, step };
    std::string name;  ///< legend entry ("" = not in the legend)
    std::vector<double> x;
    std::vector<double> y;     ///< same length as x; non-finite values are gaps
    std::vector<double> band;  ///< empty, or half-widths: a shaded band y +- band
    Style style{Style::line};
    std::string colour{"#1f77b4"};
    bool dashed{false};
    std::vector<std::string> tooltips;  ///< empty, or one per point (an SVG <title> on each marker)
    /// false: drawn, but the y axis is not widened for it (a diverged simulation next to the measured error)
    bool sets_y_range{true};
};

/// A horizontal line across the plot (a baseline, a limit, a final value).
struct HorizontalLine {
    std::string label;
    double y{0.0};
    std::string colour{"#555555"};
    bool dashed{true};
};

/// A vertical line (the end of the RLS transient).
struct VerticalLine {
    std::string label;
    double x{0.0};
    std::string colour{"#555555"};
};

/// A highlighted point (a run in alarm).
struct Highlight {
    double x{0.0};
    double y{0.0};
    std::string label;  ///< tooltip
};

struct Plot {
    std::string id;       ///< element id of the <svg> (letters, digits, '-')
    std::string title;    ///< shown above the plot and as the SVG's <title>
    std::string x_label;  ///< with the unit: "time [s]"
    std::string y_label;  ///< with the unit: "Coulomb friction F_C [N]"
    std::vector<Series> series;
    std::vector<HorizontalLine> horizontal;
    std::vector<VerticalLine> vertical;
    std::vector<Highlight> highlights;
    bool log_x{false};  ///< logarithmic x axis (every x must be > 0)
    /// x counts something (runs in recording order): ticks on whole numbers only, the axis wider than the data (or
    /// x_limits) by half a unit or 3 % of the span, whichever is more, on both sides.
    bool integer_x{false};
    /// Fixed x axis ends (in x, not log10 x); none: the data's range with a margin.
    std::optional<std::pair<double, double>> x_limits;
    /// The y axis covers the data of series that set it at x in [y_range_from_x, y_range_to_x] (the settled part
    /// of an RLS estimate, the stretch before a simulation diverged) and every horizontal line; what lies beyond is
    /// clipped at the frame and marked there (a triangle, with the farthest value as its tooltip).
    double y_range_from_x{-std::numeric_limits<double>::infinity()};
    double y_range_to_x{std::numeric_limits<double>::infinity()};
    std::string off_scale_label{"beyond the axis (clipped)"};  ///< legend entry of the markers, when there are any
    double width{760.0};                                       ///< [px]
    /// [px]: the frame is height - 104 px tall; a wrapped title or label and each legend row add to the image.
    double height{340.0};
};

/// The plot as a standalone SVG element (well-formed XML, the SVG namespace declared).
std::string render_svg(const Plot& plot);

/// The width of a line of text in the report's sans-serif, estimated from its characters (code points) and font size,
/// never less than Chromium draws it with DejaVu Sans for the report's text (letters, digits, symbols) [px].
double estimated_text_width(std::string_view text, double font_size, bool bold = false);

/// Escapes &, <, >, " and ' for XML text and attribute values.
std::string escape_xml(std::string_view text);

}  // namespace feedid::report
