#pragma once
// Stage 3 of identify, the paper's step 1: the linear model of eq. (11) on the samples fast enough for the Stribeck
// term to be negligible,
//   y = F_d,  phi = [x'', x', sgn(x') (, 1)],  theta = [M, B, F_C (, F_0)],
// or per direction [x'', x'+, x'-, s+, s- (, 1)] with x'+ = max(x', 0), x'- = min(x', 0), s+ = [x' > 0],
// s- = -[x' < 0] (so the reverse Coulomb friction comes out as a positive magnitude, as in EMPS eq. 12).
// Estimated by batch Householder QR (the certified reference, with standard errors) and by RLS (the paper's
// eq. 7-9, or directional forgetting) with the transient detected from the data.

#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "feedid/numeric/least_squares.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/preprocess.hpp"
#include "feedid/numeric/rls.hpp"

namespace feedid {

enum class FrictionModelKind { symmetric, asymmetric };

/// One column of the step-1 regressor and the parameter it estimates.
struct RegressorColumn {
    Term term;
    Direction direction;
};

/// The columns of eq. (11) (or per direction), with the offset column last when `offset`.
std::vector<RegressorColumn> linear_columns(FrictionModelKind model, bool offset);

/// The regressor of eq. (11) on every analysed sample: one column per parameter, formed at the full rate and
/// decimated like the force (Derivatives), and the output y = F_d. The columns that are the Derivatives' own (x'' for
/// M, x' for B, F_d for y: the same values, decimated alike) are views of them, not copies: the Derivatives must
/// outlive the Regressors. The others (the filtered sgn(x'), x' per direction, the constant) are held in `owned`,
/// shared with the other Regressors built from the same cache.
struct Regressors {
    std::vector<RegressorColumn> columns;
    std::vector<std::span<const double>> values;  ///< values[c][k]: column c at sample k
    std::span<const double> output;               ///< y[k] = F_d
    /// the storage of the columns that are not the Derivatives'
    std::vector<std::shared_ptr<const std::vector<double>>> owned;

    Regressors() = default;
    Regressors(Regressors&&) = default;
    Regressors& operator=(Regressors&&) = default;
    // a copy's views would point into the original's storage
    Regressors(const Regressors&) = delete;
    Regressors& operator=(const Regressors&) = delete;

    /// Row k of Phi into `row` (parameters() values) and y[k] as the result.
    double row(std::size_t k, double* phi) const {
        for (std::size_t c = 0; c < values.size(); ++c) phi[c] = values[c][k];
        return output[k];
    }

    /// Phi over the given samples (rows in that order).
    [[nodiscard]] Eigen::MatrixXd matrix(std::span<const SampleIndex> rows) const;
    /// y over the given samples.
    [[nodiscard]] Eigen::VectorXd outputs(std::span<const SampleIndex> rows) const;
    [[nodiscard]] std::size_t parameters() const { return columns.size(); }
};

/// The columns build_regressors forms (each a low-pass of the whole trace) by term and direction, kept for the
/// Regressors of other models on the same Derivatives: the model-adequacy stage fits four models to one trace. Valid
/// while the Derivatives' x'' and x' stay as they were (the force may change: it is not cached).
class RegressorColumnCache {
public:
    [[nodiscard]] std::shared_ptr<const std::vector<double>> find(const RegressorColumn& column) const;
    void store(const RegressorColumn& column, std::shared_ptr<const std::vector<double>> values);
    /// The columns `regressors` holds, kept for the next models.
    void remember(const Regressors& regressors);

private:
    std::vector<std::pair<RegressorColumn, std::shared_ptr<const std::vector<double>>>> columns_;
};

/// The values of one regressor column on every analysed sample, and the storage behind them when they are not the
/// Derivatives' own (x'' and x' are viewed).
struct RegressorValues {
    std::span<const double> values;
    std::shared_ptr<const std::vector<double>> owned;
};

/// Column `column` of the regressor on `derivatives`, as build_regressors forms it: taken from `cache` when it holds
/// it, else formed (a low-pass of the whole trace for the columns nonlinear in x') and not stored.
RegressorValues regressor_values(const Derivatives& derivatives, const RegressorColumn& column,
                                 const RegressorColumnCache* cache = nullptr);

/// The regressor of `model` (with an offset column when `offset`) on `derivatives`; the columns it has to form are
/// taken from and left in `cache` when one is given.
Regressors build_regressors(const Derivatives& derivatives, FrictionModelKind model, bool offset,
                            RegressorColumnCache* cache = nullptr);

struct Step1Options {
    RlsOptions rls;
    /// Step 1 needs at least this many samples per parameter.
    std::size_t minimum_samples_per_parameter{10};
    /// M is usable only when its standard error is below this fraction of it (the acceleration explains a
    /// significant part of the force).
    double mass_relative_standard_error{0.25};
    /// The drive signal counts the other way than the position when M and every Coulomb term lie more than this many
    /// standard errors below zero.
    double sign_standard_errors{3.0};
    /// A trace whose travel stays below this is a micro-step or creep test, and the message says so [m or rad].
    double creep_travel{1e-3};
    /// The RLS transient ends where every parameter stays within max(this fraction of |batch estimate|,
    /// rls_settle_standard_errors * its batch standard error) of the final RLS estimate.
    double rls_settle_fraction{0.02};
    double rls_settle_standard_errors{3.0};
    /// The standard errors count residuals as correlated over blocks of this many correlation lengths of the
    /// preprocessing's low-pass (batch means, least_squares.hpp): with the force filtered like the position, the
    /// plain estimate sigma^2 (Phi^T Phi)^-1 would count each of the correlated samples as news.
    double correlation_blocks{2.0};
    /// A relative error above this [%] is investigated: which samples carry the residual (accelerating ones, above
    /// residual_acceleration_fraction of the largest |x''|; slow ones, below residual_slow_multiple of the slowest
    /// step-1 speed; those within residual_reversal_s of a reversal), and a class carrying more than
    /// residual_concentration times its share of the samples names the likely cause.
    double investigate_relative_error_pct{10.0};
    double residual_acceleration_fraction{0.3};
    double residual_slow_multiple{2.0};
    double residual_reversal_s{0.05};
    double residual_concentration{2.0};
    /// The RLS trajectory is kept at about this many points (history for plots and the transient).
    std::size_t rls_history_points{2000};
    /// Run RLS beside the batch estimate (false where only the estimates are wanted).
    bool run_rls{true};
};

/// The RLS run over the step-1 samples in time order.
struct RlsRun {
    Eigen::VectorXd final_estimate;  ///< the last estimate
    Eigen::VectorXd averaged;        ///< the paper's value: the mean after the transient (the final one if unsettled)
    std::size_t settled_index{0};    ///< first step-1 sample of the settled part
    double transient_end_s{0.0};     ///< its time [s]
    bool settled{false};
    bool wound_up{false};      ///< the covariance grew without bound (paper's variant)
    bool covariance_ok{true};  ///< finite and symmetric at the end
    std::vector<double> history_time;
    std::vector<Eigen::VectorXd> history;
};

struct Step1Fit {
    std::vector<RegressorColumn> columns;
    std::size_t samples{0};        ///< step-1 samples offered
    LeastSquaresResult batch;      ///< batch QR on them (empty when too few)
    std::optional<RlsRun> rls;     ///< run only when the batch fit determines the mass
    RlsOptions rls_options;        ///< the RLS options used
    double max_acceleration{0.0};  ///< largest |x''| among the samples used [m/s^2]

    /// Why step 1 cannot identify the model ("" when it can); when set, `batch` may still hold the attempted fit.
    std::string failure;
    bool mass_unidentifiable{false};  ///< the failure is the mass's (the friction may still be determined)
    /// Where a poor fit's residual sits and the likely cause ("" when the fit is not poor).
    std::string residual_finding;
    [[nodiscard]] bool failed() const { return !failure.empty(); }
    /// The batch estimate of a parameter (0 when the model has no such column).
    [[nodiscard]] double coefficient(Term term, Direction direction) const;
};

/// The batch-means block length [analysed samples] of standard errors for data preprocessed as `derivatives`: `blocks`
/// correlation lengths of its low-pass.
std::size_t correlation_block(const Derivatives& derivatives, double blocks);

/// The drive signal counts the other way than the position: M (when a column) and every Coulomb term of `batch` lie
/// more than `standard_errors` below zero (real friction never pushes the axis along; a sign convention, not the
/// data's content). The message with the fix; nullopt otherwise.
std::optional<std::string> opposed_drive_signal(const std::vector<RegressorColumn>& columns,
                                                const LeastSquaresResult& batch, const Derivatives& derivatives,
                                                double standard_errors);

/// Batch QR and RLS on the step-1 samples `rows` (ascending, i.e. in time order). `source` names the trace in
/// messages.
Step1Fit fit_step1(const Regressors& regressors, const Derivatives& derivatives, std::span<const SampleIndex> rows,
                   const Step1Options& options);

/// RLS over the rows of phi in order, with a thinned history and transient detection (the first point after which
/// every parameter stays within `tolerance` of the final estimate).
RlsRun run_rls(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const std::vector<double>& time,
               const RlsOptions& options, const Eigen::VectorXd& tolerance, std::size_t history_points);

}  // namespace feedid
