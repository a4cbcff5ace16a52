#pragma once
// The numerics of step 2 (public for its tests and benchmarks; not a stable API): the paper's log-linear Stribeck RLS and the nonlinear least-squares fit
// of the whole friction curve.

#include <array>
#include <cmath>
#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "feedid/numeric/rls.hpp"
#include "feedid/identify/step2.hpp"

namespace feedid::detail {

/// Samples for a fit: acceleration, velocity, drive force, all the same length, with each sample's index in the
/// analysed samples (Derivatives) and the block over which neighbouring residuals are correlated (least_squares.hpp).
struct FitSamples {
    std::vector<double> acceleration;
    std::vector<double> velocity;
    std::vector<double> force;
    std::vector<std::size_t> index;
    /// Per sample, the inverse variance of its force [1/N^2] (a bin's mean, see fit_curve); empty: every sample
    /// weighs the same and the residuals give the noise.
    std::vector<double> weight;
    std::size_t correlation_block{1};
    [[nodiscard]] std::size_t size() const { return velocity.size(); }
    /// The square root of sample k's weight (1 without weights).
    [[nodiscard]] double root_weight(std::size_t k) const { return weight.empty() ? 1.0 : std::sqrt(weight[k]); }
    void push(double a, double v, double f, std::size_t k) {
        acceleration.push_back(a);
        velocity.push_back(v);
        force.push_back(f);
        index.push_back(k);
    }
};

/// The paper's step 2 for one direction (eq. 12-14): F_stri = F - M*a - B*v - F_C*sgn(v) - F_0;
/// ln|F_stri| = ln|F_B - F_C| - |v|/v_s, by RLS. Samples where F_stri has the wrong sign or lies below the noise
/// level are excluded and counted.
LogLinearStribeck fit_log_linear(const FitSamples& samples, double mass, double viscous, double coulomb, double offset,
                                 double noise_level, const RlsOptions& rls_options);

/// The same on `n` samples given by sample(k) -> {a, v, F} (the samples need not be gathered first).
template <class Sample>
LogLinearStribeck fit_log_linear_over(std::size_t n, const Sample& sample, double mass, double viscous, double coulomb,
                                      double offset, double noise_level, const RlsOptions& rls_options) {
    LogLinearStribeck result;
    Rls<2> rls(rls_options);
    for (std::size_t k = 0; k < n; ++k) {
        const auto [a, v, f] = sample(k);
        const double direction = v > 0.0 ? 1.0 : -1.0;
        // eq. (12): what the first step's model leaves unexplained is the Stribeck part
        const double stribeck = f - mass * a - viscous * v - coulomb * direction - offset;
        if (stribeck * direction <= 0.0) {
            ++result.wrong_sign;
            continue;
        }
        if (std::abs(stribeck) < noise_level) {
            ++result.below_noise;
            continue;
        }
        // eq. (13): ln|F_stri| = ln|F_B - F_C| - |v|/v_s
        rls.update(Eigen::Vector2d(1.0, std::abs(v)), std::log(std::abs(stribeck)));
        ++result.used;
    }
    if (result.used >= 3 && rls.estimate()(1) < 0.0) {
        result.breakaway = coulomb + std::exp(rls.estimate()(0));
        result.stribeck_velocity = -1.0 / rls.estimate()(1);
    }
    return result;
}

/// Layout of the nonlinear model: M (unless the caller has taken M*a out of the force), then per direction group
/// (one shared group, or forward and reverse) B, F_C and, where enabled, F_B - F_C and ln v_s; then the offset F_0
/// where enabled.
struct CurveModel {
    bool asymmetric{false};
    bool stribeck_forward{true};
    bool stribeck_reverse{true};
    bool offset{false};
    bool mass{true};
};

struct CurveFit {
    bool converged{false};
    Eigen::VectorXd parameters;  ///< in the layout above, with v_s (not ln v_s)
    Eigen::VectorXd standard_errors;
    Eigen::MatrixXd covariance;  ///< of the parameters above (v_s entries by the delta method)
    double residual_std{0.0};
    double relative_error_pct{0.0};
    std::size_t samples{0};
    int iterations{0};
};

/// Number of parameters and index helpers for a CurveModel.
struct CurveLayout {
    explicit CurveLayout(const CurveModel& model);
    int mass{-1};
    int viscous[2]{-1, -1};
    int coulomb[2]{-1, -1};
    int delta[2]{-1, -1};  ///< F_B - F_C
    int log_vs[2]{-1, -1};
    int offset{-1};
    int size{0};
    /// Direction group of a velocity: 0 forward (or the shared group), 1 reverse.
    [[nodiscard]] int group(double velocity, bool asymmetric) const { return asymmetric && velocity < 0.0 ? 1 : 0; }
    /// The friction force (with the offset, without M*a) that parameters x in this layout, with ln v_s (the fit's
    /// internal form, not CurveFit::parameters), give at velocity v.
    [[nodiscard]] double friction(const Eigen::VectorXd& x, double velocity, bool asymmetric) const;
};

/// The curve fit's residuals (model - force) and their analytic Jacobian at x (the fit's internal form, with ln v_s),
/// as Levenberg-Marquardt sees them; for checking the Jacobian against finite differences.
Eigen::VectorXd curve_residuals(const FitSamples& samples, const CurveModel& model, const Eigen::VectorXd& x);
Eigen::MatrixXd curve_jacobian(const FitSamples& samples, const CurveModel& model, const Eigen::VectorXd& x);

/// Above this many samples, a curve without M (the quasi-static curve) is fitted to speed bins (see fit_curve).
inline constexpr std::size_t curve_bin_above = 50000;

/// Fits the whole friction curve (with mass and offset) by a grid search over v_s (variable projection) followed by
/// Levenberg-Marquardt. `vs_low`..`vs_high` bound the grid [m/s]. A curve without M on more than `bin_above` samples
/// is fitted to per-speed-bin means (|v| bins 1 % wide per direction), each weighted by the inverse variance of its
/// mean from its own samples (cluster-robust over blocks of `correlation_block` consecutive samples, as the
/// sample-by-sample fit's covariance is): the same estimates and standard errors to a small fraction of a standard
/// error, the iterations on hundreds of points instead of 10^5.
CurveFit fit_curve(const FitSamples& samples, const CurveModel& model, double vs_low, double vs_high,
                   std::size_t bin_above = curve_bin_above);

}  // namespace feedid::detail
