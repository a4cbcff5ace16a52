#include "feedid/sim/transmission_synth.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/model/controller.hpp"
#include "feedid/plan/reversal_test.hpp"
#include "feedid/plan/test_plan.hpp"

namespace feedid {

std::string TransmissionModel::validate() const {
    const auto positive = [](double value) { return std::isfinite(value) && value > 0.0; };
    const auto not_negative = [](double value) { return std::isfinite(value) && value >= 0.0; };
    if (!not_negative(backlash_m) || backlash_m > 1e-2)
        return fmt::format("backlash {}: must be from 0 to 10 mm (in m)", backlash_m);
    if (!positive(stiffness_N_per_m)) return fmt::format("stiffness {}: must be positive (N/m)", stiffness_N_per_m);
    if (!not_negative(damping_ratio) || damping_ratio > 10.0)
        return fmt::format("damping ratio {}: must be from 0 to 10", damping_ratio);
    if (!(motor_mass_fraction > 0.0 && motor_mass_fraction < 1.0))
        return fmt::format("motor mass fraction {}: must be between 0 and 1", motor_mass_fraction);
    if (!not_negative(scale_noise_m) || !not_negative(scale_resolution_m) || !not_negative(motor_resolution_m))
        return "the encoders' noise and quanta must be finite and not negative";
    return {};
}

// ---- the two-mass transmission (delimited from synth.cpp's rigid axis so that each can change alone) ----
namespace {

struct TwoMassState {
    double motor{0.0};
    double motor_velocity{0.0};
    double load{0.0};
    double load_velocity{0.0};
};

struct TwoMassPlant {
    double motor_mass{0.0};
    double load_mass{0.0};
    double stiffness{0.0};
    double damping{0.0};
    double half_band{0.0};
    Friction friction;
    double offset{0.0};

    // F_t: the force the transmission carries (positive: the motor pushes the load forward).
    [[nodiscard]] double transmitted(const TwoMassState& s) const {
        const double deflection = s.motor - s.load;
        const double relative_velocity = s.motor_velocity - s.load_velocity;
        if (deflection > half_band) return stiffness * (deflection - half_band) + damping * relative_velocity;
        if (deflection < -half_band) return stiffness * (deflection + half_band) + damping * relative_velocity;
        return 0.0;
    }

    // Semi-implicit Euler over h; the load sticks at rest while the net force stays below its breakaway force, and
    // stops where its velocity would change sign.
    void step(double drive_force, double h, TwoMassState& s) const {
        const double carried = transmitted(s);
        s.motor_velocity += h * (drive_force - carried) / motor_mass;
        s.motor += h * s.motor_velocity;
        const double net = carried - offset;
        if (s.load_velocity == 0.0 && std::abs(net) <= friction.breakaway_force(net > 0.0)) return;
        const double direction =
            s.load_velocity != 0.0 ? (s.load_velocity > 0.0 ? 1.0 : -1.0) : (net > 0.0 ? 1.0 : -1.0);
        const double resisting = direction > 0.0 ? friction.forward.magnitude(std::abs(s.load_velocity))
                                                 : -friction.reverse.magnitude(std::abs(s.load_velocity));
        const double next = s.load_velocity + h * (net - resisting) / load_mass;
        s.load_velocity = next * direction > 0.0 ? next : 0.0;
        s.load += h * s.load_velocity;
    }
};

TwoMassPlant make_two_mass_plant(const SynthSpec& spec, const TransmissionModel& transmission) {
    TwoMassPlant plant;
    plant.motor_mass = spec.axis.mass * transmission.motor_mass_fraction;
    plant.load_mass = spec.axis.mass - plant.motor_mass;
    plant.stiffness = transmission.stiffness_N_per_m;
    const double reduced = plant.motor_mass * plant.load_mass / spec.axis.mass;
    plant.damping = 2.0 * transmission.damping_ratio * std::sqrt(plant.stiffness * reduced);
    plant.half_band = 0.5 * transmission.backlash_m;
    plant.friction = spec.axis.friction;
    plant.offset = spec.axis.offset;
    return plant;
}

double quantised(double value, double quantum) {
    return quantum > 0.0 ? quantum * std::round(value / quantum) : value;
}

struct TwoMassRecording {
    std::vector<double> time, reference, scale, motor, velocity_command, current;
};

// The velocity loop runs every `control_steps`-th of a sample (an 8 kHz speed controller at 1 kHz logging), the
// mechanics four times finer than that (the resonance of a stiff screw is several hundred Hz).
TwoMassRecording run_two_mass(const SynthSpec& spec, const TransmissionModel& transmission,
                              const std::vector<double>& reference) {
    constexpr int control_steps = 8;
    constexpr int mechanics_steps = 4;
    const double dt = spec.sensors.sample_time_s;
    const double h = dt / (control_steps * mechanics_steps);
    const TwoMassPlant plant = make_two_mass_plant(spec, transmission);
    const double force_per_ampere = spec.force_constant_N_per_A();
    std::mt19937_64 random(spec.seed);
    std::normal_distribution<double> unit_noise(0.0, 1.0);
    Controller controller(spec.controller, dt, dt / control_steps);
    TwoMassState state{reference.front(), 0.0, reference.front(), 0.0};
    controller.reset(reference.front(), 0.0);
    const double lag = spec.controller.current_lag_s;
    const double lag_factor = lag > 0.0 ? 1.0 - std::exp(-h / lag) : 1.0;
    double drive_force = 0.0;
    TwoMassRecording out;
    for (std::size_t k = 0; k < reference.size(); ++k) {
        const double scale =
            quantised(state.load + transmission.scale_noise_m * unit_noise(random), transmission.scale_resolution_m);
        const double next = k + 1 < reference.size() ? reference[k + 1] : reference[k];
        const double velocity_command = controller.position_step(reference[k], (next - reference[k]) / dt, scale);
        const double current = drive_force / force_per_ampere + spec.sensors.current_noise_A * unit_noise(random);
        out.time.push_back(static_cast<double>(k) * dt);
        out.reference.push_back(reference[k]);
        out.scale.push_back(scale);
        out.motor.push_back(quantised(state.motor, transmission.motor_resolution_m));
        out.velocity_command.push_back(velocity_command);
        out.current.push_back(quantised(current, spec.sensors.current_resolution_A));
        for (int c = 0; c < control_steps; ++c) {
            const double command =
                controller.velocity_step(velocity_command, quantised(state.motor, transmission.motor_resolution_m));
            for (int m = 0; m < mechanics_steps; ++m) {
                drive_force += lag_factor * (command - drive_force);
                plant.step(drive_force, h, state);
            }
        }
    }
    return out;
}

std::vector<double> default_reversal_reference(const SynthSpec& spec) {
    ReversalTestOptions options = default_reversal_options(spec.axis.rotary ? "A" : "X");
    options.sample_time = spec.sensors.sample_time_s;
    const TestPlan plan = make_reversal_plan(options);
    const Trace trajectory = reference_trajectory(plan);
    const auto column = trajectory.column(Role::reference_position);
    return {column.begin(), column.end()};
}

void add_truth(Trace& trace, const SynthSpec& spec, const TransmissionModel& transmission) {
    const bool rotary = spec.axis.rotary;
    trace.constants["kt_Nm_per_A"] = spec.kt_Nm_per_A;
    trace.constants["gear_ratio"] = spec.gear_ratio;
    if (rotary) {
        trace.constants["torque_constant_Nm_per_A"] = spec.force_constant_N_per_A();
    } else {
        trace.constants["lead_m"] = spec.lead_m;
        trace.constants["force_constant_N_per_A"] = spec.force_constant_N_per_A();
    }
    trace.constants[rotary ? "true_backlash_rad" : "true_backlash_m"] = transmission.backlash_m;
    trace.constants[rotary ? "true_stiffness_Nm_per_rad" : "true_stiffness_N_per_m"] = transmission.stiffness_N_per_m;
    trace.constants[rotary ? "true_breakaway_forward_Nm" : "true_breakaway_forward_N"] =
        spec.axis.friction.breakaway_force(true);
    trace.constants[rotary ? "true_breakaway_reverse_Nm" : "true_breakaway_reverse_N"] =
        spec.axis.friction.breakaway_force(false);
}

}  // namespace

Trace synthesize_with_transmission(const SynthSpec& spec, const TransmissionModel& transmission,
                                   const std::optional<std::vector<double>>& reference) {
    if (const auto problem = spec.validate(); !problem.empty()) throw InputError(problem);
    if (const auto problem = transmission.validate(); !problem.empty()) throw InputError(problem);
    const std::vector<double> commanded = reference ? *reference : default_reversal_reference(spec);
    if (commanded.size() < 2) throw InputError("the reference holds fewer than two samples");
    TwoMassRecording recording = run_two_mass(spec, transmission, commanded);
    const bool rotary = spec.axis.rotary;
    const std::string length = rotary ? "rad" : "m";
    Trace trace;
    trace.format = "synthetic";
    trace.rotary = rotary;
    trace.set("t", Role::time, "s", std::move(recording.time));
    trace.set("x_ref", Role::reference_position, length, std::move(recording.reference));
    trace.set("x", Role::position, length, std::move(recording.scale));
    if (transmission.log_motor_position) trace.set("x_motor", Role::motor_position, length, std::move(recording.motor));
    trace.set("v_cmd", Role::velocity_command, length + "/s", std::move(recording.velocity_command));
    trace.set("i", Role::current, "A", std::move(recording.current));
    add_truth(trace, spec, transmission);
    return trace;
}

}  // namespace feedid
