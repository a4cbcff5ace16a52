#pragma once
// The online identifier (issue 15): mass and friction from the traces of ordinary production, sample by sample.
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
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "feedid/core/estimate.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/numeric/signal.hpp"

namespace feedid {

struct OnlineOptions {
    double window_s{2.0};                 ///< window length [s]
    std::optional<double> sample_time_s;  ///< [s]; default: from the first window's time stamps
    std::optional<double> cutoff_hz;      ///< low-pass [Hz]; default min(100 Hz, fs/10) as identify's
    int filter_order{4};                  ///< Butterworth order
    double filter_settling_periods{2.5};  ///< filter margin at each window edge, in cut-off periods (as identify)
    bool offset{false};                   ///< also estimate a constant force offset F_0
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
    double stick_stop_fraction{0.2};    ///< stick-slip: |x'| falls below this fraction of the pass's speed ...
    int stick_slip_stops{2};            ///< ... and restarts in the same direction this often in a window
    double max_stick_s{0.15};           ///< ... each stop and each burst between them shorter than this [s]
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

class OnlineIdentifier {
public:
    explicit OnlineIdentifier(OnlineOptions options);

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
    [[nodiscard]] const OnlineOptions& options() const { return options_; }
    /// Columns of the step-1 model: 3, or 4 with the offset.
    [[nodiscard]] std::size_t parameters() const { return p_; }

    /// Samples in the buffers (a window and its filter margins) of an identifier with these options on a stream
    /// sampled every sample_time_s [s].
    [[nodiscard]] static std::size_t buffer_samples(const OnlineOptions& options, double sample_time_s);
    /// The memory such an identifier takes: its buffers and its fixed state [bytes]. For a service that holds many.
    [[nodiscard]] static std::size_t memory_bytes(const OnlineOptions& options, double sample_time_s);

private:
    static constexpr int max_p = 4;
    using Vec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, max_p, 1>;
    using Mat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, max_p, max_p>;
    struct StribeckBin {
        double n{0}, speed{0}, force{0}, force_sq{0}, acceleration{0};
        std::size_t windows{0}, last_window{0};  ///< windows that put samples in it, the last of them (1-based)
    };
    /// A one-speed window's least-squares sufficient statistics: enough to judge it against any pooled estimate.
    struct OneSpeedWindow {
        Mat h;  ///< Phi^T Phi
        Vec c;  ///< Phi^T y
        double yy{0.0};
        std::size_t rows{0};
        WindowVerdict own{WindowVerdict::low_excitation};  ///< its verdict on its own
    };

    /// The low-pass cut-off [Hz], the window's core samples and its filter margin at a sample time.
    struct Layout {
        double cutoff_hz{0.0};
        std::size_t window{0}, margin{0};
    };
    static Layout layout(const OnlineOptions& options, double sample_time_s);
    void setup(double sample_time_s);
    void process_window(std::size_t count);
    /// Why the pool gives no value ("" when it does): no window, one window, or windows that disagree.
    [[nodiscard]] std::string no_value_reason() const;
    WindowVerdict judge_window(std::size_t first, std::size_t last);
    WindowVerdict fit_window(std::size_t rows);
    [[nodiscard]] Vec solve_weighted(std::size_t rows) const;
    void residuals(const Vec& theta, std::size_t rows);
    Vec tukey_fit(const Vec& start, std::size_t rows, double& scale);
    struct WindowInformation {
        Mat h;  ///< Phi^T W Phi
        Vec c;  ///< Phi^T W y
        double scale{0.0};
        std::size_t rows{0};
    };
    WindowVerdict admit(std::size_t rows, double scale);
    void pool(const WindowInformation& window);
    void update_reference_scale();
    Vec independent_fit(std::size_t rows, const Vec& least_squares, double fast, double& best_scale);
    bool settle_weights(std::size_t rows, const Vec& theta, double scale);
    WindowVerdict judge_change(std::size_t rows, const Vec& least_squares, double fast);
    [[nodiscard]] WindowInformation information(std::size_t rows, double scale) const;
    void reset_pool();
    void settle_pending();
    [[nodiscard]] bool consistent(const WindowInformation& window, const Vec& reference) const;
    WindowVerdict one_speed(std::size_t rows, WindowVerdict own);
    WindowVerdict judge_rows(std::size_t rows);
    WindowVerdict judge_one_speed(const OneSpeedWindow& window);
    [[nodiscard]] bool fits_pool(const Mat& h, const Vec& c) const;
    void settle_deferred();
    void bin_slow_samples(std::size_t first, std::size_t last);
    void filter(std::span<const double> in, std::span<double> out, std::size_t count);
    [[nodiscard]] bool stick_slips(std::size_t first, std::size_t last) const;
    std::size_t build_rows(std::size_t first, std::size_t last);
    [[nodiscard]] Vec pooled_theta() const;
    void estimate_stribeck(const Vec& theta, const Vec& standard_error, OnlineEstimate& e) const;

    OnlineOptions options_;
    std::size_t p_{3};
    bool ready_{false};
    double dt_{0.0};
    double cutoff_hz_{0.0};
    SecondOrderSections filter_;
    std::size_t window_{0};  ///< core samples per window
    std::size_t margin_{0};  ///< filter margin on each side
    std::size_t filled_{0};  ///< samples in the buffers
    std::size_t pushed_{0};
    // buffers (margin + window + margin), allocated once
    std::vector<double> t_, x_, f_, xf_, ff_, v_, a_, s_, sf_, workspace_;
    std::vector<char> use_;
    // the window's rows (step-1 samples), allocated once
    /// [x'', x', filtered sgn x' (, 1)], y after them; row-major, so that a row is contiguous
    Eigen::Matrix<double, Eigen::Dynamic, max_p + 1, Eigen::RowMajor> rows_;
    std::vector<double> weights_, residual_, scratch_;
    // pooled square-root information: R (p x p upper), z (p), and the cluster moments
    Eigen::Matrix<double, max_p, max_p + 1> r_z_;
    Mat sum_cc_;
    std::array<Mat, max_p> sum_cH_;                     ///< sum_w c_w[i] * H_w
    std::array<std::array<Mat, max_p>, max_p> sum_HH_;  ///< sum_w H_w[i][j] * H_w
    double forgotten_windows_{0.0};                     ///< effective qualified windows (with forgetting)
    double sum_scale_sq_{0.0};
    std::size_t rows_used_{0};
    Vec column_scale_;
    bool have_pooled_{false};
    std::array<double, 32> recent_scales_{};
    std::size_t recent_count_{0};
    double reference_scale_{0.0};  ///< 0 until the first windows are settled
    std::array<WindowInformation, 8> pending_;
    std::vector<OneSpeedWindow> deferred_;  ///< allocated once (deferred_windows)
    std::size_t deferred_count_{0};
    std::size_t pending_count_{0};
    std::size_t inconsistent_run_{0};
    std::size_t changes_{0};
    double last_outlier_fraction_{0.0};
    WindowCounts counts_;
    std::array<std::vector<StribeckBin>, 2> bins_;  ///< forward, reverse
};

}  // namespace feedid
