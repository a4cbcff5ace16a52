#pragma once
// Identification of the cascaded P-PI controller's gains (controller.hpp) from a trace: the position loop's K_v, the
// velocity loop's K_p and K_i, and the structure between them (velocity measurement, reference delay, current-loop
// lag), by RLS on the loop equations; and the gains document that carries them to `feedid simulate`.

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/model/controller.hpp"
#include "feedid/model/drive.hpp"
#include "feedid/core/estimate.hpp"
#include "feedid/numeric/rls.hpp"
#include "feedid/core/status.hpp"
#include "feedid/core/trace.hpp"

namespace feedid {

enum class VelocityLoopStructure { automatic, p, pi };

struct GainOptions {
    /// P or PI velocity loop; automatic: PI, falling back to P when the integral gain is not significant.
    VelocityLoopStructure velocity_loop{VelocityLoopStructure::automatic};
    bool feedforward{false};                            ///< also estimate a velocity feed-forward k_ff
    std::optional<int> velocity_difference_samples;     ///< n of the velocity measurement; none = chosen from the data
    std::optional<double> current_lag_s;                ///< tau [s]; none = estimated from the data
    /// The rate the velocity loop runs at [Hz], a whole multiple of the trace's sample rate; none = the trace's
    /// `servo_cycle_s` constant when it has one, else detected from the data (the log rate unless a faster loop
    /// explains the drive signal clearly better).
    std::optional<double> servo_rate_hz;
    std::optional<double> saturation_N;                 ///< samples at this force command limit are left out [N]
    double force_per_signal{0.0};                       ///< N per unit of the logged drive signal (0 = unknown)
    std::string signal_unit;                            ///< the logged drive signal's unit ("V", "A"), for reporting
    RlsOptions rls{1.0, 1e6, RlsVariant::directional};  ///< constant gains: no forgetting by default

    [[nodiscard]] std::string validate() const;
};

/// Sets what the options take from the drive signal, as `feedid gains` does: force_per_signal and signal_unit when the
/// trace's drive signal is a current or voltage that `drive` turns into force (not when the trace has a force
/// channel), and saturation_N from a limit given in the drive signal's own units (e.g. 10 for 10 V; its magnitude,
/// times force_per_signal when known).
void set_drive_signal(GainOptions& options, const Trace& trace, const DriveConstants& drive,
                      std::optional<double> saturation_in_signal_units);

/// The largest systematic error [%] of the velocity loop's force fit (GainResult::systematic_error_pct: the part of
/// the residual that is not white sensor noise) at which the gains are trusted. Measured (README, "Injected test
/// signals"): a correct controller model leaves 0.00 % on EMPS and 0.03 to 0.56 % on synthetic traces (current noise
/// 0.02 to 0.2 A, that is a total relative error of 1.1 to 11 %); a model that misses an injected square wave leaves
/// 12 % (200 N on the demo drive) to 87 % (EMPS-like 176 N pulses). 3 % lies five times above the one and four times
/// below the other. Above it the gains are reported as failed.
inline constexpr double gain_fit_error_limit_pct = 3.0;

/// One model of the position loop fitted from a logged velocity command: "P" (v_cmd = K_v*e) or "P+FF" (with a
/// velocity feed-forward k_ff*x_ref').
struct PositionLoopModel {
    std::string name;
    Estimate position_gain_per_s;  ///< K_v of this model [1/s], its standard error within the model
    double relative_error_pct{0.0};  ///< of its fit [%]: to the velocity command, or from the structure to the drive signal
    /// Its Akaike weight [-]: exp(-AIC/2) normalised over the models, AIC = N*ln(RSS/N) + 2*p
    double weight{0.0};
};

struct GainResult {
    /// ok; failed when the controller model does not explain the drive signal (systematic error above
    /// gain_fit_error_limit_pct), when the drive force is too large for its squares to be finite numbers (nothing is
    /// fitted), when a gain or fit figure is not a finite number (it is dropped), or when K_v or K_p came out
    /// negative (no stable controller; the fix is named): the gains are then not to be trusted, and the first
    /// diagnostic says why, with the figures.
    Status status{Status::ok};
    ControllerModel controller;               ///< the identified controller (for simulation)
    Estimate position_gain_per_s;             ///< K_v
    Estimate velocity_gain_N_s_per_m;         ///< K_p
    Estimate velocity_integral_gain_N_per_m;  ///< K_i (null for a P-only loop)
    Estimate velocity_feedforward;            ///< k_ff (null unless asked for or shown by the data)
    /// The position-loop models fitted from a logged velocity command (P and P+FF), with K_v of each; empty from the
    /// structure alone. position_gain_per_s is the chosen model's K_v, its standard error taken over the models by
    /// their weights (Burnham and Anderson's unconditional standard error, sum of w*sqrt(se^2 + (K_v,m - K_v)^2)).
    std::vector<PositionLoopModel> position_loop_models;
    /// K_v's standard error within the chosen model alone [1/s]; none where no other model was fitted.
    std::optional<double> position_gain_within_model_stderr;
    /// K_v of the P-only fit of a loop fitted with a feed-forward [1/s]: an effective gain (the one a P loop would
    /// need to follow as this one does), not the loop's; null otherwise.
    Estimate effective_position_gain_per_s;
    Estimate reset_time_s;                    ///< T_n = K_p / K_i
    /// "velocity_command" when the trace holds the velocity command (each loop identified on its own), or
    /// "structure" when only reference, position and drive signal are there (v = K_p*(K_v*e - v) [+ integral]).
    std::string method;
    int velocity_difference_samples{1};
    int reference_delay_samples{0};  ///< samples by which the controller's reference lags the logged one
    /// The setpoint delay [s]: the position loop works on the reference this much after it was logged (a few servo
    /// cycles), with its standard error from the residual's curvature in it. Finer than whole samples where the
    /// loop is fitted from a logged velocity command or at a servo rate above the log's; reference_delay_samples
    /// is it rounded to samples.
    Estimate setpoint_delay_s;
    int drive_delay_samples{0};      ///< samples by which the logged drive signal lags the command
    double current_lag_s{0.0};
    /// The velocity loop's rate [Hz]: the log rate, or a multiple of it for a loop that runs between the logged
    /// samples (velocity_difference_samples then counts its cycles).
    double servo_rate_hz{0.0};
    /// "equation_error" (the loop equations on the logged samples: the loop runs at the log rate) or "output_error"
    /// (the controller simulated at servo_rate_hz between the logged samples, its output fitted to the drive signal).
    std::string fit_kind{"equation_error"};
    /// Why that fit: "log rate", "--servo-rate", "trace" (its servo_cycle_s), "detected".
    std::string servo_rate_from{"log rate"};
    double relative_error_pct{0.0};  ///< of the velocity loop's force fit, 100*||F - F_hat||/||F||
    /// 100*||r_s||/||F||, r_s the part of the velocity loop's residual that is not white (sensor) noise: what the
    /// model misses. The fit-quality gate (gain_fit_error_limit_pct) looks at this.
    double systematic_error_pct{0.0};
    double position_loop_relative_error_pct{0.0};  ///< of the position loop's fit (velocity_command method)
    std::size_t samples_used{0};
    bool injection_subtracted{false};  ///< an injected signal was taken out of the drive force before the fit
    /// The gain [-] with which the injection enters the drive signal (drive force = controller output + g * the
    /// injection as logged), fitted with the controller; 1 without a standard error where the data cannot tell it
    /// (a diagnostic says so). Null without an injection.
    Estimate injection_gain;
    std::vector<std::string> diagnostics;
};

/// Identifies the controller gains from a trace (reference position, position, and a velocity command when present)
/// and the drive force [N] per sample (drive_force() of drive.hpp). Estimates by RLS (GainOptions::rls; with
/// lambda = 1 it equals batch least squares) on normalised regressors; standard errors from the batch residuals.
/// `injection` [N] per sample (injection_force() of drive.hpp; empty = none) is a test signal added to the
/// controller's output before the drive: it is in the drive force but not the controller's doing, so it is taken
/// out (through the same current-loop lag) before the controller is fitted.
/// Throws InputError when the trace lacks a reference or position; AnalysisError when the data cannot determine
/// the gains (no following error, too few samples). A fit too poor to trust is status failed with a diagnostic.
GainResult identify_gains(const Trace& trace, std::span<const double> drive_force, const GainOptions& options = {},
                          std::span<const double> injection = {});

/// A channel without a role that looks like a test signal injected at the controller's output: named like one
/// ("pulses_N", "injection", "excitation", "dither", "prbs") or a square wave (two levels, switching at least four
/// times) that the following error does not follow (|correlation| < 0.3). Its name, and why it looks like one
/// ("named like one" or "a square wave ..."); none when there is no such channel.
struct InjectionLike {
    std::string channel;
    std::string why;
};
std::optional<InjectionLike> unmapped_injection(const Trace& trace);

/// The finding on such a channel: what it looks like, and `--channel injection=NAME` to map it.
std::string unmapped_injection_message(const InjectionLike& found);

/// The gains document (`feedid gains --json`, docs/documents.md) of the gains identified from `trace` (its path and
/// length are in the document).
nlohmann::json gains_document(const GainResult& result, const GainOptions& options, const Trace& trace);

/// Whether a gains document is of a rotary axis ("rotary": true, or without that key its rotary gain keys).
[[nodiscard]] bool gains_document_is_rotary(const nlohmann::json& document);

/// Reads a controller from a gains document (as written by gains_document), InputError naming `source` when a
/// required key is missing.
ControllerModel controller_from_document(const nlohmann::json& document, const std::string& source);

}  // namespace feedid
