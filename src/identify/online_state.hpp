#pragma once
// The online identifier's state (online_identifier.hpp): the window buffers and rows, allocated once; the pooled
// square-root information and cluster moment sums; the first and the one-speed windows held for judgement; the
// Stribeck bins; the counts. Private to src/identify: the steps that work on it are each in a file of their own
// (online_identifier.cpp the stream into windows, online_window.cpp a window's preprocessing and tests, online_fit.cpp
// its own fit, online_robust.cpp the robust weighting, online_one_speed.cpp windows judged against the pool,
// online_pool.cpp the pooling, online_estimate.cpp the estimate and why a value is null, online_stribeck.cpp F_B and
// v_s).

#include <array>
#include <optional>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "feedid/identify/online_identifier.hpp"
#include "feedid/identify/stick_slip.hpp"
#include "feedid/numeric/signal.hpp"

namespace feedid {

struct OnlineIdentifier::State {
    static constexpr int max_p = 4;
    /// The model's columns and the delay's, -F_log' (OnlineOptions::estimate_delay): [x'', x', s, 1, -F_log']
    static constexpr int timed_p = max_p + 1;
    /// A row of rows_: the model's max_p columns, the drive force y, the delay's column, and the derivatives the
    /// delay's column is made of (x''' and the filtered sgn's)
    static constexpr int row_stride = max_p + 4;
    static constexpr std::size_t bins_per_direction = 24;
    using Vec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, max_p, 1>;
    using Mat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, max_p, max_p>;
    using TVec = Eigen::Matrix<double, timed_p, 1>;
    using TMat = Eigen::Matrix<double, timed_p, timed_p>;
    /// A window's (weighted) sums over the model's columns and the delay's: Phi_t^T W Phi_t, Phi_t^T W y.
    struct TimedSums {
        TMat h{TMat::Zero()};
        TVec c{TVec::Zero()};
    };
    struct StribeckBin {
        double n{0}, speed{0}, force{0}, force_sq{0}, acceleration{0};
        std::size_t windows{0}, last_window{0};  ///< windows that put samples in it, the last of them (1-based)
    };
    /// A one-speed window's least-squares sufficient statistics: enough to judge it against any pooled estimate.
    /// A window's sums are kept over all max_p columns (the offset's too, whichever model judges the windows): the
    /// pool can then test the offset at any time; the model in use judges on their leading p_ x p_ block.
    struct OneSpeedWindow {
        Mat h;  ///< Phi^T Phi (max_p x max_p)
        Vec c;  ///< Phi^T y
        double yy{0.0};
        std::size_t rows{0};
        WindowVerdict own{WindowVerdict::low_excitation};  ///< its verdict on its own
        TimedSums timed;
    };
    struct WindowInformation {
        Mat h;  ///< Phi^T W Phi (max_p x max_p)
        Vec c;  ///< Phi^T W y
        double scale{0.0};
        std::size_t rows{0};
        TimedSums timed;
    };
    /// The delay as one more parameter of the pooled model (estimate_delay).
    struct TimedFit {
        bool valid{false};
        double delay{0.0};           ///< [s]
        double standard_error{0.0};  ///< [s]
        Vec sensitivity;             ///< d theta / d tau of the model's parameters [unit/s]
        double correlation{0.0};     ///< of the delay's column with the model's (0..1)
        std::size_t columns{0};  ///< the model's columns (3 or 4), the delay after them
    };

    /// The low-pass cut-off [Hz], the window's core samples and its filter margin at a sample time.
    struct Layout {
        double cutoff_hz{0.0};
        std::size_t window{0}, margin{0};
    };

    explicit State(OnlineOptions options);

    // the stream into windows (online_identifier.cpp)
    static Layout layout(const OnlineOptions& options, double sample_time_s);
    void setup(double sample_time_s);
    void push(double t, double x, double force, bool use);
    void flush();
    // a window's preprocessing and tests (online_window.cpp)
    void process_window(std::size_t count);
    void filter(std::span<const double> in, std::span<double> out, std::size_t count);
    WindowVerdict judge_window(std::size_t first, std::size_t last);
    [[nodiscard]] bool stick_slips(std::size_t first, std::size_t last);
    std::size_t build_rows(std::size_t first, std::size_t last);
    // the window's own fit (online_fit.cpp)
    WindowVerdict fit_window(std::size_t rows);
    [[nodiscard]] Vec solve_weighted(std::size_t rows) const;
    void residuals(const Vec& theta, std::size_t rows);
    // robust weighting (online_robust.cpp)
    /// Median of |values| by selection in `scratch` (no allocation: scratch holds at least values.size()).
    static double median_absolute(std::span<const double> values, std::vector<double>& scratch);
    Vec tukey_fit(const Vec& start, std::size_t rows, double& scale);
    Vec independent_fit(std::size_t rows, const Vec& least_squares, double fast, double& best_scale);
    bool settle_weights(std::size_t rows, const Vec& theta, double scale);
    WindowVerdict judge_change(std::size_t rows, const Vec& least_squares, double fast);
    // windows judged against the pool (online_one_speed.cpp)
    WindowVerdict one_speed(std::size_t rows, WindowVerdict own);
    WindowVerdict judge_one_speed(const OneSpeedWindow& window);
    WindowVerdict judge_rows(std::size_t rows);
    [[nodiscard]] bool fits_pool(const Mat& h, const Vec& c) const;
    void settle_deferred();
    // pooling (online_pool.cpp)
    [[nodiscard]] WindowInformation information(std::size_t rows, double scale);
    void reset_pool();
    WindowVerdict admit(std::size_t rows, double scale);
    void update_reference_scale();
    void settle_pending();
    [[nodiscard]] bool consistent(const WindowInformation& window, const Vec& reference) const;
    void pool(const WindowInformation& window);
    [[nodiscard]] Vec pooled_theta() const;
    void pool_timed(const TimedSums& window);
    /// The timed sums of the first `rows` rows with weights_ (all 1 when `weighted` is false), their delay column
    /// -(Phi' theta) from `theta` (M, B, F_C leading).
    [[nodiscard]] TimedSums timed_sums(std::size_t rows, bool weighted, const Vec& theta);
    // the drive signal's timing (online_timing.cpp)
    void shift_force(std::size_t count);
    [[nodiscard]] TimedFit timed_fit(std::size_t columns) const;
    void estimate_timing(OnlineEstimate& e, Vec& theta, Mat& covariance) const;
    // the estimate (online_estimate.cpp)
    /// The pooled fit of the leading `p` columns: theta, its covariance (cluster, or model-based for few windows).
    struct PooledFit {
        Vec theta;
        Mat covariance;
        bool model_based{false};
        bool separable{true};  ///< the pool informs every one of the p directions
    };
    [[nodiscard]] PooledFit pooled_fit(std::size_t p) const;
    /// sum_w H_w H^-1 H_w over the pooled windows, of the leading `columns` columns (from the moment sums)
    [[nodiscard]] Mat clusters_leverage(const Mat& h_inverse, std::size_t columns) const;
    /// The Wald test of the offset on the pool of all max_p columns (model_selection.hpp's rule, at
    /// options_.offset_test_level): its statistic, or none where the pool cannot separate F_0 from F_C.
    [[nodiscard]] std::optional<double> offset_statistic(const PooledFit& full) const;
    /// `select_offset`: the options' (estimate()), or false for the model without the offset, untested.
    void describe_offset(OnlineEstimate& e, bool select_offset) const;

    void judge_plausibility(OnlineEstimate& e, bool select_offset) const;
    /// Why the pool gives no value ("" when it does): no window, one window, or windows that disagree.
    [[nodiscard]] std::string no_value_reason() const;
    [[nodiscard]] OnlineEstimate estimate(bool select_offset) const;
    // F_B and v_s (online_stribeck.cpp)
    void bin_slow_samples(std::size_t first, std::size_t last);
    void estimate_stribeck(const Vec& theta, const Vec& standard_error, OnlineEstimate& e) const;

    OnlineOptions options_;
    /// Columns of the model the windows are judged by: 3, or 4 with a forced offset. The selection of the offset
    /// happens at estimate time, on the pool of all max_p columns of the windows this model admitted: a direction-
    /// dependent cutting force, which a model with an offset would take for one, does not choose the windows.
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
    std::vector<double> t_, x_, f_, xf_, ff_, v_, a_, s_, sf_, workspace_, shifted_;
    std::vector<char> use_;
    // the window's rows (step-1 samples), allocated once
    /// [x'', x', filtered sgn x', 1, y, -F', x''', (filtered sgn x')']; row-major, so that a row is contiguous (y in
    /// column max_p)
    Eigen::Matrix<double, Eigen::Dynamic, row_stride, Eigen::RowMajor> rows_;
    std::vector<double> weights_, residual_, scratch_;
    // pooled square-root information: R (p x p upper), z (p), and the cluster moments
    Eigen::Matrix<double, max_p, max_p + 1> r_z_;
    Mat sum_cc_;
    std::array<Mat, max_p> sum_cH_;                     ///< sum_w c_w[i] * H_w
    std::array<std::array<Mat, max_p>, max_p> sum_HH_;  ///< sum_w H_w[i][j] * H_w
    // the same sums over the model's and the delay's columns (estimate_delay)
    TimedSums timed_pool_;
    TMat timed_cc_{TMat::Zero()};
    std::array<TMat, timed_p> timed_cH_{};
    std::array<std::array<TMat, timed_p>, timed_p> timed_HH_{};
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
    WindowRecord last_window_;
    StickSlipTracker stick_slip_;
    std::array<std::vector<StribeckBin>, 2> bins_;  ///< forward, reverse
};

}  // namespace feedid
