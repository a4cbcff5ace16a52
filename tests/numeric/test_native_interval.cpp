// Native intervals: sample-and-hold detection on constructed signals (held ones and the look-alikes that are not),
// the interpolation of a held signal, and what import and `feedid info` make of them.
#include <cmath>
#include <random>
#include <vector>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"
#include "feedid/numeric/native_interval.hpp"
#include "testing.hpp"

namespace {

using feedid::detect_sample_and_hold;

// A smooth motion sampled every `factor` grid samples (from `phase` on) and held in between.
std::vector<double> held(const std::vector<double>& signal, int factor, int phase) {
    std::vector<double> out(signal.size());
    double value = signal.front();
    for (std::size_t j = 0; j < signal.size(); ++j) {
        if (static_cast<int>(j % static_cast<std::size_t>(factor)) == phase % factor) value = signal[j];
        out[j] = value;
    }
    return out;
}

// Back-and-forth moves with dwells: x(t) in m on a 2 ms grid, quantised to `quantum`.
std::vector<double> strokes(std::size_t n, double quantum, double amplitude = 0.05) {
    std::vector<double> x(n);
    for (std::size_t j = 0; j < n; ++j) {
        const double t = 2e-3 * static_cast<double>(j);
        const double raw = amplitude * std::sin(2.0 * M_PI * 0.5 * t);
        x[j] = quantum > 0.0 ? quantum * std::round(raw / quantum) : raw;
    }
    return x;
}

TEST(SampleAndHold, FindsTheFactorAndPhaseOfAHeldSignal) {
    const auto x = strokes(5000, 1e-8);
    for (const int factor : {2, 3, 4, 8}) {
        for (const int phase : {0, 1}) {
            const auto hold = detect_sample_and_hold(held(x, factor, phase));
            ASSERT_TRUE(hold) << "factor " << factor << ", phase " << phase;
            EXPECT_EQ(hold->factor, factor);
            EXPECT_EQ(hold->phase, phase % factor);
            EXPECT_EQ(hold->off_grid, 0u);
        }
    }
}

TEST(SampleAndHold, ASignalOnTheGridIsNotHeld) {
    EXPECT_FALSE(detect_sample_and_hold(strokes(5000, 1e-8)));
    // Noise: a current sensor at 5 mA with 20 mA noise repeats values now and then, at random.
    std::mt19937_64 generator(3);
    std::normal_distribution<double> noise(0.0, 0.02);
    std::vector<double> current(5000);
    for (auto& i : current) i = 0.005 * std::round((1.0 + noise(generator)) / 0.005);
    EXPECT_FALSE(detect_sample_and_hold(current));
}

TEST(SampleAndHold, AQuantisedPositionAtCreepSpeedIsNotHeld) {
    // 1 um encoder at 0.25 mm/s on a 2 ms grid: one step every second sample, exactly: the values repeat in pairs as
    // if held, but every step is one quantum. Then faster moves, where it changes at every sample.
    std::vector<double> x;
    double position = 0.0;
    for (int j = 0; j < 4000; ++j) {
        position += 0.25e-3 * 2e-3;
        x.push_back(1e-6 * std::round(position / 1e-6));
    }
    EXPECT_FALSE(detect_sample_and_hold(x)) << "creep alone: one-quantum steps are no evidence";
    for (int j = 0; j < 2000; ++j) {
        position += 20e-3 * 2e-3 * std::sin(j * 0.01);
        x.push_back(1e-6 * std::round(position / 1e-6));
    }
    EXPECT_FALSE(detect_sample_and_hold(x)) << "and where it moves, it changes at every sample";
}

TEST(SampleAndHold, StandstillsAndAFewExceptionsDoNotHideAHold) {
    auto x = strokes(6000, 1e-7);
    // a long standstill in the middle
    for (std::size_t j = 2000; j < 3500; ++j) x[j] = x[2000];
    auto h = held(x, 2, 0);
    // two samples off the grid (a dropped record)
    h[1001] = 0.5 * (h[1000] + h[1002]);
    h[4001] = 0.5 * (h[4000] + h[4002]);
    const auto hold = detect_sample_and_hold(h);
    ASSERT_TRUE(hold);
    EXPECT_EQ(hold->factor, 2);
    EXPECT_GE(hold->off_grid, 2u);
    EXPECT_LE(hold->off_grid, 4u);
    // ... but many exceptions do
    for (std::size_t j = 1; j < h.size(); j += 40) h[j] = h[j] + 3e-7;
    EXPECT_FALSE(detect_sample_and_hold(h));
}

// Changes at neighbouring samples rule a hold out before its factor is looked for (at most one of two neighbours lies
// on a grid of k >= 2): that shortcut must refuse exactly what the factor's own count of exceptions refuses. Each
// exception here is a change one sample after a grid change, the most the allowance admits, then one more; held by
// 2, each makes a run of three changes in a row (one off the grid), held by 4 a pair.
TEST(SampleAndHold, NeighbouringChangesRefuseExactlyWhatTheAllowanceRefuses) {
    for (const std::size_t factor : {2u, 4u}) {
        const auto h = held(strokes(8000, 1e-8), static_cast<int>(factor), 0);
        std::size_t on_grid = 0;
        std::vector<std::size_t> grid_changes;  // those followed by another change a whole hold later
        for (std::size_t j = 1; j < h.size(); ++j) {
            if (h[j] == h[j - 1]) continue;
            ++on_grid;
            if (j + factor < h.size() && h[j + factor] != h[j]) grid_changes.push_back(j);
        }
        std::size_t allowed = 0;  // the largest count of exceptions e with e <= 2 % of all changes
        while (static_cast<double>(allowed + 1) <= 0.02 * static_cast<double>(on_grid + allowed + 1)) ++allowed;
        ASSERT_GT(allowed, 10u);
        const auto with_exceptions = [&](std::size_t count) {
            auto out = h;
            for (std::size_t e = 0; e < count; ++e) {
                const std::size_t j = grid_changes[e * grid_changes.size() / count];
                for (std::size_t i = 1; i < factor; ++i) out[j + i] = h[j] + 3e-9;  // a change at j + 1, held
            }
            return out;
        };
        const auto hold = detect_sample_and_hold(with_exceptions(allowed));
        ASSERT_TRUE(hold) << "held by " << factor << ": " << allowed << " exceptions in " << on_grid + allowed;
        EXPECT_EQ(hold->factor, static_cast<int>(factor));
        EXPECT_EQ(hold->phase, 0);
        EXPECT_EQ(hold->off_grid, allowed);
        EXPECT_EQ(hold->changes, on_grid + allowed);
        EXPECT_FALSE(detect_sample_and_hold(with_exceptions(allowed + 1))) << "held by " << factor;
    }
}

TEST(SampleAndHold, TooLittleMotionSaysNothing) {
    std::vector<double> flat(3000, 1.5);
    EXPECT_FALSE(detect_sample_and_hold(flat));
    auto x = strokes(60, 1e-8);  // 30 changes held by 2, below the evidence needed ...
    feedid::HoldDetectionOptions demanding;
    demanding.minimum_moving_changes = 40;
    EXPECT_FALSE(detect_sample_and_hold(held(x, 2, 0), demanding));
    std::vector<double> with_nan = held(strokes(3000, 1e-8), 4, 1);
    for (std::size_t j = 0; j < 100; ++j) with_nan[j] = NAN;  // a signal that starts later
    const auto hold = detect_sample_and_hold(with_nan);
    ASSERT_TRUE(hold);
    EXPECT_EQ(hold->factor, 4);
}

TEST(SampleAndHold, InterpolationUndoesTheHoldOfASmoothSignal) {
    const auto x = strokes(3000, 0.0);
    const auto h = held(x, 4, 1);
    ASSERT_EQ(feedid::hold_phase(h, 4), 1);
    const auto back = feedid::interpolate_held(h, 4, 1);
    double largest_held = 0.0, largest_back = 0.0;
    for (std::size_t j = 1; j + 4 < x.size(); ++j) {
        largest_held = std::max(largest_held, std::abs(h[j] - x[j]));
        largest_back = std::max(largest_back, std::abs(back[j] - x[j]));
    }
    // Holding errs by up to 3 samples of motion (0.157 m/s * 6 ms); linear interpolation over 4 samples (8 ms) only
    // by the curvature: at most |x''| * (8 ms)^2 / 8 with |x''| <= 0.05 m * pi^2 /s^2.
    EXPECT_GT(largest_held, 0.9 * 0.05 * M_PI * 6e-3);
    EXPECT_LE(largest_back, 0.05 * M_PI * M_PI * 8e-3 * 8e-3 / 8.0 * (1.0 + 1e-9));
    EXPECT_GT(largest_back, 0.0);
}

TEST(NativeInterval, ImportDetectsAHeldCsvChannelAndInfoShowsIt) {
    const auto dir = feedid::testing::temp_dir();
    const auto x = strokes(3000, 1e-8);
    const auto x_held = held(x, 2, 0);
    std::string text = "t [s],x [mm],i [A]\n";
    for (std::size_t j = 0; j < x.size(); ++j)
        text += fmt::format("{},{},{}\n", 2e-3 * static_cast<double>(j), x_held[j] * 1e3, std::cos(0.01 * j));
    feedid::testing::write_text(dir / "held.csv", text);
    const auto trace = feedid::read_trace(dir / "held.csv");
    const auto* position = trace.find(feedid::Role::position);
    ASSERT_NE(position, nullptr);
    ASSERT_TRUE(position->native_interval_s);
    EXPECT_NEAR(*position->native_interval_s, 4e-3, 1e-12);
    EXPECT_EQ(position->interval_source, feedid::IntervalSource::detected);
    const auto* current = trace.find(feedid::Role::current);
    EXPECT_NEAR(current->native_interval_s.value_or(0.0), 2e-3, 1e-12);
    EXPECT_EQ(current->interval_source, feedid::IntervalSource::time_base);

    const auto info = feedid::testing::run_cli("info '" + (dir / "held.csv").string() + "' --json -");
    ASSERT_EQ(info.exit_code, 0) << info.err;
    const auto document = nlohmann::json::parse(info.out);
    bool seen = false;
    for (const auto& channel : document["channels"]) {
        if (channel["name"] != "x") continue;
        seen = true;
        EXPECT_NEAR(channel["native_interval_s"].get<double>(), 4e-3, 1e-12);
        EXPECT_EQ(channel["interval_source"], "detected");
    }
    EXPECT_TRUE(seen);
    const auto text_info = feedid::testing::run_cli("info '" + (dir / "held.csv").string() + "'");
    EXPECT_NE(text_info.out.find("4 ms (detected)"), std::string::npos) << text_info.out;
}

TEST(NativeInterval, SinumerikTraceStatesEachSignalsInterval) {
    FEEDID_REQUIRE_SHARED("sinumerik-trace/X_BK300_1.xml");
    const auto trace = feedid::read_trace(feedid::testing::shared_data() / "sinumerik-trace/X_BK300_1.xml");
    for (const auto& channel : trace.channels) {
        ASSERT_TRUE(channel.native_interval_s) << channel.name;
        EXPECT_NEAR(*channel.native_interval_s, 2e-3, 1e-12) << channel.name;
        if (channel.role != feedid::Role::time) {
            EXPECT_EQ(channel.interval_source, feedid::IntervalSource::format) << channel.name;
        }
    }
}

TEST(NativeInterval, TwinCatScopeStatesEachChannelGroupsSampleTime) {
    // An export with an oversampled channel (func_OS, 0.2 ms) beside 1 ms channels: the time base is the 0.2 ms one.
    FEEDID_REQUIRE_SHARED("twincat-scope/tc3_scope_3_4_3145_3-ContainEOF_true.csv");
    const auto trace =
        feedid::read_trace(feedid::testing::shared_data() / "twincat-scope/tc3_scope_3_4_3145_3-ContainEOF_true.csv");
    EXPECT_NEAR(trace.time_base().sample_time_s, 0.2e-3, 1e-9);
    const auto* oversampled = trace.find(std::string_view("func_OS"));
    const auto* bit = trace.find(std::string_view("var_BIT"));
    ASSERT_NE(oversampled, nullptr);
    ASSERT_NE(bit, nullptr);
    EXPECT_NEAR(oversampled->native_interval_s.value_or(0.0), 0.2e-3, 1e-9);
    EXPECT_NEAR(bit->native_interval_s.value_or(0.0), 1e-3, 1e-9);
    EXPECT_EQ(bit->interval_source, feedid::IntervalSource::format);
}

TEST(NativeInterval, EmpsIsSampledOnItsTimeBase) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto trace = feedid::read_trace(feedid::testing::shared_data() / "emps/DATA_EMPS.mat");
    const double sample_time = trace.time_base().sample_time_s;
    for (const auto& channel : trace.channels) {
        ASSERT_TRUE(channel.native_interval_s) << channel.name;
        EXPECT_DOUBLE_EQ(*channel.native_interval_s, sample_time) << channel.name;
    }
}

}  // namespace
