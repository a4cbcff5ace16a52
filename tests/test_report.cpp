// feedid report: SVG plots that parse as XML with their titles and axis labels, and a self-contained HTML page that a
// real browser (headless Chromium) renders: every plot's title, axis labels and data get a non-empty box.

#include <gtest/gtest.h>

#include <cmath>
#include <regex>

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <pugixml.hpp>

#include "feedid/error.hpp"
#include "feedid/history/store.hpp"
#include "feedid/report.hpp"
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
        if (type == "plot-title") text.heading = node.node().text().get();
        if (type == "axis-label x-label") text.x_label = node.node().text().get();
        if (type == "axis-label y-label") text.y_label = node.node().text().get();
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
    plots.push({id: svg.id, title: text('.plot-title'), x_label: text('.x-label'), y_label: text('.y-label'),
                title_area: area(svg.querySelector('.plot-title')), x_area: area(svg.querySelector('.x-label')),
                y_area: area(svg.querySelector('.y-label')), data_area: area(svg.querySelector('g.data')),
                width: svg.getBoundingClientRect().width});
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

    const auto chromium = find_chromium();
    if (chromium.empty())
        GTEST_SKIP() << "headless Chromium not found (install Debian's chromium package); the "
                        "browser rendering check is skipped";
    expect_rendered(render_in_chromium(chromium, page, folder_), svgs);
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
