#include "feedid/sim/simulate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/json_adapters.hpp"
#include "feedid/numeric/native_interval.hpp"
#include "feedid/core/null_reasons.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/numeric/signal.hpp"

namespace feedid {

std::string SimulationOptions::validate() const {
    if (substeps < 1 || substeps > 1000) return "the integration substeps per sample must be between 1 and 1000";
    if (drive_signal_delay_steps < 0 || drive_signal_delay_steps > max_drive_signal_delay_steps)
        return fmt::format("the drive signal's delay must be 0 to {} integration steps", max_drive_signal_delay_steps);
    if (position_resolution_m && !(*position_resolution_m > 0.0 && std::isfinite(*position_resolution_m))) {
        return "the position resolution must be a positive length";
    }
    for (const auto& zone : friction_zones) {
        if (!(std::isfinite(zone.from_m) && std::isfinite(zone.to_m) && zone.from_m < zone.to_m)) {
            return "a friction zone needs finite limits with from < to";
        }
        if (!(zone.coulomb_factor > 0.0 && std::isfinite(zone.coulomb_factor))) {
            return "a friction zone's Coulomb factor must be a positive number";
        }
    }
    return {};
}

namespace {

std::string validate_axis(const AxisModel& axis) {
    if (!(axis.mass > 0.0 && std::isfinite(axis.mass))) return "the mass must be a positive number";
    for (const auto* branch : {&axis.friction.forward, &axis.friction.reverse}) {
        if (!(std::isfinite(branch->viscous) && std::isfinite(branch->coulomb))) {
            return "the friction levels must be finite numbers";
        }
        if (branch->coulomb < 0.0) return "the Coulomb friction must be >= 0";
        if (branch->has_stribeck() && !(*branch->breakaway >= 0.0)) return "the breakaway force must be >= 0";
    }
    if (!std::isfinite(axis.offset)) return "the force offset must be a finite number";
    return {};
}

void check_simulation(const AxisModel& axis, const ControllerModel& model, const SimulationInput& input,
                      const SimulationOptions& options) {
    if (const auto problem = validate_axis(axis); !problem.empty()) throw InputError("simulation: " + problem);
    if (const auto problem = model.validate(); !problem.empty()) throw InputError("simulation: " + problem);
    if (const auto problem = options.validate(); !problem.empty()) throw InputError("simulation: " + problem);
    if (!(input.sample_time_s > 0.0 && std::isfinite(input.sample_time_s))) {
        throw InputError("simulation: the sample time must be positive");
    }
    if (!input.external_force.empty() && input.external_force.size() != input.reference.size()) {
        throw InputError("simulation: the external force must have as many samples as the reference");
    }
    if (!input.injection.empty() && input.injection.size() != input.reference.size()) {
        throw InputError("simulation: the injected signal must have as many samples as the reference");
    }
}

// Cleared and reserved, not resized: each column is written once, in order (no zero-filling pass over ~40 MB for
// 60 s at 8 kHz); a reused output keeps its memory.
void prepare_output(SimulationOutput& out, std::size_t samples) {
    for (auto* column :
         {&out.time, &out.reference, &out.position, &out.measured_position, &out.velocity, &out.acceleration,
          &out.velocity_command, &out.force_command, &out.force, &out.tracking_error}) {
        column->clear();
        column->reserve(samples);
    }
    out.stick_transitions = 0;
}

// Friction at 0+ in each direction: what the drive must exceed to break away.
struct Breakaway {
    double forward;
    double reverse;
};

// The friction of a stretch of the axis: the law of each direction and the breakaway forces.
struct FrictionSection {
    FrictionLaw forward;
    FrictionLaw reverse;
    Breakaway breakaway;
};

FrictionSection section_of(const Friction& friction) {
    return {friction.forward.law(),
            friction.reverse.law(),
            {friction.breakaway_force(true), friction.breakaway_force(false)}};
}

// In a friction zone the Coulomb and breakaway friction, so the Stribeck rise F_B - F_C, scale by its factor.
FrictionSection scaled(FrictionSection section, double factor) {
    for (FrictionLaw* law : {&section.forward, &section.reverse}) {
        law->coulomb *= factor;
        law->stribeck_rise *= factor;
    }
    section.breakaway = {section.breakaway.forward * factor, section.breakaway.reverse * factor};
    return section;
}

struct Zone {
    double from;
    double to;
    FrictionSection friction;
};

// The axis, unpacked once for the time loop: M*x'' = F_a - F_f(x'),  F_a = F_d + F_ext - F_0.
struct Plant {
    double inverse_mass{0.0};
    double offset{0.0};  // F_0 [N]
    FrictionSection friction;
    std::vector<Zone> zones;  // sized here, not in the loop

    // The first zone that holds the position, or the axis' own friction.
    [[nodiscard]] const FrictionSection& friction_at(double x) const {
        for (const auto& zone : zones) {
            if (x >= zone.from && x <= zone.to) return zone.friction;
        }
        return friction;
    }
};

Plant make_plant(const AxisModel& axis, const std::vector<FrictionZone>& friction_zones) {
    Plant plant;
    plant.inverse_mass = 1.0 / axis.mass;
    plant.offset = axis.offset;
    plant.friction = section_of(axis.friction);
    plant.zones.reserve(friction_zones.size());
    for (const auto& zone : friction_zones) {
        plant.zones.push_back({zone.from_m, zone.to_m, scaled(plant.friction, zone.coulomb_factor)});
    }
    return plant;
}

struct Motion {
    double position;  // x [m]
    double velocity;  // x' [m/s]
};

// One integration step [t, t+h] at rest with the applied force held: the axis stays exactly where it is while
// static friction balances the force, and starts in its direction once it exceeds the breakaway force.
double step_from_rest(const Breakaway& breakaway, double inverse_mass, double applied, double h, Motion& motion) {
    double acceleration = 0.0;
    if (applied > breakaway.forward) {
        acceleration = (applied - breakaway.forward) * inverse_mass;
    } else if (applied < -breakaway.reverse) {
        acceleration = (applied + breakaway.reverse) * inverse_mass;
    }
    const double v_next = acceleration * h;
    motion.position += 0.5 * v_next * h;
    motion.velocity = v_next;
    return acceleration;
}

// One integration step [t, t+h] in motion with the applied force held (trapezoidal position); an axis whose velocity
// would pass through zero within the step stops there, at t + v/(v - v_next)*h, and counts as a stick transition.
double step_moving(const FrictionSection& friction, double inverse_mass, double applied, double h, Motion& motion,
                   std::size_t& stick_transitions) {
    const double v = motion.velocity;
    const double friction_force = v > 0.0 ? friction.forward.magnitude(v) : -friction.reverse.magnitude(-v);
    const double acceleration = (applied - friction_force) * inverse_mass;
    const double v_next = v + acceleration * h;
    if ((v > 0.0 && v_next <= 0.0) || (v < 0.0 && v_next >= 0.0)) {
        const double until = v / (v - v_next) * h;
        motion.position += 0.5 * v * until;
        motion.velocity = 0.0;
        ++stick_transitions;
    } else {
        motion.position += 0.5 * (v + v_next) * h;
        motion.velocity = v_next;
    }
    return acceleration;
}

// The plant over one integration step; returns the acceleration during it.
double step_plant(const Plant& plant, double applied, double h, Motion& motion, std::size_t& stick_transitions) {
    const FrictionSection& friction = plant.friction_at(motion.position);
    if (motion.velocity == 0.0) return step_from_rest(friction.breakaway, plant.inverse_mass, applied, h, motion);
    return step_moving(friction, plant.inverse_mass, applied, h, motion, stick_transitions);
}

// The position as the controller measures it: quantised to the encoder's resolution, or exact.
struct PositionSensor {
    double resolution{0.0};
    double inverse_resolution{0.0};

    explicit PositionSensor(std::optional<double> resolution_m)
        : resolution(resolution_m.value_or(0.0)), inverse_resolution(resolution > 0.0 ? 1.0 / resolution : 0.0) {}
    [[nodiscard]] double measure(double x) const {
        return resolution > 0.0 ? resolution * std::nearbyint(x * inverse_resolution) : x;
    }
};

// The controller on the integration grid: each loop runs every whole number of integration steps, then the current
// loop F_d' = (F_cmd - F_d)/tau, exact over a step with F_cmd held.
class DriveLoops {
public:
    DriveLoops(const ControllerModel& model, double sample_time_s, double h)
        : position_every_(std::max(1L, std::lround(position_cycle(model, sample_time_s) / h))),
          velocity_every_(std::max(1L, std::lround(velocity_cycle(model, sample_time_s) / h))),
          reference_step_(static_cast<double>(position_every_) * h),
          lag_(model.current_lag_s > 0.0 ? std::exp(-h / model.current_lag_s) : 0.0),
          saturation_(model.saturation_N.value_or(std::numeric_limits<double>::infinity())),
          injection_gain_(model.injection_gain),
          setpoint_delay_samples_(model.setpoint_delay_s / sample_time_s),
          controller_(model, reference_step_, static_cast<double>(velocity_every_) * h) {}

    // At rest at the measured position, on the first reference sample, the integrator holding `held_force` [N] (and
    // the force command with it, when there is an integrator).
    void start(double measured, std::span<const double> reference, double held_force) {
        reference_ = reference;
        controller_.reset(measured, held_force);
        force_command_ = controller_.model().velocity_integral_gain_N_per_m > 0.0 ? held_force : 0.0;
        drive_force_ = force_command_;
        previous_reference_ = reference.front();
    }

    // One integration step. The reference between samples is interpolated linearly (exact at the samples) at
    // `fraction` of the way from `reference_now` to `reference_next` (sample `k`), or, with a setpoint delay, that
    // long before; `injection` [N] is added to the force command before the current loop, and the sum saturates at
    // the command's limit.
    void step(std::size_t k, double reference_now, double reference_next, double fraction, double measured,
              double injection) noexcept {
        if (position_countdown_ == 0) {
            position_countdown_ = position_every_;
            const double reference = setpoint_delay_samples_ > 0.0
                                         ? delayed_reference(static_cast<double>(k) + fraction)
                                         : reference_now + fraction * (reference_next - reference_now);
            const double reference_velocity = first_ ? 0.0 : (reference - previous_reference_) / reference_step_;
            first_ = false;
            previous_reference_ = reference;
            velocity_command_ = controller_.position_step(reference, reference_velocity, measured);
        }
        --position_countdown_;
        if (velocity_countdown_ == 0) {
            velocity_countdown_ = velocity_every_;
            force_command_ = controller_.velocity_step(velocity_command_, measured);
        }
        --velocity_countdown_;
        const double command = std::clamp(force_command_ + injection_gain_ * injection, -saturation_, saturation_);
        drive_force_ = lag_ * drive_force_ + (1.0 - lag_) * command;
    }

    [[nodiscard]] double velocity_command() const noexcept { return velocity_command_; }
    [[nodiscard]] double force_command() const noexcept { return force_command_; }
    [[nodiscard]] double drive_force() const noexcept { return drive_force_; }

private:
    // The reference at `at` - the setpoint delay [samples], linear between its samples; the first before the start.
    [[nodiscard]] double delayed_reference(double at) const noexcept {
        const double back = at - setpoint_delay_samples_;
        if (!(back > 0.0)) return reference_.front();
        const auto i = static_cast<std::size_t>(back);
        if (i + 1 >= reference_.size()) return reference_.back();
        const double f = back - static_cast<double>(i);
        return reference_[i] + f * (reference_[i + 1] - reference_[i]);
    }

    static double position_cycle(const ControllerModel& model, double sample_time_s) {
        return model.position_cycle_s > 0.0 ? model.position_cycle_s : sample_time_s;
    }
    static double velocity_cycle(const ControllerModel& model, double sample_time_s) {
        return model.velocity_cycle_s > 0.0 ? model.velocity_cycle_s : position_cycle(model, sample_time_s);
    }

    long position_every_;
    long velocity_every_;
    double reference_step_;  // the position loop's period [s], for the reference velocity
    double lag_;             // exp(-h/tau)
    double saturation_;      // |F_cmd + u_inj| limit [N] (infinite = none)
    double injection_gain_;  // g of F_cmd + g*u_inj
    double setpoint_delay_samples_;  // the setpoint delay [samples]
    std::span<const double> reference_;
    Controller controller_;
    long position_countdown_{0};  // steps until the position loop runs again
    long velocity_countdown_{0};
    bool first_{true};
    double previous_reference_{0.0};
    double velocity_command_{0.0};
    double force_command_{0.0};
    double drive_force_{0.0};
};

// The drive force of the last integration steps, so that the one `delay` steps back can be recorded (a drive signal
// logged late); fixed size, no allocation in the time loop.
class ForceHistory {
public:
    explicit ForceHistory(double initial) { values_.fill(initial); }
    void push(double force) noexcept {
        head_ = (head_ + 1) % values_.size();
        values_[head_] = force;
    }
    [[nodiscard]] double back(int delay) const noexcept {
        return values_[(head_ + values_.size() - static_cast<std::size_t>(delay)) % values_.size()];
    }

private:
    std::array<double, SimulationOptions::max_drive_signal_delay_steps + 1> values_{};
    std::size_t head_{0};
};

// The signals at a sample instant, `at_sample` the motion there; `force` the drive force as logged.
void record_sample(SimulationOutput& out, double time, double reference, const Motion& at_sample, double measured,
                   double acceleration, const DriveLoops& drive, double force) {
    out.time.push_back(time);
    out.reference.push_back(reference);
    out.position.push_back(at_sample.position);
    out.measured_position.push_back(measured);
    out.velocity.push_back(at_sample.velocity);
    out.acceleration.push_back(acceleration);
    out.velocity_command.push_back(drive.velocity_command());
    out.force_command.push_back(drive.force_command());
    out.force.push_back(force);
    out.tracking_error.push_back(reference - at_sample.position);
}

// The integration steps per sample: `substeps`, raised to a whole multiple of the velocity loop's cycles per sample
// when it runs faster than the samples (an 8 kHz speed controller in a 1 kHz trace), so that it runs at its own cycle.
int integration_steps(const ControllerModel& model, double dt, int substeps) {
    if (!(model.velocity_cycle_s > 0.0) || model.velocity_cycle_s >= dt) return substeps;
    const auto per_sample = std::lround(dt / model.velocity_cycle_s);
    if (per_sample < 2 || std::abs(dt / model.velocity_cycle_s - static_cast<double>(per_sample)) > 1e-6 * per_sample)
        return substeps;
    const auto cycles = static_cast<int>(per_sample);
    return std::max(1, (substeps + cycles - 1) / cycles) * cycles;
}

}  // namespace

SimulationOutput simulate(const AxisModel& axis, const ControllerModel& model, const SimulationInput& input,
                          const SimulationOptions& options) {
    SimulationOutput out;
    simulate(axis, model, input, options, out);
    return out;
}

void simulate(const AxisModel& axis, const ControllerModel& model, const SimulationInput& input,
              const SimulationOptions& options, SimulationOutput& out) {
    check_simulation(axis, model, input, options);
    const std::size_t n = input.reference.size();
    prepare_output(out, n);
    if (n == 0) return;
    const double dt = input.sample_time_s;
    const int substeps = integration_steps(model, dt, options.substeps);
    const double h = dt / substeps;
    const Plant plant = make_plant(axis, options.friction_zones);
    const PositionSensor sensor(options.position_resolution_m);
    DriveLoops drive(model, dt, h);
    Motion motion{options.initial_position_m.value_or(input.reference[0]), 0.0};
    drive.start(sensor.measure(motion.position), input.reference, options.hold_offset ? axis.offset : 0.0);

    const double inverse_substeps = 1.0 / substeps;
    std::size_t stick_transitions = 0;
    ForceHistory history(drive.drive_force());
    for (std::size_t k = 0; k < n; ++k) {
        const double reference_now = input.reference[k];
        const double reference_next = k + 1 < n ? input.reference[k + 1] : reference_now;
        const double external = input.external_force.empty() ? 0.0 : input.external_force[k];
        const double injection = input.injection.empty() ? 0.0 : input.injection[k];
        for (int sub = 0; sub < substeps; ++sub) {
            const double measured = sensor.measure(motion.position);
            drive.step(k, reference_now, reference_next, static_cast<double>(sub) * inverse_substeps, measured, injection);
            history.push(drive.drive_force());
            const Motion at_sample = motion;
            const double applied = drive.drive_force() + external - plant.offset;
            const double acceleration = step_plant(plant, applied, h, motion, stick_transitions);
            if (sub == 0) {
                record_sample(out, static_cast<double>(k) * dt, reference_now, at_sample, measured, acceleration,
                              drive, history.back(options.drive_signal_delay_steps));
            }
        }
    }
    out.stick_transitions = stick_transitions;
}

namespace {

// A number from `parent[key]`, either {"value": x} or x; nullopt when absent or null. InputError naming the key when
// it is something else (a text, a list).
std::optional<double> number_at(const nlohmann::json& parent, const std::string& key) {
    if (!parent.is_object()) return std::nullopt;
    const auto found = parent.find(key);
    if (found == parent.end()) return std::nullopt;
    const nlohmann::json& entry = found->is_object() ? found->value("value", nlohmann::json()) : *found;
    if (entry.is_number()) return entry.get<double>();
    if (!entry.is_null()) throw InputError(fmt::format("{}: must be a number or null", key));
    return std::nullopt;
}

bool present(const nlohmann::json& parent, const std::string& key) {
    return parent.is_object() && parent.contains(key);
}

}  // namespace

namespace {

/// The axis of an identify result, read through the result document's own reader (result_document.hpp).
AxisModel axis_from_result(const nlohmann::json& document, const std::string& source) {
    IdentifyResult result;
    try {
        result = document.get<IdentifyResult>();
    } catch (const InputError& e) {
        throw InputError(fmt::format("{}: {}", source, e.what()));
    }
    const ParameterNaming naming{result.rotary};
    const Parameter* mass = result.find(Term::mass);
    if (mass == nullptr || !mass->estimate.value) {
        throw InputError(fmt::format("{}: parameters.{}.value is missing or null", source, naming.key(Term::mass)));
    }
    const bool asymmetric = result.model == FrictionModelKind::asymmetric;
    for (const auto direction :
         asymmetric ? std::vector{Direction::forward, Direction::reverse} : std::vector{Direction::both}) {
        const Parameter* coulomb = result.find(Term::coulomb, direction);
        if (coulomb == nullptr || !coulomb->estimate.value) {
            throw InputError(fmt::format("{}: the Coulomb friction (parameters.{}) is missing or null", source,
                                         naming.key(Term::coulomb, direction)));
        }
    }
    AxisModel axis = result.axis;
    for (FrictionBranch* branch : {&axis.friction.forward, &axis.friction.reverse}) {
        branch->coulomb = std::abs(branch->coulomb);  // the reverse values are magnitudes; a sign is forgiven
        if (branch->breakaway) branch->breakaway = std::abs(*branch->breakaway);
        if (branch->stribeck_velocity && !(*branch->stribeck_velocity > 0.0)) {
            branch->breakaway.reset();
            branch->stribeck_velocity.reset();
        }
    }
    if (const auto problem = validate_axis(axis); !problem.empty()) {
        throw InputError(fmt::format("{}: {}", source, problem));
    }
    return axis;
}

/// The axis of a drive file (feedid synth --drive): the values under "axis" or at the top.
AxisModel axis_from_drive_file(const nlohmann::json& document, const std::string& source) {
    // A drive file (feedid synth) gives the values under "axis" or at the top, as numbers or {value} objects.
    const nlohmann::json& parameters = document.contains("axis") ? document["axis"] : document;
    AxisModel axis;
    if (document.contains("rotary") && !document["rotary"].is_boolean())
        throw InputError(fmt::format("{}: rotary: must be true or false", source));
    axis.rotary = present(parameters, ParameterNaming{true}.key(Term::mass)) ||
                  (document.contains("rotary") && document["rotary"].get<bool>());
    const ParameterNaming naming{axis.rotary};
    const std::string mass_key = naming.key(Term::mass);
    const auto mass = number_at(parameters, mass_key);
    if (!mass) throw InputError(fmt::format("{}: parameters.{}.value is missing or null", source, mass_key));
    axis.mass = *mass;
    axis.offset = number_at(parameters, naming.key(Term::offset)).value_or(0.0);

    // "coulomb_N" or "coulomb_forward_N" / "coulomb_reverse_N" (reverse as a positive magnitude).
    const auto directional = [&](Term term, Direction direction) -> std::pair<std::optional<double>, bool> {
        const std::string per_direction = naming.key(term, direction);
        if (present(parameters, per_direction)) return {number_at(parameters, per_direction), true};
        const std::string both = naming.key(term);
        return {number_at(parameters, both), present(parameters, both)};
    };
    for (const auto direction : {Direction::forward, Direction::reverse}) {
        FrictionBranch& branch = direction == Direction::forward ? axis.friction.forward : axis.friction.reverse;
        const auto [viscous, has_viscous] = directional(Term::viscous, direction);
        const auto [coulomb, has_coulomb] = directional(Term::coulomb, direction);
        if (!coulomb) {
            throw InputError(fmt::format("{}: the Coulomb friction (parameters.{}) is missing or null", source,
                                         naming.key(Term::coulomb, has_coulomb ? Direction::both : direction)));
        }
        branch.viscous = viscous.value_or(0.0);
        branch.coulomb = std::abs(*coulomb);
        const auto [breakaway, has_breakaway] = directional(Term::breakaway, direction);
        const auto [stribeck, has_stribeck] = directional(Term::stribeck_velocity, direction);
        if (breakaway && stribeck && *stribeck > 0.0) {
            branch.breakaway = std::abs(*breakaway);
            branch.stribeck_velocity = *stribeck;
        }
        (void)has_viscous;
        (void)has_breakaway;
        (void)has_stribeck;
    }
    if (const auto problem = validate_axis(axis); !problem.empty()) {
        throw InputError(fmt::format("{}: {}", source, problem));
    }
    return axis;
}

}  // namespace

AxisModel axis_from_document(const nlohmann::json& document, const std::string& source) {
    if (!document.is_object()) throw InputError(fmt::format("{}: not a JSON object", source));
    if (document.contains("parameters")) return axis_from_result(document, source);
    try {
        return axis_from_drive_file(document, source);
    } catch (const InputError& e) {
        const std::string message = e.what();
        if (message.starts_with(source + ":")) throw;
        throw InputError(fmt::format("{}: {}", source, message));
    }
}

namespace {

double relative_error_pct(std::span<const double> measured, std::span<const double> simulated) {
    double error = 0.0;
    double norm = 0.0;
    for (std::size_t k = 0; k < measured.size(); ++k) {
        error += (measured[k] - simulated[k]) * (measured[k] - simulated[k]);
        norm += measured[k] * measured[k];
    }
    return norm > 0.0 ? 100.0 * std::sqrt(error / norm) : 0.0;
}

}  // namespace

namespace {

/// The hold of the trace's channel with this role: {factor, phase}, factor 1 when it is not held (or absent).
std::pair<int, int> hold_of(const Trace& trace, Role role) {
    const auto* channel = trace.find(role);
    if (channel == nullptr || trace.samples() < 2) return {1, 0};
    const auto factor = static_cast<int>(std::lround(native_interval_of(trace, role) / trace.time_base().sample_time_s));
    if (factor < 2) return {1, 0};
    return {factor, hold_phase(channel->values, factor)};
}

/// A simulated signal as the trace records the channel with this role: held over its native interval, at the same
/// samples (between its samples the machine's value is not known, so the comparison holds the model's alike).
std::vector<double> held_like(const Trace& trace, Role role, std::span<const double> simulated) {
    std::vector<double> out(simulated.begin(), simulated.end());
    const auto [factor, phase] = hold_of(trace, role);
    if (factor < 2) return out;
    for (std::size_t k = static_cast<std::size_t>(phase) + 1; k < out.size(); ++k) {
        if ((k - static_cast<std::size_t>(phase)) % static_cast<std::size_t>(factor) != 0) out[k] = out[k - 1];
    }
    return out;
}

}  // namespace

namespace {

struct MeasuredMotion {
    std::vector<double> velocity;
    std::vector<double> acceleration;
};

// Measured velocity and acceleration: the logged velocity, or the position low-passed forwards and backwards
// (4th-order Butterworth at min(100 Hz, fs/10), the EMPS practice, fs the position signal's native rate) and
// differenced centrally.
MeasuredMotion measured_motion(const Trace& trace) {
    const auto position = trace.column(Role::position);
    const double dt = trace.time_base().sample_time_s;
    MeasuredMotion motion;
    std::vector<double> velocity_for_acceleration;
    if (const auto* logged = trace.find(Role::velocity)) {
        motion.velocity = logged->values;
        // a held velocity between its own samples, for its differences
        const auto [factor, phase] = hold_of(trace, Role::velocity);
        if (factor > 1) velocity_for_acceleration = interpolate_held(motion.velocity, factor, phase);
    } else {
        const double fs = 1.0 / dt;
        const double native_rate = 1.0 / native_interval_of(trace, Role::position);
        const auto filter = butterworth_lowpass(4, std::min(100.0, 0.1 * native_rate), fs);
        motion.velocity = central_difference(filtfilt(filter, position), dt);
    }
    motion.acceleration =
        central_difference(velocity_for_acceleration.empty() ? motion.velocity : velocity_for_acceleration, dt);
    return motion;
}

}  // namespace

ValidationMetrics validate_simulation(const Trace& trace, std::span<const double> measured_force,
                                      const SimulationOutput& simulated) {
    const std::size_t n = simulated.position.size();
    const auto position = trace.column(Role::position);
    if (position.size() != n || measured_force.size() != n) {
        throw InputError("simulation and trace differ in length");
    }
    ValidationMetrics metrics;
    if (n == 0) return metrics;
    const MeasuredMotion motion = measured_motion(trace);
    const std::vector<double>& velocity = motion.velocity;
    const std::vector<double>& acceleration = motion.acceleration;
    const std::vector<double> simulated_position = held_like(trace, Role::position, simulated.position);
    metrics.position_relative_error_pct = relative_error_pct(position, simulated_position);
    metrics.velocity_relative_error_pct =
        relative_error_pct(velocity, trace.has(Role::velocity) ? held_like(trace, Role::velocity, simulated.velocity)
                                                               : simulated.velocity);
    metrics.acceleration_relative_error_pct = relative_error_pct(acceleration, simulated.acceleration);
    metrics.force_relative_error_pct = relative_error_pct(measured_force, simulated.force);
    double model = 0.0, machine = 0.0, modelling = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        const double e_model = simulated.reference[k] - simulated_position[k];
        const double e_machine = simulated.reference[k] - position[k];
        const double e_m = position[k] - simulated_position[k];
        model += std::abs(e_model);
        machine += std::abs(e_machine);
        modelling += std::abs(e_m);
        metrics.tracking_error_max_model_m = std::max(metrics.tracking_error_max_model_m, std::abs(e_model));
        metrics.tracking_error_max_machine_m = std::max(metrics.tracking_error_max_machine_m, std::abs(e_machine));
        metrics.modelling_error_max_m = std::max(metrics.modelling_error_max_m, std::abs(e_m));
    }
    metrics.tracking_error_mae_model_m = model / static_cast<double>(n);
    metrics.tracking_error_mae_machine_m = machine / static_cast<double>(n);
    metrics.modelling_error_mae_m = modelling / static_cast<double>(n);
    return metrics;
}

std::string model_does_not_fit(const AxisModel& axis, const Trace& trace, std::span<const double> drive_force) {
    const std::size_t n = trace.samples();
    if (drive_force.size() != n) throw InputError("the drive force and the trace differ in length");
    if (n < 3 || !trace.has(Role::position)) return {};
    const MeasuredMotion motion = measured_motion(trace);
    const auto* external = trace.find(Role::external_force);
    double fastest = 0.0;
    for (const double v : motion.velocity) fastest = std::max(fastest, std::isfinite(v) ? std::abs(v) : 0.0);
    // F_d = M*a + F_f(v) + F_0 - F_ext over the samples that move (at rest friction takes any value up to F_B)
    double cross = 0.0, predicted = 0.0, measured = 0.0, largest_predicted = 0.0, largest_measured = 0.0;
    std::size_t used = 0;
    for (std::size_t k = 1; k + 1 < n; ++k) {
        if (!(std::abs(motion.velocity[k]) > 0.05 * fastest) || !std::isfinite(drive_force[k])) continue;
        double model = axis.mass * motion.acceleration[k] + axis.friction.force(motion.velocity[k]) + axis.offset;
        if (external != nullptr) model -= external->values[k];
        cross += model * drive_force[k];
        predicted += model * model;
        measured += drive_force[k] * drive_force[k];
        largest_predicted = std::max(largest_predicted, std::abs(model));
        largest_measured = std::max(largest_measured, std::abs(drive_force[k]));
        ++used;
    }
    const char* unit = trace.rotary ? "N*m" : "N";
    if (used == 0) return {};
    if (!std::isfinite(cross + predicted + measured) || !(predicted > 0.0) || !(measured > 0.0)) {
        return fmt::format(
            "over {} moving samples, the force the model predicts from the trace's motion (M*a + friction + offset) "
            "reaches {:.4g} {}, the trace's drive force {:.4g} {}: no factor between them is a finite number other "
            "than 0; are the model's values and the trace's units right?",
            used, largest_predicted, unit, largest_measured, unit);
    }
    const double factor = cross / predicted;  // F ~ factor * F_hat in least squares
    if (factor >= 1.0 / model_scale_limit && factor <= model_scale_limit) return {};
    const std::string figures = fmt::format(
        "over {} moving samples, the force the model predicts from the trace's motion (M*a + friction + offset) has "
        "an rms of {:.4g} {}, the trace's drive force {:.4g} {}; the best factor between them is {:.3g}, where the "
        "axis's own model gives about 1",
        used, std::sqrt(predicted / static_cast<double>(used)), unit, std::sqrt(measured / static_cast<double>(used)),
        unit, factor);
    if (factor < 0.0) {
        return figures +
               ": the drive signal's sign is the opposite of the identification's (a negative force constant turns it)";
    }
    return figures +
           ": are the units of position, time and drive signal, and the force constant, the ones the model was "
           "identified with, and is it this axis's model?";
}

nlohmann::json validation_document(const ValidationMetrics& m, bool rotary) {
    const std::string unit = ParameterNaming{rotary}.length_key_suffix();
    return {
        {"relative_error_pct",
         {{"position", m.position_relative_error_pct},
          {"velocity", m.velocity_relative_error_pct},
          {"acceleration", m.acceleration_relative_error_pct},
          {"force", m.force_relative_error_pct}}},
        {"tracking_error_mae" + unit,
         {{"model", m.tracking_error_mae_model_m}, {"machine", m.tracking_error_mae_machine_m}}},
        {"modelling_error_mae" + unit, m.modelling_error_mae_m},
        {"tracking_error_max" + unit,
         {{"model", m.tracking_error_max_model_m}, {"machine", m.tracking_error_max_machine_m}}},
        {"modelling_error_max" + unit, m.modelling_error_max_m},
    };
}

ValidationSeries validation_series(const Trace& trace, const SimulationOutput& simulated, std::size_t max_points) {
    const std::size_t n = simulated.position.size();
    const auto position = trace.column(Role::position);
    if (position.size() != n) throw InputError("simulation and trace differ in length");
    if (max_points < 6) throw InputError("validation series: at least 6 points are needed (two per error)");
    std::vector<double> machine(n), model(n), modelling(n);
    const std::vector<double> simulated_position = held_like(trace, Role::position, simulated.position);
    // The same differences as validate_simulation(), so the series' extremes equal its largest errors; up to the first
    // sample where one is not a finite number (a diverged simulation's series ends there).
    std::size_t finite = n;
    for (std::size_t k = 0; k < n; ++k) {
        machine[k] = simulated.reference[k] - position[k];
        model[k] = simulated.reference[k] - simulated_position[k];
        modelling[k] = position[k] - simulated_position[k];
        if (!(std::isfinite(machine[k]) && std::isfinite(model[k]) && std::isfinite(modelling[k]))) {
            finite = k;
            break;
        }
    }
    const std::array<std::span<const double>, 3> errors{std::span<const double>(machine).first(finite),
                                                        std::span<const double>(model).first(finite),
                                                        std::span<const double>(modelling).first(finite)};
    ValidationSeries series;
    series.samples = finite;
    if (finite == 0) return series;
    for (const std::size_t k : extreme_preserving_indices(errors, finite, max_points)) {
        series.time.push_back(simulated.time[k]);
        series.tracking_error_machine.push_back(machine[k]);
        series.tracking_error_model.push_back(model[k]);
        series.modelling_error.push_back(modelling[k]);
    }
    return series;
}

nlohmann::json validation_series_document(const ValidationSeries& series, bool rotary) {
    const std::string unit = ParameterNaming{rotary}.length_key_suffix();
    return {{"time_s", series.time},
            {"tracking_error_machine" + unit, series.tracking_error_machine},
            {"tracking_error_model" + unit, series.tracking_error_model},
            {"modelling_error" + unit, series.modelling_error},
            {"samples", series.samples},
            {"thinning", "min-max per bucket"}};
}

Trace simulation_trace(const SimulationOutput& output, bool rotary) {
    Trace trace;
    trace.format = "synthetic";
    trace.rotary = rotary;
    const std::string length = rotary ? "rad" : "m";
    const std::string speed = rotary ? "rad/s" : "m/s";
    const std::string acceleration = rotary ? "rad/s^2" : "m/s^2";
    const std::string force = rotary ? "N*m" : "N";
    trace.set("t", Role::time, "s", output.time);
    trace.set("x_ref", Role::reference_position, length, output.reference);
    trace.set("x", Role::position, length, output.position);
    trace.set("v", Role::velocity, speed, output.velocity);
    trace.set("a", Role::other, acceleration, output.acceleration);
    trace.set("v_cmd", Role::velocity_command, speed, output.velocity_command);
    trace.set("F_cmd", Role::other, force, output.force_command);
    trace.set("F", Role::force, force, output.force);
    trace.set("e_t", Role::other, length, output.tracking_error);
    return trace;
}

namespace {

// What the options set in place of the document's: settings of the drive the gains are simulated on.
ControllerModel with_options(ControllerModel model, const GainOptions& options) {
    if (options.saturation_N) model.saturation_N = options.saturation_N;
    if (options.current_lag_s) model.current_lag_s = *options.current_lag_s;
    if (options.velocity_difference_samples) model.velocity_difference_samples = *options.velocity_difference_samples;
    return model;
}

}  // namespace

TwinController documented_twin_controller(const nlohmann::json& gains_document, const std::string& source,
                                          const GainOptions& options, const Trace& trace) {
    if (gains_document_is_rotary(gains_document) != trace.rotary) {
        throw InputError(fmt::format("{}: the gains are of a {} axis, the trace {} of a {} axis", source,
                                     ParameterNaming{!trace.rotary}.axis_kind(),
                                     trace.source_path.empty() ? std::string("trace") : trace.source_path,
                                     ParameterNaming{trace.rotary}.axis_kind()));
    }
    TwinController controller;
    controller.model = with_options(controller_from_document(gains_document, source), options);
    ControllerModel& model = controller.model;
    if (model.position_cycle_s == 0.0) model.position_cycle_s = trace.time_base().sample_time_s;
    if (model.velocity_cycle_s == 0.0) model.velocity_cycle_s = model.position_cycle_s;
    return controller;
}

TwinController identified_twin_controller(const Trace& trace, std::span<const double> drive_force,
                                          const GainOptions& options, std::span<const double> injection) {
    TwinController controller;
    const GainResult gains = identify_gains(trace, drive_force, options, injection);
    // a fit that gave no gains at all leaves nothing to simulate
    if (gains.status == Status::failed && !gains.controller.validate().empty()) {
        throw AnalysisError(
            fmt::format("no simulation: no gains could be identified from the trace: {}", gains.diagnostics.front()));
    }
    controller.model = gains.controller;
    controller.status = gains.status;
    if (gains.status == Status::failed) controller.notes.push_back(gains.diagnostics.front());
    controller.notes.push_back(
        fmt::format("gains identified from the trace: K_v {:.6g} 1/s, K_p {:.6g} {}, K_i {:.6g} {}",
                    controller.model.position_gain_per_s, controller.model.velocity_gain_N_s_per_m,
                    ParameterNaming{trace.rotary}.velocity_gain_unit(), controller.model.velocity_integral_gain_N_per_m,
                    ParameterNaming{trace.rotary}.velocity_integral_gain_unit()));
    return controller;
}

namespace {

// The first sample at which a simulated signal is not a finite number, or none.
std::optional<std::size_t> first_non_finite(const SimulationOutput& output) {
    for (std::size_t k = 0; k < output.position.size(); ++k) {
        if (!std::isfinite(output.position[k]) || !std::isfinite(output.velocity[k]) ||
            !std::isfinite(output.force[k])) {
            return k;
        }
    }
    return std::nullopt;
}

// A simulation that produced no numbers, or ran farther from the machine than the whole travel of the trace (an
// unstable loop: gains or signs wrong), validates nothing: status failed, with the figures.
void check_divergence(const Trace& trace, TraceSimulation& simulation) {
    const auto fail = [&](std::string why) {
        simulation.status = Status::failed;
        simulation.diagnostics.push_back(std::move(why));
    };
    if (const auto k = first_non_finite(simulation.output)) {
        fail(
            fmt::format("the simulation diverged: its position, velocity or force is not a finite number from "
                        "t = {:.6g} s on (an unstable loop: are the gains and the channels' signs right?)",
                        simulation.output.time[*k]));
        return;
    }
    const auto reference = trace.column(Role::reference_position);
    const auto position = trace.column(Role::position);
    const auto [reference_low, reference_high] = std::minmax_element(reference.begin(), reference.end());
    const auto [position_low, position_high] = std::minmax_element(position.begin(), position.end());
    const double travel = std::max(*reference_high, *position_high) - std::min(*reference_low, *position_low);
    const double away = simulation.metrics.modelling_error_max_m;
    const char* unit = trace.rotary ? "rad" : "m";
    if (travel > 0.0 && away > travel) {
        fail(
            fmt::format("the simulation diverged: the simulated axis came {:.4g} {} away from the machine, farther "
                        "than the whole travel of the trace ({:.4g} {}); an unstable loop: are the gains and the "
                        "channels' signs right?",
                        away, unit, travel, unit));
        return;
    }
    // A twin that stood on the reference would be closer to the machine than this one: it reproduces nothing.
    const ValidationMetrics& m = simulation.metrics;
    if (m.modelling_error_mae_m > m.tracking_error_mae_machine_m) {
        fail(fmt::format(
            "the simulated axis does not follow the machine: its mean distance from the machine, {:.4g} {}, is larger "
            "than the machine's own mean tracking error, {:.4g} {} (the reference itself is closer to the machine "
            "than the twin); are the gains those of this machine, and the result this axis's?",
            m.modelling_error_mae_m, unit, m.tracking_error_mae_machine_m, unit));
    }
}

}  // namespace

TraceSimulation simulate_trace(const Trace& trace, std::span<const double> drive_force, const AxisModel& axis,
                               const ControllerModel& controller, SimulationOptions options,
                               std::span<const double> injection) {
    SimulationInput input;
    input.sample_time_s = trace.time_base().sample_time_s;
    input.reference = trace.column(Role::reference_position);
    if (const auto* external = trace.find(Role::external_force)) input.external_force = external->values;
    input.injection = injection;
    if (!options.initial_position_m) options.initial_position_m = trace.column(Role::position)[0];
    TraceSimulation simulation;
    simulation.output = simulate(axis, controller, input, options);
    simulation.injected = !injection.empty();
    simulation.metrics = validate_simulation(trace, drive_force, simulation.output);
    check_divergence(trace, simulation);
    return simulation;
}

nlohmann::json simulation_document(const Trace& trace, const TwinController& controller,
                                   const TraceSimulation& simulation) {
    const ControllerModel& model = controller.model;
    const ParameterNaming naming{trace.rotary};
    nlohmann::json document = validation_document(simulation.metrics, trace.rotary);
    document["trace"] = {
        {"path", trace.source_path}, {"samples", trace.samples()}, {"sample_time_s", trace.time_base().sample_time_s}};
    document["controller"] = {{"position_gain_per_s", model.position_gain_per_s},
                              {naming.velocity_gain_key(), model.velocity_gain_N_s_per_m},
                              {naming.velocity_integral_gain_key(), model.velocity_integral_gain_N_per_m},
                              {naming.saturation_key(), model.saturation_N},
                              {"current_lag_s", model.current_lag_s},
                              {"velocity_difference_samples", model.velocity_difference_samples}};
    document["rotary"] = trace.rotary;
    // The paper's Fig. 6 for `feedid report --simulation`: the errors over time, thinned for plotting.
    document["series"] = validation_series_document(validation_series(trace, simulation.output), trace.rotary);
    const bool failed = controller.status == Status::failed || simulation.status == Status::failed;
    document["status"] = to_string(failed ? Status::failed : Status::ok);
    document["injection"] = simulation.injected;
    std::vector<std::string> diagnostics = simulation.diagnostics;
    diagnostics.insert(diagnostics.end(), controller.notes.begin(), controller.notes.end());
    document["diagnostics"] = diagnostics;
    explain_nulls(document, [&](std::string_view path) -> std::string {
        if (path == "controller." + naming.saturation_key()) return "no limit of the drive signal given (--saturation)";
        if (simulation.status == Status::failed) return "the simulation diverged (the first diagnostic says where)";
        return {};
    });
    return document;
}

}  // namespace feedid
