#include "feedid/plan/test_plan.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <numeric>
#include <numbers>
#include <system_error>

#include <fmt/core.h>
#include <Eigen/Dense>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/model/demo_drives.hpp"
#include "feedid/plan/motion_profile.hpp"
#include "feedid/core/version.hpp"
#include "timeline.hpp"

namespace feedid {

namespace {

// The paper's feedrate ladder (docs/method.md): 1250 mm/min up to about 9350 mm/min; 1250 + 6 * 1350 = 9350. A
// rotary axis runs the same numbers in deg/min.
constexpr double ladder_first_per_min = 1250.0;
constexpr double ladder_step_per_min = 1350.0;
constexpr int ladder_steps = 6;
// Slow strokes are multiples of 0.01 mm (or 0.01 deg), so that the part program (positions to 0.1 um or 0.0001 deg)
// carries them exactly; a slow stroke below one step cannot be run.
constexpr double slow_stroke_steps_per_unit = 100.0;
// Halvings of the bisection for the slow stroke: 2^-100 of a stroke is far below double precision.
constexpr int stroke_bisections = 100;
// Two positions [m] or feedrates [m/s] this close are the same: only the rounding of the arithmetic separates them.
constexpr double same_position_tolerance = 1e-12;
constexpr double same_feed_tolerance = 1e-12;
// A move may pass the travel limits by 1 nm [m] (rounding of centre +- stroke/2; far below encoder resolution) and
// the feedrate limit by a relative 1e-12 (a feedrate equal to the limit in mm/min but computed another way, as the
// log-spaced feeds are, differs from it by rounding only).
constexpr double travel_tolerance = 1e-9;
// What the command line allows (past any machine, short of nonsense): travel limits within +-1 km (or 1e6 degrees),
// feedrates from 0.001 to 1e6 mm/min (or deg/min), at most 100 log-spaced slow feeds.
constexpr double max_travel_units = 1e6;
constexpr double min_feed_per_min = 1e-3;
constexpr double max_feed_per_min = 1e6;
constexpr double max_slow_feeds = 100.0;
constexpr double feed_limit_relative_tolerance = 1e-12;

// A length [m or rad] in mm or degrees, a feedrate [m/s or rad/s] in mm/min or deg/min.
double shown_length(double si, const PlanUnits& units) {
    return si / units.length();
}
double shown_feed(double si, const PlanUnits& units) {
    return si / units.feed();
}

bool all_finite(const std::vector<double>& values) {
    return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

// Longest stroke s <= longest whose pass (2*cycles strokes, each followed by a dwell) fits in max_time:
// 2*cycles*(move_duration(s) + dwell) <= max_time, a whole number of `step`s. move_duration grows with s, so bisect.
double stroke_for_time(double longest, double feed, int cycles, double dwell, double max_time, double acceleration,
                       std::optional<double> jerk, double step) {
    const double per_stroke = max_time / (2.0 * cycles) - dwell;
    if (per_stroke <= 0.0) return 0.0;
    if (move_duration(longest, feed, acceleration, jerk) <= per_stroke) return longest;
    double low = 0.0;
    double high = longest;
    for (int iteration = 0; iteration < stroke_bisections; ++iteration) {
        const double middle = 0.5 * (low + high);
        (move_duration(middle, feed, acceleration, jerk) <= per_stroke ? low : high) = middle;
    }
    return std::floor(low / step) * step;
}

// A number as the command line writes it: decimal, finite, nothing before or after.
double parse_number(std::string_view text, std::string_view option) {
    double value = 0.0;
    const auto* begin = text.data();
    const auto* end = begin + text.size();
    const auto [ptr, error] = std::from_chars(begin, end, value);
    if (error != std::errc() || ptr != end || !std::isfinite(value))
        throw InputError(fmt::format("{}: '{}' is not a number.", option, text));
    return value;
}

std::vector<std::string_view> split(std::string_view text, char separator) {
    std::vector<std::string_view> parts;
    std::size_t start = 0;
    while (true) {
        const auto at = text.find(separator, start);
        parts.push_back(text.substr(start, at == std::string_view::npos ? std::string_view::npos : at - start));
        if (at == std::string_view::npos) break;
        start = at + 1;
    }
    return parts;
}

// The entries of a list option joined as the user wrote them, for messages.
std::string joined(const std::vector<std::string>& entries) {
    std::string text;
    for (std::size_t k = 0; k < entries.size(); ++k) text += (k == 0 ? "" : ",") + entries[k];
    return text;
}

bool is_none(const std::vector<std::string>& entries) {
    return entries.size() == 1 && entries.front() == "none";
}

std::string describe_center(int index, double position, const PlanUnits& units) {
    return fmt::format("centre {} at {:.3f} {}", index + 1, shown_length(position, units), units.length_unit());
}

}  // namespace

double move_duration(double distance, double feed, double acceleration, std::optional<double> jerk) {
    return MotionProfile::rest_to_rest(std::abs(distance), feed, acceleration, jerk).duration;
}

bool is_rotary_axis(std::string_view axis) {
    if (axis.empty()) return false;
    const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(axis.front())));
    return (letter == 'A' || letter == 'B' || letter == 'C') && std::all_of(axis.begin() + 1, axis.end(), [](char c) {
               return std::isdigit(static_cast<unsigned char>(c));
           });
}

std::vector<double> paper_feed_ladder(const PlanUnits& units) {
    std::vector<double> feeds;
    for (int step = 0; step <= ladder_steps; ++step)
        feeds.push_back((ladder_first_per_min + ladder_step_per_min * step) * units.feed());
    return feeds;
}

std::vector<double> log_spaced_feeds(double lowest, double highest, int count, const PlanUnits& units) {
    std::vector<double> feeds;
    if (count <= 0 || !(lowest > 0.0) || !(highest >= lowest)) return feeds;
    for (int k = 0; k < count; ++k) {
        const double fraction = count == 1 ? 0.0 : static_cast<double>(k) / (count - 1);
        const double value = shown_feed(lowest, units) * std::pow(highest / lowest, fraction);
        // Two significant digits in mm/min (deg/min).
        const double scale = std::pow(10.0, std::floor(std::log10(value)) - 1.0);
        const double rounded = std::round(value / scale) * scale * units.feed();
        if (feeds.empty() || std::abs(rounded - feeds.back()) > same_feed_tolerance) feeds.push_back(rounded);
    }
    return feeds;
}

std::pair<double, double> parse_travel(std::string_view text, const PlanUnits& units) {
    const auto limits = split(text, ':');
    if (limits.size() != 2)
        throw InputError(fmt::format("--travel: '{}' is not MIN:MAX [{}].", text, units.length_unit()));
    const double low = parse_number(limits[0], "--travel");
    const double high = parse_number(limits[1], "--travel");
    if (std::max(std::abs(low), std::abs(high)) > max_travel_units)
        throw InputError(fmt::format("--travel: '{}' reaches past the allowed range -{:g} to {:g} {}.", text,
                                     max_travel_units, max_travel_units, units.length_unit()));
    return {low * units.length(), high * units.length()};
}

std::vector<double> parse_number_list(const std::vector<std::string>& entries, std::string_view option, double scale) {
    std::vector<double> values;
    for (const auto& entry : entries) {
        if (entry.empty()) throw InputError(fmt::format("{}: empty entry in '{}'.", option, joined(entries)));
        values.push_back(parse_number(entry, option) * scale);
    }
    return values;
}

std::vector<double> parse_feeds(const std::vector<std::string>& entries, const PlanUnits& units) {
    if (is_none(entries)) return {};
    return parse_number_list(entries, "--feeds", units.feed());
}

std::vector<double> parse_slow_feeds(const std::vector<std::string>& entries, const PlanUnits& units) {
    if (is_none(entries)) return {};
    const char* unit = units.feed_unit();
    if (entries.size() != 1 || entries.front().find(':') == std::string::npos) {
        const auto feeds = parse_number_list(entries, "--slow-feeds", units.feed());
        for (const double feed : feeds) {
            if (!(feed >= min_feed_per_min * units.feed() && feed <= max_feed_per_min * units.feed()))
                throw InputError(fmt::format("--slow-feeds: {:g} {} is outside the allowed range {:g} to {:g} {}.",
                                             shown_feed(feed, units), unit, min_feed_per_min, max_feed_per_min, unit));
        }
        return feeds;
    }
    const std::string_view text = entries.front();
    const auto parts = split(text, ':');
    if (parts.size() < 2 || parts.size() > 3)
        throw InputError(fmt::format("--slow-feeds: '{}' is not LO:HI or LO:HI:N ({}).", text, unit));
    const double low = parse_number(parts[0], "--slow-feeds");
    const double high = parse_number(parts[1], "--slow-feeds");
    const double count = parts.size() == 3 ? parse_number(parts[2], "--slow-feeds") : 7.0;
    if (!(low >= min_feed_per_min) || !(high >= low) || !(high <= max_feed_per_min) || !(count >= 1.0) ||
        !(count <= max_slow_feeds) || count != std::floor(count))
        throw InputError(
            fmt::format("--slow-feeds: '{}' needs {:g} <= LO <= HI <= {:g} {} and a whole N from 1 to {:g}.", text,
                        min_feed_per_min, max_feed_per_min, unit, max_slow_feeds));
    return log_spaced_feeds(low * units.feed(), high * units.feed(), static_cast<int>(count), units);
}

AxisModel nominal_demo_drive(bool rotary) {
    return demo_drive(rotary).axis;
}

PredictionOptions default_prediction_options(bool rotary) {
    PredictionOptions options;
    if (!rotary) return options;
    // The rotary demo table's current noise 0.02 A through 2 N*m/A; its level error, as the linear drive's, 0.67 % of
    // F_C; an encoder of 1 millidegree.
    constexpr double torque_noise_Nm = 0.04;
    constexpr double level_error_Nm = 0.135;
    constexpr double resolution_deg = 1e-3;
    options.drive = nominal_demo_drive(true);
    options.force_noise = torque_noise_Nm;
    options.level_error = level_error_Nm;
    options.position_resolution = resolution_deg * std::numbers::pi / 180.0;
    return options;
}

TestPlanOptions default_plan_options(const std::string& axis) {
    TestPlanOptions options;
    options.axis = axis;
    const PlanUnits units = options.units();
    if (!units.rotary) return options;
    // every length and feed of the linear defaults, the same numbers in degrees instead of mm
    options.stroke = TestPlanOptions::default_stroke * units.length();
    options.feeds = paper_feed_ladder(units);
    options.slow_feeds = log_spaced_feeds(TestPlanOptions::default_slowest_feed * units.feed(),
                                          TestPlanOptions::default_fastest_slow_feed * units.feed(),
                                          TestPlanOptions::default_slow_feed_count, units);
    options.positioning_feed = TestPlanOptions::default_positioning_feed * units.feed();
    options.acceleration *= 1000.0 * units.acceleration();  // 1 m/s^2 = 1000 mm/s^2 -> 1000 deg/s^2
    return options;
}

std::string TestPlanOptions::validate() const {
    if (axis.empty() || !std::isalpha(static_cast<unsigned char>(axis.front())))
        return fmt::format("axis '{}' is not an axis name (a letter such as X, Y, Z, A, or X1)", axis);
    for (const char c : axis) {
        if (!std::isalnum(static_cast<unsigned char>(c)))
            return fmt::format("axis '{}' is not an axis name (letters and digits only)", axis);
    }
    const PlanUnits u = units();
    const char* length = u.length_unit();
    if (!std::isfinite(travel_min) || !std::isfinite(travel_max) || !(travel_min < travel_max))
        return fmt::format("travel {:.3f}:{:.3f} {} is not a range MIN:MAX with MIN < MAX", shown_length(travel_min, u),
                           shown_length(travel_max, u), length);
    if (centers.empty()) return "no centres given: state where along the axis to test (--centers C1,C2,...)";
    if (!all_finite(centers)) return "a centre is not a finite number";
    if (!(stroke > 0.0) || !std::isfinite(stroke))
        return fmt::format("stroke {} {} must be positive", shown_length(stroke, u), length);
    if (feeds.empty() && slow_feeds.empty()) return "no feedrates: give ladder feeds (--feeds) or slow feeds";
    for (const auto* list : {&feeds, &slow_feeds}) {
        for (const double feed : *list) {
            if (!(feed > 0.0) || !std::isfinite(feed))
                return fmt::format("feedrate {} {} must be positive", shown_feed(feed, u), u.feed_unit());
        }
    }
    if (cycles < 1) return fmt::format("cycles {} must be at least 1", cycles);
    if (!(acceleration > 0.0) || !std::isfinite(acceleration))
        return fmt::format("acceleration {} {} must be positive", acceleration / u.acceleration(),
                           u.acceleration_unit());
    if (jerk && (!(*jerk > 0.0) || !std::isfinite(*jerk)))
        return fmt::format("jerk {} {} must be positive", *jerk / u.acceleration(), u.jerk_unit());
    if (!(dwell >= 0.0) || !std::isfinite(dwell)) return fmt::format("dwell {} s must not be negative", dwell);
    if (!(sample_time > 0.0) || !std::isfinite(sample_time))
        return fmt::format("sample time {} s must be positive", sample_time);
    if (!(max_pass_time > 0.0)) return fmt::format("maximum pass time {} s must be positive", max_pass_time);
    if (!slow_feeds.empty() && 2.0 * cycles * dwell >= max_pass_time)
        return fmt::format("the dwells alone ({} x 2 x {} s) fill the maximum pass time {} s of a slow pass", cycles,
                           dwell, max_pass_time);
    if (!(positioning_feed > 0.0)) return "positioning feedrate must be positive";
    if (max_feed && !(*max_feed > 0.0)) return "feedrate limit must be positive";
    if (start_position && !std::isfinite(*start_position)) return "start position is not a finite number";
    return {};
}

namespace {

// One feedrate of a centre's sequence: the slow (Stribeck) passes come first, then the ladder.
struct PlannedFeed {
    double value;  // [m/s]
    bool slow;
};

std::vector<PlannedFeed> feed_sequence(const TestPlanOptions& options) {
    std::vector<PlannedFeed> sequence;
    for (const double feed : options.slow_feeds) sequence.push_back({feed, true});
    for (const double feed : options.feeds) sequence.push_back({feed, false});
    return sequence;
}

// The feedrate of the moves between passes: the option's, lowered (with a note) to the feedrate limit.
double limited_positioning_feed(const TestPlanOptions& options, std::vector<std::string>& notes) {
    double positioning_feed = options.positioning_feed;
    if (options.max_feed && positioning_feed > *options.max_feed) {
        positioning_feed = *options.max_feed;
        notes.push_back(fmt::format("positioning moves run at the feedrate limit {:.0f} {}",
                                    shown_feed(positioning_feed, options.units()), options.units().feed_unit()));
    }
    return positioning_feed;
}

// The pass at one centre and feedrate, before timing: a slow pass's stroke is shortened to fit the maximum pass time.
Pass design_pass(const TestPlanOptions& options, int center, const PlannedFeed& feed) {
    Pass pass;
    pass.center = center;
    pass.center_position = options.centers[static_cast<std::size_t>(center)];
    pass.feed = feed.value;
    pass.slow = feed.slow;
    pass.stroke = options.stroke;
    if (feed.slow) {
        const PlanUnits units = options.units();
        const double step = units.length() / slow_stroke_steps_per_unit;
        pass.stroke = stroke_for_time(options.stroke, feed.value, options.cycles, options.dwell, options.max_pass_time,
                                      options.acceleration, options.jerk, step);
        if (pass.stroke < step) {
            throw InputError(fmt::format(
                "test plan: at {:.4g} {} a stroke that fits the maximum pass time {} s is shorter than "
                "0.01 {}; allow a longer pass (--max-pass-time) or fewer cycles.",
                shown_feed(feed.value, units), units.feed_unit(), options.max_pass_time, units.length_unit()));
        }
    }
    return pass;
}

// "centre 2 at -300.000 mm, 1250 mm/min": how the moves and notes name a pass.
std::string describe_pass(const Pass& pass, const PlanUnits& units) {
    return fmt::format("{}, {:.4g} {}", describe_center(pass.center, pass.center_position, units),
                       shown_feed(pass.feed, units), units.feed_unit());
}

// The blocks of the next pass (index plan.passes.size()): a move to its start unless the axis stands there (at
// `position`, updated), then `cycles` strokes + and -, each followed by the dwell.
void append_pass_moves(TestPlan& plan, const Pass& pass, double positioning_feed, double& position) {
    const auto& options = plan.options;
    const int center = pass.center;
    const int pass_index = static_cast<int>(plan.passes.size());
    const double low = pass.center_position - pass.stroke / 2.0;
    const double high = pass.center_position + pass.stroke / 2.0;
    const std::string what = describe_pass(pass, options.units());
    if (!(std::abs(position - low) < same_position_tolerance)) {
        plan.moves.push_back({MoveKind::feed, low, positioning_feed, 0.0, center, -1,
                              fmt::format("{}: move to the start of the pass", what)});
        if (options.dwell > 0.0)
            plan.moves.push_back(
                {MoveKind::dwell, 0.0, 0.0, options.dwell, center, -1, fmt::format("{}: dwell before the pass", what)});
        position = low;
    }
    for (int cycle = 1; cycle <= options.cycles; ++cycle) {
        plan.moves.push_back({MoveKind::feed, high, pass.feed, 0.0, center, pass_index,
                              fmt::format("{}, cycle {}, stroke +", what, cycle)});
        if (options.dwell > 0.0)
            plan.moves.push_back({MoveKind::dwell, 0.0, 0.0, options.dwell, center, pass_index,
                                  fmt::format("{}, cycle {}, dwell at +", what, cycle)});
        plan.moves.push_back({MoveKind::feed, low, pass.feed, 0.0, center, pass_index,
                              fmt::format("{}, cycle {}, stroke -", what, cycle)});
        if (options.dwell > 0.0)
            plan.moves.push_back({MoveKind::dwell, 0.0, 0.0, options.dwell, center, pass_index,
                                  fmt::format("{}, cycle {}, dwell at -", what, cycle)});
    }
}

// The pass's duration and time at constant feedrate, with a note when its strokes never reach the feedrate.
void time_pass(const TestPlanOptions& options, Pass& pass, std::vector<std::string>& notes) {
    const auto profile = MotionProfile::rest_to_rest(pass.stroke, pass.feed, options.acceleration, options.jerk);
    pass.duration = 2.0 * options.cycles * (profile.duration + options.dwell);
    pass.cruise_time = 2.0 * options.cycles * profile.cruise_time;
    if (profile.cruise_time <= 0.0) {
        const PlanUnits u = options.units();
        notes.push_back(
            fmt::format("{}: the {:.3f} {} stroke is too short to reach the feedrate at {} {} (peak {:.4g} {}); "
                        "this pass holds no constant-velocity data",
                        describe_pass(pass, u), shown_length(pass.stroke, u), u.length_unit(),
                        options.acceleration / u.acceleration(), u.acceleration_unit(),
                        shown_feed(profile.peak_speed, u), u.feed_unit()));
    }
}

// One note per distinct slow feedrate whose stroke was shortened.
void note_shortened_slow_strokes(TestPlan& plan) {
    const auto& options = plan.options;
    const PlanUnits u = options.units();
    for (const auto& feed : options.slow_feeds) {
        for (const auto& pass : plan.passes) {
            if (pass.slow && pass.feed == feed && pass.stroke < options.stroke) {
                plan.notes.push_back(
                    fmt::format("slow pass at {:.4g} {}: stroke shortened to {:.2f} {} to keep the "
                                "pass within {} s",
                                shown_feed(feed, u), u.feed_unit(), shown_length(pass.stroke, u), u.length_unit(),
                                options.max_pass_time));
                break;
            }
        }
    }
}

// Safety: the start and every move inside the travel, every move within the feedrate limit. InputError naming the
// first offender.
void check_travel_and_feed_limits(const TestPlan& plan) {
    const auto& options = plan.options;
    const PlanUnits u = options.units();
    const auto length = [&](double si) { return shown_length(si, u); };
    const auto feed = [&](double si) { return shown_feed(si, u); };
    const char* l = u.length_unit();
    const char* f = u.feed_unit();
    if (options.start_position && (*options.start_position < options.travel_min - travel_tolerance ||
                                   *options.start_position > options.travel_max + travel_tolerance)) {
        throw InputError(
            fmt::format("test plan: the start position {:.3f} {} lies outside the travel {:.3f}:{:.3f} {}.",
                        length(*options.start_position), l, length(options.travel_min), length(options.travel_max), l));
    }
    for (std::size_t k = 0; k < plan.moves.size(); ++k) {
        const auto& move = plan.moves[k];
        if (move.kind != MoveKind::feed) continue;
        if (move.target > options.travel_max + travel_tolerance) {
            throw InputError(
                fmt::format("test plan: move {} ({}) goes to {:.3f} {}, {:.3f} {} beyond the travel maximum {:.3f} {}.",
                            k + 1, move.description, length(move.target), l, length(move.target - options.travel_max),
                            l, length(options.travel_max), l));
        }
        if (move.target < options.travel_min - travel_tolerance) {
            throw InputError(
                fmt::format("test plan: move {} ({}) goes to {:.3f} {}, {:.3f} {} beyond the travel minimum {:.3f} {}.",
                            k + 1, move.description, length(move.target), l, length(options.travel_min - move.target),
                            l, length(options.travel_min), l));
        }
        if (options.max_feed && move.feed > *options.max_feed * (1.0 + feed_limit_relative_tolerance)) {
            throw InputError(
                fmt::format("test plan: move {} ({}) runs at {:.4g} {}, {:.4g} {} above the feedrate limit {:.4g} {}.",
                            k + 1, move.description, feed(move.feed), f, feed(move.feed - *options.max_feed), f,
                            feed(*options.max_feed), f));
        }
    }
}

}  // namespace

TestPlan make_test_plan(const TestPlanOptions& options) {
    if (auto problem = options.validate(); !problem.empty()) throw InputError("test plan: " + problem + ".");
    TestPlan plan;
    plan.options = options;
    const double positioning_feed = limited_positioning_feed(options, plan.notes);
    const auto sequence = feed_sequence(options);
    double position = std::numeric_limits<double>::quiet_NaN();  // the axis's position is unknown at the start
    for (std::size_t c = 0; c < options.centers.size(); ++c) {
        for (const auto& feed : sequence) {
            Pass pass = design_pass(options, static_cast<int>(c), feed);
            append_pass_moves(plan, pass, positioning_feed, position);
            time_pass(options, pass, plan.notes);
            plan.passes.push_back(pass);
        }
    }
    note_shortened_slow_strokes(plan);
    check_travel_and_feed_limits(plan);
    plan.duration = detail::make_timeline(plan).duration;
    return plan;
}

Trace reference_trajectory(const TestPlan& plan) {
    // Half a second at rest before and after the program, as a trace started before the cycle start would hold.
    constexpr double rest = 0.5;
    const auto timeline = detail::make_timeline(plan);
    const auto samples = detail::sample_timeline(timeline, plan.options.sample_time, rest, rest);
    std::vector<double> time(samples.size());
    std::vector<double> position(samples.size());
    for (std::size_t k = 0; k < samples.size(); ++k) {
        time[k] = static_cast<double>(k) * plan.options.sample_time;
        position[k] = samples[k].position;
    }
    Trace trace;
    trace.format = "reference";
    trace.rotary = plan.options.units().rotary;
    trace.set("t", Role::time, "s", std::move(time));
    trace.set("x_ref", Role::reference_position, trace.rotary ? "rad" : "m", std::move(position));
    return trace;
}

// ---- identifiability prediction ----

const ParameterPrediction* IdentifiabilityPrediction::find(const std::string& key) const {
    for (const auto& parameter : parameters) {
        if (parameter.key == key) return &parameter;
    }
    return nullptr;
}

namespace {

// The identification's default differentiation low-pass (IdentifyOptions::cutoff_hz in identify.hpp):
// min(100 Hz, 0.1 f_s).
constexpr double differentiation_cutoff_hz = 100.0;
constexpr double differentiation_cutoff_per_sample_rate = 0.1;
// Step 1 fits above 5 v_s by default (PredictionOptions::split_velocity): the Stribeck term is below exp(-5) < 1 %
// of F_B - F_C there.
constexpr double split_velocity_per_stribeck_velocity = 5.0;
// Unknowns of the two steps: M, B, F_C; and B, F_C, F_B, v_s.
constexpr std::size_t step1_unknowns = 3;
constexpr std::size_t step2_unknowns = 4;
// Smallest eigenvalue of the information matrix, relative to the largest, below which the data do not determine the
// step's parameters: cond(Phi) above 1e6 in step 1 (SI units), cond(J) above 1e7 in step 2 (relative parameters).
// Inverting in double precision loses about log10 of the ratio of the 16 digits; at these bounds 4 and 2 remain,
// still enough for a standard error.
constexpr double step1_rank_tolerance = 1e-12;
constexpr double step2_rank_tolerance = 1e-14;
// Slowest constant-velocity pass above 3 v_s: the Stribeck term is below exp(-3) = 5 % of F_B - F_C on every pass,
// too little to separate F_B and v_s; the prediction says so.
constexpr double stribeck_visible_below_speeds = 3.0;

// The nominal drive's parameters the prediction is made for (forward branch; the model is symmetric).
struct NominalDrive {
    double mass;
    double viscous;
    double coulomb;
    double breakaway;
    double stribeck_velocity;
};

NominalDrive nominal_drive(const PredictionOptions& options) {
    const auto& drive = options.drive;
    const auto& branch = drive.friction.forward;
    const NominalDrive nominal{drive.mass, branch.viscous, branch.coulomb, branch.breakaway.value_or(branch.coulomb),
                               branch.stribeck_velocity.value_or(0.0)};
    if (!(nominal.mass > 0.0) || !(nominal.stribeck_velocity > 0.0) || !(nominal.breakaway > nominal.coulomb))
        throw InputError("identifiability prediction: the nominal drive needs M > 0, v_s > 0 and F_B > F_C.");
    return nominal;
}

// Standard deviation of the force equation's error per sample [N]. Differentiating the quantised position (uniform
// error, variance q^2/12) through a low-pass of cut-off f_c (the identification's default min(100 Hz, 0.1 f_s))
// leaves acceleration noise of variance
//   sigma_a^2 = sigma_x^2 * (2/f_s) * integral_0^f_c (2 pi f)^4 df = sigma_x^2 * 2 (2 pi)^4 f_c^5 / (5 f_s),
// which enters the equation as force noise M * sigma_a beside the current noise.
double equation_noise(const PredictionOptions& options, double mass, double sample_time) {
    const double sample_rate = 1.0 / sample_time;
    const double cutoff = std::min(differentiation_cutoff_hz, differentiation_cutoff_per_sample_rate * sample_rate);
    const double position_variance = options.position_resolution * options.position_resolution / 12.0;
    const double acceleration_variance =
        position_variance * 2.0 * std::pow(2.0 * M_PI, 4) * std::pow(cutoff, 5) / (5.0 * sample_rate);
    return std::sqrt(options.force_noise * options.force_noise + mass * mass * acceleration_variance);
}

// Step 1: the regressors [x'', x', sgn x'] of the ideal trajectory above the split speed; standard errors of M, B
// and F_C as sigma*sqrt(diag((Phi^T Phi)^-1)), infinite when the data do not determine them. Sets the step-1 sample
// count and condition number of the prediction.
Eigen::Vector3d predict_step1(const TestPlan& plan, double split, double sigma, IdentifiabilityPrediction& prediction) {
    const double infinity = std::numeric_limits<double>::infinity();
    const auto timeline = detail::make_timeline(plan);
    const auto samples = detail::sample_timeline(timeline, plan.options.sample_time, 0.0, 0.0);
    Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
    for (const auto& s : samples) {
        if (std::abs(s.velocity) < split) continue;
        const Eigen::Vector3d phi(s.acceleration, s.velocity, s.velocity > 0.0 ? 1.0 : -1.0);
        information += phi * phi.transpose();
        ++prediction.step1_samples;
    }
    Eigen::Vector3d step1_error = Eigen::Vector3d::Constant(infinity);
    if (prediction.step1_samples >= step1_unknowns) {
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(information);
        const double smallest = eigen.eigenvalues().minCoeff();
        const double largest = eigen.eigenvalues().maxCoeff();
        // cond(Phi) = sqrt(cond(Phi^T Phi)).
        prediction.step1_condition_number = smallest > 0.0 ? std::sqrt(largest / smallest) : infinity;
        if (smallest > step1_rank_tolerance * largest) {
            const Eigen::Matrix3d covariance = sigma * sigma * information.inverse();
            step1_error = covariance.diagonal().cwiseSqrt();
        }
    } else {
        const ParameterNaming naming{plan.options.units().rotary};
        prediction.diagnostics.push_back(fmt::format(
            "no samples above the split speed {:.4g} {}: M, B and F_C cannot be identified (add ladder passes)",
            split * naming.display_velocity_scale(), naming.display_velocity_unit()));
    }
    return step1_error;
}

// Step 2. Each constant-velocity pass gives, per direction, one point of the friction curve
//   F(v) = B v + F_C + (F_B - F_C) exp(-v / v_s),
// with error sigma_level^2 = sigma^2 / n + level_error^2 (n samples at constant velocity). Gauss-Newton
// covariance (J^T W J)^-1 with J = dF/d[B, F_C, F_B, v_s], computed in relative parameters (scaled by the
// nominal values) so that the conditioning reflects the data, not the units. Returns the relative standard errors of
// [B, F_C, F_B, v_s] (infinite when not determined); sets the level count and slowest cruise speed.
Eigen::Vector4d predict_step2(const TestPlan& plan, const NominalDrive& drive, double sigma, double level_error,
                              IdentifiabilityPrediction& prediction) {
    const double infinity = std::numeric_limits<double>::infinity();
    const double dt = plan.options.sample_time;
    const double stribeck_velocity = drive.stribeck_velocity;
    const Eigen::Vector4d nominal(drive.viscous > 0.0 ? drive.viscous : 1.0, drive.coulomb, drive.breakaway,
                                  stribeck_velocity);
    Eigen::Matrix4d level_information = Eigen::Matrix4d::Zero();
    prediction.slowest_cruise_speed = infinity;
    for (const auto& pass : plan.passes) {
        if (pass.cruise_time <= 0.0) continue;
        const double v = pass.feed;
        prediction.slowest_cruise_speed = std::min(prediction.slowest_cruise_speed, v);
        const double per_direction = pass.cruise_time / 2.0;
        const double n = std::max(1.0, per_direction / dt);
        const double variance = sigma * sigma / n + level_error * level_error;
        const double decay = std::exp(-v / stribeck_velocity);
        Eigen::Vector4d jacobian(
            v, 1.0 - decay, decay,
            (drive.breakaway - drive.coulomb) * decay * v / (stribeck_velocity * stribeck_velocity));
        jacobian = jacobian.cwiseProduct(nominal);
        level_information += 2.0 * jacobian * jacobian.transpose() / variance;  // both directions
        prediction.step2_levels += 2;
    }
    Eigen::Vector4d step2_relative = Eigen::Vector4d::Constant(infinity);
    if (prediction.step2_levels >= step2_unknowns) {
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eigen(level_information);
        const double smallest = eigen.eigenvalues().minCoeff();
        const double largest = eigen.eigenvalues().maxCoeff();
        if (smallest > step2_rank_tolerance * largest)
            step2_relative = level_information.inverse().diagonal().cwiseSqrt();
    }
    return step2_relative;
}

/// A predicted parameter, keyed as identify's result of the axis (symmetric model).
void add_parameter(IdentifiabilityPrediction& prediction, const ParameterNaming& naming, Term term, double value,
                   double error, double identifiable_relative_error) {
    ParameterPrediction parameter;
    parameter.key = naming.key(term);
    parameter.symbol = ParameterNaming::symbol(term, Direction::both);
    parameter.unit = naming.unit(term);
    parameter.nominal = value;
    parameter.standard_error = error;
    parameter.identifiable = std::isfinite(error) && std::abs(error) <= identifiable_relative_error * std::abs(value);
    prediction.parameters.push_back(std::move(parameter));
}

// What the plan misses: slow passes for the Stribeck curve, and each parameter it does not identify and why.
void add_diagnostics(IdentifiabilityPrediction& prediction, const TestPlan& plan, double stribeck_velocity,
                     double identifiable_relative_error) {
    const PlanUnits units = plan.options.units();
    const ParameterNaming naming{units.rotary};
    const double speed = naming.display_velocity_scale();
    if (!std::isfinite(prediction.slowest_cruise_speed)) {
        prediction.diagnostics.push_back("no pass reaches a constant velocity: the friction curve is not sampled");
    } else if (prediction.slowest_cruise_speed > stribeck_visible_below_speeds * stribeck_velocity) {
        prediction.diagnostics.push_back(fmt::format(
            "the slowest constant-velocity pass runs at {:.3g} {} = {:.3g} v_s (nominal v_s {:.3g} {}): the Stribeck "
            "term is below {:.2g} % of F_B - F_C there, so F_B and v_s are not identifiable; add slow passes "
            "(e.g. --slow-feeds 10:1000 {})",
            prediction.slowest_cruise_speed * speed, naming.display_velocity_unit(),
            prediction.slowest_cruise_speed / stribeck_velocity, stribeck_velocity * speed,
            naming.display_velocity_unit(), 100.0 * std::exp(-prediction.slowest_cruise_speed / stribeck_velocity),
            units.feed_unit()));
    }
    for (const auto& parameter : prediction.parameters) {
        if (parameter.identifiable) continue;
        prediction.diagnostics.push_back(
            std::isfinite(parameter.standard_error)
                ? fmt::format("{} is not identifiable from this plan: expected standard error {:.3g} {} = {:.3g} % of "
                              "the nominal {:.4g} {} (limit {:.3g} %)",
                              parameter.symbol, parameter.standard_error, parameter.unit,
                              100.0 * parameter.standard_error / std::abs(parameter.nominal), parameter.nominal,
                              parameter.unit, 100.0 * identifiable_relative_error)
                : fmt::format("{} is not identifiable from this plan: the data do not determine it", parameter.symbol));
    }
}

}  // namespace

IdentifiabilityPrediction predict_identifiability(const TestPlan& plan, const PredictionOptions& options) {
    IdentifiabilityPrediction prediction;
    const ParameterNaming naming{plan.options.units().rotary};
    if (options.drive.rotary != naming.rotary)
        throw InputError(fmt::format("identifiability prediction: axis '{}' is {} but the nominal drive is {}.",
                                     plan.options.axis, naming.rotary ? "rotary" : "linear",
                                     options.drive.rotary ? "rotary" : "linear"));
    const NominalDrive drive = nominal_drive(options);
    const double split =
        options.split_velocity.value_or(split_velocity_per_stribeck_velocity * drive.stribeck_velocity);
    const double sigma = equation_noise(options, drive.mass, plan.options.sample_time);
    const Eigen::Vector3d step1_error = predict_step1(plan, split, sigma, prediction);
    const Eigen::Vector4d step2_relative = predict_step2(plan, drive, sigma, options.level_error, prediction);

    const double limit = options.identifiable_relative_error;
    add_parameter(prediction, naming, Term::mass, drive.mass, step1_error(0), limit);
    add_parameter(prediction, naming, Term::viscous, drive.viscous, step1_error(1), limit);
    add_parameter(prediction, naming, Term::coulomb, drive.coulomb, step1_error(2), limit);
    add_parameter(prediction, naming, Term::breakaway, drive.breakaway, step2_relative(2) * drive.breakaway, limit);
    add_parameter(prediction, naming, Term::stribeck_velocity, drive.stribeck_velocity,
                  step2_relative(3) * drive.stribeck_velocity, limit);
    add_diagnostics(prediction, plan, drive.stribeck_velocity, limit);
    return prediction;
}

nlohmann::json plan_document(const TestPlan& plan, const IdentifiabilityPrediction& prediction) {
    // SI keys as identify's documents name them: m on a linear axis, rad on a rotary one
    const PlanUnits units = plan.options.units();
    const std::string length = units.rotary ? "rad" : "m";
    const std::string speed = units.rotary ? "rad_per_s" : "m_per_s";
    nlohmann::json passes = nlohmann::json::array();
    for (const auto& pass : plan.passes) {
        passes.push_back({{"center", pass.center + 1},
                          {"center_" + length, pass.center_position},
                          {"feed_" + speed, pass.feed},
                          {units.rotary ? "feed_deg_per_min" : "feed_mm_per_min", shown_feed(pass.feed, units)},
                          {"stroke_" + length, pass.stroke},
                          {"slow", pass.slow},
                          {"duration_s", pass.duration},
                          {"cruise_time_s", pass.cruise_time}});
    }
    nlohmann::json parameters = nlohmann::json::object();
    for (const auto& p : prediction.parameters) {
        parameters[p.key] = {
            {"nominal", p.nominal},
            {"stderr", std::isfinite(p.standard_error) ? nlohmann::json(p.standard_error) : nlohmann::json()},
            {"identifiable", p.identifiable}};
    }
    const auto& o = plan.options;
    return {{"feedid_version", version},
            {"axis", o.axis},
            {"rotary", units.rotary},
            {"travel_" + length, {o.travel_min, o.travel_max}},
            {"centers_" + length, o.centers},
            {"duration_s", plan.duration},
            {"blocks", plan.moves.size()},
            {"sample_time_s", o.sample_time},
            {"passes", passes},
            {"notes", plan.notes},
            {"prediction",
             {{"step1_condition_number", std::isfinite(prediction.step1_condition_number)
                                             ? nlohmann::json(prediction.step1_condition_number)
                                             : nlohmann::json()},
              {"step1_samples", prediction.step1_samples},
              {"step2_levels", prediction.step2_levels},
              {"slowest_cruise_speed_" + speed, std::isfinite(prediction.slowest_cruise_speed)
                                                    ? nlohmann::json(prediction.slowest_cruise_speed)
                                                    : nlohmann::json()},
              {"parameters", parameters},
              {"diagnostics", prediction.diagnostics}}}};
}

}  // namespace feedid
