#include "feedid/core/trace.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "feedid/core/error.hpp"

using namespace feedid;

namespace {
Trace make_trace(std::vector<double> time, std::vector<double> position) {
    Trace trace;
    trace.source_path = "test.csv";
    trace.set("t", Role::time, "s", std::move(time));
    trace.set("x", Role::position, "m", std::move(position));
    return trace;
}
}  // namespace

TEST(Trace, ReportsSampleTimeAndDuration) {
    Trace trace = make_trace({0.0, 0.001, 0.002, 0.003}, {0, 1, 2, 3});
    trace.validate();
    const auto base = trace.time_base();
    EXPECT_NEAR(base.sample_time_s, 0.001, 1e-15);
    EXPECT_NEAR(base.duration_s, 0.003, 1e-15);
    EXPECT_FALSE(base.jittery);
    EXPECT_TRUE(trace.findings.empty());
    EXPECT_EQ(trace.samples(), 4u);
}

TEST(Trace, RejectsTimeThatDoesNotIncrease) {
    Trace trace = make_trace({0.0, 0.001, 0.001, 0.003}, {0, 1, 2, 3});
    try {
        trace.validate();
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("sample 3"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("test.csv"), std::string::npos) << e.what();
    }
}

TEST(Trace, RejectsNonFiniteValuesInRoleChannels) {
    Trace trace = make_trace({0.0, 0.001, 0.002}, {0, std::numeric_limits<double>::quiet_NaN(), 2});
    EXPECT_THROW(trace.validate(), InputError);
    // ... but not in channels without a role
    Trace other = make_trace({0.0, 0.001, 0.002}, {0, 1, 2});
    other.set("note", Role::other, "", {1, std::numeric_limits<double>::quiet_NaN(), 3});
    EXPECT_NO_THROW(other.validate());
}

TEST(Trace, RejectsColumnsOfDifferentLength) {
    Trace trace = make_trace({0.0, 0.001, 0.002}, {0, 1});
    EXPECT_THROW(trace.validate(), InputError);
}

TEST(Trace, ReportsJitterWithItsFigures) {
    Trace trace = make_trace({0.0, 0.001, 0.0021, 0.003, 0.004}, {0, 1, 2, 3, 4});
    trace.validate();
    const auto base = trace.time_base();
    EXPECT_TRUE(base.jittery);
    EXPECT_NEAR(base.max_deviation_s, 0.0001, 1e-12);
    ASSERT_EQ(trace.findings.size(), 1u);
    EXPECT_NE(trace.findings[0].find("jittery"), std::string::npos);
}

TEST(Trace, SetReplacesTheRoleHolder) {
    Trace trace = make_trace({0.0, 0.001}, {0, 1});
    trace.set("x2", Role::position, "m", {5, 6});
    EXPECT_EQ(trace.find(Role::position)->name, "x2");
    EXPECT_EQ(trace.find("x")->role, Role::other);
}

TEST(Trace, ColumnOfMissingRoleNamesTheRole) {
    Trace trace = make_trace({0.0, 0.001}, {0, 1});
    try {
        (void)trace.column(Role::current);
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("current"), std::string::npos);
    }
}

TEST(Trace, SampleTimeIsNotBiasedByRoundedTimeStamps) {
    // time stamps rounded to single precision, as a logger with float time writes them: the steps alternate between
    // two values either side of 1 ms, and the median alone would pick one of them
    std::vector<double> time;
    std::vector<double> position;
    for (int k = 0; k <= 30000; ++k) {
        time.push_back(static_cast<double>(static_cast<float>(k * 0.001)));
        position.push_back(0.0);
    }
    Trace trace = make_trace(time, position);
    trace.validate();
    const auto base = trace.time_base();
    EXPECT_NEAR(base.sample_time_s, 0.001, 1e-9);  // (30 s - 0 s) / 30000 steps, to float rounding of 30 s
    EXPECT_NEAR(base.duration_s, 30.0, 1e-6);
    EXPECT_FALSE(base.jittery);  // float steps deviate by < 2e-6 s, far below 1 %
}

TEST(Trace, SampleTimeIgnoresAGapButTheGapIsReported) {
    // 1 ms samples with one sample missing after 0.1 s
    std::vector<double> time;
    for (int k = 0; k <= 200; ++k) {
        if (k != 101) time.push_back(k * 0.001);
    }
    Trace trace = make_trace(time, std::vector<double>(time.size(), 0.0));
    trace.validate();
    const auto base = trace.time_base();
    EXPECT_NEAR(base.sample_time_s, 0.001, 1e-15);
    EXPECT_NEAR(base.max_deviation_s, 0.001, 1e-12);  // the 2 ms step
    EXPECT_TRUE(base.jittery);
    ASSERT_EQ(trace.findings.size(), 1u);
    EXPECT_NE(trace.findings[0].find("0.001"), std::string::npos) << trace.findings[0];
}

// A memo computes nothing when it is made (import makes one before the time column is checked): the first request
// computes the time base and the later ones, while the memo lives, return that one. Changing the column in place
// shows which pass was taken.
TEST(Trace, TimeBaseMemoKeepsWhatTheFirstRequestComputed) {
    Trace trace = make_trace({0.0, 0.001, 0.002, 0.003, 0.004}, {0, 1, 2, 3, 4});
    auto& time = trace.find(Role::time)->values;
    {
        const TimeBaseMemo memo(trace);
        time[2] = 0.0025;  // after the memo was made, before any request
        const double first = trace.time_base().max_deviation_s;
        EXPECT_NEAR(first, 0.0005, 1e-12) << "the column as it is at the first request";
        time[2] = 0.002;
        EXPECT_EQ(trace.time_base().max_deviation_s, first) << "remembered while the memo lives";
    }
    EXPECT_NEAR(trace.time_base().max_deviation_s, 0.0, 1e-15) << "computed again once it is gone";
}
