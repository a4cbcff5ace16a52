#pragma once
// The reversal test: the measurement program for the mechanical fingerprint (identify/fingerprint.hpp). Around each
// centre along the travel it makes micro-steps through a reversal (n steps forward, 2n back, n forward again, each
// followed by a dwell: the motor crosses the backlash while the scale stands), then slow constant-speed strokes back
// and forth at a few feedrates (each reversal at rest, the friction force of each direction held long enough to settle
// the force-deflection figures). The moves are a TestPlan, so the part program (gcode_writer.hpp) and the reference
// trajectory (test_plan.hpp) come from the same code as the friction test's.
//
// SI inside (m, m/s, m/s^2, s; rad on a rotary axis); the command line writes mm, um and mm/min (deg, mdeg, deg/min).

#include <string>
#include <vector>

#include "feedid/plan/test_plan.hpp"

namespace feedid {

struct ReversalTestOptions {
    std::string axis{"X"};             ///< as the NC knows it; A, B, C are rotary
    double travel_min{-0.1};           ///< lower travel limit [m]
    double travel_max{0.1};            ///< upper travel limit [m]
    std::vector<double> centers{0.0};  ///< where the reversals happen [m]
    double micro_step{1e-6};           ///< one micro-step [m] (1 um)
    int micro_steps{10};               ///< micro-steps each way around a reversal
    int micro_cycles{2};               ///< reversal cycles of micro-steps per centre
    double micro_feed{100.0 / 60e3};   ///< feedrate of a micro-step [m/s] (100 mm/min)
    double micro_dwell{0.1};           ///< dwell after each micro-step [s]
    std::vector<double> feeds{20.0 / 60e3, 200.0 / 60e3, 2000.0 / 60e3};  ///< slow strokes' feedrates [m/s]
    double stroke{0.002};                                                 ///< length of the slow strokes [m] (2 mm)
    int cycles{2};                                                        ///< back-and-forth cycles per feedrate
    double dwell{0.3};                       ///< dwell at each reversal of the slow strokes [s]
    double acceleration{1.0};                ///< path acceleration (machine data) [m/s^2]
    double positioning_feed{5000.0 / 60e3};  ///< between centres [m/s]
    double sample_time{0.001};               ///< the trace's sample time (the reference trajectory's) [s]

    [[nodiscard]] PlanUnits units() const { return {is_rotary_axis(axis)}; }
    /// What is wrong ("" when nothing); make_reversal_plan checks the travel.
    [[nodiscard]] std::string validate() const;
};

/// The defaults for an axis: the linear axis's as above; a rotary axis's the same numbers in degrees (1 mdeg steps,
/// 2 deg strokes, deg/min, travel +-100 deg).
ReversalTestOptions default_reversal_options(const std::string& axis);

/// The reversal test as moves (every move ends at rest; the part program programs exact stop). InputError for invalid
/// options or a move that leaves the travel.
TestPlan make_reversal_plan(const ReversalTestOptions& options);

}  // namespace feedid
