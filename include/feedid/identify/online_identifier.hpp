#pragma once
// The online identifier: mass and friction from the traces of ordinary production, sample by sample.
// Samples (t, x, F_d) are pushed one at a time or in blocks into a window buffer allocated once. Each full window is
// preprocessed as identify does (zero-phase Butterworth of the position AND of the drive force, central differences;
// the sgn(x') column through the same low-pass, IDIM's parallel filtering), tested (at rest, saturation, stick-slip,
// too little excitation, ill-conditioned), fitted robustly (Tukey's biweight by IRLS from several starts, the one of
// smallest robust scale kept, so that the rows a cutting force pushes off the model weigh nothing) and, when it
// qualifies, pooled by its information:
//   [R z]  <-  QR of [sqrt(lambda) [R z] ; L_w^T, L_w^-1 c_w]   (square-root information by Givens rotations,
//   L_w L_w^T = H_w the window's information: the same as rotating its weighted rows in)
// A window that cannot be fitted on its own (one speed, too little acceleration, ill-conditioned, or a short rapid
// with too few rows) still informs the directions it excites: it is judged row by row against the pooled estimate
// (Tukey weights of its residuals there, in the clean windows' scale) and its weighted H_w, possibly singular, enters
// the same way (by its eigen-decomposition); the process-force gates judge it whole.
// theta = R^-1 z. Standard errors treat windows as clusters (they are long against the filter's correlation length):
//   Cov = H^-1 (sum_w g_w g_w^T) H^-1,  g_w = c_w - H_w theta,  H_w = Phi_w^T W Phi_w,  c_w = Phi_w^T W y_w,
// whose meat is kept as fixed-size moment sums (sum c c^T, sum c (x) H, sum H (x) H) and evaluated at the final theta.
// Breakaway friction and Stribeck velocity come from the quasi-static slow samples binned by speed (a fixed set of
// log-spaced bins per direction), fitted at estimate time as the paper's eq. (13) on the bins.
// State is O(1) in the stream's length; nothing is allocated per sample (tests/identify/test_online.cpp counts).

#include <array>
#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include <Eigen/Core>

#include "feedid/core/estimate.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/model_adequacy.hpp"
#include "feedid/identify/stick_slip.hpp"

namespace feedid {

struct OnlineOptions {
    double window_s{2.0};                 ///< window length [s]
    std::optional<double> sample_time_s;  ///< [s]; default: from the first window's time stamps
    std::optional<double> cutoff_hz;      ///< low-pass [Hz]; default min(100 Hz, fs/10) as identify's
    int filter_order{4};                  ///< Butterworth order
    double filter_settling_periods{2.5};  ///< filter margin at each window edge, in cut-off periods (as identify)
    bool offset{false};                   ///< always estimate a constant force offset F_0 (no selection)
    /// Select the offset from the data (identify's model selection): the pool keeps the offset's column of the
    /// windows the model without it admitted, and the estimate includes the offset when its Wald statistic
    /// |F_0| / SE (cluster standard error) exceeds the two-sided normal quantile of offset_test_level (1e-3: 3.29).
    /// Where those windows move in one direction only (F_0 and F_C one number), F_C and F_B are null with the reason.
    /// False: the model without offset unless `offset`.
    bool select_offset{true};
    double offset_test_level{1e-3};
    /// Judge the windows (robust weights, acceptance, the one-speed windows' gradient) by the model with the offset
    /// while the estimate still selects it (select_offset): on an axis that carries a weight the model without it bends
    /// or rejects every window that moves both ways, and keeps those that move one way with the weight in F_C, so that
    /// the windows it admits are chosen by the wrong model before the selection sees them. scan's second pass.
    bool judge_with_offset{false};
    /// The drive signal's timing (identify's model-adequacy stage, model_adequacy.hpp, made online). With the drive
    /// signal logged tau late (a current sampled at another instant of the servo cycle than the position, a loop
    /// faster than the log, a current loop's lag), F_log = Phi*theta - tau*F_log' to first order. estimate_delay: the
    /// pool keeps the column -F_log' of every pooled window beside the model's, so that the estimate knows tau (its
    /// Wald statistic against the offset's threshold) and carries its uncertainty into M, B, F_C and F_0 (the
    /// covariance of the model with tau as one more parameter); where tau is significant and within max_delay_s the
    /// estimate is that model's (first-order corrected). drive_delay_s: each window reads the filtered drive force
    /// this much later (cubic interpolation), exactly; scan's timing pass applies the estimated one so.
    bool estimate_delay{true};
    double drive_delay_s{0.0};  ///< [s], within the filter margin
    double max_delay_s{0.005};  ///< a larger one is two recorders' clocks, not a timing within the servo cycle [s]
    bool robust{true};                    ///< Tukey biweight by IRLS; false: plain least squares
    double tukey_c{4.685};                ///< Tukey's tuning constant, in robust scales (95 % efficiency)
    int irls_iterations{20};
    /// Forgetting per window (1 = none): the pooled information and moment sums are scaled by it (and its square)
    /// before each new window, for slow drift.
    double forgetting{1.0};
    double moving_threshold{1e-3};  ///< |x'| above this counts as moving [m/s]
    /// A rotary axis: its quantities in rad, rad/s and N*m (as the trace's), the messages in rad/s, and the split
    /// speed's default.
    bool rotary{false};
    /// Step 1 (M, B, F_C) uses |x'| above this, where the Stribeck term has decayed; slower quasi-static samples
    /// feed the Stribeck bins [m/s or rad/s]. Default split(): 20 mm/s, four times the 5 mm/s Stribeck speed of a
    /// ball-screw drive; 0.2 rad/s (11.5 deg/s), four times the rotary demo table's 0.05 rad/s.
    std::optional<double> split_velocity;
    [[nodiscard]] double split() const { return split_velocity.value_or(rotary ? 0.2 : 0.02); }
    double quasi_static_acceleration{0.02};  ///< |x''| below this: quasi-static (Stribeck bins) [m/s^2]
    // Qualification of a window:
    double minimum_moving_fraction{0.05};  ///< at rest below this fraction of moving samples
    double minimum_row_fraction{0.1};      ///< too little excitation below this fraction of step-1 rows
    double minimum_acceleration{0.1};      ///< ... or an rms x'' over the rows below this [m/s^2]
    double minimum_speed_ratio{1.5};       ///< ... or 90th / 10th percentile of |x'| below this (one speed)
    double maximum_condition{200.0};       ///< ill-conditioned above this (column-scaled Phi)
    double maximum_outlier_fraction{0.3};  ///< process force when more rows than this are rejected by the weights
    /// ... or when the window's robust residual scale exceeds this multiple of the clean windows' (the lower quartile
    /// of the last 32 windows'): the fit bent to a force the model does not have
    double maximum_scale_ratio{2.0};
    /// ... or when its own estimate lies farther than this chi^2 (p degrees of freedom) from the pooled one, in its
    /// own information (the first windows: from their consensus, the median of their estimates)
    double consistency_chi2{25.0};
    double scale_cap{1.5};
    /// A rejected window fits the model on its own when its own fit rejects at most this fraction of its rows ...
    double clean_outlier_fraction{0.1};
    /// ... and this many such windows in a row that disagree with the pooled estimate are a change of the axis.
    std::size_t change_windows{8};      ///< the IRLS scale is at most this multiple of the clean windows' scale
    std::optional<double> force_limit;  ///< saturation: |F_d| at or above 0.99 of it in a window [N]
    /// Stick-slip: identify's rule without a reference (stick_slip.hpp), on each window, with its options.
    StickSlipOptions stick_slip;
    // Stribeck bins: log-spaced speed bins from stribeck_lowest_speed to split_velocity, per direction.
    double stribeck_lowest_speed{1e-4};  ///< [m/s]
    std::size_t minimum_bin_samples{20};
    std::size_t minimum_stribeck_bins{3};
    /// F_B and v_s need the slow samples of at least this many windows (one slow move is one realisation of the
    /// drive's noise and of the cutting force)
    std::size_t minimum_stribeck_windows{2};
    /// One-speed windows (too little excitation or ill-conditioned on their own) held until a pooled estimate exists
    /// to judge them against; beyond this many they are counted as low_excitation
    std::size_t deferred_windows{256};
    /// A window with fewer step-1 rows than minimum_row_fraction (a short rapid between two holes, the end of a feed
    /// move) is not fitted on its own but judged against the pooled model as a one-speed window is, when it has at
    /// least this many rows; below, low_excitation
    std::size_t minimum_pool_rows{50};
    /// Evidence before numbers: no value from fewer pooled step-1 rows than this (with at least 2 qualified windows,
    /// always); nor a mass <= 0, a Coulomb friction <= 0 or a viscous friction below -2 standard errors (null, with
    /// the reason).
    std::size_t minimum_rows{200};

    /// What is wrong ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// Why windows were not used (the document's windows.rejected, in this order).
enum class WindowVerdict {
    qualified,
    at_rest,
    low_excitation,
    ill_conditioned,
    process_force,
    stick_slip,
    saturation,
    gap,
    gated_out,
    /// fits the model on its own but not the pooled estimate: the axis changed? (with forgetting, change_windows of
    /// them in a row start the pool again)
    inconsistent,
    pending,  ///< one of the first windows, held until the clean windows' residual scale is known (not counted)
};
constexpr std::size_t window_verdicts = 10;
/// "qualified", "at_rest", "low_excitation", ...
const char* verdict_name(WindowVerdict verdict);

struct WindowCounts {
    std::size_t total{0};
    std::array<std::size_t, window_verdicts> by_verdict{};
    [[nodiscard]] std::size_t qualified() const { return by_verdict[0]; }
    [[nodiscard]] std::size_t count(WindowVerdict v) const { return by_verdict[static_cast<std::size_t>(v)]; }
};

/// The estimate at one moment. Keys M, B, F_C (, F_0), F_B, v_s; a null value carries its reason.
struct OnlineEstimate {
    Estimate mass, viscous, coulomb, offset, breakaway, stribeck_velocity;
    /// The estimate of a parameter's term (the model is symmetric: one per term).
    [[nodiscard]] const Estimate& of(Term term) const {
        switch (term) {
            case Term::mass: return mass;
            case Term::viscous: return viscous;
            case Term::coulomb: return coulomb;
            case Term::offset: return offset;
            case Term::breakaway: return breakaway;
            case Term::stribeck_velocity: return stribeck_velocity;
        }
        return mass;  // unreachable: every term is listed
    }
    std::string mass_reason, friction_reason, stribeck_reason;  ///< why null ("" when determined)
    /// The model the estimate is of: with the offset F_0 (forced, or taken by the selection) or without.
    bool offset_in_model{false};
    bool offset_selected{false};  ///< the offset was chosen by the data (select_offset), not forced
    bool offset_judged{false};    ///< the windows were judged by the model with the offset (judge_with_offset)
    /// The offset's Wald statistic |F_0| / SE on the pool (none: not testable, see offset_verdict), and the
    /// threshold it is compared with.
    std::optional<double> offset_statistic;
    std::optional<double> offset_estimate, offset_standard_error;  ///< [N or N*m]
    double offset_threshold{0.0};
    std::string offset_verdict;  ///< why the offset was taken or not, in words
    /// Why F_C (and F_B) are null although M is determined: the windows cannot separate a constant force from the
    /// Coulomb friction ("" when they can).
    std::string aliased_reason;
    /// The drive signal's timing: the delay applied to every window (OnlineOptions::drive_delay_s) [s]; what the pool
    /// says is left beyond it (none where not estimated or not estimable), its standard error and Wald statistic; and
    /// whether that residual delay was corrected in the estimate (significant and plausible: to first order).
    double delay_applied_s{0.0};
    std::optional<double> delay_residual_s, delay_standard_error_s, delay_statistic;
    double delay_threshold{0.0};
    bool delay_corrected{false};
    bool delay_given{false};  ///< the applied delay was given, not estimated (OnlineOptions::estimate_delay false)
    /// d theta / d tau of M, B, F_C (, F_0) [unit/s] (empty where the delay was not estimated): their covariance took
    /// in sensitivity sensitivity^T var(tau)
    Eigen::VectorXd delay_sensitivity;
    std::string delay_verdict;  ///< in words: "not significant", "corrected to first order", ...
    /// What the data says of each step-1 parameter (M, B, F_C (, F_0)), from the cluster covariance.
    Eigen::VectorXd information;  ///< 1 / variance of each parameter (from the cluster covariance) [1/unit^2]
    /// Eigenvalues of the correlation-scaled information (the information matrix with every parameter in units of
    /// its standard error): all 1 for uncorrelated parameters; a small one names a poorly separated combination.
    Eigen::VectorXd information_eigenvalues;
    Eigen::MatrixXd covariance;  ///< of M, B, F_C (, F_0)
    WindowCounts windows;
    std::size_t changes{0};    ///< times the pool started again after a change of the axis (with forgetting)
    std::size_t samples{0};    ///< pushed
    std::size_t rows_used{0};  ///< step-1 rows pooled (weighted rows count once)
    double residual_std{0.0};  ///< robust scale of the pooled windows' residuals [N]
    std::size_t stribeck_bins_used{0};
};

/// The model an online estimate is of, as identify's model-selection stage states it (the result document's
/// model_selection and timing): the offset's candidate with its Wald statistic, and the drive signal's delay (applied,
/// estimated, with its standard error).
ModelChoice model_choice_of(const OnlineEstimate& estimate);

/// One window as it was judged: its core's first and last time stamps [s] and its verdict.
struct WindowRecord {
    double first_s{0.0};
    double last_s{0.0};
    WindowVerdict verdict{WindowVerdict::pending};  ///< pending: held until the clean windows' scale is known
    bool stick_slip{false};  ///< the stick-slip rule found it in the window (whatever decided the verdict first)
};

/// The online identifier: push samples, read estimates. Its state (buffers, pool, bins) lives behind a pointer,
/// allocated once at construction and start-up; an identifier moves (the pointer) but is not copied (a copy of a
/// stream's state is no use). A moved-from identifier may only be destroyed or assigned to.
class OnlineIdentifier {
public:
    explicit OnlineIdentifier(OnlineOptions options);
    ~OnlineIdentifier();
    OnlineIdentifier(OnlineIdentifier&&) noexcept;
    OnlineIdentifier& operator=(OnlineIdentifier&&) noexcept;
    OnlineIdentifier(const OnlineIdentifier&) = delete;
    OnlineIdentifier& operator=(const OnlineIdentifier&) = delete;

    /// One sample: time [s], position [m], drive force [N]; `use` false keeps the sample out of every fit (it is
    /// still filtered as the neighbour of others): the --only-when gate. Never throws, never allocates.
    void push(double t, double x, double force, bool use = true);
    /// A block of samples (equal lengths; `use` empty = all used). The same as pushing them one at a time.
    void push(std::span<const double> t, std::span<const double> x, std::span<const double> force,
              std::span<const char> use = {});
    /// Processes the samples buffered since the last window (a last, shorter window, if long enough): call at the
    /// end of a stream before estimate() so that its tail counts.
    void flush();
    /// The current estimates (cheap: fixed-size algebra).
    [[nodiscard]] OnlineEstimate estimate() const;
    /// The estimate of the model without the offset, the offset not tested (as with OnlineOptions::select_offset
    /// false; the windows are the same, judged by p = 3 columns): what scan's rule takes where the windows judged by
    /// the model with the offset do not take it (online_selection.hpp).
    [[nodiscard]] OnlineEstimate estimate_without_offset() const;
    /// The window processed last (none before the first).
    [[nodiscard]] std::optional<WindowRecord> last_window() const;
    [[nodiscard]] const OnlineOptions& options() const;
    /// Columns of the step-1 model the windows are judged by: 3, or 4 with the forced offset (the selected one is
    /// the estimate's: OnlineEstimate::offset_in_model).
    [[nodiscard]] std::size_t parameters() const;

    /// Samples in the buffers (a window and its filter margins) of an identifier with these options on a stream
    /// sampled every sample_time_s [s].
    [[nodiscard]] static std::size_t buffer_samples(const OnlineOptions& options, double sample_time_s);
    /// The memory such an identifier takes: its buffers and its fixed state [bytes]. For a service that holds many.
    [[nodiscard]] static std::size_t memory_bytes(const OnlineOptions& options, double sample_time_s);

    struct State;  ///< opaque: defined in the library's sources only

private:
    std::unique_ptr<State> state_;
};

}  // namespace feedid
