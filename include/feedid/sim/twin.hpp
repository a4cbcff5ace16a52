#pragma once
// The twin of a recorded trace: the identified axis (a result document) simulated in closed loop with its controller
// (a gains document, or gains identified from the trace) on the trace's recorded reference, and compared with what
// the machine did. One orchestration for every front-end (`feedid simulate`, Python's feedid.simulate), so that each
// refuses the same input with the same message and fails for the same reasons.

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/core/status.hpp"
#include "feedid/core/trace.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/model/drive.hpp"
#include "feedid/model/friction.hpp"
#include "feedid/sim/simulate.hpp"

namespace feedid {

/// A result document (feedid identify --json, or a drive file) and the name its messages give it.
struct TwinDocument {
    const nlohmann::json& document;
    std::string source;  ///< a path, or what the caller calls it ("result")
};

struct TwinOptions {
    DriveConstants drive;  ///< turns the trace's drive signal into force [N]
    /// The controller's structure and what identifying or overriding its gains uses; run_twin sets force_per_signal,
    /// signal_unit and saturation_N from the trace, `drive` and `saturation` (set_drive_signal()).
    GainOptions gains;
    /// The drive signal's limit in its own units (e.g. 10 for 10 V); none = no limit.
    std::optional<double> saturation;
    SimulationOptions simulation;
};

/// A recorded trace's twin, simulated.
struct Twin {
    AxisModel axis;              ///< from the result document
    TwinController controller;   ///< documented or identified
    TraceSimulation simulation;  ///< how the simulated axis compares with the machine
    /// failed when the controller's gains are not to be trusted or the simulation diverged or does not follow the
    /// machine: the twin then validates nothing (`failure` says why).
    Status status{Status::ok};
    /// Why the twin failed: the simulation's first diagnostic when it failed, else the controller's first note; ""
    /// when ok.
    std::string failure;

    /// The controller's notes, then the simulation's diagnostics.
    [[nodiscard]] std::vector<std::string> diagnostics() const;
};

/// Builds and runs the twin of `trace`: the axis of `result` (axis_from_document()), refused with InputError when its
/// axis kind is not the trace's or when it does not fit the trace's drive force (model_does_not_fit(): units, sign,
/// another axis); the controller of `gains` (documented_twin_controller(), which refuses gains of the other axis
/// kind) or, without one, identified from the trace (identified_twin_controller()); then simulate_trace() with the
/// injected signal the trace logs. InputError for bad options and as the functions named throw; AnalysisError when the
/// trace gives no gains. A failed controller or simulation is not an exception: Twin::status and Twin::failure say.
Twin run_twin(const Trace& trace, const TwinDocument& result, const std::optional<TwinDocument>& gains,
              const TwinOptions& options);

/// The simulate document of the twin (simulation_document()): `feedid simulate --json`, Simulation.to_dict().
nlohmann::json twin_document(const Trace& trace, const Twin& twin);

}  // namespace feedid
