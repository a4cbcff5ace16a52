#pragma once
// Stage 4 of identify, the paper's step 2 and past it: Stribeck friction per direction.
//   the paper's log-linear RLS (eq. 12-14): F_stri = F - M*x'' - B*x' - F_C*sgn(x') (- F_0),
//     ln|F_stri| = ln|F_B - F_C| - |x'|/v_s, on the quasi-static slow samples;
//   then a Levenberg-Marquardt fit of the whole friction curve (all parameters at once, no log bias). When the
//   quasi-static samples span the fast speeds too (a designed test: the feed ladder and slow passes), the curve is
//   fitted to the quasi-static samples alone and M to the accelerating ones with the curve held, so that what
//   transients carry besides M*x'' (current-loop lag, the drive signal held over a sample) cannot leak into friction.
//   Otherwise M and the curve are fitted jointly. F_B and v_s are accepted only where the data pins them down.

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "feedid/core/estimate.hpp"
#include "feedid/identify/selection.hpp"
#include "feedid/identify/step1.hpp"

namespace feedid {

/// Step 2's thresholds. The model (symmetric or per direction, with or without offset) and the RLS options of the
/// log-linear fit are step 1's.
struct FrictionFitOptions {
    /// A direction needs at least this many quasi-static slow samples for F_B and v_s (identify() sets it from
    /// SelectionOptions).
    std::size_t minimum_slow_samples{20};
    /// The log-linear fit ignores Stribeck residuals below this many step-1 residual standard deviations.
    double log_linear_noise_multiple{2.0};
    /// Each of step 1's and step 2's sample sets enters the curve fit thinned to about this many samples: beyond
    /// that the fit gains little but time (a million-sample trace).
    std::size_t max_fit_samples{100000};
    /// v_s is searched between the slowest quasi-static speed / stribeck_velocity_search_below and the larger of the
    /// split speed and stribeck_velocity_search_above times the initial split (a third of the typical speed).
    double stribeck_velocity_search_below{5.0};
    double stribeck_velocity_search_above{3.3};
    /// Refits after dropping undetermined Stribeck terms.
    int max_attempts{3};
    /// v_s is accepted only inside (vs_low * 1.05, vs_high * 0.95) (not on a bound of the search), with a relative
    /// standard error below 0.3, with F_B - F_C above 3 standard errors, and with enough quasi-static samples below
    /// 3 v_s (where the Stribeck term has not yet decayed).
    double bound_margin_low{1.05};
    double bound_margin_high{0.95};
    double max_stribeck_velocity_relative_error{0.3};
    double rise_significance{3.0};
    double determining_speed_multiple{3.0};
    /// ... at more than one speed: their 90th percentile at least this multiple of their 10th.
    double determining_speed_ratio{1.5};
    /// The curve and M separate (quasi-static curve, M from the transients) when every direction has at least this
    /// multiple of minimum_slow_samples quasi-static samples, with speeds at least `separable_speed_ratio` apart
    /// (90th against 10th percentile): B needs two speeds.
    std::size_t separable_sample_multiple{10};
    double separable_speed_ratio{2.0};
    /// Standard errors count residuals as correlated over this many correlation lengths of the preprocessing's
    /// low-pass, as step 1's do (Step1Options::correlation_blocks; identify() sets it from there).
    double correlation_blocks{2.0};
    /// The paper's log-linear fit per direction (FrictionFit::log_linear), which is reported, not used by the
    /// estimates: off where only the estimates count (the preprocessing family's reruns).
    bool log_linear{true};
};

/// The paper's log-linear estimate for one direction (eq. 13-14).
struct LogLinearStribeck {
    std::optional<double> breakaway;          ///< F_B [N]
    std::optional<double> stribeck_velocity;  ///< v_s [m/s]
    std::size_t used{0};
    std::size_t wrong_sign{0};   ///< samples whose Stribeck force has the wrong sign
    std::size_t below_noise{0};  ///< samples whose Stribeck force is below the noise
};

/// How the accepted nonlinear fit went.
struct NonlinearFitReport {
    std::string method;  ///< "joint" or "quasi-static curve, mass from the transients"
    bool converged{false};
    double relative_error_pct{0.0};
    double residual_std{0.0};
    std::size_t samples_used{0};
    int function_evaluations{0};
};

/// The friction parameters of one direction group (the shared one, or forward / reverse).
struct BranchEstimates {
    Estimate viscous;
    Estimate coulomb;
    Estimate breakaway;          ///< null without a Stribeck term
    Estimate stribeck_velocity;  ///< null without a Stribeck term
};

struct FrictionFit {
    std::array<std::optional<LogLinearStribeck>, 2> log_linear;  ///< forward, reverse
    std::optional<NonlinearFitReport> nonlinear;                 ///< set when a curve was accepted
    /// The accepted curve: M (and F_0) with it, and the branches (group 1 only per direction).
    Estimate mass;
    Estimate offset;
    std::array<BranchEstimates, 2> groups;
    std::vector<std::string> diagnostics;  ///< what the data could not determine, and what would
    [[nodiscard]] bool accepted() const { return nonlinear.has_value(); }
};

/// Step 2 on the selected samples, starting from step 1's linear model.
FrictionFit fit_friction_curve(const Derivatives& derivatives, const Selection& selection, const Step1Fit& step1,
                               const FrictionFitOptions& options);

}  // namespace feedid
