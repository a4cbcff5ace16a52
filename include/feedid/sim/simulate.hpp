#pragma once
// The digital twin: fixed-step simulation of an identified axis in closed loop with its controller, driven by a
// reference position (the paper's validation, docs/method.md; the EMPS benchmark's simulation).
//   M*x'' = F_d + F_ext - F_f(x') - F_0,   F_d = current loop(F_cmd + u_inj),   F_cmd = controller(x_ref, x)
// (F_ext: a force on the mass from outside the drive; u_inj: a test signal injected at the controller's output).
// Stick-slip: at rest (x' = 0) the axis stays at rest while the applied force F_a = F_d + F_ext - F_0 lies within
// [-F_B(reverse), F_B(forward)] (friction takes whatever value holds it), and starts in the direction of F_a when it
// exceeds the breakaway force. A moving axis whose velocity would pass through zero within a step stops exactly
// there (the crossing instant is found by linear interpolation) and then obeys the rest condition again: no
// chattering about zero and no creeping below breakaway.

#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/model/controller.hpp"
#include "feedid/model/friction.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/core/status.hpp"
#include "feedid/core/trace.hpp"

namespace feedid {

/// A stretch of the axis whose friction differs from the rest (a worn or a tight part of the screw): while the axis
/// is inside [from_m, to_m], the Coulomb and breakaway friction of both directions are `coulomb_factor` times the
/// axis model's (so the Stribeck rise F_B - F_C scales with them); viscous friction and mass are unchanged.
struct FrictionZone {
    double from_m{0.0};          ///< [m]
    double to_m{0.0};            ///< [m], > from_m
    double coulomb_factor{1.0};  ///< > 0
};

struct SimulationOptions {
    int substeps{8};                              ///< integration steps per sample of the reference (>= 1)
    std::optional<double> position_resolution_m;  ///< the controller sees the position quantised to this [m]
    std::optional<double> initial_position_m;     ///< default: the first reference sample
    /// Start with the velocity-loop integrator holding the offset F_0 (the axis at rest under its weight).
    bool hold_offset{true};
    /// Friction along the axis (synthetic wear); the first zone that holds the position applies. Empty = uniform.
    std::vector<FrictionZone> friction_zones;
    /// The recorded drive force is the one this many integration steps before the usual instant (one step after the
    /// sample): a drive signal logged late. 0 to max_drive_signal_delay_steps.
    int drive_signal_delay_steps{0};
    static constexpr int max_drive_signal_delay_steps = 256;

    [[nodiscard]] std::string validate() const;
};

/// What drives the simulation: the reference on a regular sample grid.
struct SimulationInput {
    double sample_time_s{0.0};               ///< T [s] of the reference samples
    std::span<const double> reference;       ///< x_ref(k*T) [m]
    std::span<const double> external_force;  ///< F_ext(k*T) [N], acting in +x; empty = none
    /// u_inj(k*T) [N]: a test signal added to the controller's force command before the current loop (held over
    /// the sample); the sum saturates as the command does. Empty = none.
    std::span<const double> injection;
};

/// Signals at the sample instants k*T (the controller's state when it has just computed its outputs).
struct SimulationOutput {
    std::vector<double> time;               ///< [s], from 0
    std::vector<double> reference;          ///< x_ref [m]
    std::vector<double> position;           ///< x [m] (exact; the controller saw it quantised)
    std::vector<double> measured_position;  ///< x as the controller measured it [m]
    std::vector<double> velocity;           ///< x' [m/s]
    std::vector<double> acceleration;       ///< x'' [m/s^2] during the first integration step after the sample
    std::vector<double> velocity_command;   ///< position loop output [m/s]
    std::vector<double> force_command;      ///< velocity loop output, saturated [N]
    std::vector<double> force;              ///< drive force F_d after the current loop, one integration step after the
                                            ///< sample (what a current sensor sampled there would read) [N]
    std::vector<double> tracking_error;     ///< x_ref - x [m]
    std::size_t stick_transitions{0};       ///< how often the axis came to rest
};

/// Simulates the axis in closed loop. Throws InputError for an invalid model, controller or options.
/// Never allocates inside the time loop (outputs are sized up front).
SimulationOutput simulate(const AxisModel& axis, const ControllerModel& controller, const SimulationInput& input,
                          const SimulationOptions& options = {});

/// The same into an output that is reused: its columns keep their memory, so repeated simulations (a parameter
/// sweep, a benchmark) allocate nothing and touch no fresh pages once the output has held as many samples.
void simulate(const AxisModel& axis, const ControllerModel& controller, const SimulationInput& input,
              const SimulationOptions& options, SimulationOutput& out);

/// The axis model from an identification result document (docs/documents.md keys: parameters.mass_kg.value, ...;
/// per-direction `_forward`/`_reverse` keys; rotary-axis keys). A null breakaway force or Stribeck velocity means no
/// Stribeck term; a missing offset means 0. Values may also be plain numbers (a drive file). InputError naming
/// `source` and the key when the mass or a friction level is missing.
AxisModel axis_from_document(const nlohmann::json& document, const std::string& source);

/// The paper's validation figures and the EMPS relative errors.
struct ValidationMetrics {
    double position_relative_error_pct{0.0};      ///< 100*||x - x_sim|| / ||x||
    double velocity_relative_error_pct{0.0};      ///< against the measured velocity (logged, or filtered differences)
    double acceleration_relative_error_pct{0.0};  ///< against the measured acceleration (filtered differences)
    double force_relative_error_pct{0.0};         ///< 100*||F - F_sim|| / ||F||
    double tracking_error_mae_model_m{0.0};       ///< mean |x_ref - x_sim|
    double tracking_error_mae_machine_m{0.0};     ///< mean |x_ref - x|
    double modelling_error_mae_m{0.0};            ///< mean |x - x_sim|  (e_m = x_CNC - x_model)
    double tracking_error_max_model_m{0.0};
    double tracking_error_max_machine_m{0.0};
    double modelling_error_max_m{0.0};
};

/// Compares a simulation with the trace it reproduces. `measured_force` is the drive force per sample [N].
ValidationMetrics validate_simulation(const Trace& trace, std::span<const double> measured_force,
                                      const SimulationOutput& simulated);

/// The largest factor, either way, between a trace's drive force and the force an axis model predicts from the
/// trace's motion at which the model is taken to be of this axis, in these units. The axis's own model gives about 1
/// (its fit's relative error is a few to some tens of per cent); units mislabelled by 60 (per minute) or 1000 (mm,
/// mA) lie far outside, as does another axis's model.
inline constexpr double model_scale_limit = 10.0;

/// Why `axis` does not fit `trace` and its drive force [N] per sample ("" when it does, or when the trace does not
/// move): the force the model predicts from the trace's motion, F_hat = M*a + F_f(v) + F_0 - F_ext (velocity and
/// acceleration as validate_simulation() measures them), against the drive force F over the samples moving faster
/// than 5 % of the top speed. Their least-squares factor c = <F, F_hat>/<F_hat, F_hat> must lie within
/// [1/model_scale_limit, model_scale_limit]: a negative c is a drive signal of the opposite sign, a c far from 1 a
/// model in other units than the trace or of another axis. The reason gives the figures.
std::string model_does_not_fit(const AxisModel& axis, const Trace& trace, std::span<const double> drive_force);

/// The simulate document (docs/documents.md); a rotary axis's lengths in rad (`tracking_error_mae_rad`, ...).
nlohmann::json validation_document(const ValidationMetrics& metrics, bool rotary = false);

/// The errors of the paper's Fig. 6 over time, thinned for plotting by extreme_preserving_indices() over all three
/// together: every point is one real sample (so e_m = e_model - e_machine holds at each), and each error's largest and
/// smallest values are kept exactly. Lengths [m], or [rad] on a rotary axis.
struct ValidationSeries {
    std::vector<double> time;                    ///< [s], from 0 as SimulationOutput::time
    std::vector<double> tracking_error_machine;  ///< x_ref - x
    std::vector<double> tracking_error_model;    ///< x_ref - x_sim
    std::vector<double> modelling_error;         ///< e_m = x - x_sim
    std::size_t samples{0};                      ///< samples before thinning
};

/// At most this many points per series by default: a plot's worth, and a few tens of kB of JSON.
inline constexpr std::size_t validation_series_points = 2000;

/// The errors of a simulation against the trace it reproduces, thinned to at most `max_points` (>= 6); up to the first
/// sample at which one is not a finite number (ValidationSeries::samples counts the samples before it).
ValidationSeries validation_series(const Trace& trace, const SimulationOutput& simulated,
                                   std::size_t max_points = validation_series_points);

/// The "series" object of the simulate document: time_s and the three errors, with the length unit in the key
/// (`tracking_error_machine_m`, `tracking_error_model_m`, `modelling_error_m`; `_rad` on a rotary axis).
nlohmann::json validation_series_document(const ValidationSeries& series, bool rotary);

/// The controller of a recorded trace's twin, and how it was obtained.
struct TwinController {
    ControllerModel model;           ///< loop sample times resolved (never 0)
    std::vector<std::string> notes;  ///< how it was obtained, for the simulate document's diagnostics
    Status status{Status::ok};       ///< failed: gains identified from a fit too poor to trust (the first note says)
};

/// The controller of a gains document (`source` names it in messages) for simulating `trace`: the saturation,
/// current-loop lag and velocity measurement that `options` sets replace the document's, and loop sample times the
/// document leaves open become the trace's sample time. InputError as controller_from_document(), and when the
/// gains are of a rotary axis and the trace of a linear one, or the other way round.
TwinController documented_twin_controller(const nlohmann::json& gains_document, const std::string& source,
                                          const GainOptions& options, const Trace& trace);

/// The controller identified from the trace, its drive force [N] per sample and the injected signal [N] per sample
/// (identify_gains), with a note giving its gains; status failed (and the reason first among the notes) when the
/// gains' fit is too poor to trust. Throws as identify_gains() does, and AnalysisError when the fit gave no gains.
TwinController identified_twin_controller(const Trace& trace, std::span<const double> drive_force,
                                          const GainOptions& options, std::span<const double> injection = {});

/// A recorded trace simulated by its twin, and how the simulation compares with the machine.
struct TraceSimulation {
    SimulationOutput output;
    ValidationMetrics metrics;
    bool injected{false};  ///< an injected signal was added to the simulated controller output
    /// failed when the simulation diverged (a simulated value not finite, or the simulated axis farther from the
    /// machine than the trace's whole travel: an unstable loop), or when it does not follow the machine (its mean
    /// distance from the machine above the machine's own mean tracking error); the diagnostics say which, with the
    /// figures.
    Status status{Status::ok};
    std::vector<std::string> diagnostics;
};

/// Simulates the axis in closed loop with `controller` on the trace's reference (and its external force, when
/// logged), starting where the machine started unless `options` says otherwise, and compares the result with the
/// trace and its drive force [N] per sample. `injection` [N] per sample (injection_force() of drive.hpp; empty =
/// none), a test signal the machine's controller added to its output, is added to the simulated controller's output
/// likewise, so that measured and simulated force both contain it. Throws InputError as simulate() does, and for a
/// trace without a reference or position.
TraceSimulation simulate_trace(const Trace& trace, std::span<const double> drive_force, const AxisModel& axis,
                               const ControllerModel& controller, SimulationOptions options = {},
                               std::span<const double> injection = {});

/// The simulate document (docs/documents.md): the validation figures of validation_document(),
/// the trace (path, samples, sample time), the controller simulated, whether the axis is rotary, the series of errors
/// (validation_series_document()) and the controller's notes as diagnostics; "status" "failed" when the controller or
/// the simulation failed. It holds no NaN or infinity: a figure that is not a finite number is null, and every null is
/// named in a diagnostic with its reason (null_reasons.hpp).
nlohmann::json simulation_document(const Trace& trace, const TwinController& controller,
                                   const TraceSimulation& simulation);

/// The simulated signals as a trace (time, reference, position, velocity, acceleration, velocity command, force
/// command, force, tracking error), for `feedid simulate --out`.
Trace simulation_trace(const SimulationOutput& output, bool rotary = false);

}  // namespace feedid
