// SVG line and point plots with a shaded band, reference lines, highlighted points, linear or logarithmic x axis.
// Ticks at 1, 2 or 5 times a power of ten (Heckbert, "Nice numbers for graph labels", Graphics Gems, 1990).

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/core.h>

#include "feedid/report.hpp"

namespace feedid::report {
namespace {

struct Range {
    double low{std::numeric_limits<double>::infinity()};
    double high{-std::numeric_limits<double>::infinity()};

    void include(double value) {
        if (!std::isfinite(value)) return;
        low = std::min(low, value);
        high = std::max(high, value);
    }
    [[nodiscard]] bool empty() const { return !(low <= high); }
};

/// 1, 2 or 5 times a power of ten, close to `value` (> 0).
double nice_step(double value) {
    const double exponent = std::floor(std::log10(value));
    const double fraction = value / std::pow(10.0, exponent);
    const double nice = fraction < 1.5 ? 1.0 : fraction < 3.0 ? 2.0 : fraction < 7.0 ? 5.0 : 10.0;
    return nice * std::pow(10.0, exponent);
}

/// Widens a degenerate or empty range so that it can be drawn.
Range drawable(Range range) {
    if (range.empty()) return {0.0, 1.0};
    if (range.high - range.low <= 1e-12 * std::max(1.0, std::abs(range.high))) {
        const double half = range.low == 0.0 ? 1.0 : 0.05 * std::abs(range.low);
        return {range.low - half, range.high + half};
    }
    return range;
}

std::string number(double value) {
    return fmt::format("{:.2f}", value);
}

std::string tick_label(double value, double step) {
    if (std::abs(value) < step * 1e-9) value = 0.0;
    return fmt::format("{:.6g}", value);
}

class Canvas {
public:
    Canvas(const Plot& plot, Range x, Range y)
        : plot_(plot),
          x_(x),
          y_(y),
          left_(84.0),
          right_(plot.width - 24.0),
          top_(40.0),
          bottom_(plot.height - 64.0) {}  // the legend grows the image below this, see render_svg

    [[nodiscard]] double px(double x) const {
        if (plot_.log_x) return left_ + (std::log10(x) - x_.low) / (x_.high - x_.low) * (right_ - left_);
        return left_ + (x - x_.low) / (x_.high - x_.low) * (right_ - left_);
    }
    [[nodiscard]] double py(double y) const { return bottom_ - (y - y_.low) / (y_.high - y_.low) * (bottom_ - top_); }
    [[nodiscard]] bool valid(double x, double y) const {
        return std::isfinite(x) && std::isfinite(y) && (!plot_.log_x || x > 0.0);
    }

private:
    const Plot& plot_;
    Range x_;  // in log10 units for a log axis
    Range y_;

public:
    double left_, right_, top_, bottom_;
};

std::string dash(bool dashed) {
    return dashed ? R"( stroke-dasharray="6 4")" : "";
}

}  // namespace

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

// What the plot holds, within which ranges (x in log10 units on a log axis).
struct DataExtent {
    Range x;
    Range y;
    bool any_data{false};
};

DataExtent data_extent(const Plot& plot) {
    DataExtent extent;
    for (const auto& series : plot.series) {
        for (std::size_t i = 0; i < series.x.size() && i < series.y.size(); ++i) {
            const double x = series.x[i];
            const double y = series.y[i];
            if (!std::isfinite(x) || !std::isfinite(y) || (plot.log_x && x <= 0.0)) continue;
            extent.any_data = true;
            extent.x.include(plot.log_x ? std::log10(x) : x);
            extent.y.include(y);
            if (i < series.band.size() && std::isfinite(series.band[i])) {
                extent.y.include(y + series.band[i]);
                extent.y.include(y - series.band[i]);
            }
        }
    }
    for (const auto& line : plot.horizontal) extent.y.include(line.y);
    for (const auto& line : plot.vertical)
        if (!plot.log_x || line.x > 0.0) extent.x.include(plot.log_x ? std::log10(line.x) : line.x);
    return extent;
}

// The axes end on ticks (linear) or whole decades (log).
struct Axes {
    Range x;  // in log10 units on a log axis
    Range y;
    std::vector<double> x_ticks;  // in log10 units on a log axis
    std::vector<double> y_ticks;
    double x_step{1.0};
    double y_step{1.0};
};

Axes axes_on_ticks(const Plot& plot, Range x_range, Range y_range) {
    Axes axes;
    axes.y_step = nice_step((y_range.high - y_range.low) / 5.0);
    const double y_step = axes.y_step;
    axes.y = {std::floor(y_range.low / y_step) * y_step, std::ceil(y_range.high / y_step) * y_step};
    for (double t = axes.y.low; t <= axes.y.high + 0.5 * y_step; t += y_step) axes.y_ticks.push_back(t);
    if (plot.log_x) {
        axes.x = {std::floor(x_range.low), std::ceil(x_range.high)};
        if (axes.x.high <= axes.x.low) axes.x.high = axes.x.low + 1.0;
        for (double t = axes.x.low; t <= axes.x.high + 0.5; t += 1.0) axes.x_ticks.push_back(t);
    } else {
        axes.x_step = nice_step((x_range.high - x_range.low) / 6.0);
        const double x_step = axes.x_step;
        axes.x = {std::floor(x_range.low / x_step) * x_step, std::ceil(x_range.high / x_step) * x_step};
        for (double t = axes.x.low; t <= axes.x.high + 0.5 * x_step; t += x_step) axes.x_ticks.push_back(t);
    }
    return axes;
}

// The pixel column of an x tick (given in log10 units on a log axis).
double tick_px(const Plot& plot, const Canvas& canvas, double t) {
    return canvas.px(plot.log_x ? std::pow(10.0, t) : t);
}

struct LegendEntry {
    std::string label;
    std::string swatch;  // SVG elements around (0, 0), 20 px wide
    double x{0.0};
    int row{0};
};

std::vector<LegendEntry> legend_entries(const Plot& plot) {
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
    return entries;
}

// Legend entries flow left to right below the x label, wrapping at the plot's width (text width estimated at 6.8 px
// per character of 12 px sans-serif). Returns the number of rows.
int place_legend(std::vector<LegendEntry>& entries, double plot_width) {
    double x = 24.0;
    int row = 0;
    for (auto& entry : entries) {
        const double width = 26.0 + 6.8 * static_cast<double>(entry.label.size()) + 18.0;
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

// The <svg> element's start, its title, the clip path of the plot area, the background and the title text.
void write_head(std::string& svg, const Plot& plot, const Canvas& canvas, double height) {
    const std::string id = escape_xml(plot.id);
    svg += fmt::format(R"(<svg xmlns="http://www.w3.org/2000/svg" id="{}" class="plot" width="{}" height="{}" )"
                       R"(viewBox="0 0 {} {}" role="img" aria-labelledby="{}-title" font-family="sans-serif" )"
                       R"(font-size="12">)"
                       "\n",
                       id, number(plot.width), number(height), number(plot.width), number(height), id);
    svg += fmt::format(R"(<title id="{}-title">{}</title>)"
                       "\n",
                       id, escape_xml(plot.title));
    svg += fmt::format(R"(<defs><clipPath id="{}-clip"><rect x="{}" y="{}" width="{}" height="{}"/></clipPath></defs>)"
                       "\n",
                       id, number(canvas.left_), number(canvas.top_), number(canvas.right_ - canvas.left_),
                       number(canvas.bottom_ - canvas.top_));
    svg += fmt::format(R"(<rect x="0" y="0" width="{}" height="{}" fill="#ffffff"/>)"
                       "\n",
                       number(plot.width), number(height));
    svg += fmt::format(R"(<text class="plot-title" x="{}" y="22" text-anchor="middle" font-size="15" )"
                       R"(font-weight="bold">{}</text>)"
                       "\n",
                       number(plot.width / 2.0), escape_xml(plot.title));
}

void write_grid_and_ticks(std::string& svg, const Plot& plot, const Canvas& canvas, const Axes& axes) {
    svg += R"(<g class="grid" stroke="#e3e3e3" stroke-width="1">)";
    for (const double t : axes.y_ticks)
        svg += fmt::format(R"(<line x1="{}" y1="{}" x2="{}" y2="{}"/>)", number(canvas.left_), number(canvas.py(t)),
                           number(canvas.right_), number(canvas.py(t)));
    for (const double t : axes.x_ticks) {
        const double x = tick_px(plot, canvas, t);
        svg += fmt::format(R"(<line x1="{}" y1="{}" x2="{}" y2="{}"/>)", number(x), number(canvas.top_), number(x),
                           number(canvas.bottom_));
    }
    svg += "</g>\n";
    svg += R"(<g class="ticks" fill="#333333">)";
    for (const double t : axes.y_ticks)
        svg += fmt::format(R"(<text x="{}" y="{}" text-anchor="end" dominant-baseline="middle">{}</text>)",
                           number(canvas.left_ - 6.0), number(canvas.py(t)), tick_label(t, axes.y_step));
    for (const double t : axes.x_ticks) {
        const double x = tick_px(plot, canvas, t);
        const std::string label = plot.log_x ? fmt::format("{:g}", std::pow(10.0, t)) : tick_label(t, axes.x_step);
        svg += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle">{}</text>)", number(x),
                           number(canvas.bottom_ + 16.0), label);
    }
    svg += "</g>\n";
}

double y_middle(const Canvas& canvas) {
    return (canvas.top_ + canvas.bottom_) / 2.0;
}

void write_frame_and_labels(std::string& svg, const Plot& plot, const Canvas& canvas) {
    svg += fmt::format(R"(<rect class="frame" x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#333333"/>)"
                       "\n",
                       number(canvas.left_), number(canvas.top_), number(canvas.right_ - canvas.left_),
                       number(canvas.bottom_ - canvas.top_));
    svg += fmt::format(R"(<text class="axis-label x-label" x="{}" y="{}" text-anchor="middle">{}</text>)"
                       "\n",
                       number((canvas.left_ + canvas.right_) / 2.0), number(canvas.bottom_ + 36.0),
                       escape_xml(plot.x_label));
    const double middle = y_middle(canvas);
    svg += fmt::format(R"(<text class="axis-label y-label" x="{}" y="{}" text-anchor="middle" )"
                       R"~(transform="rotate(-90 {} {})">{}</text>)~"
                       "\n",
                       number(18.0), number(middle), number(18.0), number(middle), escape_xml(plot.y_label));
}

// The shaded band y ± band: one polygon per run of consecutive valid points.
void write_band(std::string& svg, const Series& series, const Canvas& canvas) {
    const std::size_t n = std::min(series.x.size(), series.y.size());
    std::vector<std::size_t> run;
    const auto flush = [&] {
        if (run.size() >= 2) {
            std::string points;
            for (const auto i : run)
                points += fmt::format("{},{} ", number(canvas.px(series.x[i])),
                                      number(canvas.py(series.y[i] + series.band[i])));
            for (auto i = run.rbegin(); i != run.rend(); ++i)
                points += fmt::format("{},{} ", number(canvas.px(series.x[*i])),
                                      number(canvas.py(series.y[*i] - series.band[*i])));
            svg += fmt::format(R"(<polygon class="band" points="{}" fill="{}" fill-opacity="0.18" stroke="none"/>)"
                               "\n",
                               points, series.colour);
        }
        run.clear();
    };
    for (std::size_t i = 0; i < n; ++i) {
        if (i < series.band.size() && std::isfinite(series.band[i]) && canvas.valid(series.x[i], series.y[i]))
            run.push_back(i);
        else
            flush();
    }
    flush();
}

// One polyline per run of valid points; a step series holds each value from half-way to its neighbours.
void write_line(std::string& svg, const Series& series, const Canvas& canvas) {
    const std::size_t n = std::min(series.x.size(), series.y.size());
    std::string points;
    const auto flush = [&] {
        if (!points.empty())
            svg += fmt::format(R"(<polyline class="series-line" points="{}" fill="none" stroke="{}" )"
                               R"(stroke-width="1.6"{}/>)"
                               "\n",
                               points, series.colour, dash(series.dashed));
        points.clear();
    };
    for (std::size_t i = 0; i < n; ++i) {
        if (!canvas.valid(series.x[i], series.y[i])) {
            flush();
            continue;
        }
        if (series.style == Series::Style::step) {
            // Each value holds from half-way to its neighbours (per-run limits on a run axis).
            const double half_left = i > 0 ? (series.x[i] - series.x[i - 1]) / 2.0 : 0.5;
            const double half_right = i + 1 < n ? (series.x[i + 1] - series.x[i]) / 2.0 : 0.5;
            points +=
                fmt::format("{},{} {},{} ", number(canvas.px(series.x[i] - half_left)), number(canvas.py(series.y[i])),
                            number(canvas.px(series.x[i] + half_right)), number(canvas.py(series.y[i])));
        } else {
            points += fmt::format("{},{} ", number(canvas.px(series.x[i])), number(canvas.py(series.y[i])));
        }
    }
    flush();
}

void write_points(std::string& svg, const Series& series, const Canvas& canvas) {
    const std::size_t n = std::min(series.x.size(), series.y.size());
    svg += fmt::format(R"(<g class="series-points" fill="{}">)", series.colour);
    for (std::size_t i = 0; i < n; ++i) {
        if (!canvas.valid(series.x[i], series.y[i])) continue;
        if (i < series.tooltips.size())
            svg += fmt::format(R"(<circle cx="{}" cy="{}" r="3"><title>{}</title></circle>)",
                               number(canvas.px(series.x[i])), number(canvas.py(series.y[i])),
                               escape_xml(series.tooltips[i]));
        else
            svg += fmt::format(R"(<circle cx="{}" cy="{}" r="3"/>)", number(canvas.px(series.x[i])),
                               number(canvas.py(series.y[i])));
    }
    svg += "</g>\n";
}

void write_series(std::string& svg, const Series& series, const Canvas& canvas) {
    if (!series.band.empty()) write_band(svg, series, canvas);
    if (series.style != Series::Style::points) write_line(svg, series, canvas);
    if (series.style == Series::Style::points || series.style == Series::Style::line_and_points)
        write_points(svg, series, canvas);
}

// Horizontal reference lines, vertical markers with their labels, and the highlighted points.
void write_marks(std::string& svg, const Plot& plot, const Canvas& canvas) {
    for (const auto& line : plot.horizontal) {
        svg +=
            fmt::format(R"(<line class="reference" x1="{}" y1="{}" x2="{}" y2="{}" stroke="{}" stroke-width="1.2"{}/>)"
                        "\n",
                        number(canvas.left_), number(canvas.py(line.y)), number(canvas.right_),
                        number(canvas.py(line.y)), line.colour, dash(line.dashed));
    }
    for (const auto& line : plot.vertical) {
        if (plot.log_x && line.x <= 0.0) continue;
        const double x = canvas.px(line.x);
        svg += fmt::format(R"(<line class="marker" x1="{}" y1="{}" x2="{}" y2="{}" stroke="{}" stroke-width="1.2" )"
                           R"(stroke-dasharray="3 3"/>)"
                           R"(<text x="{}" y="{}" fill="{}" font-size="11">{}</text>)"
                           "\n",
                           number(x), number(canvas.top_), number(x), number(canvas.bottom_), line.colour,
                           number(x + 4.0), number(canvas.top_ + 13.0), line.colour, escape_xml(line.label));
    }
    for (const auto& point : plot.highlights) {
        if (!canvas.valid(point.x, point.y)) continue;
        svg += fmt::format(R"(<circle class="alarm" cx="{}" cy="{}" r="6.5" fill="none" stroke="#d62728" )"
                           R"(stroke-width="2"><title>{}</title></circle>)"
                           "\n",
                           number(canvas.px(point.x)), number(canvas.py(point.y)), escape_xml(point.label));
    }
}

// The data, clipped to the plot area.
void write_data(std::string& svg, const Plot& plot, const Canvas& canvas) {
    svg += fmt::format(R"~(<g class="data" clip-path="url(#{}-clip)">)~"
                       "\n",
                       escape_xml(plot.id));
    for (const auto& series : plot.series) write_series(svg, series, canvas);
    write_marks(svg, plot, canvas);
    svg += "</g>\n";
}

// The legend, below the x label.
void write_legend(std::string& svg, const std::vector<LegendEntry>& entries, const Canvas& canvas) {
    svg += R"(<g class="legend">)";
    for (const auto& entry : entries) {
        const double y = canvas.bottom_ + 58.0 + 18.0 * entry.row;
        svg += fmt::format(R"~(<g transform="translate({} {})">{}<text x="26" y="4">{}</text></g>)~", number(entry.x),
                           number(y), entry.swatch, escape_xml(entry.label));
    }
    svg += "</g>\n";
}

}  // namespace

std::string render_svg(const Plot& plot) {
    const DataExtent extent = data_extent(plot);
    const Axes axes = axes_on_ticks(plot, drawable(extent.x), drawable(extent.y));
    auto legend = legend_entries(plot);
    const int legend_rows = place_legend(legend, plot.width);
    const Canvas canvas(plot, axes.x, axes.y);
    const double height = plot.height + 18.0 * std::max(0, legend_rows - 1);

    std::string svg;
    write_head(svg, plot, canvas, height);
    write_grid_and_ticks(svg, plot, canvas, axes);
    write_frame_and_labels(svg, plot, canvas);
    write_data(svg, plot, canvas);
    if (!extent.any_data)
        svg += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" fill="#888888">no data</text>)"
                           "\n",
                           number((canvas.left_ + canvas.right_) / 2.0), number(y_middle(canvas)));
    write_legend(svg, legend, canvas);
    svg += "</svg>\n";
    return svg;
}

}  // namespace feedid::report
