#pragma once
// Test-procedure design (docs/method.md): constant-velocity back-and-forth strokes at several centres along the
// axis at rising feedrates (the paper's ladder, 1250 to 9350 mm/min), plus slow passes for the Stribeck curve
// (log-spaced, strokes shortened so that each pass stays brief). A plan is a list of moves the NC executes; from it
// come the part program (ISO, SINUMERIK 840D, LinuxCNC; gcode_writer.hpp), the reference trajectory an ideal NC would
// command, the predicted duration and a prediction of which parameters the data will identify and how well.
//
// All quantities in SI (m, m/s, m/s^2, s; on a rotary axis rad, rad/s, rad/s^2); the options' text, the messages and
// the emitters use mm and mm/min, or degrees and deg/min on a rotary axis (PlanUnits).

#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/model/friction.hpp"
#include "feedid/core/trace.hpp"

namespace feedid {

/// The units a plan is written in: mm and mm/min on a linear axis; degrees and deg/min on a rotary axis, as NCs program
/// rotary axes (G94: a move of the rotary axis alone runs at F deg/min). Accelerations in m/s^2 or deg/s^2.
struct PlanUnits {
    bool rotary{false};

    /// SI per length unit: m per mm, or rad per degree.
    [[nodiscard]] double length() const { return rotary ? std::numbers::pi / 180.0 : 1e-3; }
    /// SI per feed unit: m/s per mm/min, or rad/s per deg/min.
    [[nodiscard]] double feed() const { return length() / 60.0; }
    /// SI per acceleration unit (and per jerk unit): 1 (m/s^2), or rad/s^2 per deg/s^2.
    [[nodiscard]] double acceleration() const { return rotary ? std::numbers::pi / 180.0 : 1.0; }
    [[nodiscard]] const char* length_unit() const { return rotary ? "deg" : "mm"; }
    [[nodiscard]] const char* feed_unit() const { return rotary ? "deg/min" : "mm/min"; }
    [[nodiscard]] const char* acceleration_unit() const { return rotary ? "deg/s^2" : "m/s^2"; }
    [[nodiscard]] const char* jerk_unit() const { return rotary ? "deg/s^3" : "m/s^3"; }
};

/// A, B and C turn about X, Y and Z (DIN 66025 / ISO 6983); on SINUMERIK with a number (A1, C2).
bool is_rotary_axis(std::string_view axis);

/// The paper's feedrate ladder: 1250 to 9350 mm/min (deg/min on a rotary axis) in six equal steps of 1350 [m/s or
/// rad/s].
std::vector<double> paper_feed_ladder(const PlanUnits& units = {});

/// `count` feedrates log-spaced from `lowest` to `highest` [m/s or rad/s], each rounded to two significant digits in
/// mm/min or deg/min (10, 22, 46, 100, ...) so that the part program reads well; duplicates after rounding are dropped.
std::vector<double> log_spaced_feeds(double lowest, double highest, int count, const PlanUnits& units = {});

// ---- the plan's options as the command line writes them (mm, mm/min; deg, deg/min on a rotary axis) ----
// Each parser reads the text of one option (a comma-separated option as its entries, split by the command line) and
// throws InputError naming the option for a malformed value; TestPlanOptions::validate checks the ranges.

/// --travel "MIN:MAX" [mm or deg] -> {travel_min, travel_max} [m or rad].
std::pair<double, double> parse_travel(std::string_view text, const PlanUnits& units = {});
/// The entries of a comma-separated option (--centers C1,C2,...) as numbers, each times `scale` (1e-3: mm -> m).
std::vector<double> parse_number_list(const std::vector<std::string>& entries, std::string_view option, double scale);
/// --feeds: F1,F2,... [mm/min or deg/min], or "none" -> ladder feedrates [m/s or rad/s].
std::vector<double> parse_feeds(const std::vector<std::string>& entries, const PlanUnits& units = {});
/// --slow-feeds: "LO:HI" or "LO:HI:N" [mm/min or deg/min] (N log-spaced feedrates, default 7; see log_spaced_feeds),
/// F1,F2,... [mm/min or deg/min], or "none" -> slow feedrates [m/s or rad/s].
std::vector<double> parse_slow_feeds(const std::vector<std::string>& entries, const PlanUnits& units = {});

/// The defaults are a linear axis's; a rotary axis (A, B, C) takes every length in rad (its options' text in degrees:
/// PlanUnits) and needs its own values.
struct TestPlanOptions {
    // Defaults in the units the options are written in: mm and mm/min here; default_plan_options() reads the same
    // numbers in degrees and deg/min on a rotary axis.
    static constexpr double default_stroke{30.0};
    static constexpr double default_slowest_feed{10.0};
    static constexpr double default_fastest_slow_feed{1000.0};
    static constexpr int default_slow_feed_count{7};
    static constexpr double default_positioning_feed{5000.0};

    std::string axis{"X"};        ///< axis letter as the NC knows it (X, Y, Z, A, ..., X1 on SINUMERIK)
    double travel_min{0.0};       ///< lower travel limit (software limit switch) [m]
    double travel_max{0.0};       ///< upper travel limit [m]
    std::vector<double> centers;  ///< centres of the strokes along the axis [m]
    double stroke{default_stroke * PlanUnits{}.length()};  ///< stroke of the ladder passes (the paper: 30 mm) [m]
    std::vector<double> feeds{paper_feed_ladder()};  ///< ladder feedrates [m/s]
    /// Slow feedrates for the Stribeck curve, log-spaced [m/s].
    std::vector<double> slow_feeds{log_spaced_feeds(default_slowest_feed * PlanUnits{}.feed(),
                                                    default_fastest_slow_feed * PlanUnits{}.feed(),
                                                    default_slow_feed_count)};
    double max_pass_time{8.0};                  ///< a slow pass takes at most this long: its stroke is shortened [s]
    int cycles{2};                              ///< back-and-forth cycles per feedrate
    double acceleration{1.0};                   ///< path acceleration the NC uses (machine data) [m/s^2]
    std::optional<double> jerk;                 ///< jerk limit [m/s^3]; none = trapezoidal velocity (BRISK)
    double dwell{0.2};                          ///< dwell at every reversal [s]
    double sample_time{0.001};                  ///< trace sample time (servo trace / reference file) [s]
    std::optional<double> max_feed;             ///< feedrate limit of the axis [m/s]; none = not checked
    /// Feedrate of the moves between passes and centres [m/s].
    double positioning_feed{default_positioning_feed * PlanUnits{}.feed()};
    /// Where the axis stands when the program starts [m]; none = at the first pass's start (the reference trajectory
    /// then begins there).
    std::optional<double> start_position;

    /// mm or degrees: the axis's kind, from its name.
    [[nodiscard]] PlanUnits units() const { return {is_rotary_axis(axis)}; }

    /// What is wrong with these options ("" when nothing). Does not check the travel (make_test_plan does, per move).
    [[nodiscard]] std::string validate() const;
};

/// The defaults for an axis: a linear axis's as TestPlanOptions has them (travel and centres still to be set); a
/// rotary axis's the same numbers in degrees (30 deg strokes, the ladder and the slow feeds in deg/min, 5000 deg/min
/// between passes, 1000 deg/s^2: a degree of the one is a mm of the other, as `feedid synth --rotary` has it), in SI.
TestPlanOptions default_plan_options(const std::string& axis);

enum class MoveKind { feed, dwell };

/// One block of the part program.
struct Move {
    MoveKind kind{MoveKind::feed};
    double target{0.0};       ///< end position of a feed move [m]
    double feed{0.0};         ///< feedrate of a feed move [m/s]
    double dwell{0.0};        ///< dwell time [s]
    int center{-1};           ///< index of the centre this move belongs to
    int pass{-1};             ///< index of the pass (into TestPlan::passes); -1 for positioning moves
    std::string description;  ///< "centre 2 (-300 mm), 1250 mm/min, cycle 1, stroke +" (names it in messages)
};

/// One pass: `cycles` back-and-forth strokes at one feedrate around one centre.
struct Pass {
    int center{0};
    double center_position{0.0};  ///< [m]
    double feed{0.0};             ///< [m/s]
    double stroke{0.0};           ///< [m] (shortened for slow passes)
    bool slow{false};             ///< one of the Stribeck passes
    double duration{0.0};         ///< including its dwells [s]
    double cruise_time{0.0};      ///< time at constant feedrate, both directions together [s]
};

struct TestPlan {
    TestPlanOptions options;
    std::vector<Move> moves;
    std::vector<Pass> passes;
    double duration{0.0};            ///< predicted test duration (start to end of the program) [s]
    std::vector<std::string> notes;  ///< what the design changed or warns about (shortened strokes, unreached feeds)
    /// The part program's header comment lines; empty = the friction test's (strokes, ladder and slow feeds).
    std::vector<std::string> description;
};

/// Designs the test. Throws InputError for invalid options, or naming the first move that leaves the travel (and by
/// how much) or exceeds the feedrate limit.
TestPlan make_test_plan(const TestPlanOptions& options);

/// Duration of a rest-to-rest move of `distance` [m] at feedrate `feed` [m/s] with acceleration [m/s^2] and an
/// optional jerk limit [m/s^3] (trapezoidal or jerk-limited seven-phase velocity profile).
double move_duration(double distance, double feed, double acceleration, std::optional<double> jerk);

/// What an ideal NC commands: the plan's moves as rest-to-rest profiles (every move ends at rest: the programs use
/// exact stop), sampled at the plan's sample time. Channels `t` [s] (time) and `x_ref` [m] (reference_position).
Trace reference_trajectory(const TestPlan& plan);

// ---- identifiability prediction ----

/// The demo drive used as the nominal model: M 69.1 kg, B 54.2 N*s/m, F_C 742.8 N, F_B 946.2 N (the paper's
/// values) with a ball-screw Stribeck velocity v_s = 5 mm/s instead of the paper's 0.864 m/s. Rotary: the rotary demo
/// table of `feedid synth --rotary` (J 2 kg*m^2, B 5 N*m*s/rad, F_C 20 N*m, F_B 26 N*m, v_s 0.05 rad/s).
AxisModel nominal_demo_drive(bool rotary = false);

struct PredictionOptions {
    AxisModel drive{nominal_demo_drive()};  ///< nominal drive model (drive.rotary: the prediction's keys and units)
    double force_noise{10.0};               ///< white noise on the drive force per sample (current noise * K) [N]
    double position_resolution{1e-6};       ///< position quantisation [m or rad]
    /// Error of one pass's friction level beyond white noise (friction varying along the stroke, force ripple) [N]:
    /// what limits the Stribeck fit, which sees each constant-velocity pass as one point of the friction curve.
    double level_error{5.0};
    std::optional<double> split_velocity;      ///< step 1 above this speed [m/s]; default 5 * nominal v_s
    double identifiable_relative_error{0.10};  ///< a parameter counts as identifiable below this relative std. error
};

/// The defaults for an axis kind: a linear axis's as PredictionOptions has them (the demo drive; the force noise of
/// its 0.02 A of current noise through 453.6 N/A; one pass's level error 0.67 % of F_C; a 1 um encoder), a rotary
/// axis's the rotary demo table's (0.02 A through 2 N*m/A: 0.04 N*m; 0.135 N*m; 1 millidegree), in SI.
PredictionOptions default_prediction_options(bool rotary);

struct ParameterPrediction {
    std::string key;     ///< result-document key ("mass_kg", "breakaway_N", ...)
    std::string symbol;  ///< "M", "F_B", ...
    std::string unit;
    double nominal{0.0};
    double standard_error{0.0};  ///< expected standard error [unit of the parameter]; inf when not determined
    bool identifiable{false};
};

struct IdentifiabilityPrediction {
    double step1_condition_number{0.0};  ///< of the step-1 regressor [x'', x', sgn x'] as the trace will give it
    std::size_t step1_samples{0};
    std::size_t step2_levels{0};       ///< constant-velocity friction levels (passes x directions) for step 2
    double slowest_cruise_speed{0.0};  ///< [m/s]
    std::vector<ParameterPrediction> parameters;
    std::vector<std::string> diagnostics;

    [[nodiscard]] const ParameterPrediction* find(const std::string& key) const;
};

/// Predicts what the plan's data can identify. Step 1 (M, B, F_C): the regressors [x'', x', sgn x'] of the ideal
/// trajectory above the split speed, with the force noise plus the acceleration noise that differentiating the
/// quantised position adds; standard errors sigma*sqrt(diag((Phi^T Phi)^-1)). Step 2 (B, F_C, F_B, v_s): one friction
/// level per constant-velocity pass and direction, weighted by its error, fitted with the nominal friction curve's
/// Jacobian (Gauss-Newton covariance).
IdentifiabilityPrediction predict_identifiability(const TestPlan& plan, const PredictionOptions& options = {});

/// The plan and its prediction as the `feedid plan --json` document: axis, travel, centres, duration, blocks, sample
/// time, every pass (centre, feedrate in m/s and mm/min, stroke, durations), the notes, and the prediction with
/// each parameter's nominal value, standard error (null when not determined) and identifiability.
nlohmann::json plan_document(const TestPlan& plan, const IdentifiabilityPrediction& prediction);

}  // namespace feedid
