#include "feedid/model/controller.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/core.h>

namespace feedid {

std::optional<double> ControllerModel::reset_time_s() const {
    if (!(velocity_integral_gain_N_per_m > 0.0)) return std::nullopt;
    return velocity_gain_N_s_per_m / velocity_integral_gain_N_per_m;
}

std::string ControllerModel::validate() const {
    const auto finite_non_negative = [](double x) { return std::isfinite(x) && x >= 0.0; };
    if (!finite_non_negative(position_gain_per_s)) return "the position gain K_v must be a finite number >= 0";
    if (!(std::isfinite(velocity_gain_N_s_per_m) && velocity_gain_N_s_per_m > 0.0)) {
        return "the velocity gain K_p must be a positive number";
    }
    if (!finite_non_negative(velocity_integral_gain_N_per_m)) return "the integral gain K_i must be a number >= 0";
    if (!std::isfinite(velocity_feedforward)) return "the velocity feed-forward must be a finite number";
    if (saturation_N && !(*saturation_N > 0.0)) return "the force saturation must be positive";
    if (!finite_non_negative(current_lag_s)) return "the current-loop lag must be a time >= 0";
    if (!finite_non_negative(position_cycle_s) || !finite_non_negative(velocity_cycle_s)) {
        return "the loop sample times must be >= 0";
    }
    if (!std::isfinite(injection_gain)) return "the injection's gain must be a finite number";
    if (!finite_non_negative(setpoint_delay_s)) return "the setpoint delay must be a time >= 0";
    if (velocity_difference_samples < 1 || velocity_difference_samples > 8) {
        return "the velocity measurement must difference over 1 to 8 samples";
    }
    return {};
}

Controller::Controller(const ControllerModel& model, double position_cycle_s, double velocity_cycle_s)
    : model_(model), position_cycle_s_(position_cycle_s), velocity_cycle_s_(velocity_cycle_s) {
    model_.velocity_difference_samples = std::clamp(model_.velocity_difference_samples, 1, 8);
    reset(0.0);
}

void Controller::reset(double position, double integrator_force) {
    history_.fill(position);
    head_ = 0;
    integrator_ = model_.velocity_integral_gain_N_per_m > 0.0 ? integrator_force : 0.0;
    measured_velocity_ = 0.0;
}

double Controller::position_step(double reference, double reference_velocity, double position) noexcept {
    return model_.position_gain_per_s * (reference - position) + model_.velocity_feedforward * reference_velocity;
}

double Controller::velocity_step(double velocity_command, double position) noexcept {
    // v = (x_k - x_{k-n}) / (n*T): the mean of the last n positions, differenced.
    const int n = model_.velocity_difference_samples;
    const int size = static_cast<int>(history_.size());
    if (++head_ == size) head_ = 0;
    history_[static_cast<std::size_t>(head_)] = position;
    int back = head_ - n;
    if (back < 0) back += size;
    const double old = history_[static_cast<std::size_t>(back)];
    measured_velocity_ = (position - old) / (n * velocity_cycle_s_);
    const double error = velocity_command - measured_velocity_;
    const double proportional = model_.velocity_gain_N_s_per_m * error;
    double command = proportional + integrator_;
    if (model_.velocity_integral_gain_N_per_m > 0.0) {
        // Integrate, except where the output is saturated and the error would drive it further (clamping
        // anti-windup), so that the loop recovers from the limit without overshoot.
        const double next = integrator_ + model_.velocity_integral_gain_N_per_m * error * velocity_cycle_s_;
        const double candidate = proportional + next;
        const bool saturated =
            model_.saturation_N && std::abs(candidate) > *model_.saturation_N && (candidate > 0.0) == (error > 0.0);
        if (!saturated) integrator_ = next;
        command = proportional + integrator_;
    }
    if (model_.saturation_N) command = std::clamp(command, -*model_.saturation_N, *model_.saturation_N);
    return command;
}

}  // namespace feedid
