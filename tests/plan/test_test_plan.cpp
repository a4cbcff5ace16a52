// Test design: the ladder, slow passes, profiles, refusals, the reference trajectory and the identifiability
// prediction.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "feedid/core/error.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"
#include "feedid/plan/test_plan.hpp"

namespace {

constexpr double mm = 1e-3;
constexpr double mm_per_min = 1e-3 / 60.0;

feedid::TestPlanOptions options_at(std::vector<double> centers) {
    feedid::TestPlanOptions options;
    options.travel_min = -0.4;
    options.travel_max = 0.4;
    options.centers = std::move(centers);
    return options;
}

std::string message_of(const feedid::TestPlanOptions& options) {
    try {
        (void)feedid::make_test_plan(options);
    } catch (const feedid::InputError& e) {
        return e.what();
    }
    return {};
}

TEST(TestPlan, PaperLadderAndSlowFeeds) {
    const auto ladder = feedid::paper_feed_ladder();
    ASSERT_EQ(ladder.size(), 7u);
    EXPECT_NEAR(ladder.front() / mm_per_min, 1250.0, 1e-9);
    EXPECT_NEAR(ladder.back() / mm_per_min, 9350.0, 1e-9);
    const auto slow = feedid::log_spaced_feeds(10 * mm_per_min, 1000 * mm_per_min, 7);
    const std::vector<double> expected{10, 22, 46, 100, 220, 460, 1000};
    ASSERT_EQ(slow.size(), expected.size());
    for (std::size_t k = 0; k < slow.size(); ++k) EXPECT_NEAR(slow[k] / mm_per_min, expected[k], 1e-9);
}

TEST(TestPlan, MoveDurationsMatchTheClosedForms) {
    const double a = 1.0;
    // Trapezoid reaching the feed: T = D/v + v/a.
    const double v = 1250 * mm_per_min;
    EXPECT_NEAR(feedid::move_duration(0.030, v, a, std::nullopt), 0.030 / v + v / a, 1e-12);
    // Too short to reach the feed: triangle, T = 2 sqrt(D/a).
    EXPECT_NEAR(feedid::move_duration(1e-4, 0.15, a, std::nullopt), 2.0 * std::sqrt(1e-4 / a), 1e-9);
    // Jerk-limited, v >= a^2/j: T = D/v + v/a + a/j.
    const double j = 20.0;
    const double fast = 9350 * mm_per_min;
    EXPECT_NEAR(feedid::move_duration(0.100, fast, a, j), 0.100 / fast + fast / a + a / j, 1e-9);
    // Jerk-limited, v < a^2/j: T = D/v + 2 sqrt(v/j).
    EXPECT_NEAR(feedid::move_duration(0.030, v, a, 2.0), 0.030 / v + 2.0 * std::sqrt(v / 2.0), 1e-9);
}

TEST(TestPlan, StructureOfAMultiCentrePlan) {
    auto options = options_at({-0.3, 0.0, 0.3});
    const auto plan = feedid::make_test_plan(options);
    const std::size_t per_center = options.feeds.size() + options.slow_feeds.size();
    ASSERT_EQ(plan.passes.size(), 3 * per_center);
    for (const auto& pass : plan.passes) {
        EXPECT_LE(pass.stroke, options.stroke + 1e-15);
        if (pass.slow) {
            EXPECT_LE(pass.duration, options.max_pass_time + 1e-9) << pass.feed / mm_per_min << " mm/min";
            EXPECT_GT(pass.cruise_time, 0.0);
        } else {
            EXPECT_DOUBLE_EQ(pass.stroke, options.stroke);
        }
    }
    // Every stroke of a pass is symmetric about its centre; every move stays in the travel.
    for (const auto& move : plan.moves) {
        if (move.kind != feedid::MoveKind::feed) continue;
        EXPECT_GE(move.target, options.travel_min);
        EXPECT_LE(move.target, options.travel_max);
        if (move.pass >= 0) {
            const auto& pass = plan.passes[static_cast<std::size_t>(move.pass)];
            EXPECT_NEAR(std::abs(move.target - pass.center_position), pass.stroke / 2.0, 1e-12);
            EXPECT_DOUBLE_EQ(move.feed, pass.feed);
        }
    }
    // The duration is the sum of the move durations (rest to rest) and dwells, the first positioning move excluded.
    double duration = 0.0;
    double position = plan.moves.front().target;
    for (const auto& move : plan.moves) {
        if (move.kind == feedid::MoveKind::dwell) {
            duration += move.dwell;
        } else {
            duration +=
                feedid::move_duration(std::abs(move.target - position), move.feed, options.acceleration, options.jerk);
            position = move.target;
        }
    }
    EXPECT_NEAR(plan.duration, duration, 1e-9);
    EXPECT_GT(plan.duration, 60.0);
    EXPECT_LT(plan.duration, 600.0);
}

TEST(TestPlan, RefusesMovesOutsideTheTravelNamingTheMove) {
    auto options = options_at({-0.39});
    options.slow_feeds.clear();
    const auto message = message_of(options);
    ASSERT_FALSE(message.empty());
    EXPECT_NE(message.find("move 1 "), std::string::npos) << message;  // the very first positioning move
    EXPECT_NE(message.find("5.000 mm beyond the travel minimum -400.000 mm"), std::string::npos) << message;

    options = options_at({0.39});
    options.slow_feeds.clear();
    const auto upper = message_of(options);
    EXPECT_NE(upper.find("move 3 "), std::string::npos) << upper;  // positioning, dwell, first stroke +
    EXPECT_NE(upper.find("stroke +"), std::string::npos) << upper;
    EXPECT_NE(upper.find("goes to 405.000 mm, 5.000 mm beyond the travel maximum 400.000 mm"), std::string::npos)
        << upper;
}

TEST(TestPlan, RefusesFeedsAboveTheLimitNamingTheMove) {
    auto options = options_at({0.0});
    options.max_feed = 9000 * mm_per_min;
    const auto message = message_of(options);
    EXPECT_NE(message.find("9350 mm/min, 350 mm/min above the feedrate limit 9000 mm/min"), std::string::npos)
        << message;
    EXPECT_NE(message.find("move "), std::string::npos);
}

TEST(TestPlan, RefusesInvalidOptions) {
    auto options = options_at({});
    EXPECT_NE(message_of(options).find("no centres"), std::string::npos);
    options = options_at({0.0});
    options.travel_max = options.travel_min;
    EXPECT_NE(message_of(options).find("travel"), std::string::npos);
    options = options_at({0.0});
    options.cycles = 0;
    EXPECT_NE(message_of(options).find("cycles"), std::string::npos);
    options = options_at({0.0});
    options.feeds = {-1.0};
    EXPECT_NE(message_of(options).find("feedrate"), std::string::npos);
}

TEST(TestPlan, ReferenceTrajectoryFollowsTheMovesWithinTheLimits) {
    for (const std::optional<double> jerk : {std::optional<double>{}, std::optional<double>{40.0}}) {
        auto options = options_at({-0.2, 0.1});
        options.slow_feeds = feedid::log_spaced_feeds(10 * mm_per_min, 1000 * mm_per_min, 3);
        options.jerk = jerk;
        const auto plan = feedid::make_test_plan(options);
        const auto trace = feedid::reference_trajectory(plan);
        const auto t = trace.column(feedid::Role::time);
        const auto x = trace.column(feedid::Role::reference_position);
        const double dt = options.sample_time;
        EXPECT_NEAR(t.back(), plan.duration + 1.0, dt);  // 0.5 s at rest before and after
        EXPECT_DOUBLE_EQ(x.front(), plan.moves.front().target);
        double peak_speed = 0.0;
        double peak_acceleration = 0.0;
        for (std::size_t k = 1; k + 1 < x.size(); ++k) {
            peak_speed = std::max(peak_speed, std::abs(x[k + 1] - x[k - 1]) / (2 * dt));
            peak_acceleration = std::max(peak_acceleration, std::abs(x[k + 1] - 2 * x[k] + x[k - 1]) / (dt * dt));
        }
        EXPECT_LE(peak_speed, 9350 * mm_per_min * (1 + 1e-9));
        EXPECT_GE(peak_speed, 9350 * mm_per_min * 0.999);
        // A second difference across an acceleration step averages it, so the bound holds for both profiles.
        EXPECT_LE(peak_acceleration, options.acceleration * (1 + 1e-6));
        // Each move's target is reached and held through its dwell.
        for (const auto& move : plan.moves) {
            if (move.kind != feedid::MoveKind::feed) continue;
            const bool reached =
                std::any_of(x.begin(), x.end(), [&](double p) { return std::abs(p - move.target) < 1e-12; });
            EXPECT_TRUE(reached) << move.description;
        }
    }
}

TEST(TestPlan, ReferenceFileReadsBackWithGuessedRoles) {
    auto options = options_at({0.0});
    options.slow_feeds.clear();
    options.feeds = {2000 * mm_per_min};
    const auto plan = feedid::make_test_plan(options);
    const auto text = feedid::write_csv(feedid::reference_trajectory(plan));
    auto trace = feedid::parse_csv(text, "ref.csv");
    feedid::prepare_trace(trace, {});
    ASSERT_TRUE(trace.has(feedid::Role::time));
    ASSERT_TRUE(trace.has(feedid::Role::reference_position));
    EXPECT_EQ(trace.find(feedid::Role::reference_position)->unit, "m");
    EXPECT_NEAR(trace.time_base().sample_time_s, options.sample_time, 1e-12);
}

TEST(TestPlan, PredictionWithSlowPassesIdentifiesEveryParameter) {
    const auto plan = feedid::make_test_plan(options_at({-0.3}));
    const auto prediction = feedid::predict_identifiability(plan);
    for (const auto* key : {"mass_kg", "viscous_Ns_per_m", "coulomb_N", "breakaway_N", "stribeck_velocity_m_per_s"}) {
        const auto* p = prediction.find(key);
        ASSERT_NE(p, nullptr) << key;
        EXPECT_TRUE(p->identifiable) << key << " +- " << p->standard_error;
    }
    EXPECT_GT(prediction.step1_condition_number, 1.0);
    EXPECT_TRUE(std::isfinite(prediction.step1_condition_number));
    EXPECT_LT(prediction.find("breakaway_N")->standard_error, 0.05 * 946.2);
    EXPECT_LT(prediction.find("stribeck_velocity_m_per_s")->standard_error, 0.15 * 0.005);
}

TEST(TestPlan, PredictionForThePapersLadderAloneRefusesStribeck) {
    auto options = options_at({-0.3});
    options.slow_feeds.clear();
    const auto prediction = feedid::predict_identifiability(feedid::make_test_plan(options));
    EXPECT_TRUE(prediction.find("mass_kg")->identifiable);
    EXPECT_TRUE(prediction.find("coulomb_N")->identifiable);
    EXPECT_FALSE(prediction.find("breakaway_N")->identifiable);
    EXPECT_FALSE(prediction.find("stribeck_velocity_m_per_s")->identifiable);
    EXPECT_NEAR(prediction.slowest_cruise_speed, 1250 * mm_per_min, 1e-12);
    const bool says_why = std::any_of(prediction.diagnostics.begin(), prediction.diagnostics.end(), [](const auto& d) {
        return d.find("F_B and v_s are not identifiable") != std::string::npos &&
               d.find("slow passes") != std::string::npos;
    });
    EXPECT_TRUE(says_why);
}

// The command line's spellings: what each option accepts, in SI, and the message that names the option otherwise.
std::string parse_message(const std::function<void()>& parse) {
    try {
        parse();
    } catch (const feedid::InputError& e) {
        return e.what();
    }
    return {};
}

TEST(TestPlanText, ParsesTravelListsAndFeedSpellings) {
    const auto [low, high] = feedid::parse_travel("-400:400.5");
    EXPECT_DOUBLE_EQ(low, -400 * mm);
    EXPECT_DOUBLE_EQ(high, 400.5 * mm);
    const auto centers = feedid::parse_number_list({"-300", "0", "3e2"}, "--centers", mm);
    ASSERT_EQ(centers.size(), 3u);
    EXPECT_DOUBLE_EQ(centers[2], 300 * mm);
    EXPECT_TRUE(feedid::parse_feeds({"none"}).empty());
    EXPECT_DOUBLE_EQ(feedid::parse_feeds({"1250", "9350"}).back(), 9350 * mm_per_min);
    EXPECT_TRUE(feedid::parse_slow_feeds({"none"}).empty());
    EXPECT_EQ(feedid::parse_slow_feeds({"10:1000"}), feedid::log_spaced_feeds(10 * mm_per_min, 1000 * mm_per_min, 7));
    EXPECT_EQ(feedid::parse_slow_feeds({"10:1000:3"}).size(), 3u);
    EXPECT_DOUBLE_EQ(feedid::parse_slow_feeds({"5", "20"}).front(), 5 * mm_per_min);
}

TEST(TestPlanText, RefusalsNameTheOptionAndTheText) {
    using feedid::parse_slow_feeds;
    EXPECT_EQ(parse_message([] { (void)feedid::parse_travel("-400"); }), "--travel: '-400' is not MIN:MAX [mm].");
    EXPECT_EQ(parse_message([] { (void)feedid::parse_travel("-400:inf"); }), "--travel: 'inf' is not a number.");
    EXPECT_EQ(parse_message([] {
                  (void)feedid::parse_number_list({"0", " 1"}, "--centers", mm);
              }),
              "--centers: ' 1' is not a number.");
    EXPECT_EQ(parse_message([] { (void)feedid::parse_number_list({""}, "--centers", mm); }),
              "--centers: empty entry in ''.");
    EXPECT_EQ(parse_message([] { (void)feedid::parse_feeds({"none", "5"}); }), "--feeds: 'none' is not a number.");
    EXPECT_EQ(parse_message([] { (void)parse_slow_feeds({"10:"}); }), "--slow-feeds: '' is not a number.");
    EXPECT_EQ(parse_message([] { (void)parse_slow_feeds({"1:2:3:4"}); }),
              "--slow-feeds: '1:2:3:4' is not LO:HI or LO:HI:N (mm/min).");
    EXPECT_EQ(parse_message([] { (void)parse_slow_feeds({"1000:10"}); }),
              "--slow-feeds: '1000:10' needs 0.001 <= LO <= HI <= 1e+06 mm/min and a whole N from 1 to 100.");
    // absurd values are refused with the allowed range, not left to run out of memory
    EXPECT_EQ(parse_message([] { (void)parse_slow_feeds({"10:1000:1e12"}); }),
              "--slow-feeds: '10:1000:1e12' needs 0.001 <= LO <= HI <= 1e+06 mm/min and a whole N from 1 to 100.");
    EXPECT_EQ(parse_message([] {
                  (void)parse_slow_feeds({"5", "1e300"});
              }),
              "--slow-feeds: 1e+300 mm/min is outside the allowed range 0.001 to 1e+06 mm/min.");
    EXPECT_EQ(parse_message([] { (void)feedid::parse_travel("-1e300:400"); }),
              "--travel: '-1e300:400' reaches past the allowed range -1e+06 to 1e+06 mm.");
}

TEST(TestPlan, DocumentHoldsEveryPassAndNullForUndeterminedErrors) {
    auto options = options_at({-0.3, 0.3});
    options.slow_feeds.clear();
    const auto plan = feedid::make_test_plan(options);
    const auto prediction = feedid::predict_identifiability(plan);
    const auto document = feedid::plan_document(plan, prediction);
    EXPECT_EQ(document.at("centers_m").size(), 2u);
    ASSERT_EQ(document.at("passes").size(), plan.passes.size());
    EXPECT_EQ(document.at("passes").at(0).at("center"), 1);
    EXPECT_NEAR(document.at("passes").at(0).at("feed_mm_per_min").get<double>(), 1250.0, 1e-9);
    EXPECT_EQ(document.at("blocks"), plan.moves.size());
    const auto& parameters = document.at("prediction").at("parameters");
    EXPECT_TRUE(parameters.at("mass_kg").at("stderr").is_number());
    EXPECT_EQ(parameters.at("breakaway_N").at("identifiable"), false);
}

// A rotary axis (A, B, C): the same test in degrees and deg/min, every quantity in rad inside, and the prediction for
// the rotary demo table keyed as identify keys a rotary result.
TEST(TestPlan, ARotaryAxisIsPlannedInDegreesWithRadiansInside) {
    constexpr double deg = M_PI / 180.0;
    auto options = feedid::default_plan_options("C");
    ASSERT_TRUE(options.units().rotary);
    EXPECT_FALSE(feedid::default_plan_options("X").units().rotary);
    EXPECT_TRUE(feedid::is_rotary_axis("A1"));
    EXPECT_FALSE(feedid::is_rotary_axis("X1"));
    EXPECT_NEAR(options.stroke, 30.0 * deg, 1e-15);
    EXPECT_NEAR(options.feeds.front(), 1250.0 * deg / 60.0, 1e-15);
    EXPECT_NEAR(options.feeds.back(), 9350.0 * deg / 60.0, 1e-15);
    EXPECT_NEAR(options.acceleration, 1000.0 * deg, 1e-12);
    options.travel_min = -M_PI;
    options.travel_max = M_PI;
    options.centers = {0.0, 120.0 * deg};
    const auto plan = feedid::make_test_plan(options);
    ASSERT_FALSE(plan.moves.empty());
    EXPECT_NE(plan.moves.front().description.find("centre 1 at 0.000 deg"), std::string::npos)
        << plan.moves.front().description;
    EXPECT_NE(plan.moves.front().description.find("deg/min"), std::string::npos);
    for (const auto& note : plan.notes) EXPECT_EQ(note.find("mm"), std::string::npos) << note;
    // a slow stroke is a whole number of 0.01 deg
    for (const auto& pass : plan.passes) {
        if (!pass.slow) continue;
        EXPECT_NEAR(pass.stroke / (0.01 * deg), std::round(pass.stroke / (0.01 * deg)), 1e-6);
    }

    const auto reference = feedid::reference_trajectory(plan);
    EXPECT_TRUE(reference.rotary);
    EXPECT_EQ(reference.find(feedid::Role::reference_position)->unit, "rad");

    feedid::PredictionOptions nominal;
    nominal.drive = feedid::nominal_demo_drive(true);
    nominal.force_noise = 0.04;
    nominal.level_error = 0.135;
    nominal.position_resolution = 1e-3 * deg;
    const auto prediction = feedid::predict_identifiability(plan, nominal);
    for (const auto* key :
         {"inertia_kgm2", "viscous_Nms_per_rad", "coulomb_Nm", "breakaway_Nm", "stribeck_velocity_rad_per_s"}) {
        const auto* p = prediction.find(key);
        ASSERT_NE(p, nullptr) << key;
        EXPECT_TRUE(p->identifiable) << key << " +- " << p->standard_error;
    }
    // the linear demo drive is not a nominal for a rotary axis
    EXPECT_NE(parse_message([&] { (void)feedid::predict_identifiability(plan); }).find("nominal drive is linear"),
              std::string::npos);

    const auto document = feedid::plan_document(plan, prediction);
    EXPECT_EQ(document.at("rotary"), true);
    EXPECT_EQ(document.at("centers_rad").size(), 2u);
    EXPECT_FALSE(document.contains("centers_m"));
    const auto& first = document.at("passes").at(0);
    EXPECT_NEAR(first.at("feed_deg_per_min").get<double>(), 10.0, 1e-9);
    EXPECT_NEAR(first.at("feed_rad_per_s").get<double>(), 10.0 * deg / 60.0, 1e-15);
    EXPECT_TRUE(document.at("prediction").contains("slowest_cruise_speed_rad_per_s"));

    // refusals speak degrees
    options.travel_max = 100.0 * deg;
    EXPECT_NE(message_of(options).find("deg beyond the travel maximum 100.000 deg"), std::string::npos)
        << message_of(options);
}

}  // namespace
