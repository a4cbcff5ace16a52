// feedid._feedid.defaults(): the keyword defaults of the Python functions, read from the library's Options structs
// (a default-constructed struct, in the unit the keyword's name states), so that a default lives in one place.
#include <string>

#include <fmt/core.h>

#include "binding.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/identify/option_names.hpp"
#include "feedid/model/drive.hpp"
#include "feedid/plan/test_plan.hpp"
#include "feedid/sim/simulate.hpp"
#include "feedid/sim/synth.hpp"

namespace feedid::python {

namespace {

// A value converted to the keyword's unit, as the decimal a person would write: 15 significant digits drop the
// rounding of the conversion (0.030 m / 1e-3 = 29.999999999999996 mm is 30 mm).
double decimal(double value) {
    return std::stod(fmt::format("{:.15g}", value));
}

py::dict drive_defaults() {
    const DriveConstants drive;
    py::dict out;
    out["gear_ratio"] = drive.gear_ratio;
    return out;
}

py::dict identify_defaults() {
    const IdentifyOptions options;
    py::dict out = drive_defaults();
    // "auto": the data choose the model (and an offset and delay) unless a model or offset= is given
    out["model"] = options.model_selection.automatic ? std::string(automatic_model_name)
                                                     : name_of(friction_model_names, options.model);
    out["stribeck"] = options.stribeck;
    out["differentiation"] = name_of(differentiation_names, options.preprocess.differentiation);
    out["velocity_source"] = name_of(velocity_source_names, options.preprocess.velocity_source);
    out["filter_order"] = options.preprocess.filter_order;
    out["savitzky_golay_order"] = options.preprocess.savitzky_golay_order;
    out["rls"] = name_of(rls_variant_names, options.step1.rls.variant);
    out["forgetting_factor"] = options.step1.rls.forgetting_factor;
    out["initial_covariance"] = options.step1.rls.initial_covariance;
    out["systematic"] = options.systematic;
    out["threads"] = options.threads;
    return out;
}

py::dict gains_defaults() {
    const GainOptions options;
    py::dict out = drive_defaults();
    out["velocity_loop"] = name_of(velocity_loop_names, options.velocity_loop);
    out["feedforward"] = options.feedforward;
    out["forgetting"] = options.rls.forgetting_factor;
    return out;
}

py::dict simulate_defaults() {
    py::dict out = gains_defaults();
    out["substeps"] = SimulationOptions{}.substeps;
    return out;
}

py::dict synth_defaults() {
    py::dict out;
    out["slow_passes"] = TestReference{}.slow_passes;
    return out;
}

// feedid.plan's keywords: mm, mm/min, um, mm/s (PlanUnits of a linear axis); the nominal drive in SI.
py::dict plan_defaults() {
    const PlanUnits mm;
    const TestPlanOptions plan = default_plan_options(TestPlanOptions{}.axis);
    const PredictionOptions prediction = default_prediction_options(false);
    const FrictionBranch& branch = prediction.drive.friction.forward;
    py::dict out;
    out["axis"] = plan.axis;
    out["stroke_mm"] = decimal(plan.stroke / mm.length());
    out["slow_feeds_mm_per_min"] = fmt::format("{:g}:{:g}:{}", decimal(plan.slow_feeds.front() / mm.feed()),
                                               decimal(plan.slow_feeds.back() / mm.feed()), plan.slow_feeds.size());
    out["max_pass_time_s"] = plan.max_pass_time;
    out["cycles"] = plan.cycles;
    out["acceleration_m_per_s2"] = plan.acceleration / mm.acceleration();
    out["dwell_s"] = plan.dwell;
    out["sample_time_s"] = plan.sample_time;
    out["positioning_feed_mm_per_min"] = decimal(plan.positioning_feed / mm.feed());
    out["mass_kg"] = prediction.drive.mass;
    out["viscous_Ns_per_m"] = branch.viscous;
    out["coulomb_N"] = branch.coulomb;
    out["breakaway_N"] = branch.breakaway.value_or(0.0);
    out["stribeck_velocity_mm_per_s"] = decimal(branch.stribeck_velocity.value_or(0.0) / mm.length());
    out["force_noise_N"] = prediction.force_noise;
    out["level_error_N"] = prediction.level_error;
    out["position_resolution_um"] = decimal(prediction.position_resolution * 1e6);
    return out;
}

}  // namespace

void bind_defaults(py::module_& m) {
    m.def(
        "defaults",
        [] {
            py::dict out;
            out["identify"] = identify_defaults();
            out["gains"] = gains_defaults();
            out["simulate"] = simulate_defaults();
            out["synth"] = synth_defaults();
            out["plan"] = plan_defaults();
            return out;
        },
        "Each function's keyword defaults, from the library's Options structs: {function: {keyword: value}}");
}

}  // namespace feedid::python
