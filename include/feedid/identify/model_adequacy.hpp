#pragma once
// The model-adequacy stage of identify, between the sample selection and the two steps: which model the data
// support, and what they cannot tell apart. Every standard error is conditional on the model; this stage checks the
// model before any number is reported.
//
//   timing:      the drive signal and the position may be offset in time (a current sampled at another instant of
//                the servo cycle than the position, a current loop's lag, two recorders' clocks). With the drive
//                signal logged late by tau, F_log(t) = F(t - tau), so to first order
//                    F_log = Phi*theta - tau * F_log'                                   (F_log' the filtered dF/dt)
//                and tau is one more linear parameter of step 1 (a fractional-delay regressor). Where it is
//                significant, the filtered drive force is read tau later (cubic interpolation) and everything
//                downstream sees aligned signals; its standard error is carried into M, B, F_C and F_0.
//   the model:   symmetric [x'', x', s] within symmetric with an offset [.., 1] within per direction
//                [x'', x'+, x'-, s+, s-] (on moving samples s+ - s- = 1, so the per-direction Coulomb terms carry
//                any constant force). Each extension is taken when its Wald statistic z = estimate / standard error
//                (standard errors that allow for correlated residuals, least_squares.hpp) exceeds the two-sided
//                normal quantile of `test_level`: the offset on z(F_0), friction per direction on z(B+ - B-).
//   process:     a force the model has no term for (cutting, a load) shows as bursts: stretches where the residual
//                of a robust fit stays far on one side. identify refuses such a trace and names `feedid scan`,
//                which identifies production traces window by window with robust weights.
//   aliasing:    on a move in one direction, sgn(x') is constant: a constant force (a weight, a sensor's zero) and
//                Coulomb (and breakaway) friction are one number. Unless the drive signal was tared, or is
//                observed at zero force at rest, F_C, F_B and F_0 are null with that reason.

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "feedid/identify/preprocess.hpp"
#include "feedid/identify/selection.hpp"
#include "feedid/identify/step1.hpp"
#include "feedid/model/friction.hpp"

namespace feedid {

struct ModelSelectionOptions {
    /// Choose the friction model, the offset and the delay from the data. False: the model of IdentifyOptions as
    /// given (--model, --offset, --no-offset force it), what the data say against it only in findings.
    bool automatic{true};
    /// An extension of the model is taken when its Wald statistic exceeds the two-sided normal quantile at this
    /// level (1e-3: 3.29 standard errors).
    double test_level{1e-3};
    /// The delay between the drive signal and the position: follow_model estimates it, and applies it where
    /// significant in automatic mode (with a forced model it is only said); estimate applies it where significant
    /// either way; none neither estimates nor applies it; known_delay_s below applies a given one.
    enum class Delay { follow_model, estimate, none };
    Delay delay{Delay::follow_model};
    /// With a forced model, test whether the data reject it (said in findings).
    bool test_forced{true};
    /// A delay beyond this is not a sub-sample timing offset but two recorders' clocks (--join @SHIFT) [s].
    double max_delay_s{0.005};
    /// A delay known beforehand [s] (the drive signal logged this much later than the position): applied, not
    /// estimated.
    std::optional<double> known_delay_s;
    /// A direction with fewer than this fraction of step 1's samples does not count: the move goes one way.
    double one_way_fraction{0.02};
    /// Process forces (cutting, a load the drive's model does not have): a stretch of samples whose residual (from a
    /// robust fit: Tukey's biweight with this constant, in robust standard deviations) stays beyond
    /// burst_deviations robust standard deviations on one side for at least burst_correlation_lengths lengths of
    /// the low-pass's correlation and burst_min_s (longer than the transient a late drive signal leaves at a jerk) is a
    /// burst; a trace with one is refused.
    double tukey_constant{4.685};
    double burst_deviations{4.0};
    double burst_correlation_lengths{3.0};
    double burst_min_s{0.1};
    /// ... and beyond this fraction of the Coulomb friction (a force too small to matter is not refused).
    double burst_friction_fraction{0.05};
    /// Standard errors count residuals as correlated over blocks of at least this many integrated autocorrelation
    /// times of step 1's residual (when that is longer than the low-pass's reach): a force the model misses that
    /// varies slowly (friction along the axis, a load) makes neighbouring residuals news only once.
    double autocorrelation_blocks{4.0};
    /// Two estimates correlated beyond this are not separated by the data: both null with the reason.
    double collinearity_limit{0.999};
    /// On a move in one direction, the drive force at rest before the move counts as zero when it lies within this
    /// many of its standard errors (and within zero_force_fraction of the moving force) of zero.
    double rest_zero_standard_errors{4.0};
    double zero_force_fraction{0.02};
    /// The model fits when its residual, averaged over groups of samples (by speed and direction, by acceleration
    /// and direction, over time), shows no structure: a check fails when the chi-square of the group means exceeds
    /// test_level's quantile and the largest group mean exceeds this fraction of the typical drive force (a structure
    /// too small to move a parameter materially is not a lack of fit worth a status). Where a check fails, the
    /// standard errors are scaled by sqrt(chi-square / groups) (the Birge ratio) and the status is partial.
    double lack_of_fit_fraction{0.01};

    /// What is wrong with these options ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// One extension of the model, tested.
struct ModelCandidate {
    std::string name;            ///< "symmetric", "offset", "per direction", "delay"
    std::string tested;          ///< the term tested: "F_0", "B+ - B-", "tau"
    std::optional<double> estimate;        ///< of the tested term (SI)
    std::optional<double> standard_error;
    std::optional<double> statistic;       ///< |estimate| / standard error
    double threshold{0.0};                 ///< the statistic needed
    bool taken{false};
    std::string verdict;  ///< why taken or not, in words
};

/// The drive force at rest before the move (the samples a tare would average: io/tare.hpp).
struct RestLevel {
    std::size_t samples{0};
    double mean{0.0};            ///< [N or N*m]
    double standard_error{0.0};  ///< of the mean, counting correlated neighbours once
};

/// A lack-of-fit check of the identified model: its residual F - M x'' - F_f(x') - F_0 on the samples it describes,
/// averaged over groups of them; the group means should be zero within their standard errors (each group's spread
/// over its effective number of samples: correlated neighbours count once).
struct FitCheck {
    std::string name;                       ///< the grouping: "speed", "acceleration", "time"
    std::size_t groups{0};                  ///< groups with enough samples to count
    double chi_square{0.0};                 ///< of the group means against zero, over `groups` degrees of freedom
    std::optional<double> statistic;        ///< the chi-square as a standard normal deviate
    double threshold{0.0};                  ///< the deviate beyond which the structure is significant
    double largest{0.0};                    ///< the largest group mean [N or N*m]
    double largest_standard_error{0.0};     ///< its standard error [N or N*m]
    double relative{0.0};                   ///< |largest| / the typical drive force
    double material_fraction{0.0};          ///< the relative size beyond which the structure matters
    std::string where;                      ///< the group of the largest mean, in words
    bool passed{true};
};

struct ModelChoice {
    FrictionModelKind model{FrictionModelKind::symmetric};
    bool offset{false};
    bool automatic{true};
    bool one_way{false};
    /// The delay of the drive signal behind the position [s] and its standard error; null when not estimated.
    std::optional<double> delay_s;
    std::optional<double> delay_standard_error;
    bool delay_applied{false};  ///< the drive force was read delay_s later
    /// estimated, but not significant: not applied, and its standard error carried into the parameters
    bool delay_uncertain{false};
    std::string delay_source;   ///< "estimated", "given", "" (none)
    /// dtheta/dtau of step 1's linear parameters (per column of linear_columns(model, offset)) [unit per s]: the
    /// delay's standard error times this is added to each parameter's where the delay was applied or is uncertain (a
    /// delay the test does not take is still known only to its standard error).
    std::vector<double> delay_sensitivity;
    std::vector<ModelCandidate> candidates;
    std::vector<std::string> findings;
    /// Why the trace cannot be identified as a test (process forces in it), "" when it can.
    std::string process_forces;
    /// Why F_C, F_B and F_0 are null (a move in one direction with a constant force that cannot be ruled out); ""
    /// when they are not.
    std::string aliased_friction;
    std::optional<RestLevel> rest;
    /// Step 1's residual's integrated autocorrelation time [analysed samples], and the block the standard errors
    /// then use when it is longer than the low-pass's (0 when not widened).
    double residual_autocorrelation_samples{1.0};
    std::size_t correlation_block_samples{0};
    /// Step 1's estimates of the chosen model (per column of linear_columns(model, offset)) on the samples selected
    /// under the symmetric model, before the selection was made again under the chosen one (empty when the model
    /// stayed symmetric). How far the final estimates lie from them is a systematic part of their uncertainty: which
    /// samples step 1 takes depends on the model the selection assumed.
    std::vector<double> first_selection_estimate;
    /// The lack-of-fit checks of the identified model (empty where no full model was identified).
    std::vector<FitCheck> fit_checks;
};

/// The rest level of a drive force over its first `samples` samples (the leading rest, io/tare.hpp); nullopt with
/// fewer than 10.
std::optional<RestLevel> rest_level(std::span<const double> force, std::size_t samples);

/// The column -F_log'(t): the filtered drive force's time derivative (central differences within each stretch),
/// negated so that its coefficient is the delay.
std::vector<double> delay_column(const Derivatives& derivatives);

/// Reads the filtered drive force `delay_s` later (F_aligned(t) = F_log(t + delay_s)), by cubic interpolation within
/// each stretch (held at the stretch's ends).
void shift_drive_force(Derivatives& derivatives, double delay_s);

/// The integrated autocorrelation time [samples] of `values` at ascending sample indices `rows` (gaps allowed), by
/// blocking as below; 1 for uncorrelated values or fewer than 100.
double integrated_autocorrelation_time(const std::vector<std::size_t>& rows, const std::vector<double>& values);

/// The integrated autocorrelation time of step 1's residual under `regressors` [analysed samples], by blocking:
/// half the largest ratio, over blocks of 2, 4, 8 ... samples (at least 50 of them), of the sum of squared block sums
/// to the sum of squares; 1 for an uncorrelated residual.
double residual_autocorrelation_time(const Derivatives& derivatives, const Regressors& regressors,
                                     std::span<const SampleIndex> rows);

/// The lack-of-fit checks of `axis` (the identified model) on the samples it was identified from: step 1's, and step
/// 2's where the friction has a Stribeck term.
std::vector<FitCheck> check_fit(const Derivatives& derivatives, const Selection& selection, const AxisModel& axis,
                                const ModelSelectionOptions& options);

/// The stage: chooses the model on step 1's samples (`selection.step1`), estimates and applies the delay (the force
/// in `derivatives` is shifted in place), and says what the data cannot separate. `forced_model` and `forced_offset`
/// are the options' model (taken as it is when !options.automatic). `drive_tared`: the drive signal's zero was
/// removed at import (--tare), so on a one-way move no constant force remains; `rest` the drive force at rest before
/// the move. The models' regressor columns are held on step 1's samples (and their neighbours) only, for the stage
/// alone; those `columns` holds are taken from it (the caller's regressor's then cost no second low-pass).
ModelChoice choose_model(Derivatives& derivatives, const Selection& selection, FrictionModelKind forced_model,
                         bool forced_offset, bool drive_tared, const std::optional<RestLevel>& rest,
                         const ModelSelectionOptions& options, double correlation_blocks,
                         const RegressorColumnCache* columns = nullptr);

}  // namespace feedid
