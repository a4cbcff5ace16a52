// One stick-slip rule: identify's rule without a reference (detect_stick_slip over the whole trace) and the online
// identifier's (the same StickSlipTracker over its stream, window after window, with the same StickSlipOptions) find
// the same stick-slip on the same traces: the demo drive's test with its slow passes, which stick and slip below about
// 100 mm/min, and the same test without them. And the rule itself on hand-made velocities: brief stops and bursts are
// stick-slip, dwells and moves of production length are not.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <fmt/core.h>

#include "feedid/identify/online_identifier.hpp"
#include "feedid/identify/preprocess.hpp"
#include "feedid/identify/selection.hpp"
#include "feedid/identify/stick_slip.hpp"
#include "feedid/model/drive.hpp"
#include "feedid/sim/synth.hpp"

namespace feedid {
namespace {

/// A stretch of samples [first_s, last_s].
struct Span {
    double first_s, last_s;
};

bool overlap(const Span& a, const Span& b) {
    return a.first_s <= b.last_s && b.first_s <= a.last_s;
}

/// The demo test (with or without its slow passes) as a trace without a reference: the position and the current only,
/// as production recordings often are.
struct DemoTrace {
    Trace trace;
    std::vector<double> force;
};

DemoTrace demo_trace(bool slow_passes, bool reference) {
    SynthSpec spec = demo_spec();
    spec.test.slow_passes = slow_passes;
    DemoTrace demo{synthesize(spec), {}};
    for (auto& channel : demo.trace.channels) {
        if (!reference && (channel.role == Role::reference_position || channel.role == Role::velocity_command))
            channel.role = Role::other;
    }
    DriveConstants drive;
    drive.force_constant = spec.force_constant_N_per_A();
    demo.force = drive_force(demo.trace, drive);
    return demo;
}

DemoTrace demo_without_reference(bool slow_passes) {
    return demo_trace(slow_passes, false);
}

/// The stretches identify leaves out as stick-slip by the rule with a reference (the commanded speed), at selection's
/// moving threshold (the commanded speeds of the slow passes lie below the online identifier's).
std::vector<Span> by_reference(const DemoTrace& demo) {
    const Derivatives d = preprocess(demo.trace, demo.force, PreprocessOptions{});
    EXPECT_FALSE(d.reference_velocity.empty());
    const StickSlip found = detect_stick_slip(d, SelectionOptions{}.rest_noise_multiple * d.velocity_noise);
    std::vector<Span> spans;
    for (std::size_t k = 0; k < d.size(); ++k) {
        if (!found.flags[k]) continue;
        if (k == 0 || !found.flags[k - 1]) spans.push_back({d.time[k], d.time[k]});
        spans.back().last_s = d.time[k];
    }
    return spans;
}

/// identify's verdict: the stick-slip passes of the whole trace, as time spans, with their speeds [m/s].
struct BatchVerdict {
    std::vector<Span> segments;
    std::vector<double> speeds;
    std::size_t passes{0};
};

BatchVerdict batch(const DemoTrace& demo, const OnlineOptions& options) {
    const Derivatives d = preprocess(demo.trace, demo.force, PreprocessOptions{});
    EXPECT_TRUE(d.reference_velocity.empty());
    const StickSlip found = detect_stick_slip(d, options.moving_threshold, options.stick_slip);
    BatchVerdict out;
    out.passes = found.passes.size();
    for (const MotionPass& pass : found.passes) {
        if (!pass.stick_slip) continue;
        out.segments.push_back({d.time[pass.first], d.time[pass.last - 1]});
        out.speeds.push_back(pass.speed);
    }
    return out;
}

/// The online identifier's windows, as each was judged (pushed one sample at a time to see each one).
std::vector<WindowRecord> online_windows(const DemoTrace& demo, const OnlineOptions& options) {
    const auto t = demo.trace.column(Role::time);
    const auto x = demo.trace.column(Role::position);
    OnlineIdentifier online(options);
    std::vector<WindowRecord> windows;
    const auto note = [&] {
        const auto w = online.last_window();
        if (w && (windows.empty() || windows.back().first_s != w->first_s)) windows.push_back(*w);
    };
    for (std::size_t k = 0; k < t.size(); ++k) {
        online.push(t[k], x[k], demo.force[k]);
        note();
    }
    online.flush();
    note();
    return windows;
}

TEST(StickSlip, OnlineWindowsAndIdentifyPassesAgreeOnTheDemoTestsSlowPasses) {
    const OnlineOptions options;  // the default moving threshold and stick-slip options, for both
    const DemoTrace demo = demo_without_reference(true);
    const BatchVerdict passes = batch(demo, options);
    const std::vector<WindowRecord> windows = online_windows(demo, options);
    fmt::print("identify: {} of {} passes stick-slip:", passes.segments.size(), passes.passes);
    for (std::size_t i = 0; i < passes.segments.size(); ++i)
        fmt::print(" {:.2f}-{:.2f} s ({:.3g} mm/s)", passes.segments[i].first_s, passes.segments[i].last_s,
                   1e3 * passes.speeds[i]);
    fmt::print("\nonline windows with stick-slip:");
    for (const auto& w : windows)
        if (w.stick_slip) fmt::print(" {:.2f}-{:.2f} s ({})", w.first_s, w.last_s, verdict_name(w.verdict));
    fmt::print("\n");

    // the demo's slow passes stick and slip below 100 mm/min (10 to 56 mm/min with its reference, 8 passes)
    ASSERT_GE(passes.segments.size(), 6U);
    const double feed_100_mm_per_min = 0.1 / 60.0;
    for (const double speed : passes.speeds) EXPECT_LT(speed, feed_100_mm_per_min);
    // ... and they lie where the rule with a reference finds stick-slip (the commanded speed, before it was removed)
    const std::vector<Span> commanded = by_reference(demo_trace(true, true));
    for (const Span& c : commanded) fmt::print("left out with the reference: {:.2f}-{:.2f} s\n", c.first_s, c.last_s);
    for (const Span& s : passes.segments) {
        const bool inside = std::any_of(commanded.begin(), commanded.end(),
                                        [&](const Span& c) { return c.first_s <= s.first_s && s.last_s <= c.last_s; });
        EXPECT_TRUE(inside) << s.first_s << "-" << s.last_s << " s: not stick-slip by the commanded speed";
    }
    // the same segments: every pass identify finds lies in a window the online identifier finds it in, and every such
    // window holds one of identify's passes
    std::size_t flagged = 0, rejected_as_stick_slip = 0;
    for (const auto& w : windows) {
        if (w.verdict == WindowVerdict::stick_slip) {
            EXPECT_TRUE(w.stick_slip);
        }
        if (!w.stick_slip) continue;
        ++flagged;
        // a window the rule finds stick-slip is rejected for it, unless a test that comes first rejected it already
        if (w.verdict == WindowVerdict::stick_slip) {
            ++rejected_as_stick_slip;
        } else {
            EXPECT_TRUE(w.verdict == WindowVerdict::at_rest || w.verdict == WindowVerdict::saturation)
                << verdict_name(w.verdict) << " at " << w.first_s << " s";
        }
        const bool held = std::any_of(passes.segments.begin(), passes.segments.end(), [&](const Span& s) {
            return overlap(s, {w.first_s, w.last_s});
        });
        EXPECT_TRUE(held) << "online window " << w.first_s << "-" << w.last_s << " s: no stick-slip pass of identify's";
    }
    for (const Span& s : passes.segments) {
        const bool found = std::any_of(windows.begin(), windows.end(), [&](const WindowRecord& w) {
            return w.stick_slip && overlap(s, {w.first_s, w.last_s});
        });
        EXPECT_TRUE(found) << "identify's stick-slip pass " << s.first_s << "-" << s.last_s
                           << " s: in no online window";
    }
    EXPECT_GT(flagged, 0U);
    EXPECT_GT(rejected_as_stick_slip, 0U);
}

TEST(StickSlip, NeitherFindsAnyInTheDemoTestWithoutSlowPasses) {
    const OnlineOptions options;
    const DemoTrace demo = demo_without_reference(false);
    const BatchVerdict passes = batch(demo, options);
    const std::vector<WindowRecord> windows = online_windows(demo, options);
    EXPECT_GE(passes.passes, 10U);  // the strokes are there, and judged
    EXPECT_TRUE(passes.segments.empty());
    EXPECT_GE(windows.size(), 7U);
    for (const auto& w : windows) {
        EXPECT_FALSE(w.stick_slip) << w.first_s << "-" << w.last_s << " s";
        EXPECT_NE(w.verdict, WindowVerdict::stick_slip);
    }
}

/// A velocity at 1 kHz: each piece a speed [m/s] held for a duration [s].
std::vector<double> pieces(std::initializer_list<std::pair<double, double>> speed_and_duration) {
    std::vector<double> v;
    for (const auto& [speed, duration] : speed_and_duration)
        v.insert(v.end(), static_cast<std::size_t>(std::lround(duration * 1000.0)), speed);
    return v;
}

std::vector<MotionPass> track(const std::vector<double>& velocity, const StickSlipOptions& options = {}) {
    StickSlipTracker tracker(1e-3, options);
    std::vector<MotionPass> passes;
    for (std::size_t k = 0; k < velocity.size(); ++k) {
        if (auto ended = tracker.add(1e-3 * static_cast<double>(k), velocity[k])) passes.push_back(*ended);
    }
    if (auto ended = tracker.finish()) passes.push_back(*ended);
    return passes;
}

TEST(StickSlip, BriefStopsAndBurstsInOneDirectionAreStickSlip) {
    // three slips of 20 ms at 5 mm/s with stops of 40 ms between them, then a reversal
    const auto passes = track(pieces({{0.0, 0.1},
                                      {0.005, 0.02},
                                      {0.0, 0.04},
                                      {0.005, 0.02},
                                      {0.0, 0.04},
                                      {0.005, 0.02},
                                      {0.0, 0.1},
                                      {-0.005, 0.5}}));
    ASSERT_EQ(passes.size(), 2U);
    EXPECT_TRUE(passes[0].stick_slip);
    EXPECT_EQ(passes[0].direction, 1);
    EXPECT_EQ(passes[0].first, 100U);
    EXPECT_EQ(passes[0].last, 100U + 20 + 40 + 20 + 40 + 20);
    EXPECT_FALSE(passes[1].stick_slip);
    EXPECT_EQ(passes[1].direction, -1);
}

TEST(StickSlip, DwellsAndMovesOfProductionLengthAreNot) {
    // feed moves of 0.3 s between dwells of 0.1 s, all in one direction (a row of holes): the moves are too long
    EXPECT_FALSE(track(pieces({{0.02, 0.3}, {0.0, 0.1}, {0.02, 0.3}, {0.0, 0.1}, {0.02, 0.3}}))[0].stick_slip);
    // brief slips, but dwells of half a second between them
    EXPECT_FALSE(track(pieces({{0.005, 0.02}, {0.0, 0.5}, {0.005, 0.02}, {0.0, 0.5}, {0.005, 0.02}}))[0].stick_slip);
    // one stop only
    EXPECT_FALSE(track(pieces({{0.005, 0.02}, {0.0, 0.04}, {0.005, 0.02}}))[0].stick_slip);
    // a stop is relative to the burst before it: a dip to 30 % of 5 mm/s is no stop, one to 10 % is
    EXPECT_FALSE(
        track(pieces({{0.005, 0.02}, {0.0015, 0.04}, {0.005, 0.02}, {0.0015, 0.04}, {0.005, 0.02}}))[0].stick_slip);
    EXPECT_TRUE(
        track(pieces({{0.012, 0.02}, {0.0011, 0.04}, {0.012, 0.02}, {0.0011, 0.04}, {0.012, 0.02}}))[0].stick_slip);
}

TEST(StickSlip, TheTrackerSaysSoWhileThePassRuns) {
    StickSlipTracker tracker(1e-3, StickSlipOptions{});
    const auto v = pieces({{0.005, 0.02}, {0.0, 0.04}, {0.005, 0.02}, {0.0, 0.04}, {0.005, 0.02}});
    for (std::size_t k = 0; k < v.size(); ++k) tracker.add(1e-3 * static_cast<double>(k), v[k]);
    EXPECT_TRUE(tracker.stick_slipping());
    ASSERT_TRUE(tracker.current());
    EXPECT_EQ(tracker.current()->last, v.size());
    EXPECT_EQ(tracker.samples(), v.size());
    EXPECT_TRUE(tracker.finish()->stick_slip);
    EXPECT_FALSE(tracker.current());
    EXPECT_FALSE(tracker.stick_slipping());
}

}  // namespace
}  // namespace feedid
