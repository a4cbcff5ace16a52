#pragma once
// The identification pipeline: a Trace and options in, a result with values, uncertainties and diagnostics out.
// identify() wires four stages, each a pure function with a typed record (see README, "Architecture"):
//   preprocess()         preprocess.hpp  x' and x'' from the position: filter, differentiate, trim, decimate
//   select_samples()     selection.hpp   moving, quasi-static, step-1 and step-2 samples, each drop explained
//   fit_step1()          step1.hpp       eq. (11) by batch QR and RLS (eq. 7-9), transient detected
//   fit_friction_curve() step2.hpp       eq. (12-14) log-linear RLS, then the nonlinear fit of the whole curve
// The result document (its keys: docs/documents.md) is written and read only by result_document.hpp.

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/model/drive.hpp"
#include "feedid/core/estimate.hpp"
#include "feedid/model/friction.hpp"
#include "feedid/identify/friction_only.hpp"
#include "feedid/identify/model_adequacy.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/preprocess.hpp"
#include "feedid/numeric/rls.hpp"
#include "feedid/identify/selection.hpp"
#include "feedid/core/status.hpp"
#include "feedid/identify/step1.hpp"
#include "feedid/identify/step2.hpp"
#include "feedid/identify/preprocessing_family.hpp"
#include "feedid/core/trace.hpp"

namespace feedid {

struct IdentifyOptions {
    /// The friction model and offset when the model is forced (model_selection.automatic false); in automatic mode
    /// the data choose (model_adequacy.hpp).
    FrictionModelKind model{FrictionModelKind::symmetric};
    bool offset{false};  ///< also estimate a constant force offset F_0 (gravity, sensor offset)
    /// Which model the data support: chosen from them (default), or forced; the drive signal's delay.
    ModelSelectionOptions model_selection;
    DriveConstants drive;
    bool stribeck{true};  ///< run step 2 (identify() sets selection.stribeck from it)

    PreprocessOptions preprocess;
    SelectionOptions selection;
    Step1Options step1;                 ///< with the RLS options
    FrictionFitOptions friction;        ///< step 2
    FrictionOnlyOptions friction_only;  ///< when the data cannot determine a mass
    /// Rerun the stages over the preprocessing family (preprocessing_family.hpp) for each parameter's systematic uncertainty.
    bool systematic{true};
    /// Threads the family runs on at most; 0 = one per core (std::thread::hardware_concurrency). 1 keeps identify on
    /// the calling thread (a batch that runs one identify per core already). Reruns go in parallel only while their
    /// buffers fit identify's memory budget (100 bytes per sample with the trace): with today's stages, one at a time.
    unsigned threads{0};
    /// The parameters and the status alone: no RLS run, no log-linear Stribeck fit, no friction-curve points and no
    /// lack-of-fit checks (what the preprocessing family's reruns need; their status is then partial only where a
    /// parameter is null, never for a failed fit check, which would only have scaled their standard errors).
    bool estimates_only{false};
    /// A systematic part above this multiple of the standard error is said in a finding.
    double systematic_finding_multiple{2.0};
    /// Correlations between step-1 estimates above this are said in a finding, with the test that separates them.
    double correlation_finding{0.95};
    /// B and F_C are null when the constant-speed samples of their direction span less than this speed ratio (90th
    /// against 10th percentile) and are more than inseparable_steady_fraction of step 1's samples: one speed
    /// determines only their sum there, and the few ramp samples that split it are where an unmodelled Stribeck tail
    /// or current-loop lag biases it.
    double separable_speed_ratio{1.5};
    double inseparable_steady_fraction{0.5};

    /// What is wrong with these options ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// One reported parameter, keyed as in the result document ("mass_kg", "coulomb_forward_N", ...).
struct Parameter {
    std::string key;
    std::string symbol;  ///< "M", "B", "F_C+", ...
    std::string unit;    ///< "kg", "N*s/m", ...
    Estimate estimate;
    Term term{Term::mass};
    Direction direction{Direction::both};
};

/// The parameters a model reports, in document order (M; B, F_C per direction; F_0; F_B, v_s per direction), all
/// null.
std::vector<Parameter> model_parameters(FrictionModelKind model, bool offset, bool rotary);

/// The axis model the parameters describe (0 for a null value; no Stribeck term where F_B or v_s is null).
AxisModel axis_from_parameters(const std::vector<Parameter>& parameters, FrictionModelKind model, bool rotary);

/// The trace the result came from.
struct TraceSummary {
    std::string path;
    std::string format;
    std::size_t samples{0};
    double sample_time_s{0.0};
    double duration_s{0.0};
};

/// Step 1's batch fit as reported: per column its key and estimate, and the fit's figures of merit.
struct Step1Report {
    std::vector<std::string> keys;
    std::vector<Estimate> batch;
    double relative_error_pct{0.0};
    double condition_number{0.0};
    std::size_t samples_used{0};
    double residual_std{0.0};
    std::vector<double> r_diagonal;  ///< |diag R| of the QR factorisation
    std::vector<std::vector<double>> correlation;  ///< of the estimates, keys x keys (empty when not estimated)
    /// The textbook standard errors sigma*sqrt(diag((Phi^T Phi)^-1)), for comparison with published ones: the
    /// reported ones allow for residuals correlated by the low-pass (least_squares.hpp), these do not.
    std::vector<double> white_noise_standard_error;
};

/// Step 1's RLS as reported.
struct RlsReport {
    RlsOptions options;
    std::vector<std::string> keys;
    std::vector<double> final_estimate;
    std::vector<double> averaged;
    bool settled{false};
    double transient_end_s{0.0};
    std::vector<double> history_time;          ///< [s]
    std::vector<std::vector<double>> history;  ///< history[c][i]: column c at history_time[i]
};

/// Step 2 as reported.
struct StribeckReport {
    std::array<std::optional<LogLinearStribeck>, 2> log_linear;  ///< forward, reverse
    std::optional<NonlinearFitReport> nonlinear;
};

/// The friction curve for plots: the quasi-static samples binned by speed, per direction, with the fitted curve.
struct FrictionCurvePoints {
    std::vector<double> speed;   ///< [m/s]
    std::vector<double> force;   ///< friction magnitude [N]
    std::vector<double> fitted;  ///< the identified curve at `speed` [N]
};
struct FrictionCurveReport {
    std::optional<FrictionCurvePoints> forward;
    std::optional<FrictionCurvePoints> reverse;
};

/// A friction-only result (M, F_B and v_s null): why, and the steady-speed fit the friction came from.
struct FrictionOnlyReport {
    std::string reason;  ///< why the mass cannot be identified, in figures
    std::size_t samples_used{0};
    double relative_error_pct{0.0};
    double residual_std{0.0};  ///< the friction scatter [N or N*m]
    std::size_t rejected_samples{0};  ///< of samples_used, those the robust weights rejected (a cutting load)
};

struct IdentifyResult {
    Status status{Status::ok};
    FrictionModelKind model{FrictionModelKind::symmetric};
    bool offset{false};
    bool rotary{false};
    std::string feedid_version;  ///< of the program that identified it
    TraceSummary trace;
    std::vector<Parameter> parameters;
    AxisModel axis;  ///< the identified model (no Stribeck term where F_B / v_s are null)
    // The stages' records, each present once the pipeline got that far.
    std::optional<PreprocessReport> preprocessing;
    std::optional<SelectionReport> selection;
    std::optional<Step1Report> step1;
    std::optional<RlsReport> rls;
    std::optional<StribeckReport> stribeck;
    std::optional<FrictionCurveReport> friction_curve;
    std::optional<FrictionOnlyReport> friction_only;
    std::optional<SystematicReport> systematic;  ///< the preprocessing family's estimates
    /// The model-adequacy stage: the model chosen (or forced), the candidates tested, the drive signal's delay.
    std::optional<ModelChoice> model_choice;
    std::vector<std::string> diagnostics;
    /// The options that shape the result, recorded with it (identify_options_document); null when not set.
    nlohmann::json options;

    [[nodiscard]] const Parameter* find(const std::string& key) const;
    [[nodiscard]] const Parameter* find(Term term, Direction direction = Direction::both) const;
    [[nodiscard]] std::string model_name() const;
};

/// Runs the whole pipeline. Throws InputError for a trace that lacks what is needed (position or velocity, drive
/// signal); numerical trouble (nothing identifiable) comes back as Status::failed with diagnostics, never an exception.
/// When the data cannot determine a mass (too coarse: assess_resolution; or no acceleration explains the force) but
/// its steady-speed samples determine the friction, the result is friction-only: Status::partial, M, F_B and v_s
/// null, `friction_only` saying why in figures.
IdentifyResult identify(const Trace& trace, const IdentifyOptions& options);

}  // namespace feedid
