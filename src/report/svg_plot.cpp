// SVG line and point plots with a shaded band, reference lines, highlighted points, linear or logarithmic x axis.
// Ticks at 1, 2 or 5 times a power of ten (Heckbert, "Nice numbers for graph labels", Graphics Gems, 1990) inside axes
// that hold the data with a margin. Data beyond the y axis is clipped in data space (Liang-Barsky for line segments,
// Sutherland-Hodgman for bands: no coordinate of a diverged series reaches the SVG) and marked at the frame.
// The image grows to hold its text: wrapped title and axis labels, the widest tick label, the legend rows.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <fmt/core.h>

#include "feedid/report/svg_plot.hpp"

namespace feedid::report {
namespace {

constexpr double infinity = std::numeric_limits<double>::infinity();

// Type [px]: sizes, line spacing, and the glyph box around a baseline (DejaVu Sans: ascent 0.93 em, descent 0.24 em).
constexpr double text_size = 12.0;
constexpr double title_size = 15.0;
constexpr double marker_label_size = 11.0;
constexpr double label_line_height = 15.0;
constexpr double title_line_height = 19.0;
constexpr double legend_row_height = 18.0;
constexpr double ascent = 0.95;   // [em] above the baseline
constexpr double descent = 0.3;   // [em] below the baseline
constexpr double tick_gap = 6.0;  // between the frame and a tick label

// Values beyond this cannot be placed on a finite axis: they never set one, and are marked as beyond it.
constexpr double largest_drawable = 1e300;

struct Range {
    double low{infinity};
    double high{-infinity};

    void include(double value) {
        if (!std::isfinite(value) || std::abs(value) > largest_drawable) return;
        low = std::min(low, value);
        high = std::max(high, value);
    }
    [[nodiscard]] bool empty() const { return !(low <= high); }
    [[nodiscard]] bool contains(double value) const { return value >= low && value <= high; }
    [[nodiscard]] double span() const { return high - low; }
};

/// 1, 2 or 5 times a power of ten, close to `value` (> 0).
double nice_step(double value) {
    const double exponent = std::floor(std::log10(value));
    const double fraction = value / std::pow(10.0, exponent);
    const double nice = fraction < 1.5 ? 1.0 : fraction < 3.0 ? 2.0 : fraction < 7.0 ? 5.0 : 10.0;
    return nice * std::pow(10.0, exponent);
}

/// The next nice step up: 1 -> 2 -> 5 -> 10.
double larger_nice_step(double step) {
    return nice_step(step * 2.2);
}

/// Widens an empty range, or one too narrow to label with a dozen significant digits, so that it can be drawn.
Range drawable(Range range) {
    if (range.empty()) return {0.0, 1.0};
    const double smallest_span = 1e-6 * std::max(std::abs(range.low), std::abs(range.high));
    if (range.span() < smallest_span || range.span() == 0.0) {
        const double middle = (range.low + range.high) / 2.0;
        const double half = middle == 0.0 ? 1.0 : std::max(smallest_span, 0.05 * std::abs(middle)) / 2.0;
        return {middle - half, middle + half};
    }
    return range;
}

Range with_margin(Range range, double fraction) {
    const double margin = fraction * range.span();
    return {range.low - margin, range.high + margin};
}

std::string number(double value) {
    return fmt::format("{:.2f}", value);
}

/// A tick label with as many decimals as the step needs (0.25 never appears: steps are 1, 2 or 5 x 10^k).
std::string tick_label(double value, double step) {
    if (std::abs(value) < step * 1e-9) value = 0.0;
    const int decimals = std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
    if (decimals <= 6 && std::abs(value) < 1e7) return fmt::format("{:.{}f}", value, decimals);
    // the digits the step needs after the leading one
    const double largest = std::max(std::abs(value), step);
    const int digits = std::max(0, static_cast<int>(std::floor(std::log10(largest)) - std::floor(std::log10(step))));
    return fmt::format("{:.{}e}", value, digits);
}

/// Greedy word wrap of one line of text into lines no wider than `width` (estimated); a word wider than that has a
/// line of its own.
std::vector<std::string> wrap(const std::string& text, double width, double font_size, bool bold = false) {
    std::vector<std::string> lines;
    std::string line;
    std::size_t start = 0;
    while (start <= text.size()) {
        auto end = text.find(' ', start);
        if (end == std::string::npos) end = text.size();
        const std::string word = text.substr(start, end - start);
        const std::string longer = line.empty() ? word : line + " " + word;
        if (!line.empty() && estimated_text_width(longer, font_size, bold) > width) {
            lines.push_back(line);
            line = word;
        } else {
            line = longer;
        }
        start = end + 1;
    }
    lines.push_back(line);
    return lines;
}

/// A <text> element of wrapped lines: one <tspan> per line, each but the last ending in the space it was broken at,
/// so that the element's text is the text as given. `dy` moves each line from the one before.
std::string text_lines(const std::vector<std::string>& lines, double x, double y, double dx, double dy,
                       const std::string& attributes) {
    std::string svg = fmt::format("<text {}>", attributes);
    for (std::size_t i = 0; i < lines.size(); ++i)
        svg +=
            fmt::format(R"(<tspan x="{}" y="{}">{}{}</tspan>)", number(x + dx * static_cast<double>(i)),
                        number(y + dy * static_cast<double>(i)), escape_xml(lines[i]), i + 1 < lines.size() ? " " : "");
    return svg + "</text>\n";
}

std::string dash(bool dashed) {
    return dashed ? R"( stroke-dasharray="6 4")" : "";
}

// A point in axis space: x in log10 units on a log axis; NaN marks a gap.
struct Point {
    double x;
    double y;
};

bool valid(const Point& p) {
    return std::isfinite(p.x) && std::isfinite(p.y);
}

constexpr double gap = std::numeric_limits<double>::quiet_NaN();

// A series' points in axis space; a step series holds each value from half-way to its neighbours.
std::vector<Point> axis_points(const Series& series, bool log_x) {
    const std::size_t n = std::min(series.x.size(), series.y.size());
    const auto to_axis = [&](double x) { return log_x ? (x > 0.0 ? std::log10(x) : gap) : x; };
    std::vector<Point> points;
    points.reserve(series.style == Series::Style::step ? 2 * n : n);
    for (std::size_t i = 0; i < n; ++i) {
        const double y = std::abs(series.y[i]) <= std::numeric_limits<double>::max() ? series.y[i] : gap;
        if (series.style != Series::Style::step) {
            points.push_back({to_axis(series.x[i]), y});
            continue;
        }
        // Each value holds from half-way to its neighbours (per-run limits on a run axis).
        const double half_left = i > 0 ? (series.x[i] - series.x[i - 1]) / 2.0 : 0.5;
        const double half_right = i + 1 < n ? (series.x[i + 1] - series.x[i]) / 2.0 : 0.5;
        points.push_back({to_axis(series.x[i] - half_left), y});
        points.push_back({to_axis(series.x[i] + half_right), y});
    }
    return points;
}

// What the plot holds (x in axis space): x over all data and vertical lines; y over the data that sets the y axis
// (its series, within the plot's x window) and the horizontal lines, or over all data when none is in the window.
struct DataExtent {
    Range x;
    Range y;
    bool any_data{false};
};

DataExtent data_extent(const Plot& plot) {
    DataExtent extent;
    Range window_y;
    Range all_y;
    bool window_data = false;
    for (const auto& series : plot.series) {
        const auto points = axis_points(series, plot.log_x);
        const std::size_t n = std::min(series.x.size(), series.y.size());
        for (std::size_t k = 0; k < points.size(); ++k) {
            const auto& p = points[k];
            if (!valid(p) || std::abs(p.y) > largest_drawable) continue;
            extent.any_data = true;
            extent.x.include(p.x);
            const std::size_t i = series.style == Series::Style::step ? k / 2 : k;
            const double band = i < series.band.size() && i < n && std::isfinite(series.band[i]) ? series.band[i] : 0.0;
            all_y.include(p.y + band);
            all_y.include(p.y - band);
            const double x = series.x[i];
            if (!series.sets_y_range || x < plot.y_range_from_x || x > plot.y_range_to_x) continue;
            window_data = true;
            window_y.include(p.y + band);
            window_y.include(p.y - band);
        }
    }
    extent.y = window_data ? window_y : all_y;
    for (const auto& line : plot.horizontal) extent.y.include(line.y);
    for (const auto& line : plot.vertical)
        if (!plot.log_x || line.x > 0.0) extent.x.include(plot.log_x ? std::log10(line.x) : line.x);
    return extent;
}

// The axes' ranges (x in axis space) before the ticks are chosen.
struct AxisRanges {
    Range x;
    Range y;
    Range x_ticks;  // where x ticks may go: a counting axis has none beyond its first and last count
};

AxisRanges axis_ranges(const Plot& plot, const DataExtent& extent) {
    AxisRanges ranges;
    if (plot.x_limits) {
        const auto [from, to] = *plot.x_limits;
        ranges.x = plot.log_x ? Range{std::log10(from), std::log10(to)} : Range{from, to};
        ranges.x = drawable(ranges.x);
    } else {
        ranges.x = drawable(extent.x);
    }
    const Range counted = ranges.x;
    if (plot.integer_x) {
        const double margin = std::max(0.5, 0.03 * ranges.x.span());
        ranges.x = {ranges.x.low - margin, ranges.x.high + margin};
    } else if (!plot.x_limits) {
        ranges.x = with_margin(ranges.x, 0.03);
    }
    ranges.x_ticks = plot.integer_x ? counted : ranges.x;
    ranges.y = with_margin(drawable(extent.y), 0.06);
    return ranges;
}

struct Ticks {
    std::vector<double> at;  // in axis space
    std::vector<std::string> labels;
    double widest{0.0};  // [px]
};

Ticks linear_ticks(Range range, double step) {
    Ticks ticks;
    const double first = std::ceil(range.low / step - 1e-9);
    const double last = std::floor(range.high / step + 1e-9);
    for (double k = first; k <= last && ticks.at.size() < 1000; k += 1.0) {
        const double t = k * step;
        ticks.at.push_back(t);
        ticks.labels.push_back(tick_label(t, step));
        ticks.widest = std::max(ticks.widest, estimated_text_width(ticks.labels.back(), text_size));
    }
    return ticks;
}

// About one tick per 45 px, at least two.
Ticks y_ticks(Range range, double frame_height) {
    const double target = std::max(3.0, std::floor(frame_height / 45.0));
    double step = nice_step(range.span() / target);
    Ticks ticks = linear_ticks(range, step);
    for (int guard = 0; guard < 20 && ticks.at.size() < 2; ++guard) {
        step = nice_step(step / 2.2);
        ticks = linear_ticks(range, step);
    }
    return ticks;
}

// Whole decades, with 2x and 5x when fewer than three decades are in view.
Ticks log_ticks(Range range) {
    Ticks ticks;
    const auto add = [&](double t) {
        if (!range.contains(t)) return;
        ticks.at.push_back(t);
        ticks.labels.push_back(fmt::format("{:g}", std::pow(10.0, t)));
        ticks.widest = std::max(ticks.widest, estimated_text_width(ticks.labels.back(), text_size));
    };
    const double first = std::floor(range.low);
    const double last = std::ceil(range.high);
    const bool few = last - first < 3.5;
    for (double decade = first; decade <= last; decade += 1.0) {
        add(decade);
        if (few) {
            add(decade + std::log10(2.0));
            add(decade + std::log10(5.0));
        }
    }
    return ticks;
}

// About one tick per 100 px, fewer while the labels would run into each other; whole numbers on a counting axis.
Ticks x_ticks(const Plot& plot, Range range, Range within, double frame_width) {
    const double px_per_unit = frame_width / range.span();
    if (plot.log_x) {
        Ticks ticks = log_ticks(range);
        // decades alone when the 2x and 5x labels would touch (log10(2) - 0 is the narrowest spacing)
        if (ticks.at.size() > 1 && (ticks.widest + 12.0) > std::log10(2.0) * px_per_unit) {
            Ticks decades;
            for (std::size_t i = 0; i < ticks.at.size(); ++i)
                if (std::abs(ticks.at[i] - std::round(ticks.at[i])) < 1e-9) {
                    decades.at.push_back(ticks.at[i]);
                    decades.labels.push_back(ticks.labels[i]);
                    decades.widest = std::max(decades.widest, estimated_text_width(ticks.labels[i], text_size));
                }
            if (decades.at.size() >= 2) return decades;
        }
        return ticks;
    }
    double step = nice_step(range.span() / std::max(2.0, std::floor(frame_width / 100.0)));
    if (plot.integer_x) step = std::max(1.0, step);
    Ticks ticks = linear_ticks(within, step);
    for (int guard = 0; guard < 20 && ticks.widest + 12.0 > step * px_per_unit; ++guard) {
        step = larger_nice_step(step);
        ticks = linear_ticks(within, step);
    }
    return ticks;
}

struct LegendEntry {
    std::string label;
    std::string swatch;  // SVG elements around (0, 0), 20 px wide
    double x{0.0};
    int row{0};
};

constexpr const char* off_scale_swatch = R"(<path d="M3 -1 L7 -7 L11 -1 Z M9 1 L13 7 L17 1 Z" fill="#555555"/>)";

std::vector<LegendEntry> legend_entries(const Plot& plot, bool any_off_scale) {
    std::vector<LegendEntry> entries;
    for (const auto& series : plot.series) {
        if (series.name.empty()) continue;
        std::string swatch;
        if (!series.band.empty())
            swatch += fmt::format(R"(<rect x="0" y="-6" width="20" height="12" fill="{}" fill-opacity="0.18"/>)",
                                  series.colour);
        if (series.style != Series::Style::points)
            swatch += fmt::format(R"(<line x1="0" y1="0" x2="20" y2="0" stroke="{}" stroke-width="1.6"{}/>)",
                                  series.colour, dash(series.dashed));
        if (series.style == Series::Style::points || series.style == Series::Style::line_and_points)
            swatch += fmt::format(R"(<circle cx="10" cy="0" r="3" fill="{}"/>)", series.colour);
        entries.push_back({series.name, swatch});
    }
    for (const auto& line : plot.horizontal) {
        if (line.label.empty()) continue;
        entries.push_back({line.label, fmt::format(R"(<line x1="0" y1="0" x2="20" y2="0" stroke="{}" )"
                                                   R"(stroke-width="1.2"{}/>)",
                                                   line.colour, dash(line.dashed))});
    }
    if (!plot.highlights.empty())
        entries.push_back(
            {"drift alarm", R"(<circle cx="10" cy="0" r="5" fill="none" stroke="#d62728" stroke-width="2"/>)"});
    if (any_off_scale) entries.push_back({plot.off_scale_label, off_scale_swatch});
    return entries;
}

// Legend entries flow left to right below the x label, wrapping at the plot's width. Returns the number of rows.
int place_legend(std::vector<LegendEntry>& entries, double plot_width) {
    double x = 24.0;
    int row = 0;
    for (auto& entry : entries) {
        const double width = 26.0 + estimated_text_width(entry.label, text_size) + 18.0;
        if (x > 24.0 && x + width > plot_width - 12.0) {
            x = 24.0;
            ++row;
        }
        entry.x = x;
        entry.row = row;
        x += width;
    }
    return entries.empty() ? 0 : entries.back().row + 1;
}

}  // namespace

double estimated_text_width(std::string_view text, double font_size, bool bold) {
    std::size_t characters = 0;  // UTF-8 code points: every byte that does not continue a sequence
    for (const char c : text) characters += (static_cast<unsigned char>(c) & 0xC0) != 0x80 ? 1 : 0;
    return static_cast<double>(characters) * font_size * (bold ? 0.72 : 0.65);
}

std::string escape_xml(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (const char c : text) {
        switch (c) {
            case '&': out += "&amp;"; break;
            case '<': out += "&lt;"; break;
            case '>': out += "&gt;"; break;
            case '"': out += "&quot;"; break;
            case '\'': out += "&apos;"; break;
            default:
                // Control characters other than tab and newline are not allowed in XML 1.0.
                if (static_cast<unsigned char>(c) < 0x20 && c != '\t' && c != '\n')
                    out += ' ';
                else
                    out += c;
        }
    }
    return out;
}

namespace {

// Where everything goes: the frame, the axes and ticks, the lines of text, the legend.
struct Layout {
    Range x;  // axis space
    Range y;
    Range x_tick_range;
    Ticks x_ticks;
    Ticks y_ticks;
    std::vector<std::string> title;
    std::vector<std::string> x_label;
    std::vector<std::string> y_label;
    std::vector<LegendEntry> legend;
    double left{0.0}, right{0.0}, top{0.0}, bottom{0.0};  // the frame [px]
    double width{0.0}, height{0.0};                       // the image [px]
    double marker_label_baseline{0.0};                    // labels of vertical lines, above the frame
    double x_label_baseline{0.0};                         // its first line
    double legend_first_row{0.0};                         // the middle of the first row

    [[nodiscard]] double px(double axis_x) const { return left + (axis_x - x.low) / x.span() * (right - left); }
    [[nodiscard]] double py(double axis_y) const { return bottom - (axis_y - y.low) / y.span() * (bottom - top); }
};

// The frame's top: below the title's lines and, when vertical lines carry labels, a row for them.
void lay_out_top(Layout& layout, const Plot& plot) {
    layout.title = wrap(plot.title, plot.width - 60.0, title_size, true);
    const double last_title_baseline = 20.0 + title_line_height * static_cast<double>(layout.title.size() - 1);
    layout.top = last_title_baseline + 18.0;
    const bool labelled_lines = std::any_of(plot.vertical.begin(), plot.vertical.end(),
                                            [](const VerticalLine& line) { return !line.label.empty(); });
    if (labelled_lines) layout.top += 14.0;
    layout.marker_label_baseline = layout.top - 5.0;
    layout.bottom = layout.top + std::max(100.0, plot.height - 104.0);
}

// Left of the frame: the y label's lines (rotated, the first one outermost), then the y tick labels.
void lay_out_sides(Layout& layout, const Plot& plot) {
    const double frame_height = layout.bottom - layout.top;
    layout.y_ticks = y_ticks(layout.y, frame_height);
    // The rotated label may reach 30 px beyond either end of the frame, into the margins: the title's lines keep
    // 30 px from the image's sides, and the x tick labels start right of it (the first is centred at the frame's left
    // edge, at least 64 px in).
    layout.y_label = wrap(plot.y_label, frame_height + 60.0, text_size);
    const double last_y_label_baseline = 18.0 + label_line_height * static_cast<double>(layout.y_label.size() - 1);
    layout.left = std::max(64.0, last_y_label_baseline + descent * text_size + 8.0 + layout.y_ticks.widest + tick_gap);
    // The last x tick label is centred on its tick, possibly at the frame's right edge: room for half of it.
    layout.right = plot.width - 24.0;
    layout.x_ticks = x_ticks(plot, layout.x, layout.x_tick_range, layout.right - layout.left);
    layout.right = plot.width - std::max(24.0, layout.x_ticks.widest / 2.0 + 6.0);
    layout.x_ticks = x_ticks(plot, layout.x, layout.x_tick_range, layout.right - layout.left);
}

// Below the frame: tick labels, the x label's lines, the legend's rows.
void lay_out_bottom(Layout& layout, const Plot& plot, bool any_off_scale) {
    layout.x_label = wrap(plot.x_label, layout.right - layout.left, text_size);
    layout.x_label_baseline = layout.bottom + 36.0;
    const double last_x_label_baseline =
        layout.x_label_baseline + label_line_height * static_cast<double>(layout.x_label.size() - 1);
    layout.legend = legend_entries(plot, any_off_scale);
    const int rows = place_legend(layout.legend, plot.width);
    layout.legend_first_row = last_x_label_baseline + 22.0;
    layout.height = rows == 0 ? last_x_label_baseline + 12.0
                              : layout.legend_first_row + legend_row_height * static_cast<double>(rows - 1) + 12.0;
    layout.width = plot.width;
}

// A stretch of a series beyond the y axis: where it leaves the frame, and the farthest value it reaches.
struct Excursion {
    double x;  // axis space, where it leaves (or its first point)
    bool above;
    double farthest;
    double farthest_x;  // axis space
    const Series* series;
};

std::vector<Excursion> excursions(const Plot& plot, const Range& x, const Range& y) {
    std::vector<Excursion> out;
    for (const auto& series : plot.series) {
        const auto points = axis_points(series, plot.log_x);
        int side = 0;  // of the point before: 0 inside (or none), +1 above, -1 below
        const Point* before = nullptr;
        for (const auto& p : points) {
            if (!valid(p) || !x.contains(p.x)) {
                side = 0;
                before = nullptr;
                continue;
            }
            const int here = p.y > y.high ? 1 : p.y < y.low ? -1 : 0;
            if (here != 0 && here != side) {
                double leaves = p.x;
                const double edge = here > 0 ? y.high : y.low;
                if (before && series.style != Series::Style::points && std::isfinite(before->y))
                    leaves = before->x + (edge - before->y) / (p.y - before->y) * (p.x - before->x);
                out.push_back({std::isfinite(leaves) ? leaves : p.x, here > 0, p.y, p.x, &series});
            } else if (here != 0 && (here > 0 ? p.y > out.back().farthest : p.y < out.back().farthest)) {
                out.back().farthest = p.y;
                out.back().farthest_x = p.x;
            }
            side = here;
            before = &p;
        }
    }
    return out;
}

Layout lay_out(const Plot& plot, std::vector<Excursion>& beyond) {
    Layout layout;
    const DataExtent extent = data_extent(plot);
    const AxisRanges ranges = axis_ranges(plot, extent);
    layout.x = ranges.x;
    layout.y = ranges.y;
    layout.x_tick_range = ranges.x_ticks;
    lay_out_top(layout, plot);
    lay_out_sides(layout, plot);
    beyond = excursions(plot, layout.x, layout.y);
    lay_out_bottom(layout, plot, !beyond.empty());
    return layout;
}

// The <svg> element's start, its title, the clip path of the frame, the background and the title's lines.
void write_head(std::string& svg, const Plot& plot, const Layout& layout) {
    const std::string id = escape_xml(plot.id);
    svg +=
        fmt::format(R"(<svg xmlns="http://www.w3.org/2000/svg" id="{}" class="plot" width="{}" height="{}" )"
                    R"(viewBox="0 0 {} {}" role="img" aria-labelledby="{}-title" font-family="sans-serif" )"
                    R"(font-size="12">)"
                    "\n",
                    id, number(layout.width), number(layout.height), number(layout.width), number(layout.height), id);
    svg += fmt::format(R"(<title id="{}-title">{}</title>)"
                       "\n",
                       id, escape_xml(plot.title));
    svg += fmt::format(R"(<defs><clipPath id="{}-clip"><rect x="{}" y="{}" width="{}" height="{}"/></clipPath></defs>)"
                       "\n",
                       id, number(layout.left), number(layout.top), number(layout.right - layout.left),
                       number(layout.bottom - layout.top));
    svg += fmt::format(R"(<rect x="0" y="0" width="{}" height="{}" fill="#ffffff"/>)"
                       "\n",
                       number(layout.width), number(layout.height));
    svg += text_lines(layout.title, layout.width / 2.0, 20.0, 0.0, title_line_height,
                      R"(class="plot-title" text-anchor="middle" font-size="15" font-weight="bold")");
}

void write_grid_and_ticks(std::string& svg, const Layout& layout) {
    svg += R"(<g class="grid" stroke="#e3e3e3" stroke-width="1">)";
    for (const double t : layout.y_ticks.at)
        svg += fmt::format(R"(<line x1="{}" y1="{}" x2="{}" y2="{}"/>)", number(layout.left), number(layout.py(t)),
                           number(layout.right), number(layout.py(t)));
    for (const double t : layout.x_ticks.at)
        svg += fmt::format(R"(<line x1="{}" y1="{}" x2="{}" y2="{}"/>)", number(layout.px(t)), number(layout.top),
                           number(layout.px(t)), number(layout.bottom));
    svg += "</g>\n";
    svg += R"(<g class="ticks" fill="#333333">)";
    // the baseline a third of the type size below the tick: the digits centred on it
    for (std::size_t i = 0; i < layout.y_ticks.at.size(); ++i)
        svg += fmt::format(R"(<text x="{}" y="{}" text-anchor="end">{}</text>)", number(layout.left - tick_gap),
                           number(layout.py(layout.y_ticks.at[i]) + 0.35 * text_size), layout.y_ticks.labels[i]);
    for (std::size_t i = 0; i < layout.x_ticks.at.size(); ++i)
        svg += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle">{}</text>)",
                           number(layout.px(layout.x_ticks.at[i])), number(layout.bottom + 16.0),
                           layout.x_ticks.labels[i]);
    svg += "</g>\n";
}

void write_frame_and_labels(std::string& svg, const Layout& layout) {
    svg += fmt::format(R"(<rect class="frame" x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#333333"/>)"
                       "\n",
                       number(layout.left), number(layout.top), number(layout.right - layout.left),
                       number(layout.bottom - layout.top));
    svg += text_lines(layout.x_label, (layout.left + layout.right) / 2.0, layout.x_label_baseline, 0.0,
                      label_line_height, R"(class="axis-label x-label" text-anchor="middle")");
    // Rotated a quarter turn about the first line's anchor: each further line sits label_line_height to its right.
    const double middle = (layout.top + layout.bottom) / 2.0;
    svg += text_lines(layout.y_label, 18.0, middle, 0.0, label_line_height,
                      fmt::format(R"~(class="axis-label y-label" text-anchor="middle" transform="rotate(-90 {} {})")~",
                                  number(18.0), number(middle)));
}

// Liang-Barsky: the part of the segment a-b inside the rectangle x by y; false when none is.
bool clip_segment(Point& a, Point& b, const Range& x, const Range& y) {
    double enter = 0.0;
    double leave = 1.0;
    const double dx = b.x - a.x;
    const double dy = b.y - a.y;
    const std::array<std::pair<double, double>, 4> sides{
        {{-dx, a.x - x.low}, {dx, x.high - a.x}, {-dy, a.y - y.low}, {dy, y.high - a.y}}};
    for (const auto& [p, q] : sides) {
        if (p == 0.0) {
            if (q < 0.0) return false;
            continue;
        }
        const double t = q / p;
        if (p < 0.0)
            enter = std::max(enter, t);
        else
            leave = std::min(leave, t);
        if (enter > leave) return false;
    }
    // the ends that stay inside are kept exactly: a + 1 * (b - a) need not round to b
    const Point start = enter > 0.0 ? Point{a.x + enter * dx, a.y + enter * dy} : a;
    const Point end = leave < 1.0 ? Point{a.x + leave * dx, a.y + leave * dy} : b;
    a = start;
    b = end;
    return true;
}

// Sutherland-Hodgman: the polygon cut to the rectangle x by y.
std::vector<Point> clip_polygon(std::vector<Point> polygon, const Range& x, const Range& y) {
    const std::array<std::pair<int, double>, 4> edges{{{0, x.low}, {1, x.high}, {2, y.low}, {3, y.high}}};
    for (const auto& [edge, limit] : edges) {
        const auto inside = [&, edge = edge, limit = limit](const Point& p) {
            return edge == 0 ? p.x >= limit : edge == 1 ? p.x <= limit : edge == 2 ? p.y >= limit : p.y <= limit;
        };
        const auto crossing = [&, edge = edge, limit = limit](const Point& a, const Point& b) {
            const double t = edge < 2 ? (limit - a.x) / (b.x - a.x) : (limit - a.y) / (b.y - a.y);
            return Point{a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)};
        };
        std::vector<Point> out;
        for (std::size_t i = 0; i < polygon.size(); ++i) {
            const Point& current = polygon[i];
            const Point& previous = polygon[(i + polygon.size() - 1) % polygon.size()];
            if (inside(current)) {
                if (!inside(previous)) out.push_back(crossing(previous, current));
                out.push_back(current);
            } else if (inside(previous)) {
                out.push_back(crossing(previous, current));
            }
        }
        polygon = std::move(out);
    }
    return polygon;
}

// The shaded band y ± band: one polygon per run of consecutive valid points, cut to the frame.
void write_band(std::string& svg, const Series& series, const Plot& plot, const Layout& layout) {
    const auto points = axis_points(series, plot.log_x);
    std::vector<Point> upper;
    std::vector<Point> lower;
    const auto flush = [&] {
        if (upper.size() >= 2) {
            upper.insert(upper.end(), lower.rbegin(), lower.rend());
            std::string text;
            for (const auto& p : clip_polygon(upper, layout.x, layout.y))
                text += fmt::format("{},{} ", number(layout.px(p.x)), number(layout.py(p.y)));
            if (!text.empty())
                svg += fmt::format(R"(<polygon class="band" points="{}" fill="{}" fill-opacity="0.18" stroke="none"/>)"
                                   "\n",
                                   text, series.colour);
        }
        upper.clear();
        lower.clear();
    };
    for (std::size_t k = 0; k < points.size(); ++k) {
        const std::size_t i = series.style == Series::Style::step ? k / 2 : k;
        const Point& p = points[k];
        if (i < series.band.size() && std::isfinite(series.band[i]) && valid(p) &&
            std::abs(p.y) + series.band[i] <= largest_drawable) {
            upper.push_back({p.x, p.y + series.band[i]});
            lower.push_back({p.x, p.y - series.band[i]});
        } else {
            flush();
        }
    }
    flush();
}

// One polyline per stretch of valid points inside the frame.
void write_line(std::string& svg, const Series& series, const Plot& plot, const Layout& layout) {
    const auto points = axis_points(series, plot.log_x);
    std::string text;
    const auto flush = [&] {
        if (!text.empty())
            svg += fmt::format(R"(<polyline class="series-line" points="{}" fill="none" stroke="{}" )"
                               R"(stroke-width="1.6"{}/>)"
                               "\n",
                               text, series.colour, dash(series.dashed));
        text.clear();
    };
    const auto add = [&](const Point& p) {
        text += fmt::format("{},{} ", number(layout.px(p.x)), number(layout.py(p.y)));
    };
    // Geometry only: a value beyond 1e301 leaves the frame the same way, without overflowing b.y - a.y.
    const auto held = [](Point p) {
        return Point{p.x, std::clamp(p.y, -10.0 * largest_drawable, 10.0 * largest_drawable)};
    };
    for (std::size_t i = 1; i < points.size(); ++i) {
        Point a = held(points[i - 1]);
        Point b = held(points[i]);
        if (!valid(a) || !valid(b) || !clip_segment(a, b, layout.x, layout.y)) {
            flush();
            continue;
        }
        const bool entered = a.x != points[i - 1].x || a.y != held(points[i - 1]).y;
        if (entered || text.empty()) {
            flush();
            add(a);
        }
        add(b);
        if (b.x != points[i].x || b.y != held(points[i]).y) flush();  // left the frame
    }
    flush();
}

void write_points(std::string& svg, const Series& series, const Plot& plot, const Layout& layout) {
    const auto points = axis_points(series, plot.log_x);
    svg += fmt::format(R"(<g class="series-points" fill="{}">)", series.colour);
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Point& p = points[i];
        if (!valid(p) || !layout.x.contains(p.x) || !layout.y.contains(p.y)) continue;
        if (i < series.tooltips.size())
            svg += fmt::format(R"(<circle cx="{}" cy="{}" r="3"><title>{}</title></circle>)", number(layout.px(p.x)),
                               number(layout.py(p.y)), escape_xml(series.tooltips[i]));
        else
            svg += fmt::format(R"(<circle cx="{}" cy="{}" r="3"/>)", number(layout.px(p.x)), number(layout.py(p.y)));
    }
    svg += "</g>\n";
}

// A triangle at the frame where a series leaves it, pointing the way it went, the farthest value as its tooltip;
// excursions closer than 10 px on the same edge share one.
void write_off_scale(std::string& svg, const Plot& plot, const Layout& layout, std::vector<Excursion> beyond) {
    std::stable_sort(beyond.begin(), beyond.end(),
                     [](const Excursion& a, const Excursion& b) { return a.above != b.above ? a.above : a.x < b.x; });
    std::vector<Excursion> merged;
    for (const auto& e : beyond) {
        if (!merged.empty() && merged.back().above == e.above && merged.back().series == e.series &&
            layout.px(e.x) - layout.px(merged.back().x) < 10.0) {
            auto& last = merged.back();
            if (e.above ? e.farthest > last.farthest : e.farthest < last.farthest) {
                last.farthest = e.farthest;
                last.farthest_x = e.farthest_x;
            }
            continue;
        }
        merged.push_back(e);
    }
    svg += R"(<g class="off-scale">)";
    for (const auto& e : merged) {
        const double x = std::clamp(layout.px(e.x), layout.left + 6.0, layout.right - 6.0);
        const double edge = e.above ? layout.top + 1.0 : layout.bottom - 1.0;
        const double inward = e.above ? 9.0 : -9.0;
        const std::string name = e.series->name.empty() ? std::string("data") : e.series->name;
        const double at = plot.log_x ? std::pow(10.0, e.farthest_x) : e.farthest_x;
        svg += fmt::format(R"(<path d="M{} {} L{} {} L{} {} Z" fill="{}" stroke="#ffffff" stroke-width="0.5">)"
                           R"(<title>{} beyond the axis: {:.4g} at {:.4g}</title></path>)",
                           number(x), number(edge), number(x - 5.0), number(edge + inward), number(x + 5.0),
                           number(edge + inward), e.series->colour, escape_xml(name), e.farthest, at);
    }
    svg += "</g>\n";
}

// Horizontal reference lines, vertical markers, and the highlighted points (held inside the frame).
void write_marks(std::string& svg, const Plot& plot, const Layout& layout) {
    for (const auto& line : plot.horizontal) {
        svg +=
            fmt::format(R"(<line class="reference" x1="{}" y1="{}" x2="{}" y2="{}" stroke="{}" stroke-width="1.2"{}/>)"
                        "\n",
                        number(layout.left), number(layout.py(line.y)), number(layout.right), number(layout.py(line.y)),
                        line.colour, dash(line.dashed));
    }
    for (const auto& line : plot.vertical) {
        if (plot.log_x && line.x <= 0.0) continue;
        const double axis_x = plot.log_x ? std::log10(line.x) : line.x;
        if (!layout.x.contains(axis_x)) continue;
        const double x = layout.px(axis_x);
        svg += fmt::format(R"(<line class="marker" x1="{}" y1="{}" x2="{}" y2="{}" stroke="{}" stroke-width="1.2" )"
                           R"(stroke-dasharray="3 3"/>)"
                           "\n",
                           number(x), number(layout.top), number(x), number(layout.bottom), line.colour);
    }
    for (const auto& point : plot.highlights) {
        const double axis_x = plot.log_x ? (point.x > 0.0 ? std::log10(point.x) : gap) : point.x;
        if (!std::isfinite(point.y) || !layout.x.contains(axis_x)) continue;
        svg +=
            fmt::format(R"(<circle class="alarm" cx="{}" cy="{}" r="6.5" fill="none" stroke="#d62728" )"
                        R"(stroke-width="2"><title>{}</title></circle>)"
                        "\n",
                        number(layout.px(axis_x)), number(layout.py(std::clamp(point.y, layout.y.low, layout.y.high))),
                        escape_xml(point.label));
    }
}

// The labels of vertical markers, above the frame: right of the line, or left of it where the image ends.
void write_marker_labels(std::string& svg, const Plot& plot, const Layout& layout) {
    for (const auto& line : plot.vertical) {
        if (line.label.empty() || (plot.log_x && line.x <= 0.0)) continue;
        const double axis_x = plot.log_x ? std::log10(line.x) : line.x;
        if (!layout.x.contains(axis_x)) continue;
        const double x = layout.px(axis_x);
        const bool fits_right = x + 4.0 + estimated_text_width(line.label, marker_label_size) <= layout.width - 4.0;
        svg += fmt::format(R"(<text class="marker-label" x="{}" y="{}" text-anchor="{}" fill="{}" font-size="11">{})"
                           R"(</text>)"
                           "\n",
                           number(fits_right ? x + 4.0 : x - 4.0), number(layout.marker_label_baseline),
                           fits_right ? "start" : "end", line.colour, escape_xml(line.label));
    }
}

// The data, clipped to the frame.
void write_data(std::string& svg, const Plot& plot, const Layout& layout, const std::vector<Excursion>& beyond) {
    svg += fmt::format(R"~(<g class="data" clip-path="url(#{}-clip)">)~"
                       "\n",
                       escape_xml(plot.id));
    for (const auto& series : plot.series) {
        if (!series.band.empty()) write_band(svg, series, plot, layout);
        if (series.style != Series::Style::points) write_line(svg, series, plot, layout);
        if (series.style == Series::Style::points || series.style == Series::Style::line_and_points)
            write_points(svg, series, plot, layout);
    }
    write_marks(svg, plot, layout);
    if (!beyond.empty()) write_off_scale(svg, plot, layout, beyond);
    svg += "</g>\n";
    write_marker_labels(svg, plot, layout);
}

// The legend, below the x label.
void write_legend(std::string& svg, const Layout& layout) {
    svg += R"(<g class="legend">)";
    for (const auto& entry : layout.legend) {
        const double y = layout.legend_first_row + legend_row_height * entry.row;
        svg += fmt::format(R"~(<g transform="translate({} {})">{}<text x="26" y="4">{}</text></g>)~", number(entry.x),
                           number(y), entry.swatch, escape_xml(entry.label));
    }
    svg += "</g>\n";
}

}  // namespace

std::string render_svg(const Plot& plot) {
    std::vector<Excursion> beyond;
    const Layout layout = lay_out(plot, beyond);
    std::string svg;
    write_head(svg, plot, layout);
    write_grid_and_ticks(svg, layout);
    write_frame_and_labels(svg, layout);
    write_data(svg, plot, layout, beyond);
    if (!data_extent(plot).any_data)
        svg += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" fill="#888888">no data</text>)"
                           "\n",
                           number((layout.left + layout.right) / 2.0), number((layout.top + layout.bottom) / 2.0));
    write_legend(svg, layout);
    svg += "</svg>\n";
    return svg;
}

}  // namespace feedid::report
