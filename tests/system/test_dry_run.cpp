// A full dry run of the test through the CLI: feedid plan writes the reference trajectory, feedid synth makes the
// trace a machine with the demo drive would record following it, feedid identify estimates the drive.
//   with slow passes:        F_B within 5 %, v_s within 15 % of the synthetic drive's values;
//   the paper's ladder only: the plan's prediction and the identification both say F_B and v_s are not identifiable.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "testing.hpp"

namespace {

using feedid::testing::run_cli;

std::string quoted(const std::filesystem::path& path) {
    return "'" + path.string() + "'";
}

// The `# name = value` constants of a synthetic trace (its true drive values).
std::map<std::string, double> constants_of(const std::filesystem::path& csv) {
    std::map<std::string, double> constants;
    std::istringstream lines(feedid::testing::read_text(csv));
    std::string line;
    while (std::getline(lines, line) && line.rfind("#", 0) == 0) {
        const auto equals = line.find('=');
        if (equals == std::string::npos) continue;
        auto name = line.substr(1, equals - 1);
        name.erase(0, name.find_first_not_of(' '));
        name.erase(name.find_last_not_of(' ') + 1);
        constants[name] = std::stod(line.substr(equals + 1));
    }
    return constants;
}

struct DryRun {
    nlohmann::json plan;
    nlohmann::json identified;
    std::map<std::string, double> truth;
};

DryRun dry_run(const std::string& plan_arguments) {
    const auto dir = feedid::testing::temp_dir();
    DryRun run;
    const auto plan = run_cli("plan --travel=-400:400 --centers=-300 " + plan_arguments + " --reference " +
                              quoted(dir / "ref.csv") + " --json " + quoted(dir / "plan.json"));
    EXPECT_EQ(plan.exit_code, 0) << plan.err;
    run.plan = nlohmann::json::parse(feedid::testing::read_text(dir / "plan.json"));
    const auto synth = run_cli("synth --reference " + quoted(dir / "ref.csv") + " --out " + quoted(dir / "synth.csv"));
    EXPECT_EQ(synth.exit_code, 0) << synth.err;
    run.truth = constants_of(dir / "synth.csv");
    const auto identify =
        run_cli("identify " + quoted(dir / "synth.csv") + " --force-constant force_constant_N_per_A --json -");
    EXPECT_EQ(identify.exit_code, 0) << identify.err;
    run.identified = nlohmann::json::parse(identify.out.empty() ? std::string("{}") : identify.out);
    return run;
}

TEST(DryRun, PlanWithSlowPassesRecoversBreakawayAndStribeck) {
    const auto run = dry_run("");
    if (HasFailure()) return;
    const auto& predicted = run.plan.at("prediction").at("parameters");
    EXPECT_TRUE(predicted.at("breakaway_N").at("identifiable").get<bool>());
    EXPECT_TRUE(predicted.at("stribeck_velocity_m_per_s").at("identifiable").get<bool>());

    ASSERT_TRUE(run.truth.count("true_breakaway_forward_N"));
    ASSERT_TRUE(run.truth.count("true_stribeck_velocity_forward_m_per_s"));
    const double breakaway = run.truth.at("true_breakaway_forward_N");
    const double stribeck = run.truth.at("true_stribeck_velocity_forward_m_per_s");
    const auto& parameters = run.identified.at("parameters");
    ASSERT_TRUE(parameters.at("breakaway_N").at("value").is_number()) << run.identified.dump(1);
    ASSERT_TRUE(parameters.at("stribeck_velocity_m_per_s").at("value").is_number()) << run.identified.dump(1);
    EXPECT_NEAR(parameters.at("breakaway_N").at("value").get<double>(), breakaway, 0.05 * breakaway);
    EXPECT_NEAR(parameters.at("stribeck_velocity_m_per_s").at("value").get<double>(), stribeck, 0.15 * stribeck);
}

TEST(DryRun, PapersLadderAloneLeavesBreakawayAndStribeckUnidentified) {
    const auto run = dry_run("--slow-feeds none");
    if (HasFailure()) return;
    const auto& predicted = run.plan.at("prediction").at("parameters");
    EXPECT_FALSE(predicted.at("breakaway_N").at("identifiable").get<bool>());
    EXPECT_FALSE(predicted.at("stribeck_velocity_m_per_s").at("identifiable").get<bool>());
    EXPECT_TRUE(predicted.at("coulomb_N").at("identifiable").get<bool>());

    const auto& parameters = run.identified.at("parameters");
    EXPECT_TRUE(parameters.at("breakaway_N").at("value").is_null()) << parameters.dump();
    EXPECT_TRUE(parameters.at("stribeck_velocity_m_per_s").at("value").is_null()) << parameters.dump();
    EXPECT_TRUE(parameters.at("coulomb_N").at("value").is_number());
    EXPECT_FALSE(run.identified.at("diagnostics").empty());
}

}  // namespace
