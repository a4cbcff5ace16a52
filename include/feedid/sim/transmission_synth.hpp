#pragma once
// Synthetic traces of an axis whose transmission is not rigid: the motor (its inertia, reflected to the load side as
// a mass) drives the load through a spring of stiffness k with a dead band (backlash) b:
//   d = x_motor - x_load,  F_t = k*(d - b/2) + c*(v_motor - v_load)  for d > b/2,
//                          F_t = k*(d + b/2) + c*(v_motor - v_load)  for d < -b/2,  0 inside the band,
//   M_motor * a_motor = F_d - F_t,   M_load * a_load = F_t - F_f(v_load) - offset  (sticking while |F_t - offset| is
//   below the breakaway force),
// c from a damping ratio of the motor-load resonance. The cascaded controller closes its position loop on the scale
// (the load, a direct measuring system) and its velocity loop on the motor encoder, as NCs with two measuring systems
// do. Two encoders are logged: `x` (the scale, with white noise and its quantum) and `x_motor` (the motor encoder).
// The ground truth of `feedid fingerprint`.

#include <optional>
#include <string>
#include <vector>

#include "feedid/core/trace.hpp"
#include "feedid/sim/synth.hpp"

namespace feedid {

/// The transmission between motor and load, and the second encoder. Linear axes in m and N/m; rotary in rad and
/// N*m/rad (a torsional stiffness).
struct TransmissionModel {
    double backlash_m{10e-6};         ///< b: the dead band's width [m; rad]
    double stiffness_N_per_m{200e6};  ///< k [N/m; N*m/rad]
    double damping_ratio{0.3};        ///< of the motor-load resonance [-]
    double motor_mass_fraction{0.4};  ///< the part of the axis's mass (inertia) on the motor side [-]
    double scale_noise_m{5e-9};       ///< standard deviation of the scale's white noise [m; rad]
    double scale_resolution_m{1e-9};  ///< the scale's quantum [m; rad]; 0 = exact
    double motor_resolution_m{1e-9};  ///< the motor encoder's quantum in load units [m; rad]; 0 = exact
    bool log_motor_position{true};    ///< false: only the scale is logged (one measuring system)

    /// What is wrong ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// Generates the trace: channels t [s], x_ref, x (scale, position), x_motor (motor encoder, motor_position; unless
/// log_motor_position is false), v_cmd and i [A] (the drive force through spec.force_constant_N_per_A(), with the
/// spec's current noise and quantum); SI of the axis's kind. Constants as synthesize() writes them (kt_Nm_per_A,
/// force_constant_N_per_A, ...) and the truth: true_backlash_m, true_stiffness_N_per_m, true_breakaway_forward_N,
/// true_breakaway_reverse_N (rotary: _rad, _Nm_per_rad, _Nm). `reference` overrides the default, the reversal test of
/// plan/reversal_test.hpp (sampled every spec.sensors.sample_time_s). The spec's recording options and injection do
/// not apply. Deterministic for a given seed. InputError for an invalid spec or transmission.
Trace synthesize_with_transmission(const SynthSpec& spec, const TransmissionModel& transmission,
                                   const std::optional<std::vector<double>>& reference = std::nullopt);

}  // namespace feedid
