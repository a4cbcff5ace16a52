// Every default lives in its Options struct: what `feedid SUBCOMMAND --help` states as an option's default is the
// struct's value (in the option's unit), and `feedid plan` without options plans what the library plans from
// default-constructed options. A default typed again in a front-end and changed in one place only fails here (the
// Python module's keyword defaults: tests/python/test_defaults.py).

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/history/trend.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/identify/online_identifier.hpp"
#include "feedid/identify/option_names.hpp"
#include "feedid/model/demo_drives.hpp"
#include "feedid/model/drive.hpp"
#include "feedid/plan/test_plan.hpp"
#include "feedid/sim/production_synth.hpp"
#include "feedid/sim/simulate.hpp"
#include "feedid/stream/service.hpp"
#include "testing.hpp"

namespace {

using feedid::testing::run_cli;

// The defaults the help states, option -> text: "--stroke FLOAT:in 0.01 to 100000 mm or deg=30" gives "30".
std::map<std::string, std::string> help_defaults(const std::string& subcommand) {
    const auto help = run_cli(subcommand + " --help");
    EXPECT_EQ(help.exit_code, 0) << help.err;
    std::map<std::string, std::string> defaults;
    std::istringstream in(help.out);
    std::string line;
    while (std::getline(in, line)) {
        const auto first = line.find_first_not_of(' ');
        if (first == std::string::npos || line[first] != '-') continue;
        // "--name TYPE[:check]=DEFAULT" then the description; a default holds no space
        const auto name_start = line.find("--", first);
        const auto equals = line.find('=', name_start);
        if (name_start == std::string::npos || equals == std::string::npos) continue;
        const auto name_end = line.find(' ', name_start);
        const auto value_end = line.find(' ', equals);
        defaults[line.substr(name_start, name_end - name_start)] =
            line.substr(equals + 1, value_end == std::string::npos ? std::string::npos : value_end - equals - 1);
    }
    return defaults;
}

using Expected = std::variant<double, std::string>;

// Every option of `subcommand` that states a default states `expected`'s value, and every expected option states one.
void expect_help_defaults(const std::string& subcommand, const std::map<std::string, Expected>& expected) {
    const auto shown = help_defaults(subcommand);
    for (const auto& [option, value] : expected) {
        const auto it = shown.find(option);
        if (it == shown.end()) {
            ADD_FAILURE() << subcommand << " " << option << ": the help states no default";
            continue;
        }
        if (const auto* number = std::get_if<double>(&value)) {
            // the help writes numbers with 6 significant digits
            EXPECT_NEAR(std::stod(it->second), *number, 1e-6 * std::abs(*number)) << subcommand << " " << option;
        } else {
            EXPECT_EQ(it->second, std::get<std::string>(value)) << subcommand << " " << option;
        }
    }
}

TEST(Defaults, PlanHelpStatesTheLibrarysDefaults) {
    const feedid::TestPlanOptions plan = feedid::default_plan_options("X");
    const feedid::PredictionOptions prediction = feedid::default_prediction_options(false);
    const feedid::PlanUnits mm;
    expect_help_defaults("plan", {{"--axis", feedid::TestPlanOptions{}.axis},
                                  {"--stroke", plan.stroke / mm.length()},
                                  {"--max-pass-time", plan.max_pass_time},
                                  {"--cycles", static_cast<double>(plan.cycles)},
                                  {"--dwell", plan.dwell},
                                  {"--sample-time", plan.sample_time},
                                  {"--positioning-feed", plan.positioning_feed / mm.feed()},
                                  {"--position-resolution", prediction.position_resolution * 1e6}});
    // the slow feeds' LO:HI:N stands for the struct's feedrates
    const auto slow = help_defaults("plan").at("--slow-feeds");
    const auto feeds = feedid::parse_slow_feeds({slow});
    ASSERT_EQ(feeds.size(), plan.slow_feeds.size()) << slow;
    for (std::size_t k = 0; k < feeds.size(); ++k) EXPECT_DOUBLE_EQ(feeds[k], plan.slow_feeds[k]) << slow;
    // and the nominal drive's defaults named in the descriptions are the demo drives'
    const auto help = run_cli("plan --help").out;
    const auto linear = feedid::demo_drive(false).axis;
    const auto rotary = feedid::demo_drive(true).axis;
    for (const auto& text :
         {fmt::format("default {:g} kg, {:g} kg*m^2", linear.mass, rotary.mass),
          fmt::format("default {:g} N, {:g} N*m", linear.friction.forward.coulomb, rotary.friction.forward.coulomb),
          fmt::format("default {:g} m/s^2", plan.acceleration)}) {
        EXPECT_NE(help.find(text), std::string::npos) << text;
    }
}

TEST(Defaults, OtherSubcommandsHelpStatesTheLibrarysDefaults) {
    const feedid::IdentifyOptions identify;
    expect_help_defaults(
        "identify",
        {{"--model", identify.model_selection.automatic
                         ? std::string(feedid::automatic_model_name)
                         : feedid::name_of(feedid::friction_model_names, identify.model)},
         {"--differentiation", feedid::name_of(feedid::differentiation_names, identify.preprocess.differentiation)},
         {"--velocity-source", feedid::name_of(feedid::velocity_source_names, identify.preprocess.velocity_source)},
         {"--rls", feedid::name_of(feedid::rls_variant_names, identify.step1.rls.variant)},
         {"--filter-order", static_cast<double>(identify.preprocess.filter_order)},
         {"--sg-order", static_cast<double>(identify.preprocess.savitzky_golay_order)},
         {"--lambda", identify.step1.rls.forgetting_factor},
         {"--p0", identify.step1.rls.initial_covariance},
         {"--gear-ratio", feedid::DriveConstants{}.gear_ratio}});
    const feedid::GainOptions gains;
    expect_help_defaults("gains", {{"--forgetting", gains.rls.forgetting_factor},
                                   {"--gear-ratio", feedid::DriveConstants{}.gear_ratio}});
    expect_help_defaults("simulate", {{"--substeps", static_cast<double>(feedid::SimulationOptions{}.substeps)},
                                      {"--forgetting", gains.rls.forgetting_factor}});
    const feedid::history::TrendOptions trend;
    for (const std::string subcommand : {"history", "report"}) {
        expect_help_defaults(subcommand, {{"--baseline-runs", static_cast<double>(trend.baseline_runs)},
                                          {"--cusum-k", trend.cusum_k},
                                          {"--cusum-h", trend.cusum_h}});
    }
    const feedid::OnlineOptions online;
    expect_help_defaults("scan", {{"--window", online.window_s}, {"--forgetting", online.forgetting}});
    const feedid::watch::ServiceOptions service;
    expect_help_defaults("watch", {{"--topic", service.topic_filter}});
    const feedid::watch::PublishOptions publish;
    expect_help_defaults("publish", {{"--rate", fmt::format("{:g}x", publish.rate)},
                                     {"--batch", publish.batch_s},
                                     {"--buffer", publish.buffer_s},
                                     {"--replay", publish.replay_s},
                                     {"--qos", static_cast<double>(publish.qos)}});
    const auto synth = run_cli("synth --help").out;
    const auto text = fmt::format("(default {:g};", feedid::ProductionOptions{}.cutting_force_fraction);
    EXPECT_NE(synth.find(text), std::string::npos) << text;
}

// Without options, `feedid plan` plans what the library plans from its defaults: the document is the same to the bit.
TEST(Defaults, PlanWithoutOptionsIsTheLibrarysDefaultPlan) {
    for (const std::string axis : {"X", "C"}) {
        const auto cli = run_cli("plan --axis " + axis + " --travel=-400:400 --centers=-100,100 --json -");
        ASSERT_EQ(cli.exit_code, 0) << cli.err;
        const feedid::PlanUnits units{feedid::is_rotary_axis(axis)};
        feedid::TestPlanOptions options = feedid::default_plan_options(axis);
        std::tie(options.travel_min, options.travel_max) = feedid::parse_travel("-400:400", units);
        options.centers = feedid::parse_number_list({"-100", "100"}, "--centers", units.length());
        const auto plan = feedid::make_test_plan(options);
        const auto prediction = feedid::predict_identifiability(plan, feedid::default_prediction_options(units.rotary));
        EXPECT_EQ(nlohmann::json::parse(cli.out), feedid::plan_document(plan, prediction)) << axis;
    }
}

}  // namespace
