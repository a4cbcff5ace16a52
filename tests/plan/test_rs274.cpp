// The LinuxCNC program runs through LinuxCNC's own interpreter (`rs274 -g FILE`, Debian package linuxcnc-uspace,
// installed by `scripts/setup.sh --extra`) without error, and the canonical commands it prints match the plan move
// for move: STRAIGHT_FEED targets [mm, as the program is G21; degrees on a rotary axis], SET_FEED_RATE [mm/min or
// deg/min], DWELL [s].
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "feedid/plan/gcode_writer.hpp"
#include "feedid/plan/reversal_test.hpp"
#include "feedid/plan/test_plan.hpp"
#include "testing.hpp"

namespace {

struct Canonical {
    enum Kind { feed, dwell } kind;
    double value;  // target [mm or deg] or dwell [s]
    double feed_per_min;
};

void check_plan_through_rs274(const feedid::TestPlan& plan) {
    const auto rs274 = feedid::testing::find_rs274();
    if (rs274.empty())
        GTEST_SKIP() << "LinuxCNC's rs274 interpreter not found (install Debian's linuxcnc-uspace: scripts/setup.sh "
                        "--extra); the .ngc check is skipped";
    const auto dir = feedid::testing::temp_dir();
    const auto program = dir / "test.ngc";
    feedid::testing::write_text(program, feedid::emit_part_program(plan, feedid::Dialect::linuxcnc));
    // rs274 may look for its var file in the working directory: run it in ours.
    const int status = feedid::testing::run_rs274(rs274, program, dir);
    const auto out = feedid::testing::read_text(dir / "out.txt");
    const auto err = feedid::testing::read_text(dir / "err.txt");
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "rs274 failed:\n" << err << "\n" << out;

    // "   17 N..... STRAIGHT_FEED(10.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)"
    const std::regex feed_rate(R"(SET_FEED_RATE\(([-0-9.]+)\))");
    const std::regex straight_feed(R"(STRAIGHT_FEED\(([-0-9., ]+)\))");
    // STRAIGHT_FEED lists X, Y, Z, A, B, C (and U, V, W) in this order.
    const auto axis_index = std::string("XYZABCUVW").find(plan.options.axis);
    ASSERT_NE(axis_index, std::string::npos);
    const std::regex dwell(R"(DWELL\(([-0-9.]+)\))");
    std::vector<Canonical> canonical;
    double current_feed = 0.0;
    bool metric = false;
    std::istringstream lines(out);
    std::string line;
    std::smatch match;
    while (std::getline(lines, line)) {
        if (line.find("USE_LENGTH_UNITS(CANON_UNITS_MM)") != std::string::npos) metric = true;
        EXPECT_EQ(line.find("STRAIGHT_TRAVERSE"), std::string::npos) << "no rapid moves expected: " << line;
        if (std::regex_search(line, match, feed_rate)) current_feed = std::stod(match[1]);
        if (std::regex_search(line, match, straight_feed)) {
            std::vector<double> values;
            std::stringstream list(match[1].str());
            std::string value;
            while (std::getline(list, value, ',')) values.push_back(std::stod(value));
            ASSERT_GT(values.size(), axis_index) << line;
            for (std::size_t k = 0; k < values.size(); ++k) {
                if (k != axis_index) {
                    EXPECT_EQ(values[k], 0.0) << "only the tested axis moves: " << line;
                }
            }
            canonical.push_back({Canonical::feed, values[axis_index], current_feed});
        }
        if (std::regex_search(line, match, dwell)) canonical.push_back({Canonical::dwell, std::stod(match[1]), 0.0});
    }
    EXPECT_TRUE(metric) << "the program must select millimetres (G21)";
    ASSERT_EQ(canonical.size(), plan.moves.size()) << out;
    const feedid::PlanUnits units = plan.options.units();
    for (std::size_t k = 0; k < plan.moves.size(); ++k) {
        const auto& move = plan.moves[k];
        const auto& c = canonical[k];
        if (move.kind == feedid::MoveKind::feed) {
            ASSERT_EQ(c.kind, Canonical::feed) << "block " << k + 1 << ": " << move.description;
            EXPECT_NEAR(c.value, move.target / units.length(), 5e-5) << "block " << k + 1 << ": " << move.description;
            EXPECT_NEAR(c.feed_per_min, move.feed / units.feed(), 5e-4)
                << "block " << k + 1 << ": " << move.description;
        } else {
            ASSERT_EQ(c.kind, Canonical::dwell) << "block " << k + 1 << ": " << move.description;
            EXPECT_NEAR(c.value, move.dwell, 5e-5) << "block " << k + 1;
        }
    }
}

TEST(Rs274, MultiCentrePlanWithSlowPassesRunsMoveForMove) {
    feedid::TestPlanOptions options;
    options.travel_min = -0.45;
    options.travel_max = 0.05;
    options.centers = {-0.3, -0.2, 0.0};
    options.dwell = 0.15;
    check_plan_through_rs274(feedid::make_test_plan(options));
}

TEST(Rs274, PapersLadderOnTheZAxisWithoutDwells) {
    feedid::TestPlanOptions options;
    options.axis = "Z";
    options.travel_min = -0.5;
    options.travel_max = 0.0;
    options.centers = {-0.3};
    options.slow_feeds.clear();
    options.cycles = 3;
    options.dwell = 0.0;  // no dwell blocks at all
    check_plan_through_rs274(feedid::make_test_plan(options));
}

// A rotary axis: rs274 reads A in degrees and its feedrate in deg/min (a move of a rotary axis alone).
TEST(Rs274, ARotaryTableInDegrees) {
    constexpr double deg = M_PI / 180.0;
    auto options = feedid::default_plan_options("A");
    options.travel_min = -360.0 * deg;
    options.travel_max = 360.0 * deg;
    options.centers = {0.0, 120.0 * deg, 240.0 * deg};
    check_plan_through_rs274(feedid::make_test_plan(options));
}

// The reversal test (feedid fingerprint's program): 1 um micro-steps through reversals and slow strokes, at two
// centres; every micro-step a block of its own, 0.0001 mm apart at the finest.
TEST(Rs274, ReversalTestMicroStepsAndStrokesRunMoveForMove) {
    auto options = feedid::default_reversal_options("X");
    options.travel_min = -0.4;
    options.travel_max = 0.4;
    options.centers = {-0.3, 0.1};
    const auto plan = feedid::make_reversal_plan(options);
    ASSERT_FALSE(plan.description.empty());
    check_plan_through_rs274(plan);
}

TEST(Rs274, ReversalTestOnARotaryAxis) {
    constexpr double deg = M_PI / 180.0;
    auto options = feedid::default_reversal_options("C");
    options.travel_min = -360.0 * deg;
    options.travel_max = 360.0 * deg;
    options.centers = {90.0 * deg};
    check_plan_through_rs274(feedid::make_reversal_plan(options));
}

}  // namespace
