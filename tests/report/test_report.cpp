// feedid report: SVG plots that parse as XML with their titles and axis labels, and a self-contained HTML page that a
// real browser (headless Chromium) renders: every plot's title, axis labels and data get a non-empty box.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <regex>
#include <sstream>

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <pugixml.hpp>

#include "feedid/core/error.hpp"
#include "feedid/history/store.hpp"
#include "feedid/report/result_report.hpp"
#include "history_testing.hpp"
#include "testing.hpp"

namespace {

using namespace feedid::testing;
namespace fs = std::filesystem;
namespace report = feedid::report;
namespace history = feedid::history;

struct SvgText {
    std::string title;    // <title>
    std::string heading;  // the visible title
    std::string x_label;
    std::string y_label;
};

/// The text of an element and its descendants (a wrapped title or label is one <text> of <tspan> lines).
std::string text_of(const pugi::xml_node& node) {
    std::string text;
    for (const auto& child : node.children())
        text += child.type() == pugi::node_pcdata ? std::string(child.value()) : text_of(child);
    return text;
}

/// Parses one SVG element as XML; fails the test when it is not well-formed.
SvgText parse_svg(const std::string& svg) {
    pugi::xml_document document;
    const auto parsed = document.load_string(svg.c_str());
    EXPECT_TRUE(parsed) << parsed.description() << " at offset " << parsed.offset << "\n" << svg.substr(0, 300);
    const auto root = document.child("svg");
    EXPECT_TRUE(root) << svg.substr(0, 200);
    EXPECT_STREQ(root.attribute("xmlns").value(), "http://www.w3.org/2000/svg");
    SvgText text;
    text.title = root.child("title").text().get();
    for (const auto& node : document.select_nodes("//text")) {
        const std::string type = node.node().attribute("class").value();
        if (type == "plot-title") text.heading = text_of(node.node());
        if (type == "axis-label x-label") text.x_label = text_of(node.node());
        if (type == "axis-label y-label") text.y_label = text_of(node.node());
    }
    return text;
}

/// Every <svg ...>...</svg> element of an HTML page.
std::vector<std::string> svgs_of(const std::string& html) {
    std::vector<std::string> out;
    for (std::size_t start = html.find("<svg"); start != std::string::npos; start = html.find("<svg", start + 1)) {
        const auto end = html.find("</svg>", start);
        if (end == std::string::npos) break;
        out.push_back(html.substr(start, end + 6 - start));
    }
    return out;
}

bool has_unit(const std::string& label) {
    return std::regex_search(label, std::regex(R"(\[[^\]]+\]$)"));
}

// How wide and tall text is drawn, estimated from its font size and character count, conservatively: DejaVu Sans (the
// sans-serif of Debian's Chromium) draws the report's strings at most 0.64 em per character (0.70 em in bold; digits
// are its widest common glyphs), from 0.93 em above the baseline to 0.24 em below it. The browser test below checks
// the estimate against the widths Chromium measures.
constexpr double em_per_character = 0.65;
constexpr double em_per_bold_character = 0.72;
constexpr double ascent_em = 0.95;
constexpr double descent_em = 0.3;

std::size_t characters(const std::string& text) {
    std::size_t n = 0;
    for (const char c : text) n += (static_cast<unsigned char>(c) & 0xC0) != 0x80 ? 1 : 0;
    return n;
}

struct Box {
    double left, top, right, bottom;
    std::string text;
};

bool overlap(const Box& a, const Box& b) {
    return a.left < b.right && b.left < a.right && a.top < b.bottom && b.top < a.bottom;
}

std::string dump(const Box& box) {
    return fmt::format("'{}' at x {:.1f}..{:.1f}, y {:.1f}..{:.1f}", box.text, box.left, box.right, box.top,
                       box.bottom);
}

// What an ancestor passes on to the text inside it.
struct TextStyle {
    double dx{0.0};
    double dy{0.0};  // translate() of enclosing groups
    double size{16.0};
    bool bold{false};
};

TextStyle inherit(TextStyle style, const pugi::xml_node& node) {
    if (const auto size = node.attribute("font-size")) style.size = size.as_double();
    if (const auto weight = node.attribute("font-weight")) style.bold = std::string(weight.value()) == "bold";
    std::smatch match;
    const std::string transform = node.attribute("transform").value();
    if (std::regex_search(transform, match, std::regex(R"(translate\(([-\d.]+)[ ,]+([-\d.]+)\))"))) {
        style.dx += std::stod(match[1]);
        style.dy += std::stod(match[2]);
    }
    return style;
}

// The box of one line of a <text> (anchored at x, y), rotated with the element when it is.
Box line_box(const pugi::xml_node& text, const TextStyle& style, double x, double y, const std::string& line) {
    const double width =
        static_cast<double>(characters(line)) * style.size * (style.bold ? em_per_bold_character : em_per_character);
    const std::string anchor = text.attribute("text-anchor").value();
    const double left = anchor == "middle" ? x - width / 2.0 : anchor == "end" ? x - width : x;
    Box box{left, y - ascent_em * style.size, left + width, y + descent_em * style.size, line};
    std::smatch match;
    const std::string transform = text.attribute("transform").value();
    if (std::regex_search(transform, match, std::regex(R"(rotate\(-90 ([-\d.]+) ([-\d.]+)\))"))) {
        // a quarter turn clockwise about (cx, cy): a point at (cx + u, cy + v) goes to (cx + v, cy - u)
        const double cx = std::stod(match[1]);
        const double cy = std::stod(match[2]);
        box = {cx + (box.top - cy), cy - (box.right - cx), cx + (box.bottom - cy), cy - (box.left - cx), line};
    }
    box.left += style.dx;
    box.right += style.dx;
    box.top += style.dy;
    box.bottom += style.dy;
    return box;
}

void collect_boxes(const pugi::xml_node& node, TextStyle style, std::vector<Box>& boxes) {
    style = inherit(style, node);
    if (std::string(node.name()) != "text") {
        for (const auto& child : node.children("g")) collect_boxes(child, style, boxes);
        for (const auto& child : node.children("text")) collect_boxes(child, style, boxes);
        return;
    }
    bool lines = false;
    for (const auto& span : node.children("tspan")) {
        lines = true;
        boxes.push_back(
            line_box(node, style, span.attribute("x").as_double(), span.attribute("y").as_double(), text_of(span)));
    }
    if (!lines)
        boxes.push_back(
            line_box(node, style, node.attribute("x").as_double(), node.attribute("y").as_double(), text_of(node)));
}

/// Every text of the SVG lies inside its viewBox, and no two texts overlap.
void expect_text_inside_and_apart(const std::string& svg) {
    pugi::xml_document document;
    ASSERT_TRUE(document.load_string(svg.c_str()));
    const auto root = document.child("svg");
    double x0 = 0, y0 = 0, width = 0, height = 0;
    ASSERT_EQ(std::sscanf(root.attribute("viewBox").value(), "%lf %lf %lf %lf", &x0, &y0, &width, &height), 4);
    std::vector<Box> boxes;
    collect_boxes(root, TextStyle{}, boxes);
    const std::string id = root.attribute("id").value();
    ASSERT_FALSE(boxes.empty()) << id;
    for (const auto& box : boxes) {
        EXPECT_GE(box.left, x0) << id << ": " << dump(box);
        EXPECT_GE(box.top, y0) << id << ": " << dump(box);
        EXPECT_LE(box.right, x0 + width) << id << ": " << dump(box) << " in a viewBox " << width << " wide";
        EXPECT_LE(box.bottom, y0 + height) << id << ": " << dump(box) << " in a viewBox " << height << " high";
    }
    for (std::size_t i = 0; i < boxes.size(); ++i)
        for (std::size_t j = i + 1; j < boxes.size(); ++j)
            EXPECT_FALSE(overlap(boxes[i], boxes[j])) << id << ": " << dump(boxes[i]) << " overlaps " << dump(boxes[j]);
}

// The values at the bottom and top of a plot's frame, read from its y tick labels (right-aligned left of the frame)
// and their grid lines.
struct YAxis {
    double low;   // the value at the frame's bottom
    double high;  // at its top
};

YAxis y_axis_of(const std::string& svg) {
    pugi::xml_document document;
    EXPECT_TRUE(document.load_string(svg.c_str()));
    const auto frame = document.select_node("//rect[@class='frame']").node();
    const double top = frame.attribute("y").as_double();
    const double bottom = top + frame.attribute("height").as_double();
    // the horizontal grid lines, in the order of the y tick labels
    std::vector<double> grid;
    for (const auto& node : document.select_nodes("//g[@class='grid']/line"))
        if (node.node().attribute("y1").as_double() == node.node().attribute("y2").as_double())
            grid.push_back(node.node().attribute("y1").as_double());
    std::vector<std::pair<double, double>> ticks;  // value, pixel
    for (const auto& node : document.select_nodes("//g[@class='ticks']/text[@text-anchor='end']"))
        if (ticks.size() < grid.size()) ticks.emplace_back(std::stod(text_of(node.node())), grid[ticks.size()]);
    EXPECT_GE(ticks.size(), 2u) << svg.substr(0, 200);
    if (ticks.size() < 2) return {0.0, 0.0};
    const auto& [v0, p0] = ticks.front();
    const auto& [v1, p1] = ticks.back();
    const auto value_at = [&](double pixel) { return v0 + (pixel - p0) * (v1 - v0) / (p1 - p0); };
    return {value_at(bottom), value_at(top)};
}

std::size_t count_of(const std::string& text, const std::string& what) {
    std::size_t n = 0;
    for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
    return n;
}

TEST(ReportSvg, PlotIsWellFormedXmlWithTitleAndAxisLabels) {
    report::Plot plot;
    plot.id = "demo";
    plot.title = "Friction <measured> & \"fitted\"";
    plot.x_label = "speed |v| [m/s]";
    plot.y_label = "friction force [N]";
    report::Series series;
    series.name = "forward";
    series.x = {0.001, 0.01, 0.1, std::nan("")};
    series.y = {900.0, 760.0, 748.0, 700.0};
    series.band = {5.0, 5.0, 5.0, 5.0};
    series.style = report::Series::Style::line_and_points;
    series.tooltips = {"a<b", "c&d", "e", "f"};
    plot.series.push_back(series);
    plot.horizontal.push_back({"F_C", 742.8, "#555555", true});
    plot.vertical.push_back({"v_s", 0.005, "#d62728"});
    plot.highlights.push_back({0.01, 760.0, "alarm"});
    for (const bool log_x : {false, true}) {
        plot.log_x = log_x;
        const auto text = parse_svg(report::render_svg(plot));
        EXPECT_EQ(text.title, plot.title);
        EXPECT_EQ(text.heading, plot.title);
        EXPECT_EQ(text.x_label, plot.x_label);
        EXPECT_EQ(text.y_label, plot.y_label);
    }
    // No data at all still gives a valid, labelled plot.
    report::Plot empty;
    empty.id = "empty";
    empty.title = "nothing";
    empty.x_label = "time [s]";
    empty.y_label = "mass [kg]";
    const auto svg = report::render_svg(empty);
    EXPECT_EQ(parse_svg(svg).y_label, "mass [kg]");
    EXPECT_NE(svg.find("no data"), std::string::npos);
}

TEST(ReportSvg, ParameterLabelsCarryTheirUnits) {
    EXPECT_EQ(report::parameter_label("coulomb_N").name, "Coulomb friction F_C");
    EXPECT_EQ(report::parameter_label("coulomb_N").unit, "N");
    EXPECT_EQ(report::parameter_label("coulomb_reverse_N").name, "Coulomb friction F_C− (reverse)");
    EXPECT_EQ(report::parameter_label("viscous_forward_Ns_per_m").unit, "N·s/m");
    EXPECT_EQ(report::parameter_label("viscous_Nms_per_rad").unit, "N·m·s/rad");
    EXPECT_EQ(report::parameter_label("inertia_kgm2").unit, "kg·m²");
    EXPECT_EQ(report::parameter_label("mass_kg").name, "Mass M");
    EXPECT_EQ(report::parameter_label("stribeck_velocity_m_per_s").unit, "m/s");
    EXPECT_EQ(report::parameter_label("stribeck_velocity_rad_per_s").name, "Stribeck velocity v_s");
    EXPECT_EQ(report::parameter_label("offset_Nm").unit, "N·m");
}

// Titles longer than the image, labels longer than the frame, many legend entries, tick labels with many digits or
// exponents, a marker label at the right edge, a run axis of 10,000 runs: every text stays inside and apart.
TEST(ReportSvg, TextStaysInsideTheImageAndApart) {
    std::vector<report::Plot> plots;
    report::Plot base;
    base.title =
        "Friction against speed — machine 'DMU-50 #3 with a long name' axis 'X', latest run #10000 "
        "(2026-11-23T09:30:21.250Z)";
    base.x_label = "time since the start of the recording of this very long trace, in seconds of machine time [s]";
    base.y_label = "modelling error e_m = x_machine − x_model of the identified axis simulated in closed loop [mm]";
    report::Series series;
    for (int i = 0; i <= 100; ++i) {
        series.x.push_back(0.01 * i);
        series.y.push_back(std::sin(0.3 * i));
    }
    for (int k = 0; k < 7; ++k) {
        series.name = fmt::format("series number {} with a legend entry of some length", k);
        base.series.push_back(series);
    }
    base.vertical.push_back({"transient ends (estimates within 2 %)", 0.995, "#d62728"});
    const auto add = [&](const std::string& id, const std::function<void(report::Plot&)>& change) {
        report::Plot plot = base;
        plot.id = id;
        change(plot);
        plots.push_back(std::move(plot));
    };
    add("long-text", [](report::Plot&) {});
    add("many-digits", [](report::Plot& plot) {
        for (auto& s : plot.series)
            for (std::size_t i = 0; i < s.y.size(); ++i) s.y[i] = 95.089972285 + 1e-7 * std::sin(0.3 * i);
    });
    add("huge", [](report::Plot& plot) {
        for (auto& s : plot.series)
            for (auto& y : s.y) y *= -3e294;
    });
    add("log-nine-decades", [](report::Plot& plot) {
        plot.log_x = true;
        for (auto& s : plot.series)
            for (std::size_t i = 0; i < s.x.size(); ++i) s.x[i] = std::pow(10.0, -6.0 + 0.09 * i);
        plot.vertical.clear();
    });
    add("ten-thousand-runs", [](report::Plot& plot) {
        plot.integer_x = true;
        for (auto& s : plot.series)
            for (std::size_t i = 0; i < s.x.size(); ++i) s.x[i] = 1.0 + 99.99 * i;
        plot.vertical.clear();
    });
    add("empty", [](report::Plot& plot) {
        plot.series.clear();
        plot.vertical.clear();
    });
    for (const auto& plot : plots) {
        const auto svg = report::render_svg(plot);
        const auto text = parse_svg(svg);
        EXPECT_EQ(text.heading, plot.title) << plot.id;  // wrapped, but the text as given
        EXPECT_EQ(text.x_label, plot.x_label) << plot.id;
        EXPECT_EQ(text.y_label, plot.y_label) << plot.id;
        expect_text_inside_and_apart(svg);
    }
}

// The issue's case: a viscous friction that settles at 4.7 after a start-up transient of -500..2000. The y axis shows
// the settled part; the transient is clipped at the frame, with a marker where it leaves, and no coordinate of it
// reaches the SVG.
TEST(ReportSvg, TransientBeyondTheSettledPartIsClippedAndMarked) {
    report::Plot plot;
    plot.id = "rls-viscous";
    plot.title = "RLS estimate of Viscous friction B over time";
    plot.x_label = "time [s]";
    plot.y_label = "Viscous friction B [N·s/m]";
    plot.off_scale_label = "start-up transient beyond the axis";
    report::Series series;
    series.name = "RLS estimate";
    for (int i = 0; i <= 1000; ++i) {
        const double t = 0.05 * i;
        series.x.push_back(t);
        series.y.push_back(t < 0.5   ? 2000.0
                           : t < 1.0 ? -500.0
                                     : 4.7 + 10.0 * std::exp(-(t - 1.0)) + 0.01 * std::sin(t));
    }
    plot.series.push_back(series);
    plot.horizontal.push_back({"batch least-squares value", 4.7, "#2ca02c", true});
    plot.y_range_from_x = 10.0;  // where the transient ends
    const auto svg = report::render_svg(plot);
    const auto axis = y_axis_of(svg);
    double low = 4.7, high = 4.7;  // the settled part and the batch value
    for (std::size_t i = 0; i < series.x.size(); ++i)
        if (series.x[i] >= 10.0) {
            low = std::min(low, series.y[i]);
            high = std::max(high, series.y[i]);
        }
    EXPECT_LE(axis.low, low);
    EXPECT_GE(axis.high, high);
    EXPECT_LE(axis.high - axis.low, 1.25 * (high - low)) << "the axis is set by the settled part";
    // Markers where the transient leaves: above (2000, then the decay from 14.7) and below (-500).
    pugi::xml_document document;
    ASSERT_TRUE(document.load_string(svg.c_str()));
    std::vector<std::string> markers;
    for (const auto& node : document.select_nodes("//g[@class='off-scale']/path"))
        markers.push_back(text_of(node.node().child("title")));
    ASSERT_GE(markers.size(), 2u) << svg;
    EXPECT_TRUE(std::any_of(markers.begin(), markers.end(), [](const auto& m) { return m.find("2000") != m.npos; }));
    EXPECT_TRUE(std::any_of(markers.begin(), markers.end(), [](const auto& m) { return m.find("-500") != m.npos; }));
    EXPECT_NE(svg.find("start-up transient beyond the axis"), std::string::npos);
    // Every drawn vertex inside the frame.
    const auto frame = document.select_node("//rect[@class='frame']").node();
    const double top = frame.attribute("y").as_double();
    const double bottom = top + frame.attribute("height").as_double();
    for (const auto& node : document.select_nodes("//polyline")) {
        std::istringstream points(node.node().attribute("points").value());
        double x = 0, y = 0;
        char comma = 0;
        while (points >> x >> comma >> y) {
            EXPECT_GE(y, top - 0.01);
            EXPECT_LE(y, bottom + 0.01);
        }
    }
    expect_text_inside_and_apart(svg);
}

// The issue's case: a friction curve binned at three speeds two decades apart on a log axis. Drawn only through the
// bins it showed about 2.5 N·m between them where the model gives 0.66; the model curve now follows eq. (3) over the
// whole measured range.
TEST(ReportSvg, FittedFrictionModelIsDrawnDenselyOverTheSpeedRange) {
    const double viscous = 0.002, coulomb = 0.6, breakaway = 2.6, stribeck = 0.01;  // [N·m·s/rad, N·m, N·m, rad/s]
    const auto law = [&](double w) { return viscous * w + coulomb + (breakaway - coulomb) * std::exp(-w / stribeck); };
    nlohmann::json result = {{"model", "symmetric"}, {"rotary", true}, {"status", "ok"}};
    result["parameters"] = {{"inertia_kgm2", {{"value", 0.05}, {"stderr", 1e-4}}},
                            {"viscous_Nms_per_rad", {{"value", viscous}, {"stderr", 1e-4}}},
                            {"coulomb_Nm", {{"value", coulomb}, {"stderr", 1e-3}}},
                            {"breakaway_Nm", {{"value", breakaway}, {"stderr", 1e-2}}},
                            {"stribeck_velocity_rad_per_s", {{"value", stribeck}, {"stderr", 1e-4}}}};
    const std::vector<double> speeds{0.001, 0.1, 10.0};
    for (const char* direction : {"forward", "reverse"}) {
        std::vector<double> fitted;
        for (const double w : speeds) fitted.push_back(law(w));
        result["friction_curve"][direction] = {
            {"velocity_rad_per_s", speeds}, {"torque_Nm", {2.4, 0.61, 0.62}}, {"fitted_torque_Nm", fitted}};
    }
    const auto plots = report::result_plots(result, "sparse.json");
    ASSERT_EQ(plots.size(), 1u);
    const auto& plot = plots[0];
    EXPECT_TRUE(plot.log_x);
    const auto model = std::find_if(plot.series.begin(), plot.series.end(),
                                    [](const auto& s) { return s.name.find("fitted model") != std::string::npos; });
    ASSERT_NE(model, plot.series.end());
    ASSERT_GE(model->x.size(), 100u);
    EXPECT_LE(model->x.front(), speeds.front() * (1.0 + 1e-9));
    EXPECT_GE(model->x.back(), speeds.back() * (1.0 - 1e-9));
    for (std::size_t i = 0; i < model->x.size(); ++i)
        EXPECT_NEAR(model->y[i], law(model->x[i]), 1e-12 * law(model->x[i])) << model->x[i];
    // Between two points the plot draws a straight line in log speed: within 0.5 % of the model everywhere.
    for (std::size_t i = 1; i < model->x.size(); ++i) {
        const double middle = std::sqrt(model->x[i - 1] * model->x[i]);
        EXPECT_NEAR((model->y[i - 1] + model->y[i]) / 2.0, law(middle), 0.005 * law(middle)) << middle;
    }
    // At 0.03 rad/s, between the bins, the curve reads the model's 0.70 N·m.
    const auto after = std::upper_bound(model->x.begin(), model->x.end(), 0.03) - model->x.begin();
    ASSERT_GT(after, 0);
    const double t = std::log(0.03 / model->x[after - 1]) / std::log(model->x[after] / model->x[after - 1]);
    EXPECT_NEAR(model->y[after - 1] + t * (model->y[after] - model->y[after - 1]), law(0.03), 0.005 * law(0.03));
    // The SVG's polyline holds every point.
    const auto svg = report::render_svg(plot);
    std::size_t longest = 0;
    pugi::xml_document document;
    ASSERT_TRUE(document.load_string(svg.c_str()));
    for (const auto& node : document.select_nodes("//polyline"))
        longest = std::max(longest, count_of(node.node().attribute("points").value(), ","));
    EXPECT_EQ(longest, model->x.size());

    // An asymmetric model: one curve per direction, each from its own parameters.
    struct Branch {
        const char* direction;
        double viscous, coulomb, breakaway, stribeck;
    };
    const std::array<Branch, 2> branches{{{"forward", 0.002, 0.5, 2.6, 0.01}, {"reverse", 0.003, 0.7, 2.2, 0.02}}};
    result["model"] = "asymmetric";
    result["parameters"] = {{"inertia_kgm2", {{"value", 0.05}, {"stderr", 1e-4}}}};
    for (const auto& b : branches) {
        const std::string d = b.direction;
        result["parameters"]["viscous_" + d + "_Nms_per_rad"] = {{"value", b.viscous}, {"stderr", 1e-4}};
        result["parameters"]["coulomb_" + d + "_Nm"] = {{"value", b.coulomb}, {"stderr", 1e-3}};
        result["parameters"]["breakaway_" + d + "_Nm"] = {{"value", b.breakaway}, {"stderr", 1e-2}};
        result["parameters"]["stribeck_velocity_" + d + "_rad_per_s"] = {{"value", b.stribeck}, {"stderr", 1e-4}};
    }
    const auto asymmetric = report::result_plots(result, "asymmetric.json");
    ASSERT_EQ(asymmetric.size(), 1u);
    for (const auto& b : branches) {
        const std::string name = std::string(b.direction) + ": fitted model";
        const auto curve = std::find_if(asymmetric[0].series.begin(), asymmetric[0].series.end(),
                                        [&](const auto& s) { return s.name == name; });
        ASSERT_NE(curve, asymmetric[0].series.end()) << name;
        for (std::size_t i = 0; i < curve->x.size(); ++i) {
            const double w = curve->x[i];
            const double own = b.viscous * w + b.coulomb + (b.breakaway - b.coulomb) * std::exp(-w / b.stribeck);
            EXPECT_NEAR(curve->y[i], own, 1e-12 * own) << name << " at " << w;
        }
    }
}

TEST(ReportSvg, RunAxisTicksAreWholeNumbers) {
    for (const int runs : {1, 2, 3, 7, 14, 120, 10000}) {
        report::Plot plot;
        plot.id = "runs";
        plot.title = "Coulomb friction F_C";
        plot.x_label = "run (recording order)";
        plot.y_label = "Coulomb friction F_C [N]";
        plot.integer_x = true;
        report::Series series;
        series.style = report::Series::Style::line_and_points;
        for (int run = 1; run <= runs; ++run) {
            series.x.push_back(run);
            series.y.push_back(742.0 + std::sin(run));
        }
        plot.series.push_back(series);
        const auto svg = report::render_svg(plot);
        pugi::xml_document document;
        ASSERT_TRUE(document.load_string(svg.c_str()));
        std::vector<long> ticks;
        for (const auto& node : document.select_nodes("//g[@class='ticks']/text[@text-anchor='middle']")) {
            const std::string label = text_of(node.node());
            ASSERT_TRUE(std::regex_match(label, std::regex(R"(\d+)"))) << runs << " runs: tick '" << label << "'";
            ticks.push_back(std::stol(label));
        }
        ASSERT_FALSE(ticks.empty()) << runs;
        EXPECT_GE(ticks.front(), 1) << runs;
        EXPECT_LE(ticks.back(), runs) << runs;
        if (runs <= 7) {
            EXPECT_EQ(ticks.size(), static_cast<std::size_t>(runs)) << "every run has its tick";
        }
        // no point on the frame: the axis reaches beyond the first and last run
        const auto frame = document.select_node("//rect[@class='frame']").node();
        const double left = frame.attribute("x").as_double();
        const double right = left + frame.attribute("width").as_double();
        for (const auto& node : document.select_nodes("//g[@class='series-points']/circle")) {
            EXPECT_GT(node.node().attribute("cx").as_double(), left + 3.0);
            EXPECT_LT(node.node().attribute("cx").as_double(), right - 3.0);
        }
        expect_text_inside_and_apart(svg);
    }
}

TEST(ReportSvg, WrongDocumentIsAnInputError) {
    const nlohmann::json gains = {{"gains", nlohmann::json::object()}};
    EXPECT_THROW(report::result_plots(gains, "gains.json"), feedid::InputError);
    EXPECT_THROW(report::result_report_html(nlohmann::json::array(), "x.json"), feedid::InputError);
}

TEST(ReportSvg, RotarySimulationIsPlottedInMilliradians) {
    auto simulation = nlohmann::json::parse(R"({"relative_error_pct": {"position": 0.1},
        "tracking_error_mae_m": {"model": 0.002, "machine": 0.0021}, "modelling_error_mae_m": 0.0003, "rotary": true,
        "series": {"time_s": [0, 0.001, 0.002], "tracking_error_machine_rad": [0, 0.002, -0.001],
                   "tracking_error_model_rad": [0, 0.0019, -0.001], "modelling_error_rad": [0, 0.0001, 0]}})");
    const auto plots = report::simulation_plots(simulation, "rotary.json");
    ASSERT_EQ(plots.size(), 2u);
    EXPECT_EQ(plots[0].y_label, "tracking error φ_ref − φ [mrad]");
    EXPECT_EQ(plots[1].y_label, "modelling error e_m = φ − φ_sim [mrad]");
    ASSERT_EQ(plots[0].series.size(), 2u);
    EXPECT_DOUBLE_EQ(plots[0].series[0].y[1], 2.0);  // 0.002 rad shown as 2 mrad
    const auto text = parse_svg(report::render_svg(plots[0]));
    EXPECT_EQ(text.x_label, "time [s]");
    // A rotary document must carry rad series; metre keys on a rotary axis are a malformed document.
    simulation["rotary"] = false;
    EXPECT_THROW((void)report::simulation_plots(simulation, "rotary.json"), feedid::InputError);
}

/// Headless Chromium, or "" when it is not installed.
std::string find_chromium() {
    if (const char* path = std::getenv("FEEDID_CHROMIUM"); path && fs::exists(path)) return path;
    for (const char* path : {"/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"})
        if (fs::exists(path)) return path;
    return "";
}

// Appended to a copy of the report before it is opened: for every plot, the rendered boxes (getBBox) of its title,
// axis labels and data, written into the page as JSON for --dump-dom to carry out.
constexpr const char* render_probe = R"(<script>
(function () {
  const area = (element) => { if (!element) return 0; const box = element.getBBox(); return box.width * box.height; };
  const plots = [];
  for (const svg of document.querySelectorAll('svg.plot')) {
    const text = (selector) => { const e = svg.querySelector(selector); return e ? e.textContent : ''; };
    // every line of text as drawn: its width against the characters it holds, and whether it lies inside the image
    const image = svg.getBoundingClientRect();
    const lines = [];
    for (const element of svg.querySelectorAll('text, tspan')) {
      if (element.querySelector('tspan')) continue;
      const box = element.getBoundingClientRect();
      const style = getComputedStyle(element);
      lines.push({text: element.textContent, width: element.getComputedTextLength(),
                  size: parseFloat(style.fontSize), bold: parseInt(style.fontWeight) >= 600,
                  inside: box.left >= image.left - 0.5 && box.right <= image.right + 0.5 &&
                          box.top >= image.top - 0.5 && box.bottom <= image.bottom + 0.5});
    }
    plots.push({id: svg.id, title: text('.plot-title'), x_label: text('.x-label'), y_label: text('.y-label'),
                title_area: area(svg.querySelector('.plot-title')), x_area: area(svg.querySelector('.x-label')),
                y_area: area(svg.querySelector('.y-label')), data_area: area(svg.querySelector('g.data')),
                width: svg.getBoundingClientRect().width, lines: lines});
  }
  const out = document.createElement('pre');
  out.id = 'render-check';
  out.textContent = JSON.stringify(plots);
  document.body.appendChild(out);
})();
</script>
)";

std::string unescape_html(std::string text) {
    const std::pair<const char*, const char*> entities[] = {{"&lt;", "<"},  {"&gt;", ">"},   {"&quot;", "\""},
                                                            {"&#39;", "'"}, {"&nbsp;", " "}, {"&amp;", "&"}};
    for (const auto& [entity, character] : entities)
        for (auto at = text.find(entity); at != std::string::npos; at = text.find(entity, at + 1))
            text.replace(at, std::string_view(entity).size(), character);
    return text;
}

/// Opens the page in headless Chromium; returns the probe's findings per plot.
nlohmann::json render_in_chromium(const std::string& chromium, const fs::path& page, const fs::path& folder) {
    auto html = read_text(page);
    const auto body_end = html.rfind("</body>");
    EXPECT_NE(body_end, std::string::npos);
    html.insert(body_end, render_probe);
    const auto probe_page = folder / (page.stem().string() + "-probe.html");
    write_text(probe_page, html);
    const auto r =
        run_shell(fmt::format("timeout 120 '{}' --headless --no-sandbox --disable-gpu --disable-dev-shm-usage "
                              "--no-first-run --user-data-dir={} --virtual-time-budget=5000 --dump-dom "
                              "'file://{}'",
                              chromium, quoted(folder / "chromium-profile"), probe_page.string()),
                  folder);
    EXPECT_EQ(r.exit_code, 0) << r.err.substr(0, 2000);
    const std::string open = "<pre id=\"render-check\">";
    const auto start = r.out.find(open);
    if (start == std::string::npos) {
        ADD_FAILURE() << "the probe's result is not in the rendered DOM:\n" << r.out.substr(0, 1000);
        return nlohmann::json::array();
    }
    const auto end = r.out.find("</pre>", start);
    // The rendered DOM holds every SVG of the page.
    std::size_t rendered_svgs = 0;
    for (auto at = r.out.find("<svg"); at != std::string::npos; at = r.out.find("<svg", at + 1)) ++rendered_svgs;
    EXPECT_EQ(rendered_svgs, svgs_of(read_text(page)).size());
    return nlohmann::json::parse(unescape_html(r.out.substr(start + open.size(), end - start - open.size())));
}

/// Every plot rendered: its title and labels as written and boxes of non-zero size.
void expect_rendered(const nlohmann::json& plots, const std::vector<std::string>& svgs) {
    ASSERT_EQ(plots.size(), svgs.size());
    for (std::size_t i = 0; i < plots.size(); ++i) {
        const auto& plot = plots[i];
        const auto written = parse_svg(svgs[i]);
        EXPECT_EQ(plot["title"], written.heading) << plot.dump();
        EXPECT_EQ(plot["x_label"], written.x_label) << plot.dump();
        EXPECT_EQ(plot["y_label"], written.y_label) << plot.dump();
        EXPECT_GT(plot["title_area"].get<double>(), 0.0) << plot.dump();
        EXPECT_GT(plot["x_area"].get<double>(), 0.0) << plot.dump();
        EXPECT_GT(plot["y_area"].get<double>(), 0.0) << plot.dump();
        EXPECT_GT(plot["data_area"].get<double>(), 0.0) << plot.dump();
        EXPECT_GT(plot["width"].get<double>(), 100.0) << plot.dump();
        // Chromium draws every line of text inside the image, no wider than the tests' estimate.
        for (const auto& line : plot["lines"]) {
            const auto text = line["text"].get<std::string>();
            EXPECT_TRUE(line["inside"].get<bool>()) << plot["id"] << ": '" << text << "'";
            const double estimate = static_cast<double>(characters(text)) * line["size"].get<double>() *
                                    (line["bold"].get<bool>() ? em_per_bold_character : em_per_character);
            EXPECT_LE(line["width"].get<double>(), estimate + 0.5) << plot["id"] << ": '" << text << "'";
        }
    }
}

/// Everything the page needs is inside it: no script, stylesheet, image or font from elsewhere.
void expect_self_contained(const std::string& html) {
    EXPECT_EQ(html.find("<script"), std::string::npos);
    EXPECT_EQ(html.find("<link"), std::string::npos);
    EXPECT_EQ(html.find("src="), std::string::npos);
    EXPECT_EQ(html.find("@import"), std::string::npos);
    std::size_t references = 0;
    for (auto at = html.find("http"); at != std::string::npos; at = html.find("http", at + 1)) ++references;
    EXPECT_EQ(references, svgs_of(html).size()) << "only the SVG namespace may name a URL";
}

class ReportEndToEnd : public ::testing::Test {
protected:
    void SetUp() override {
        folder_ = temp_dir();
        // A real identify result of a short synthetic run with a few slow passes (for the friction curve).
        const auto drive = folder_ / "drive.json";
        write_text(drive, R"({"seed": 3, "test": {"feedrates_mm_per_min": [1500, 3000, 4500, 6000], "stroke_mm": 20,
                               "slow_feedrates_mm_per_min": [30, 100, 300]}})");
        const auto trace = folder_ / "x.csv";
        result_ = folder_ / "result.json";
        const auto synth =
            run_shell(fmt::format("{} synth --drive {} --out {}", cli(), quoted(drive), quoted(trace)), folder_);
        ASSERT_EQ(synth.exit_code, 0) << synth.err;
        const auto identify = run_shell(fmt::format("{} identify {} --force-constant force_constant_N_per_A --json {}",
                                                    cli(), quoted(trace), quoted(result_)),
                                        folder_);
        ASSERT_EQ(identify.exit_code, 0) << identify.err;

        // A history of 14 runs of that axis whose Coulomb friction rises from run 11 on (so that alarms show), made
        // from the real result with the values moved.
        const auto document = nlohmann::json::parse(read_text(result_));
        database_ = folder_ / "shop.db";
        auto store = history::open_sqlite_store(database_);
        for (int i = 1; i <= 14; ++i) {
            auto run = history::run_from_result(document, result_.string());
            run.machine = "M1";
            run.axis = "X";
            run.recorded_at = fmt::format("2026-03-{:02}T06:00:00Z", i);
            run.trace_sha256 = fmt::format("{:064}", i);
            for (auto& [key, estimate] : run.parameters)
                if (estimate.value && estimate.standard_error)
                    *estimate.value += *estimate.standard_error * std::sin(1.7 * i);  // scatter of about one error
            auto& coulomb = run.parameters.at("coulomb_N");
            if (i > 10) *coulomb.value *= 1.0 + 0.02 * (i - 10);
            store->add_run(run);
        }
    }

    fs::path folder_;
    fs::path result_;
    fs::path database_;
};

TEST_F(ReportEndToEnd, HistoryReportHasTrendsAlarmsAndTheLatestFrictionCurve) {
    const auto page = folder_ / "health.html";
    const auto r = run_shell(fmt::format("{} report {} -o {}", cli(), quoted(database_), quoted(page)), folder_);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto html = read_text(page);
    expect_self_contained(html);
    const auto svgs = svgs_of(html);
    std::map<std::string, SvgText> by_heading;
    for (const auto& svg : svgs) {
        const auto text = parse_svg(svg);
        EXPECT_EQ(text.title, text.heading);
        EXPECT_TRUE(has_unit(text.x_label) || text.x_label == "run (recording order)") << text.x_label;
        EXPECT_TRUE(has_unit(text.y_label)) << text.y_label;
        by_heading[text.heading] = text;
    }
    const std::string where = " — machine 'M1' axis 'X'";
    ASSERT_TRUE(by_heading.count("Coulomb friction F_C" + where)) << html.substr(0, 500);
    EXPECT_EQ(by_heading["Coulomb friction F_C" + where].y_label, "Coulomb friction F_C [N]");
    EXPECT_EQ(by_heading["Coulomb friction F_C" + where].x_label, "run (recording order)");
    ASSERT_TRUE(by_heading.count("CUSUM of Coulomb friction F_C" + where));
    EXPECT_EQ(by_heading["CUSUM of Coulomb friction F_C" + where].y_label, "CUSUM [combined standard errors]");
    ASSERT_TRUE(by_heading.count("Mass M" + where));
    EXPECT_EQ(by_heading["Mass M" + where].y_label, "Mass M [kg]");
    const auto friction = std::find_if(by_heading.begin(), by_heading.end(), [](const auto& entry) {
        return entry.first.rfind("Friction against speed — machine 'M1' axis 'X', latest run #14", 0) == 0;
    });
    ASSERT_NE(friction, by_heading.end());
    EXPECT_EQ(friction->second.x_label, "speed |v| [m/s]");
    EXPECT_EQ(friction->second.y_label, "friction force [N]");
    // Runs are counted in whole numbers; nothing is clipped or overlaps.
    for (const auto& svg : svgs) {
        expect_text_inside_and_apart(svg);
        if (svg.find("id=\"trend-") == std::string::npos && svg.find("id=\"cusum-") == std::string::npos) continue;
        pugi::xml_document document;
        ASSERT_TRUE(document.load_string(svg.c_str()));
        for (const auto& node : document.select_nodes("//g[@class='ticks']/text[@text-anchor='middle']"))
            EXPECT_TRUE(std::regex_match(text_of(node.node()), std::regex(R"(\d+)"))) << text_of(node.node());
    }
    // The alarm is in the page, and marked in the Coulomb plots only.
    EXPECT_NE(html.find("axis &apos;X&apos; parameter coulomb_N at run #11"), std::string::npos);
    for (const auto& svg : svgs) {
        const bool coulomb = svg.find("id=\"trend-m1-x-coulomb-n\"") != std::string::npos ||
                             svg.find("id=\"cusum-m1-x-coulomb-n\"") != std::string::npos;
        EXPECT_EQ(svg.find("class=\"alarm\"") != std::string::npos, coulomb) << svg.substr(0, 120);
    }

    const auto chromium = find_chromium();
    if (chromium.empty())
        GTEST_SKIP() << "headless Chromium not found (install Debian's chromium package); the "
                        "browser rendering check is skipped";
    expect_rendered(render_in_chromium(chromium, page, folder_), svgs);
}

// A long history: the plots keep at most 400 points per series, among them every spike and the run where the alarm
// fired; the table keeps the baseline, the alarm runs and the latest 100 runs, and says how many it leaves out.
TEST_F(ReportEndToEnd, ALongHistoryIsThinnedWithoutLosingSpikesOrAlarms) {
    const auto document = nlohmann::json::parse(read_text(result_));
    const auto database = folder_ / "long.db";
    {
        auto store = history::open_sqlite_store(database);
        const auto recorded = history::run_from_result(document, result_.string());
        for (int i = 1; i <= 2000; ++i) {
            auto run = recorded;
            run.machine = "M1";
            run.axis = "X";
            run.recorded_at = fmt::format("{:04}-01-01T06:00:00Z", 2000 + i);  // one a year: a long history
            run.trace_sha256 = fmt::format("{:064}", i);
            for (auto& [key, estimate] : run.parameters)
                if (estimate.value && estimate.standard_error)
                    *estimate.value += 0.3 * *estimate.standard_error * std::sin(1.7 * i);
            if (i == 777) *run.parameters.at("mass_kg").value *= 1.5;  // one spike
            if (i > 1900) *run.parameters.at("coulomb_N").value *= 1.0 + 0.01 * (i - 1900);
            store->add_run(run);
        }
    }
    const auto check = run_shell(fmt::format("{} history {} --check", cli(), quoted(database)), folder_);
    EXPECT_EQ(check.exit_code, 1) << check.out << check.err;
    const std::regex fired(R"(parameter coulomb_N at run #(\d+))");
    std::smatch match;
    ASSERT_TRUE(std::regex_search(check.out, match, fired)) << check.out;
    const std::string alarm_run = match[1];

    const auto page = folder_ / "long.html";
    const auto r = run_shell(fmt::format("{} report {} -o {}", cli(), quoted(database), quoted(page)), folder_);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto html = read_text(page);
    EXPECT_LT(html.size(), 1'500'000u);
    const auto count = [](const std::string& text, const std::string& what) {
        std::size_t n = 0;
        for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
        return n;
    };
    for (const auto& svg : svgs_of(html)) {
        parse_svg(svg);
        if (svg.find("id=\"trend-m1-x-") == std::string::npos) continue;
        const std::size_t points = count(svg, "<title>run #");  // the markers, each with its run in a tooltip
        EXPECT_LE(points, 400u) << svg.substr(0, 120);
        EXPECT_GE(points, 200u) << svg.substr(0, 120);
        if (svg.find("id=\"trend-m1-x-mass-kg\"") != std::string::npos) {
            EXPECT_NE(svg.find("run #777 recorded"), std::string::npos) << "the spike was thinned away";
        }
        if (svg.find("id=\"trend-m1-x-coulomb-n\"") != std::string::npos) {
            EXPECT_NE(svg.find("drift alarm at run #" + alarm_run + " "), std::string::npos)
                << "the run where the alarm fired was thinned away";
        }
    }
    // the table: 8 baseline runs, the runs where an alarm fired, the latest 100, and a row for each gap
    const std::size_t rows = count(html, "<tr><td>#");
    EXPECT_GE(rows, 108u);
    EXPECT_LE(rows, 120u);
    EXPECT_NE(html.find("run(s) not listed here (feedid history DB --csv - lists every run)"), std::string::npos);
    EXPECT_NE(html.find("<tr><td>#" + alarm_run + "</td>"), std::string::npos);
}

TEST_F(ReportEndToEnd, ResultReportHasRlsHistoriesAndTheFrictionCurve) {
    const auto page = folder_ / "result.html";
    const auto r = run_shell(fmt::format("{} report {} -o {}", cli(), quoted(result_), quoted(page)), folder_);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto html = read_text(page);
    expect_self_contained(html);
    const auto svgs = svgs_of(html);
    std::set<std::string> headings;
    for (const auto& svg : svgs) {
        const auto text = parse_svg(svg);
        EXPECT_TRUE(has_unit(text.x_label)) << text.x_label;
        EXPECT_TRUE(has_unit(text.y_label)) << text.y_label;
        headings.insert(text.heading);
    }
    EXPECT_TRUE(headings.count("RLS estimate of Mass M over time"));
    EXPECT_TRUE(headings.count("RLS estimate of Coulomb friction F_C over time"));
    EXPECT_TRUE(headings.count("Friction against speed, measured and fitted"));
    EXPECT_NE(html.find("transient ends"), std::string::npos);
    for (const auto& svg : svgs) expect_text_inside_and_apart(svg);

    const auto chromium = find_chromium();
    if (chromium.empty())
        GTEST_SKIP() << "headless Chromium not found (install Debian's chromium package); the "
                        "browser rendering check is skipped";
    expect_rendered(render_in_chromium(chromium, page, folder_), svgs);
}

// On a real result: every RLS plot's y axis is set by the settled part (after the transient) and the batch value of the
// same samples (step 1's, not the final value after the friction-curve fit), the transient is marked where it leaves;
// the friction model is drawn from the identified parameters; no text is clipped or overlaps.
TEST_F(ReportEndToEnd, ResultPlotsAreReadAtAGlance) {
    const auto document = nlohmann::json::parse(read_text(result_));
    const auto& rls = document["rls"];
    ASSERT_TRUE(rls["settled"].get<bool>()) << "the fixture's RLS settles";
    const double settled_from = rls["transient_end_s"].get<double>();
    const auto plots = report::result_plots(document, result_.string());
    std::size_t rls_plots = 0;
    std::size_t marked = 0;
    for (const auto& plot : plots) {
        const auto svg = report::render_svg(plot);
        expect_text_inside_and_apart(svg);
        if (plot.id.rfind("rls-", 0) != 0) continue;
        ++rls_plots;
        // The batch line is step 1's batch estimate of this parameter.
        std::string parameter;
        for (const auto& [k, values] : document["step1"]["batch"].items()) {
            const auto label = report::parameter_label(k);
            if (plot.y_label == label.name + " [" + label.unit + "]") parameter = k;
        }
        ASSERT_FALSE(parameter.empty()) << plot.id;
        const double batch = document["step1"]["batch"][parameter]["value"].get<double>();
        ASSERT_FALSE(plot.horizontal.empty());
        EXPECT_EQ(plot.horizontal[0].label, "batch least-squares value");
        EXPECT_DOUBLE_EQ(plot.horizontal[0].y, batch) << parameter;
        // The axis holds the settled values drawn and the lines, and not much more.
        double low = std::numeric_limits<double>::infinity(), high = -low;
        for (const auto& line : plot.horizontal) {
            low = std::min(low, line.y);
            high = std::max(high, line.y);
        }
        bool beyond = false;
        const auto& series = plot.series.at(0);
        for (std::size_t i = 0; i < series.x.size(); ++i)
            if (series.x[i] >= settled_from) {
                low = std::min(low, series.y[i]);
                high = std::max(high, series.y[i]);
            }
        const auto axis = y_axis_of(svg);
        EXPECT_LE(axis.low, low) << parameter;
        EXPECT_GE(axis.high, high) << parameter;
        EXPECT_LE(axis.high - axis.low, 1.25 * (high - low)) << parameter;
        for (const double y : series.y) beyond = beyond || y < axis.low || y > axis.high;
        EXPECT_EQ(svg.find("class=\"off-scale\"") != std::string::npos, beyond) << parameter;
        marked += beyond ? 1 : 0;
    }
    EXPECT_EQ(rls_plots, document["rls"]["history"].size() - 1);
    EXPECT_GT(marked, 0u) << "the fixture's start-up transient leaves the settled range somewhere";
    // The friction model from the parameters: F_C + (F_B - F_C) exp(-|v|/v_s) + B |v| at every drawn speed.
    const auto& p = document["parameters"];
    const auto value = [&](const char* key) { return p[key]["value"].get<double>(); };
    const auto curve =
        std::find_if(plots.begin(), plots.end(), [](const auto& plot) { return plot.id == "friction-curve"; });
    ASSERT_NE(curve, plots.end());
    const auto model = std::find_if(curve->series.begin(), curve->series.end(),
                                    [](const auto& s) { return s.name.find("fitted model") != std::string::npos; });
    ASSERT_NE(model, curve->series.end());
    for (std::size_t i = 0; i < model->x.size(); ++i) {
        const double v = model->x[i];
        const double expected =
            value("viscous_Ns_per_m") * v + value("coulomb_N") +
            (value("breakaway_N") - value("coulomb_N")) * std::exp(-v / value("stribeck_velocity_m_per_s"));
        EXPECT_NEAR(model->y[i], expected, 1e-9 * expected) << v;
    }
}

// A simulation that diverges (the result's viscous friction made -1e5 N·s/m): simulate writes status "failed" with a
// diagnostic and nulls; the report says so in a warning, shows the figures it has, and draws the machine's tracking
// error on its own scale with the diverged model clipped and marked.
TEST_F(ReportEndToEnd, FailedSimulationIsShownWithAWarning) {
    // the identified axis under a velocity loop far too stiff for its 1 ms cycle: the twin diverges (a result whose
    // forces do not fit the trace is refused before anything is simulated, so the gains are what is wrong here)
    const auto gains = folder_ / "too-stiff.json";
    write_text(gains, nlohmann::json{{"gains",
                                      {{"position_gain_per_s", {{"value", 33.3333}}},
                                       {"velocity_gain_N_s_per_m", {{"value", 1e300}}},
                                       {"velocity_integral_gain_N_per_m", {{"value", 2e6}}}}},
                                     {"structure", {{"sample_time_s", 0.001}, {"current_lag_s", 0.0003}}}}
                          .dump());
    const auto simulation = folder_ / "diverged-sim.json";
    const auto simulate =
        run_shell(fmt::format("{} simulate {} --force-constant force_constant_N_per_A --result {} --gains {} "
                              "--json {}",
                              cli(), quoted(folder_ / "x.csv"), quoted(result_), quoted(gains), quoted(simulation)),
                  folder_);
    ASSERT_TRUE(fs::exists(simulation)) << simulate.err;
    const auto written = nlohmann::json::parse(read_text(simulation));
    ASSERT_EQ(written.value("status", ""), "failed") << simulate.err;
    ASSERT_FALSE(written["diagnostics"].empty());
    const auto page = folder_ / "diverged.html";
    const auto r = run_shell(
        fmt::format("{} report {} --simulation {} -o {}", cli(), quoted(result_), quoted(simulation), quoted(page)),
        folder_);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto html = read_text(page);
    EXPECT_NE(html.find("class=\"warning\""), std::string::npos);
    EXPECT_NE(html.find("has status &quot;failed&quot;"), std::string::npos);
    EXPECT_NE(html.find(report::escape_xml(written["diagnostics"][0].get<std::string>())), std::string::npos);
    const auto svgs = svgs_of(html);
    const auto tracking = std::find_if(svgs.begin(), svgs.end(), [](const auto& svg) {
        return svg.find("id=\"fig6-tracking-error\"") != std::string::npos;
    });
    ASSERT_NE(tracking, svgs.end());
    double low = 0.0, high = 0.0;  // the machine's tracking error [mm]
    for (const auto& e : written["series"]["tracking_error_machine_m"]) {
        low = std::min(low, e.get<double>() * 1e3);
        high = std::max(high, e.get<double>() * 1e3);
    }
    const auto axis = y_axis_of(*tracking);
    EXPECT_LE(axis.low, low);
    EXPECT_GE(axis.high, high);
    EXPECT_LE(axis.high - axis.low, 1.25 * (high - low)) << "the machine's scale, not the diverged model's";
    EXPECT_NE(tracking->find("class=\"off-scale\""), std::string::npos);
    EXPECT_NE(tracking->find("model diverges"), std::string::npos);
    for (const auto& svg : svgs) expect_text_inside_and_apart(svg);
    // A null in a document that says it succeeded is still refused.
    auto lying = written;
    lying["status"] = "ok";
    write_text(folder_ / "lying.json", lying.dump());
    const auto refused = run_shell(fmt::format("{} report {} --simulation {} -o {}", cli(), quoted(result_),
                                               quoted(folder_ / "lying.json"), quoted(folder_ / "lying.html")),
                                   folder_);
    EXPECT_EQ(refused.exit_code, 2) << refused.err;
    EXPECT_EQ(count_lines(refused.err), 1) << refused.err;
}

TEST_F(ReportEndToEnd, PartialAndFailedResultsAreWarnedAbout) {
    auto document = nlohmann::json::parse(read_text(result_));
    const auto html_of = [&](const nlohmann::json& result) {
        return report::result_report_html(result, "result.json");
    };
    EXPECT_EQ(html_of(document).find("class=\"warning\""), std::string::npos) << "an ok result has no warning";
    document["status"] = "partial";
    document["parameters"]["breakaway_N"] = {{"value", nullptr}, {"stderr", nullptr}};
    document["parameters"]["stribeck_velocity_m_per_s"] = {{"value", nullptr}, {"stderr", nullptr}};
    const auto partial = html_of(document);
    EXPECT_NE(partial.find("class=\"warning\""), std::string::npos);
    EXPECT_NE(partial.find("Breakaway friction F_B, Stribeck velocity v_s could not be identified"), std::string::npos);
    document["status"] = "failed";
    EXPECT_NE(html_of(document).find("The identification failed"), std::string::npos);
}

// A production scan's report says what the scan found out: the windows, why the others were left out, and the
// information per parameter, from a real scan of a production-like trace.
TEST(ReportScan, AScanReportShowsItsWindowsAndTheInformationPerParameter) {
    const auto folder = temp_dir();
    const auto trace = folder / "pocket.csv";
    const auto document = folder / "scan.json";
    auto r =
        run_shell(fmt::format("{} synth --program {} --seed 2 --out {}", cli(),
                              quoted(fs::path(FEEDID_TEST_SOURCE_DIR) / ".." / "examples" / "programs" / "pocket.ngc"),
                              quoted(trace)),
                  folder);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = run_shell(fmt::format("{} scan {} --axis X --force-constant X_force_constant_N_per_A --json {}", cli(),
                              quoted(trace), quoted(document)),
                  folder);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto scan = nlohmann::json::parse(read_text(document));
    const std::string html = report::result_report_html(scan, document.string());
    EXPECT_NE(html.find("feedid production-scan report: pocket.csv"), std::string::npos);
    const auto& windows = scan["windows"];
    EXPECT_NE(html.find(fmt::format("cut into {} windows of 2 s; <b>{}</b> qualified", windows["total"].get<int>(),
                                    windows["qualified"].get<int>())),
              std::string::npos)
        << html;
    const int process_force = windows["rejected"]["process_force"].get<int>();
    ASSERT_GT(process_force, 0) << "the pocket's cutting moves";
    EXPECT_NE(html.find(fmt::format("a process (cutting) force, not the axis</td><td>{}</td>", process_force)),
              std::string::npos);
    const double mass_information = scan["information"]["mass_kg"]["inverse_variance"].get<double>();
    EXPECT_NE(html.find(fmt::format("<td class=\"text\">Mass M</td><td>{:.4g}</td><td>{:.3g}</td>", mass_information,
                                    1.0 / std::sqrt(mass_information))),
              std::string::npos);
    expect_self_contained(html);
    // a document that is not a scan's has no such section
    auto identify_like = scan;
    identify_like.erase("kind");
    EXPECT_EQ(report::result_report_html(identify_like, "r.json").find("<h2>Windows</h2>"), std::string::npos);
}

// The paper's Fig. 6 from a real run: EMPS identified, simulated in closed loop with the gains identified from the
// trace, and reported with --simulation.
TEST(ReportSimulation, EmpsReportHasTrackingAndModellingErrorPlots) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto folder = temp_dir();
    const std::string mat = quoted(shared_data() / "emps/DATA_EMPS.mat");
    const auto result = folder / "result.json";
    const auto simulation = folder / "sim.json";
    const auto identify = run_shell(fmt::format("{} identify {} --channel position=qm --channel current=vir "
                                                "--force-constant gtau --offset --json {}",
                                                cli(), mat, quoted(result)),
                                    folder);
    ASSERT_EQ(identify.exit_code, 0) << identify.err;
    const auto simulate = run_shell(fmt::format("{} simulate {} --channel position=qm --channel reference_position=qg "
                                                "--channel current=vir --force-constant gtau --saturation 10 "
                                                "--result {} --json {}",
                                                cli(), mat, quoted(result), quoted(simulation)),
                                    folder);
    ASSERT_EQ(simulate.exit_code, 0) << simulate.err;
    const auto page = folder / "emps.html";
    const auto r = run_shell(
        fmt::format("{} report {} --simulation {} -o {}", cli(), quoted(result), quoted(simulation), quoted(page)),
        folder);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto html = read_text(page);
    expect_self_contained(html);
    const auto svgs = svgs_of(html);
    std::map<std::string, SvgText> by_heading;
    for (const auto& svg : svgs) {
        const auto text = parse_svg(svg);
        EXPECT_EQ(text.title, text.heading);
        EXPECT_TRUE(has_unit(text.x_label)) << text.x_label;
        EXPECT_TRUE(has_unit(text.y_label)) << text.y_label;
        by_heading[text.heading] = text;
    }
    for (const auto& svg : svgs) expect_text_inside_and_apart(svg);
    ASSERT_TRUE(by_heading.count("Tracking error of machine and model over time")) << html.substr(0, 500);
    EXPECT_EQ(by_heading["Tracking error of machine and model over time"].x_label, "time [s]");
    EXPECT_EQ(by_heading["Tracking error of machine and model over time"].y_label, "tracking error x_ref − x [mm]");
    ASSERT_TRUE(by_heading.count("Modelling error over time"));
    EXPECT_EQ(by_heading["Modelling error over time"].x_label, "time [s]");
    EXPECT_EQ(by_heading["Modelling error over time"].y_label, "modelling error e_m = x − x_sim [mm]");
    EXPECT_TRUE(by_heading.count("RLS estimate of Mass M over time")) << "the result's plots are still there";
    // Both errors are drawn, with their legend.
    EXPECT_NE(html.find("machine: x_ref − x (measured)"), std::string::npos);
    EXPECT_NE(html.find("model: x_ref − x_sim (simulated)"), std::string::npos);

    // The summary table holds the document's figures, in mm and %.
    const auto document = nlohmann::json::parse(read_text(simulation));
    for (const double value : {document["tracking_error_mae_m"]["model"].get<double>() * 1e3,
                               document["tracking_error_mae_m"]["machine"].get<double>() * 1e3})
        EXPECT_NE(html.find(fmt::format("<td>{:.4g}</td>", value)), std::string::npos) << value;
    const double modelling_mae_mm = document["modelling_error_mae_m"].get<double>() * 1e3;
    EXPECT_NE(html.find(fmt::format("<td colspan=\"2\">{:.4g}</td>", modelling_mae_mm)), std::string::npos);
    for (const char* key : {"position", "velocity", "acceleration", "force"})
        EXPECT_NE(html.find(fmt::format("<td>{:.4g}</td>", document["relative_error_pct"][key].get<double>())),
                  std::string::npos)
            << key;
    EXPECT_NE(html.find("mean absolute modelling error"), std::string::npos);
    EXPECT_EQ(html.find("need a simulation"), std::string::npos);

    const auto chromium = find_chromium();
    if (chromium.empty())
        GTEST_SKIP() << "headless Chromium not found (install Debian's chromium package); the "
                        "browser rendering check is skipped";
    expect_rendered(render_in_chromium(chromium, page, folder), svgs);
}

TEST_F(ReportEndToEnd, BadSimulationDocumentIsExitTwoAndWritesNothing) {
    const std::string summary = R"("relative_error_pct": {"position": 0.01, "velocity": 0.2, "acceleration": 8,
        "force": 5}, "tracking_error_mae_m": {"model": 0.001, "machine": 0.001}, "modelling_error_mae_m": 0.0001)";
    const std::vector<std::pair<std::string, std::string>> cases{
        {"garbage.json", "this is not JSON"},
        {"result-as-simulation.json", read_text(result_)},
        {"gains.json", R"({"gains": {}, "nc_units": {}, "diagnostics": []})"},
        {"no-series.json", "{" + summary + "}"},
        {"short-series.json", "{" + summary + R"(, "series": {"time_s": [0, 0.001, 0.002],
            "tracking_error_machine_m": [0, 1e-5, 2e-5], "tracking_error_model_m": [0, 1e-5],
            "modelling_error_m": [0, 0, 0]}})"},
        {"text-in-series.json", "{" + summary + R"(, "series": {"time_s": [0, 0.001],
            "tracking_error_machine_m": [0, "x"], "tracking_error_model_m": [0, 1e-5],
            "modelling_error_m": [0, 0]}})"},
        {"rotary-keys-missing.json", "{" + summary + R"(, "rotary": true, "series": {"time_s": [0, 0.001],
            "tracking_error_machine_m": [0, 1e-5], "tracking_error_model_m": [0, 1e-5],
            "modelling_error_m": [0, 0]}})"},
    };
    for (const auto& [name, text] : cases) {
        const auto simulation = folder_ / name;
        write_text(simulation, text);
        const auto page = folder_ / (name + ".html");
        const auto r = run_shell(
            fmt::format("{} report {} --simulation {} -o {}", cli(), quoted(result_), quoted(simulation), quoted(page)),
            folder_);
        EXPECT_EQ(r.exit_code, 2) << name << ": " << r.err;
        EXPECT_EQ(count_lines(r.err), 1) << name << ": " << r.err;
        EXPECT_NE(r.err.find(name), std::string::npos) << name << ": " << r.err;
        EXPECT_FALSE(fs::exists(page)) << name;
    }
    // A history report has no single run to validate.
    const auto page = folder_ / "history-with-simulation.html";
    write_text(folder_ / "valid-shape.json", "{" + summary + R"(, "series": {"time_s": [0],
        "tracking_error_machine_m": [0], "tracking_error_model_m": [0], "modelling_error_m": [0]}})");
    const auto r = run_shell(fmt::format("{} report {} --simulation {} -o {}", cli(), quoted(database_),
                                         quoted(folder_ / "valid-shape.json"), quoted(page)),
                             folder_);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(count_lines(r.err), 1) << r.err;
    EXPECT_FALSE(fs::exists(page));
    // The same simulation document is accepted with a result.
    const auto accepted = run_shell(fmt::format("{} report {} --simulation {} -o {}", cli(), quoted(result_),
                                                quoted(folder_ / "valid-shape.json"), quoted(page)),
                                    folder_);
    EXPECT_EQ(accepted.exit_code, 0) << accepted.err;
}

}  // namespace
