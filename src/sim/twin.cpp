#include "feedid/sim/twin.hpp"

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/gains.hpp"

namespace feedid {

namespace {

std::string trace_name(const Trace& trace) {
    return trace.source_path.empty() ? std::string("trace") : trace.source_path;
}

// The result must be of this axis, in these units: a model of the other axis kind, or one whose forces are far from
// the trace's drive force (units mislabelled, the drive signal's sign flipped, another axis), would give a twin that
// validates nothing, so it is refused as bad input rather than simulated.
void check_axis_kind(const AxisModel& axis, const std::string& source, const Trace& trace) {
    if (axis.rotary == trace.rotary) return;
    throw InputError(fmt::format("{}: the result is of a {} axis, the trace {} of a {} axis", source,
                                 ParameterNaming{axis.rotary}.axis_kind(), trace_name(trace),
                                 ParameterNaming{trace.rotary}.axis_kind()));
}

void check_fit(const AxisModel& axis, const std::string& source, const Trace& trace,
               std::span<const double> drive_force) {
    if (const auto misfit = model_does_not_fit(axis, trace, drive_force); !misfit.empty())
        throw InputError(
            fmt::format("{}: the result does not fit the trace {}: {}", source, trace_name(trace), misfit));
}

}  // namespace

std::vector<std::string> Twin::diagnostics() const {
    std::vector<std::string> all = controller.notes;
    all.insert(all.end(), simulation.diagnostics.begin(), simulation.diagnostics.end());
    return all;
}

Twin run_twin(const Trace& trace, const TwinDocument& result, const std::optional<TwinDocument>& gains,
              const TwinOptions& options) {
    if (const auto problem = options.drive.validate(); !problem.empty()) throw InputError(problem);
    Twin twin;
    twin.axis = axis_from_document(result.document, result.source);
    check_axis_kind(twin.axis, result.source, trace);
    const std::vector<double> force = drive_force(trace, options.drive);
    check_fit(twin.axis, result.source, trace, force);
    const std::vector<double> injection = injection_force(trace, options.drive);
    GainOptions gain_options = options.gains;
    set_drive_signal(gain_options, trace, options.drive, options.saturation);
    if (const auto problem = gain_options.validate(); !problem.empty()) throw InputError(problem);
    twin.controller = gains ? documented_twin_controller(gains->document, gains->source, gain_options, trace)
                            : identified_twin_controller(trace, force, gain_options, injection);
    twin.simulation = simulate_trace(trace, force, twin.axis, twin.controller.model, options.simulation, injection);
    // A twin with untrusted gains, or one that diverged, validates nothing.
    if (twin.simulation.status == Status::failed) {
        twin.status = Status::failed;
        if (!twin.simulation.diagnostics.empty()) twin.failure = twin.simulation.diagnostics.front();
    }
    if (twin.controller.status == Status::failed) {
        twin.status = Status::failed;
        if (twin.failure.empty() && !twin.controller.notes.empty()) twin.failure = twin.controller.notes.front();
    }
    // A test signal in the drive that the twin does not add leaves a force error that is no model's: the root cause
    // comes first.
    if (injection.empty()) {
        if (const auto found = unmapped_injection(trace)) {
            twin.status = Status::failed;
            twin.failure = unmapped_injection_message(*found) +
                           ": a simulation without it compares the model with a "
                           "drive it does not see";
            twin.controller.notes.insert(twin.controller.notes.begin(), twin.failure);
        }
    }
    return twin;
}

nlohmann::json twin_document(const Trace& trace, const Twin& twin) {
    return simulation_document(trace, twin.controller, twin.simulation);
}

}  // namespace feedid
