#include "feedid/plan/reversal_test.hpp"

#include <cmath>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "timeline.hpp"

namespace feedid {

std::string ReversalTestOptions::validate() const {
    const auto positive = [](double value) { return std::isfinite(value) && value > 0.0; };
    if (!(travel_max > travel_min) || !std::isfinite(travel_min) || !std::isfinite(travel_max))
        return "the travel's upper limit must be above its lower one";
    if (centers.empty()) return "no centre";
    if (!positive(micro_step) || micro_step > 1e-3) return "a micro-step must be above 0 and at most 1 mm (1 deg)";
    if (micro_steps < 1 || micro_steps > 1000) return "micro-steps each way: 1 to 1000";
    if (micro_cycles < 0 || micro_cycles > 100 || cycles < 0 || cycles > 100) return "cycles: 0 to 100";
    if (micro_cycles == 0 && (cycles == 0 || feeds.empty())) return "neither micro-steps nor strokes: nothing to do";
    if (!positive(micro_feed) || !positive(positioning_feed) || !positive(acceleration) || !positive(sample_time))
        return "feedrates, acceleration and sample time must be positive";
    for (const double feed : feeds) {
        if (!positive(feed)) return "every stroke feedrate must be positive";
    }
    if (!positive(stroke)) return "the stroke must be positive";
    if (!(micro_dwell >= 0.0) || !(dwell >= 0.0)) return "dwells must not be negative";
    return {};
}

ReversalTestOptions default_reversal_options(const std::string& axis) {
    ReversalTestOptions options;
    options.axis = axis;
    if (!is_rotary_axis(axis)) return options;
    // the same numbers in degrees, as a rotary axis is programmed
    const double scale = PlanUnits{true}.length() / PlanUnits{false}.length();
    options.travel_min *= scale;
    options.travel_max *= scale;
    for (double& centre : options.centers) centre *= scale;
    options.micro_step *= scale;
    options.micro_feed *= scale;
    for (double& feed : options.feeds) feed *= scale;
    options.stroke *= scale;
    options.acceleration *= PlanUnits{true}.acceleration();
    options.positioning_feed *= scale;
    return options;
}

namespace {

void feed_to(TestPlan& plan, double target, double feed, int center, std::string description) {
    Move move;
    move.kind = MoveKind::feed;
    move.target = target;
    move.feed = feed;
    move.center = center;
    move.description = std::move(description);
    plan.moves.push_back(std::move(move));
}

void dwell(TestPlan& plan, double seconds, int center) {
    if (seconds <= 0.0) return;
    Move move;
    move.kind = MoveKind::dwell;
    move.dwell = seconds;
    move.center = center;
    plan.moves.push_back(std::move(move));
}

// n steps forward, 2n back, n forward: a reversal at each end, back where it started.
void micro_steps(TestPlan& plan, const ReversalTestOptions& o, int center, double centre) {
    const PlanUnits u = o.units();
    double position = centre;
    for (int cycle = 0; cycle < o.micro_cycles; ++cycle) {
        for (const auto& [direction, count] :
             {std::pair{1, o.micro_steps}, std::pair{-1, 2 * o.micro_steps}, std::pair{1, o.micro_steps}}) {
            for (int step = 0; step < count; ++step) {
                position += direction * o.micro_step;
                feed_to(plan, position, o.micro_feed, center,
                        fmt::format("centre {} ({:g} {}), micro-step {}{:g} {}", center + 1, centre / u.length(),
                                    u.length_unit(), direction > 0 ? "+" : "-", o.micro_step / u.length() * 1e3,
                                    u.rotary ? "mdeg" : "um"));
                dwell(plan, o.micro_dwell, center);
            }
        }
    }
}

void strokes(TestPlan& plan, const ReversalTestOptions& o, int center, double centre) {
    const PlanUnits u = o.units();
    const double low = centre - 0.5 * o.stroke;
    const double high = centre + 0.5 * o.stroke;
    for (const double feed : o.feeds) {
        feed_to(plan, low, o.positioning_feed, center, "positioning");
        dwell(plan, o.dwell, center);
        for (int cycle = 0; cycle < o.cycles; ++cycle) {
            for (const double target : {high, low}) {
                feed_to(plan, target, feed, center,
                        fmt::format("centre {} ({:g} {}), {:g} {}, stroke {}", center + 1, centre / u.length(),
                                    u.length_unit(), feed / u.feed(), u.feed_unit(), target == high ? "+" : "-"));
                dwell(plan, o.dwell, center);
            }
        }
        feed_to(plan, centre, o.positioning_feed, center, "positioning");
        dwell(plan, o.dwell, center);
    }
}

void check_travel(const TestPlan& plan, const ReversalTestOptions& o) {
    const PlanUnits u = o.units();
    for (const auto& move : plan.moves) {
        if (move.kind != MoveKind::feed) continue;
        if (move.target < o.travel_min - 1e-12 || move.target > o.travel_max + 1e-12) {
            throw InputError(fmt::format("reversal test: {} goes to {:g} {}, outside the travel {:g} .. {:g} {}",
                                         move.description, move.target / u.length(), u.length_unit(),
                                         o.travel_min / u.length(), o.travel_max / u.length(), u.length_unit()));
        }
    }
}

std::vector<std::string> describe(const ReversalTestOptions& o) {
    const PlanUnits u = o.units();
    const auto length = [&](double si) { return fmt::format("{:g}", si / u.length()); };
    std::string centres;
    for (const double c : o.centers) centres += (centres.empty() ? "" : ", ") + length(c);
    std::string feeds;
    for (const double f : o.feeds) feeds += (feeds.empty() ? "" : ", ") + fmt::format("{:g}", f / u.feed());
    return {"reversal test (lost motion, backlash, stiffness, reversal error)",
            "micro-steps through a reversal, then slow strokes back and forth; every move ends at rest",
            fmt::format("travel {} .. {} {}; centres {} {}", length(o.travel_min), length(o.travel_max),
                        u.length_unit(), centres, u.length_unit()),
            fmt::format("micro-steps {} {} x {} each way, {} cycles, {:g} {}, dwell {:g} s", length(o.micro_step),
                        u.length_unit(), o.micro_steps, o.micro_cycles, o.micro_feed / u.feed(), u.feed_unit(),
                        o.micro_dwell),
            fmt::format("strokes {} {} at {} {}, {} cycles, dwell {:g} s", length(o.stroke), u.length_unit(),
                        feeds.empty() ? "none" : feeds, u.feed_unit(), o.cycles, o.dwell),
            fmt::format("record the scale (position) and the motor encoder (motor_position) with the current")};
}

}  // namespace

TestPlan make_reversal_plan(const ReversalTestOptions& options) {
    if (auto problem = options.validate(); !problem.empty()) throw InputError("reversal test: " + problem + ".");
    TestPlan plan;
    plan.options.axis = options.axis;
    plan.options.travel_min = options.travel_min;
    plan.options.travel_max = options.travel_max;
    plan.options.centers = options.centers;
    plan.options.stroke = options.stroke;
    plan.options.feeds = options.feeds;
    plan.options.slow_feeds.clear();
    plan.options.cycles = options.cycles;
    plan.options.acceleration = options.acceleration;
    plan.options.dwell = options.dwell;
    plan.options.sample_time = options.sample_time;
    plan.options.positioning_feed = options.positioning_feed;
    for (std::size_t c = 0; c < options.centers.size(); ++c) {
        const int center = static_cast<int>(c);
        feed_to(plan, options.centers[c], options.positioning_feed, center, "positioning");
        dwell(plan, options.dwell, center);
        micro_steps(plan, options, center, options.centers[c]);
        if (options.cycles > 0) strokes(plan, options, center, options.centers[c]);
    }
    check_travel(plan, options);
    plan.description = describe(options);
    plan.duration = detail::make_timeline(plan).duration;
    return plan;
}

}  // namespace feedid
