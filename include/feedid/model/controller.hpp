#pragma once
// The NC's cascaded P-PI position control loop (its gains are identified from a trace by gains.hpp).
//   position loop (P, optional velocity feed-forward):   v_cmd = K_v*(x_ref(t - D) - x) + k_ff*x_ref'(t - D)
//   (D the setpoint delay)
//   velocity loop (PI; P only when K_i = 0):               F_cmd = K_p*e_v + K_i*integral(e_v dt),  e_v = v_cmd - v
//   current loop: ideal or a first-order lag of time constant tau;  output saturation |F_cmd| <= F_max
// Each loop runs at its own sample time. The velocity the velocity loop sees is measured from the position: the mean
// of the last n position samples, differenced, v = (x_k - x_{k-n}) / (n*T)  (n = 1: backward difference; n = 2: the
// EMPS controller's [0.5 0.5] filter followed by a difference). The EMPS structure v = k_p*k_v*(q_r - q) - k_v*q'
// is this controller with K_v = k_p, K_p = k_v*g_tau, K_i = 0.
// Force is SI inside (N, or N*m on a rotary axis); gains in signal units (V or A per m/s) follow from a force constant.

#include <array>
#include <optional>
#include <string>

namespace feedid {

/// (m/min)/mm per 1/s: the SINUMERIK servo gain factor K_V is stated in (m/min)/mm, and
/// 1 (m/min)/mm = (1/60 m/s) / (1e-3 m) = 1000/60 1/s, so K_V [(m/min)/mm] = K_v [1/s] * 60/1000.
inline constexpr double m_per_min_per_mm_per_1_per_s = 60.0 / 1000.0;

/// The gains and structure of a cascaded P-PI controller. Linear axes: m, m/s, N; rotary axes: rad, rad/s, N*m.
struct ControllerModel {
    double position_gain_per_s{0.0};             ///< K_v [1/s]: velocity command per following error
    double velocity_feedforward{0.0};            ///< k_ff [-]: fraction of the reference velocity fed forward
    double velocity_gain_N_s_per_m{0.0};         ///< K_p [N*s/m]: force command per velocity error
    double velocity_integral_gain_N_per_m{0.0};  ///< K_i [N/m] = K_p / T_n; 0 = P-only velocity loop
    std::optional<double> saturation_N;          ///< |force command| limit [N]; none = unlimited
    double current_lag_s{0.0};                   ///< current loop as a first-order lag, time constant [s]; 0 = ideal
    double position_cycle_s{0.0};                ///< position loop sample time [s]; 0 = the trace's sample time
    double velocity_cycle_s{0.0};                ///< velocity loop sample time [s]; 0 = the position loop's
    int velocity_difference_samples{1};          ///< n of the velocity measurement above, 1..8
    /// [-] an injected test signal enters the drive with this gain: the drive gets F_cmd + g*u_inj for the u_inj
    /// logged (the scale of a DAC or an amplifier between the test signal and the drive)
    double injection_gain{1.0};
    /// [s] the position setpoint reaches the position loop this much late (the path from the NC's interpolator to the
    /// drive: a few servo cycles); the loop works on x_ref(t - delay) and its feed-forward on that setpoint's velocity
    double setpoint_delay_s{0.0};

    /// K_v in the SINUMERIK unit (m/min)/mm.
    [[nodiscard]] double kv_m_per_min_per_mm() const { return position_gain_per_s * m_per_min_per_mm_per_1_per_s; }
    /// Reset time T_n = K_p / K_i [s]; none for a P-only velocity loop.
    [[nodiscard]] std::optional<double> reset_time_s() const;
    /// What is wrong with this model ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// K_v [1/s] from the SINUMERIK servo gain [(m/min)/mm].
constexpr double position_gain_from_kv(double kv_m_per_min_per_mm) {
    return kv_m_per_min_per_mm / m_per_min_per_mm_per_1_per_s;
}

/// The controller's discrete state: one instance per simulation; steps allocate nothing and never throw.
class Controller {
public:
    /// `position_cycle_s` and `velocity_cycle_s` are the resolved loop sample times [s] (> 0).
    Controller(const ControllerModel& model, double position_cycle_s, double velocity_cycle_s);

    /// Starts at rest at `position` [m] with the integrator holding `integrator_force` [N] (e.g. a vertical axis'
    /// weight, so that the axis does not sag when the simulation starts).
    void reset(double position, double integrator_force = 0.0);

    /// Position loop: velocity command [m/s] from the reference [m], its velocity [m/s] and the measured position [m].
    double position_step(double reference, double reference_velocity, double position) noexcept;

    /// Velocity loop: force command [N] (saturated) from the velocity command [m/s] and the measured position [m].
    double velocity_step(double velocity_command, double position) noexcept;

    /// The velocity [m/s] the velocity loop measured at its last step.
    [[nodiscard]] double measured_velocity() const noexcept { return measured_velocity_; }
    [[nodiscard]] const ControllerModel& model() const noexcept { return model_; }

private:
    ControllerModel model_;
    double position_cycle_s_;
    double velocity_cycle_s_;
    std::array<double, 9> history_{};  // last positions seen by the velocity loop, ring buffer
    int head_{0};
    double integrator_{0.0};  // K_i * integral(e_v dt) [N]
    double measured_velocity_{0.0};
};

}  // namespace feedid
