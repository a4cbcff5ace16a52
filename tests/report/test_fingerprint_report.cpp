// The fingerprint's page (fingerprint_report.hpp) and the fingerprint runs in the history report, on a synthetic axis
// of known backlash and stiffness: both plots are there, well-formed, with their axes labelled in the units the page
// states; the figures on the page are the fingerprint's; the history report plots the fingerprint trend in µm.

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include <fmt/core.h>
#include <pugixml.hpp>

#include "feedid/history/store.hpp"
#include "feedid/history/trend.hpp"
#include "feedid/identify/fingerprint.hpp"
#include "feedid/report/fingerprint_report.hpp"
#include "feedid/report/history_report.hpp"
#include "feedid/sim/synth.hpp"
#include "feedid/sim/transmission_synth.hpp"
#include "testing.hpp"

using namespace feedid;

namespace {

struct Labels {
    std::string heading;
    std::string x_label;
    std::string y_label;
    std::vector<std::string> legend;
};

std::string text_of(const pugi::xml_node& node) {
    std::string text;
    for (const auto& child : node.children())
        text += child.type() == pugi::node_pcdata ? std::string(child.value()) : text_of(child);
    return text;
}

std::vector<Labels> plots_of(const std::string& html) {
    std::vector<Labels> plots;
    for (std::size_t start = html.find("<svg"); start != std::string::npos; start = html.find("<svg", start + 1)) {
        const auto end = html.find("</svg>", start);
        const std::string svg = html.substr(start, end + 6 - start);
        pugi::xml_document document;
        EXPECT_TRUE(document.load_string(svg.c_str())) << svg.substr(0, 200);
        Labels labels;
        for (const auto& node : document.select_nodes("//text")) {
            const std::string type = node.node().attribute("class").value();
            if (type == "plot-title") labels.heading = text_of(node.node());
            if (type == "axis-label x-label") labels.x_label = text_of(node.node());
            if (type == "axis-label y-label") labels.y_label = text_of(node.node());
            if (type.find("legend") != std::string::npos) labels.legend.push_back(text_of(node.node()));
        }
        plots.push_back(labels);
    }
    return plots;
}

struct Fingerprinted {
    FingerprintResult result;
    nlohmann::json document;
};

Fingerprinted fingerprint_of(double backlash_um, double stiffness_N_per_um, bool motor_encoder) {
    SynthSpec spec = demo_spec();
    spec.seed = 7;
    TransmissionModel transmission;
    transmission.backlash_m = backlash_um * 1e-6;
    transmission.stiffness_N_per_m = stiffness_N_per_um * 1e6;
    transmission.log_motor_position = motor_encoder;
    const Trace trace = synthesize_with_transmission(spec, transmission);
    FingerprintOptions options;
    options.drive.force_constant = spec.force_constant_N_per_A();
    Fingerprinted out{fingerprint(trace, options), {}};
    out.document = fingerprint_document(out.result);
    out.document["trace"] = {{"path", "rev.csv"}};
    return out;
}

}  // namespace

TEST(FingerprintReport, ThePageShowsBothPlotsAndTheFiguresInTheirUnits) {
    const auto run = fingerprint_of(8.0, 150.0, true);
    const std::string html = report::fingerprint_report_html(run.document, run.result.curves, "rev.csv");
    const auto plots = plots_of(html);
    ASSERT_EQ(plots.size(), 2u) << html.substr(0, 400);
    EXPECT_EQ(plots[0].x_label, "scale position x_load [mm]");
    EXPECT_EQ(plots[0].y_label, "motor encoder − scale d [µm]");
    EXPECT_EQ(plots[1].x_label, "motor encoder − scale d [µm]");
    EXPECT_EQ(plots[1].y_label, "drive force F [N]");
    // the curves: d of the forward samples sits a lost motion above the reverse ones
    const auto& curves = run.result.curves;
    ASSERT_FALSE(curves.position.empty());
    EXPECT_LE(curves.position.size(), FingerprintCurves::max_points);
    ASSERT_TRUE(curves.compliance && curves.intercept_forward && curves.intercept_reverse);
    EXPECT_NEAR(1.0 / *curves.compliance, 150e6, 15e6);
    EXPECT_NEAR(*curves.intercept_forward - *curves.intercept_reverse, 8e-6, 0.8e-6);
    // the table holds the fingerprint's own numbers as the CLI prints them
    const auto& backlash = run.result.backlash;
    EXPECT_NE(html.find(fmt::format("{:.4g} ± {:.2g} µm", *backlash.value * 1e6, *backlash.standard_error * 1e6)),
              std::string::npos);
    const auto& stiffness = run.result.stiffness.both;
    EXPECT_NE(html.find(fmt::format("{:.4g} ± {:.2g} N/µm", *stiffness.value * 1e-6, *stiffness.standard_error * 1e-6)),
              std::string::npos);
}

TEST(FingerprintReport, OneMeasuringSystemShowsTheNullsWithTheirReasonAndNoDeflectionPlot) {
    const auto run = fingerprint_of(8.0, 150.0, false);
    const std::string html = report::fingerprint_report_html(run.document, run.result.curves, "one.csv");
    EXPECT_TRUE(plots_of(html).empty());
    EXPECT_NE(html.find("<b>lost_motion</b>: one measuring system: motor and load are not told apart"),
              std::string::npos);
    EXPECT_NE(html.find("<b>backlash</b>: one measuring system"), std::string::npos);
}

TEST(FingerprintReport, TheHistoryReportPlotsTheFingerprintTrendInMicrometres) {
    std::vector<history::RunRecord> runs;
    for (int i = 1; i <= 3; ++i) {
        const auto run = fingerprint_of(4.0 * i, 200.0, true);
        auto record = history::run_from_result(run.document, "rev.json");
        record.id = i;
        record.machine = "M1";
        record.axis = "X";
        record.recorded_at = fmt::format("2026-11-0{}T06:00:00Z", i);
        runs.push_back(record);
    }
    history::TrendOptions options;
    options.baseline_runs = 2;
    const auto trends = history::analyse_trends(runs, {}, options);
    ASSERT_EQ(trends.size(), 1u);
    EXPECT_EQ(trends[0].kind, "fingerprint");
    const std::string html = report::history_report_html(runs, trends, options, "shop.db");
    EXPECT_NE(html.find("axis X — mechanical fingerprint"), std::string::npos);
    bool backlash_plot = false;
    for (const auto& plot : plots_of(html))
        if (plot.heading.starts_with("Backlash — machine 'M1' axis 'X' (fingerprint)")) {
            backlash_plot = true;
            EXPECT_EQ(plot.y_label, "Backlash [µm]");
        }
    EXPECT_TRUE(backlash_plot);
    EXPECT_NE(html.find(fmt::format("{:.5g} ±", *runs[2].parameters.at("backlash_m").value * 1e6)), std::string::npos);
}
