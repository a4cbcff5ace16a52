#pragma once
// A friction-only result, for traces that cannot determine a mass: a machine's own coarse log (10 Hz, positions
// rounded to a millimetre) or a test without accelerations. Viscous and Coulomb friction (per direction) come from
// the steady-speed samples alone, where the drive force is friction: F = B*x' + F_C*sgn(x') (+ F_0). Whether a mass
// can be identified at all is decided from the data's figures (assess_resolution), not from a failed fit.

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "feedid/numeric/least_squares.hpp"
#include "feedid/identify/preprocess.hpp"
#include "feedid/identify/selection.hpp"
#include "feedid/identify/step1.hpp"

namespace feedid {

struct FrictionOnlyOptions {
    /// The position is too coarse for a mass when its quantisation step exceeds this fraction of the travel per
    /// sample at the typical speed (as PreprocessOptions::coarse_position_fraction).
    double coarse_position_fraction{0.1};
    /// The sample rate does not resolve the accelerations when the speed changes between two samples by more than
    /// this fraction of the typical speed (the 99th percentile of |dv|): an acceleration from rest to the typical
    /// speed then spans fewer than 1/fraction samples.
    double unresolved_speed_step_fraction{0.2};
    /// Steady: the logged velocity of a sample and both neighbours keeps its sign and lies within this fraction of
    /// |v| (without a logged velocity: step 2's quasi-static samples).
    double steady_spread_fraction{0.1};
    /// ... in passes of at least this many consecutive steady samples (constant-velocity strokes, not the moments
    /// of a micro-step).
    std::size_t minimum_steady_run{5};
    /// At least this many steady samples per friction parameter.
    std::size_t minimum_samples_per_parameter{10};
    /// B needs two speeds: per direction, this many steady samples at least `minimum_speed_ratio` times faster or
    /// slower than the median steady speed.
    double minimum_speed_ratio{1.5};
    std::size_t minimum_samples_at_another_speed{5};
    /// The smallest detectable mass is the one whose inertial force at the largest acceleration stands this many
    /// friction scatters (residual standard deviations) above the noise.
    double detectable_force_multiple{3.0};
    /// Standard errors count residuals as correlated over this many correlation lengths of the low-pass (as
    /// Step1Options::correlation_blocks).
    double correlation_blocks{2.0};
    /// Robust weighting against loads the model has no term for (a cutting force on a feed stroke): Tukey's biweight
    /// by IRLS, as scan's windows are fitted, from least squares and from the fastest third of the steady samples
    /// (rapids do not cut), keeping the fit of smallest robust scale (1.4826 MAD). false: least squares.
    bool robust{true};
    double tukey_c{4.685};  ///< Tukey's tuning constant, in robust scales (95 % efficiency on Gaussian noise)
    int irls_iterations{30};
    /// More of the steady samples rejected than this (weight 0): they do not follow one friction law, and the fit
    /// fails saying so (the estimator's breakdown point: beyond it the loaded samples are the majority).
    double maximum_rejected_fraction{0.5};
};

/// What the data resolves, in figures.
struct Resolution {
    double sample_rate_hz{0.0};
    double position_quantum{0.0};    ///< [m]; 0 without a position
    double typical_speed{0.0};       ///< 95th percentile of |x'| [m/s]
    /// 99th percentile of |x'(k+1) - x'(k)| [m/s] where the accelerations are unresolved (0 otherwise: the test
    /// against the typical speed counts the steps below the limit instead of selecting the percentile)
    double largest_speed_step{0.0};
    bool position_too_coarse{false};
    bool accelerations_unresolved{false};
    [[nodiscard]] bool coarse() const { return position_too_coarse || accelerations_unresolved; }
    /// The figures in words ("10 Hz sampling and 1 mm position resolution (1.8 mm of travel per sample at ...").
    std::string description;
};

/// The figures of the analysed samples: sample rate against the speed's changes, position resolution against the
/// travel per sample. `moving_speed` > 0: of the samples faster than it only (and the steps to or from one of them:
/// a start from rest within one sample is what a coarse log shows), so that a production trace at rest most of the
/// time is judged by its moves [m/s or rad/s].
Resolution assess_resolution(const Derivatives& derivatives, const FrictionOnlyOptions& options,
                             double moving_speed = 0.0);

/// identify's rule on a whole trace, for front-ends that do not run identify's stages (scan): the samples
/// preprocessed as identify preprocesses them (`preprocess`), then assess_resolution. `force` [N] per sample. A trace
/// the preprocessing cannot take (too short, no motion, an option it refuses) is not coarse. Judged by the samples
/// faster than `moving_speed` (a production trace rests most of the time: the drilling program's Y axis, at rest
/// in 9 of 10 samples, was taken for a coarse log by all of them).
Resolution assess_trace_resolution(const Trace& trace, std::span<const double> force,
                                   const PreprocessOptions& preprocess, const FrictionOnlyOptions& options,
                                   double moving_speed);

struct FrictionOnlyFit {
    std::vector<RegressorColumn> columns;  ///< the friction columns of the step-1 model (no mass)
    LeastSquaresResult batch;
    std::size_t samples{0};            ///< steady samples used (rejected ones included)
    std::size_t rejected{0};           ///< steady samples the robust weights rejected (weight 0)
    double robust_scale{0.0};          ///< 1.4826 MAD of the residuals of the robust fit [N]; 0 without
    double largest_acceleration{0.0};  ///< [m/s^2] among the moving samples
    /// The smallest mass whose inertial force at the largest acceleration stands above the friction scatter [kg].
    double smallest_detectable_mass{0.0};
    /// The standard errors count each steady pass's own level once (account_for_pass_levels in the source): the
    /// passes, the scatter of their levels beyond their noise [N] (raised for the drift's mean level), and the batch
    /// means' block [samples].
    std::size_t passes{0};
    double pass_level_std{0.0};
    /// The pass levels' correlation from one pass to the next in the friction's sense (a drift: AR(1), 0 without).
    double level_correlation{0.0};
    std::size_t correlation_block{1};
    std::string failure;  ///< why the steady samples cannot determine B and F_C ("" when they can)
    [[nodiscard]] bool failed() const { return !failure.empty(); }
};

/// B and F_C (per direction for the asymmetric model; F_0 with `offset`) by batch QR on the steady-speed samples.
FrictionOnlyFit fit_friction_only(const Derivatives& derivatives, const Selection& selection, FrictionModelKind model,
                                  bool offset, const FrictionOnlyOptions& options);

}  // namespace feedid
