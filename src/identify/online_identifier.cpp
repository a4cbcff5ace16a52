#include "feedid/identify/online_identifier.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/core.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "feedid/core/parameters.hpp"

namespace feedid {

namespace {

constexpr std::size_t bins_per_direction = 24;
constexpr std::size_t startup_samples = 101;  // time stamps that give the sample time when none is stated

double tukey_weight(double r, double limit) {
    if (!(std::abs(r) < limit)) return 0.0;
    const double u = r / limit;
    return (1.0 - u * u) * (1.0 - u * u);
}

// Median of |values| by selection in `scratch` (no allocation: scratch holds at least values.size()).
double median_absolute(std::span<const double> values, std::vector<double>& scratch) {
    if (values.empty()) return 0.0;
    std::transform(values.begin(), values.end(), scratch.begin(), [](double v) { return std::abs(v); });
    const auto middle = scratch.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
    std::nth_element(scratch.begin(), middle, scratch.begin() + static_cast<std::ptrdiff_t>(values.size()));
    return *middle;
}

}  // namespace

const char* verdict_name(WindowVerdict verdict) {
    switch (verdict) {
        case WindowVerdict::qualified: return "qualified";
        case WindowVerdict::at_rest: return "at_rest";
        case WindowVerdict::low_excitation: return "low_excitation";
        case WindowVerdict::ill_conditioned: return "ill_conditioned";
        case WindowVerdict::process_force: return "process_force";
        case WindowVerdict::stick_slip: return "stick_slip";
        case WindowVerdict::saturation: return "saturation";
        case WindowVerdict::gap: return "gap";
        case WindowVerdict::gated_out: return "gated_out";
        case WindowVerdict::inconsistent: return "inconsistent";
        case WindowVerdict::pending: return "pending";
    }
    return "?";
}

std::string OnlineOptions::validate() const {
    const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
    if (!positive(window_s)) return fmt::format("window length must be positive (got {} s)", window_s);
    if (sample_time_s && !positive(*sample_time_s)) return "sample time must be positive";
    if (cutoff_hz && !positive(*cutoff_hz)) return "cut-off must be positive";
    if (filter_order < 1 || filter_order > 12) return "filter order must be 1..12";
    if (!(forgetting > 0.0 && forgetting <= 1.0))
        return fmt::format("forgetting factor must lie in (0, 1] (got {})", forgetting);
    if (!positive(split()) || !positive(moving_threshold) || !positive(stribeck_lowest_speed))
        return "speeds must be positive";
    if (stribeck_lowest_speed >= split()) return "the lowest Stribeck speed must lie below the split speed";
    if (!positive(tukey_c) || irls_iterations < 1) return "Tukey constant and IRLS iterations must be positive";
    if (force_limit && !positive(*force_limit)) return "force limit must be positive";
    return "";
}

OnlineIdentifier::OnlineIdentifier(OnlineOptions options) : options_(std::move(options)) {
    p_ = options_.offset ? 4 : 3;
    counts_ = {};
    sum_cc_ = Mat::Zero(static_cast<Eigen::Index>(p_), static_cast<Eigen::Index>(p_));
    for (auto& m : sum_cH_) m = sum_cc_;
    for (auto& row : sum_HH_)
        for (auto& m : row) m = sum_cc_;
    r_z_.setZero();
    for (auto& b : bins_) b.assign(bins_per_direction, StribeckBin{});
    deferred_.assign(options_.deferred_windows, OneSpeedWindow{});
    // the start-up buffer: enough for the sample time from the first time stamps
    const std::size_t start = options_.sample_time_s ? 0 : startup_samples;
    if (options_.sample_time_s) {
        setup(*options_.sample_time_s);
    } else {
        t_.resize(start);
        x_.resize(start);
        f_.resize(start);
        use_.resize(start);
    }
}

OnlineIdentifier::Layout OnlineIdentifier::layout(const OnlineOptions& options, double sample_time_s) {
    const double fs = 1.0 / sample_time_s;
    Layout l;
    l.cutoff_hz = options.cutoff_hz.value_or(std::min(100.0, 0.1 * fs));
    l.window = std::max<std::size_t>(20, static_cast<std::size_t>(std::llround(options.window_s / sample_time_s)));
    l.margin = std::max<std::size_t>(
        3, static_cast<std::size_t>(std::ceil(options.filter_settling_periods * fs / l.cutoff_hz)));
    return l;
}

std::size_t OnlineIdentifier::buffer_samples(const OnlineOptions& options, double sample_time_s) {
    const Layout l = layout(options, sample_time_s);
    return l.window + 2 * l.margin;
}

std::size_t OnlineIdentifier::memory_bytes(const OnlineOptions& options, double sample_time_s) {
    // the buffers of setup() (12 of doubles, one of flags, the workspace, the rows), the start-up buffers they grow
    // from, the deferred windows and the Stribeck bins
    const std::size_t capacity = std::max(buffer_samples(options, sample_time_s), startup_samples);
    const std::size_t per_sample = 12 * sizeof(double) + sizeof(char) + sizeof(double) + (max_p + 1) * sizeof(double);
    return sizeof(OnlineIdentifier) + capacity * per_sample + 64 * sizeof(double) +
           options.deferred_windows * sizeof(OneSpeedWindow) + 2 * bins_per_direction * sizeof(StribeckBin);
}

void OnlineIdentifier::setup(double sample_time_s) {
    dt_ = sample_time_s;
    const double fs = 1.0 / dt_;
    const Layout l = layout(options_, dt_);
    cutoff_hz_ = l.cutoff_hz;
    filter_ = butterworth_lowpass(options_.filter_order, std::min(l.cutoff_hz, 0.45 * fs), fs);
    window_ = l.window;
    margin_ = l.margin;
    const std::size_t capacity = window_ + 2 * margin_;
    for (auto* b : {&t_, &x_, &f_, &xf_, &ff_, &v_, &a_, &s_, &sf_, &residual_, &scratch_, &weights_})
        b->resize(capacity);
    use_.resize(capacity);
    workspace_.resize(capacity + 64);
    rows_.resize(static_cast<Eigen::Index>(capacity), max_p + 1);
    ready_ = true;
}

void OnlineIdentifier::push(double t, double x, double force, bool use) {
    ++pushed_;
    if (!ready_) {
        t_[filled_] = t;
        x_[filled_] = x;
        f_[filled_] = force;
        use_[filled_] = use ? 1 : 0;
        if (++filled_ < t_.size()) return;
        // the median step of the first time stamps (robust to a gap among them); allocates once, at start-up
        std::vector<double> steps(filled_ - 1);
        for (std::size_t k = 1; k < filled_; ++k) steps[k - 1] = t_[k] - t_[k - 1];
        std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
        const double step = steps[steps.size() / 2];
        const std::vector<double> t0 = t_, x0 = x_, f0 = f_;
        const std::vector<char> u0 = use_;
        filled_ = 0;
        pushed_ -= t0.size();
        setup(step > 0.0 && std::isfinite(step) ? step : 1e-3);
        for (std::size_t k = 0; k < t0.size(); ++k) push(t0[k], x0[k], f0[k], u0[k] != 0);
        return;
    }
    t_[filled_] = t;
    x_[filled_] = x;
    f_[filled_] = force;
    use_[filled_] = use ? 1 : 0;
    if (++filled_ == t_.size()) {
        process_window(filled_);
        // the last 2 margins start the next buffer: every sample is in the core of one window
        const std::size_t keep = 2 * margin_;
        const std::size_t from = filled_ - keep;
        for (auto* b : {&t_, &x_, &f_}) std::copy(b->begin() + static_cast<std::ptrdiff_t>(from), b->end(), b->begin());
        std::copy(use_.begin() + static_cast<std::ptrdiff_t>(from), use_.end(), use_.begin());
        filled_ = keep;
    }
}

void OnlineIdentifier::push(std::span<const double> t, std::span<const double> x, std::span<const double> force,
                            std::span<const char> use) {
    const std::size_t n = std::min({t.size(), x.size(), force.size()});
    for (std::size_t k = 0; k < n; ++k) push(t[k], x[k], force[k], use.empty() || use[k] != 0);
}

void OnlineIdentifier::flush() {
    if (ready_ && filled_ >= 2 * margin_ + window_ / 4) {
        process_window(filled_);
        filled_ = 0;
    }
    settle_pending();
    settle_deferred();
}

void OnlineIdentifier::filter(std::span<const double> in, std::span<double> out, std::size_t count) {
    filtfilt(filter_, in.first(count), out.first(count), workspace_);
}

void OnlineIdentifier::process_window(std::size_t count) {
    ++counts_.total;
    const auto verdict = [&](WindowVerdict v) { ++counts_.by_verdict[static_cast<std::size_t>(v)]; };
    for (std::size_t k = 1; k < count; ++k) {
        // a gap, time running backwards, or a value that is not a number: the window is not used
        if (t_[k] - t_[k - 1] > 1.5 * dt_ || !(t_[k] > t_[k - 1]) || !std::isfinite(x_[k]) || !std::isfinite(f_[k]))
            return verdict(WindowVerdict::gap);
    }
    filter(x_, xf_, count);
    filter(f_, ff_, count);
    // central differences of the filtered position, and of the velocity for the acceleration
    for (std::size_t k = 1; k + 1 < count; ++k) v_[k] = (xf_[k + 1] - xf_[k - 1]) / (2.0 * dt_);
    v_[0] = v_[1];
    v_[count - 1] = v_[count - 2];
    for (std::size_t k = 1; k + 1 < count; ++k) a_[k] = (v_[k + 1] - v_[k - 1]) / (2.0 * dt_);
    a_[0] = a_[1];
    a_[count - 1] = a_[count - 2];
    // sgn(x') through the force's low-pass (IDIM's parallel filtering): the filtered force has the Coulomb step
    // smoothed, and so must its regressor
    for (std::size_t k = 0; k < count; ++k) s_[k] = sign(v_[k]);
    filter(s_, sf_, count);
    const std::size_t first = margin_;
    const std::size_t last = count - margin_;
    const std::size_t deferred_before = deferred_count_;
    const WindowVerdict v = judge_window(first, last);
    if (v != WindowVerdict::pending) verdict(v);
    // the slow samples only of windows whose fast rows fit the model: a slow cutting move (a helix, an arc's slow
    // stretch) adds a force opposing the motion that the bins cannot tell from Stribeck friction (a deferred window,
    // judged later from its sums, has no samples left to bin then: none)
    if (v != WindowVerdict::qualified && v != WindowVerdict::pending) return;
    if (deferred_count_ > deferred_before) return;
    bin_slow_samples(first, last);
}

WindowVerdict OnlineIdentifier::judge_window(std::size_t first, std::size_t last) {
    const std::size_t n = last - first;
    std::size_t moving = 0;
    for (std::size_t k = first; k < last; ++k) {
        if (options_.force_limit && std::abs(f_[k]) >= 0.99 * *options_.force_limit) return WindowVerdict::saturation;
        if (std::abs(v_[k]) > options_.moving_threshold) ++moving;
    }
    if (static_cast<double>(moving) < options_.minimum_moving_fraction * static_cast<double>(n))
        return WindowVerdict::at_rest;
    if (stick_slips(first, last)) return WindowVerdict::stick_slip;
    const std::size_t rows = build_rows(first, last);
    if (static_cast<double>(rows) < options_.minimum_row_fraction * static_cast<double>(window_)) {
        std::size_t ungated = 0;
        for (std::size_t k = first; k < last; ++k) ungated += std::abs(v_[k]) > options_.split() ? 1 : 0;
        if (static_cast<double>(ungated) >= options_.minimum_row_fraction * static_cast<double>(window_))
            return WindowVerdict::gated_out;
        // a short stretch of motion (a rapid between two holes): too few rows for a fit of its own, judged against
        // the pooled model
        return rows >= std::max(options_.minimum_pool_rows, p_) ? one_speed(rows, WindowVerdict::low_excitation)
                                                                : WindowVerdict::low_excitation;
    }
    return fit_window(rows);
}

// Stick-slip without a reference (stick_slip.hpp's rule for traces without one, on the window): a slow pass that
// stops and restarts in the same direction, each burst and each stop brief, at least stick_slip_stops times.
bool OnlineIdentifier::stick_slips(std::size_t first, std::size_t last) const {
    const auto brief = [&](std::size_t samples) { return static_cast<double>(samples) * dt_ < options_.max_stick_s; };
    int stops = 0;
    int direction = 0;
    std::size_t burst_start = first;
    std::size_t stopped_at = 0;
    std::size_t burst = 0;
    double peak = 0.0;
    for (std::size_t k = first; k < last; ++k) {
        const double speed = std::abs(v_[k]);
        if (direction != 0 && speed < options_.stick_stop_fraction * peak) {
            if (stopped_at == 0) {
                stopped_at = k;
                burst = k - burst_start;
            }
        } else if (speed > options_.moving_threshold) {
            const int d = v_[k] > 0.0 ? 1 : -1;
            if (stopped_at != 0 || d != direction) {
                if (stopped_at != 0 && d == direction && peak < 2.0 * options_.split() && brief(burst) &&
                    brief(k - stopped_at))
                    ++stops;
                burst_start = k;
                peak = 0.0;
            }
            direction = d;
            stopped_at = 0;
            peak = std::max(peak, speed);
        }
    }
    return stops >= options_.stick_slip_stops;
}

std::size_t OnlineIdentifier::build_rows(std::size_t first, std::size_t last) {
    std::size_t rows = 0;
    const auto p = static_cast<Eigen::Index>(p_);
    for (std::size_t k = first; k < last; ++k) {
        if (use_[k] == 0 || !(std::abs(v_[k]) > options_.split())) continue;
        const auto r = static_cast<Eigen::Index>(rows++);
        rows_(r, 0) = a_[k];
        rows_(r, 1) = v_[k];
        rows_(r, 2) = sf_[k];
        if (p_ == 4) rows_(r, 3) = 1.0;
        rows_(r, p) = ff_[k];
    }
    return rows;
}

WindowVerdict OnlineIdentifier::fit_window(std::size_t rows) {
    const auto n = static_cast<Eigen::Index>(rows);
    const auto p = static_cast<Eigen::Index>(p_);
    // excitation: rms acceleration, and more than one speed (B and F_C inseparable at one speed)
    double a2 = 0.0;
    for (Eigen::Index r = 0; r < n; ++r) {
        a2 += rows_(r, 0) * rows_(r, 0);
        scratch_[static_cast<std::size_t>(r)] = std::abs(rows_(r, 1));
    }
    if (std::sqrt(a2 / static_cast<double>(n)) < options_.minimum_acceleration)
        return one_speed(rows, WindowVerdict::low_excitation);
    const auto s_begin = scratch_.begin();
    const auto s_end = s_begin + n;
    std::nth_element(s_begin, s_begin + n / 10, s_end);
    const double p10 = scratch_[static_cast<std::size_t>(n / 10)];
    std::nth_element(s_begin, s_begin + (9 * n) / 10, s_end);
    const double p90 = scratch_[static_cast<std::size_t>((9 * n) / 10)];
    if (p90 < options_.minimum_speed_ratio * p10) return one_speed(rows, WindowVerdict::low_excitation);
    std::nth_element(s_begin, s_begin + (2 * n) / 3, s_end);
    const double fast = scratch_[static_cast<std::size_t>((2 * n) / 3)];
    // conditioning of the column-scaled regressor
    const Mat h = rows_.topLeftCorner(n, p).transpose() * rows_.topLeftCorner(n, p);
    column_scale_ = h.diagonal().cwiseSqrt().cwiseInverse();
    const Mat scaled = column_scale_.asDiagonal() * h * column_scale_.asDiagonal();
    const Eigen::SelfAdjointEigenSolver<Mat> eigen(scaled, Eigen::EigenvaluesOnly);
    const double condition =
        std::sqrt(eigen.eigenvalues().maxCoeff() / std::max(eigen.eigenvalues().minCoeff(), 1e-300));
    if (!(condition <= options_.maximum_condition)) return one_speed(rows, WindowVerdict::ill_conditioned);
    std::fill_n(weights_.begin(), rows, 1.0);
    const Vec least_squares = solve_weighted(rows);
    if (!options_.robust) {
        residuals(least_squares, rows);
        double sum = 0.0;
        for (std::size_t r = 0; r < rows; ++r) sum += residual_[r] * residual_[r];
        return admit(rows, std::sqrt(sum / static_cast<double>(rows)));
    }
    // Tukey's biweight: settled, from the pooled estimate with the clean windows' scale, so that a cutting force on
    // most of the window's rows is what gets rejected (a fit of smallest scale would follow the majority); before,
    // from several starts (independent_fit)
    Vec best = least_squares;
    double best_scale = 0.0;
    if (have_pooled_)
        best = tukey_fit(pooled_theta(), rows, best_scale);
    else
        best = independent_fit(rows, least_squares, fast, best_scale);
    const WindowVerdict verdict =
        settle_weights(rows, best, best_scale) ? admit(rows, best_scale) : WindowVerdict::process_force;
    if (verdict == WindowVerdict::qualified) inconsistent_run_ = 0;
    if (verdict != WindowVerdict::process_force || !have_pooled_) return verdict;
    return judge_change(rows, least_squares, fast);
}

// A window of one speed (or too little acceleration, or too few rows) cannot be fitted on its own, but its rows still
// inform the pooled estimate: B and F_C at its speed, M from its accelerations. It is judged against the pooled model
// instead: row by row (judge_rows) when a pooled estimate exists; before, it is held (deferred_, a fixed number) as
// its least-squares sufficient statistics and judged whole from them once one does (judge_one_speed: the rows are
// gone by then). Without robust weighting it is pooled as it is.
WindowVerdict OnlineIdentifier::one_speed(std::size_t rows, WindowVerdict own) {
    const std::size_t p = p_;
    std::array<double, max_p * max_p> h{};
    std::array<double, max_p> c{};
    double yy = 0.0;
    for (std::size_t k = 0; k < rows; ++k) {
        const double* row = rows_.data() + k * (max_p + 1);
        yy += row[p] * row[p];
        for (std::size_t i = 0; i < p; ++i) {
            c[i] += row[i] * row[p];
            for (std::size_t j = 0; j <= i; ++j) h[i * max_p + j] += row[i] * row[j];
        }
    }
    OneSpeedWindow w;
    const auto n = static_cast<Eigen::Index>(p);
    w.h = Mat::Zero(n, n);
    w.c = Vec::Zero(n);
    for (Eigen::Index i = 0; i < n; ++i) {
        w.c(i) = c[static_cast<std::size_t>(i)];
        for (Eigen::Index j = 0; j <= i; ++j) w.h(i, j) = w.h(j, i) = h[static_cast<std::size_t>(i * max_p + j)];
    }
    w.yy = yy;
    w.rows = rows;
    w.own = own;
    if (!options_.robust) {
        // plain least squares pools every window; its scale: the residual of its own (minimum-norm) fit
        const Eigen::SelfAdjointEigenSolver<Mat> eigen(w.h);
        double explained = 0.0;
        const double top = eigen.eigenvalues().maxCoeff();
        for (Eigen::Index k = 0; k < n; ++k) {
            const double lambda = eigen.eigenvalues()(k);
            if (lambda > 1e-12 * top) explained += std::pow(eigen.eigenvectors().col(k).dot(w.c), 2) / lambda;
        }
        pool(WindowInformation{w.h, w.c, std::sqrt(std::max(0.0, yy - explained) / static_cast<double>(rows)), rows});
        return WindowVerdict::qualified;
    }
    if (have_pooled_ && reference_scale_ > 0.0) return judge_rows(rows);
    if (deferred_count_ == deferred_.size()) return own;
    deferred_[deferred_count_++] = w;
    return WindowVerdict::pending;
}

// The process-force test of a one-speed window against the pooled estimate theta: its rms residual at theta within
// maximum_scale_ratio of the clean windows' scale (a cutting force shows there), and its gradient
// g = c - H theta within consistency_chi2 of zero in its own covariance s^2 kappa (H + H H_pool^-1 H) (the window's
// noise and the pooled estimate's, pseudo-inverted on the directions the window informs): a constant force at its
// speed (a cut the scale does not show) moves g.
WindowVerdict OnlineIdentifier::judge_one_speed(const OneSpeedWindow& window) {
    const Vec theta = pooled_theta();
    const double rss = window.yy - 2.0 * theta.dot(window.c) + theta.dot(window.h * theta);
    const double rms = std::sqrt(std::max(0.0, rss) / static_cast<double>(window.rows));
    if (!(rms <= options_.maximum_scale_ratio * reference_scale_) || !fits_pool(window.h, window.c))
        return WindowVerdict::process_force;
    pool(WindowInformation{window.h, window.c, rms, window.rows});
    return WindowVerdict::qualified;
}

// A window that cannot be fitted on its own, judged row by row against the pooled estimate theta (once there is one):
// Tukey's biweight of each row's residual at theta, in the clean windows' scale. The window's own fit, which the
// weights of an own-fit window come from, does not exist (its H is singular or too small to trust: one speed, or a
// short rapid), but theta does, and it is the model every clean row fits within the noise: a row that a cutting
// force pushes off by 120 N against a 4 N scale weighs nothing, a clean row of the same window counts. The weights
// are fixed (one step, no iteration on the window's own rows, which could only move along the directions the window
// informs towards whatever force it carries). The honest gates stay: more than maximum_outlier_fraction of the rows
// rejected, a robust scale of the residuals above maximum_scale_ratio of the clean windows', or the weighted
// gradient beyond consistency_chi2: process_force, the whole window. What passes enters the pool on the directions
// it informs (square-root information adds a singular H_w exactly), and counts as a cluster of its own.
WindowVerdict OnlineIdentifier::judge_rows(std::size_t rows) {
    const Vec theta = pooled_theta();
    residuals(theta, rows);
    const double scale = 1.4826 * median_absolute(std::span<const double>(residual_.data(), rows), scratch_);
    if (!(scale <= options_.maximum_scale_ratio * reference_scale_)) return WindowVerdict::process_force;
    if (!settle_weights(rows, theta, std::min(scale, options_.scale_cap * reference_scale_)))
        return WindowVerdict::process_force;
    const WindowInformation window = information(rows, scale);
    if (window.rows < p_ || !fits_pool(window.h, window.c)) return WindowVerdict::process_force;
    pool(window);
    return WindowVerdict::qualified;
}

bool OnlineIdentifier::fits_pool(const Mat& h, const Vec& c) const {
    const auto p = static_cast<Eigen::Index>(p_);
    const Vec theta = pooled_theta();
    const Mat r = r_z_.topLeftCorner(p, p);
    const Mat pooled_information = r.transpose() * r;
    const Vec g = c - h * theta;
    const Mat v = h + h * pooled_information.ldlt().solve(h);
    const Eigen::SelfAdjointEigenSolver<Mat> eigen(v);
    const double top = eigen.eigenvalues().maxCoeff();
    double distance = 0.0;
    for (Eigen::Index k = 0; k < p; ++k) {
        const double lambda = eigen.eigenvalues()(k);
        if (lambda > 1e-10 * top) distance += std::pow(eigen.eigenvectors().col(k).dot(g), 2) / lambda;
    }
    const double kappa = std::max(1.0, 1.0 / (dt_ * cutoff_hz_));
    distance /= reference_scale_ * reference_scale_ * kappa;
    return distance <= options_.consistency_chi2;
}

void OnlineIdentifier::settle_deferred() {
    for (std::size_t k = 0; k < deferred_count_; ++k) {
        const WindowVerdict v =
            have_pooled_ && reference_scale_ > 0.0 ? judge_one_speed(deferred_[k]) : deferred_[k].own;
        ++counts_.by_verdict[static_cast<std::size_t>(v)];
    }
    deferred_count_ = 0;
}

OnlineIdentifier::Vec OnlineIdentifier::independent_fit(std::size_t rows, const Vec& least_squares, double fast,
                                                        double& best_scale) {
    // Tukey's biweight from least squares and from the fastest third of the rows (rapid moves, which do not cut),
    // keeping the fit of smallest robust scale (the S-estimator's rule)
    Vec best = least_squares;
    best_scale = std::numeric_limits<double>::max();
    const auto attempt = [&](const Vec& start) {
        double scale = 0.0;
        const Vec theta = tukey_fit(start, rows, scale);
        if (scale < best_scale) {
            best = theta;
            best_scale = scale;
        }
    };
    attempt(least_squares);
    for (std::size_t r = 0; r < rows; ++r)
        weights_[r] = std::abs(rows_(static_cast<Eigen::Index>(r), 1)) >= fast ? 1.0 : 0.0;
    const Vec fastest = solve_weighted(rows);
    if (fastest.allFinite()) attempt(fastest);
    return best;
}

bool OnlineIdentifier::settle_weights(std::size_t rows, const Vec& theta, double scale) {
    residuals(theta, rows);
    std::size_t rejected = 0;
    for (std::size_t r = 0; r < rows; ++r) {
        weights_[r] = tukey_weight(residual_[r], options_.tukey_c * scale);
        rejected += weights_[r] == 0.0 ? 1 : 0;
    }
    last_outlier_fraction_ = static_cast<double>(rejected) / static_cast<double>(rows);
    return last_outlier_fraction_ <= options_.maximum_outlier_fraction;
}

WindowVerdict OnlineIdentifier::judge_change(std::size_t rows, const Vec& least_squares, double fast) {
    // A window the pool rejects but that fits the model on its own (small scale, few outliers) and disagrees with the
    // pooled estimate: the axis may have changed (a heavier workpiece, worn guides). Many in a row, with forgetting,
    // start the pool again from them; without forgetting they are counted and said.
    // A cutting force shows in the least-squares fit's own scale: only a window that least squares fits well is
    // fitted again robustly (the IRLS runs for few rejected windows)
    residuals(least_squares, rows);
    const double plain_scale = 1.4826 * median_absolute(std::span<const double>(residual_.data(), rows), scratch_);
    if (!(plain_scale <= options_.maximum_scale_ratio * reference_scale_)) return WindowVerdict::process_force;
    double scale = 0.0;
    const Vec theta = independent_fit(rows, least_squares, fast, scale);
    if (!settle_weights(rows, theta, scale) || last_outlier_fraction_ > options_.clean_outlier_fraction ||
        scale > options_.maximum_scale_ratio * reference_scale_)
        return WindowVerdict::process_force;
    if (consistent(information(rows, scale), pooled_theta())) return WindowVerdict::process_force;
    if (++inconsistent_run_ >= options_.change_windows && options_.forgetting < 1.0) {
        reset_pool();
        ++changes_;
        inconsistent_run_ = 0;
    }
    return WindowVerdict::inconsistent;
}

OnlineIdentifier::WindowInformation OnlineIdentifier::information(std::size_t rows, double scale) const {
    const auto p = static_cast<Eigen::Index>(p_);
    WindowInformation window;
    window.h = Mat::Zero(p, p);
    window.c = Vec::Zero(p);
    window.scale = scale;
    for (std::size_t k = 0; k < rows; ++k) {
        const double w = weights_[k];
        if (w == 0.0) continue;
        const auto r = static_cast<Eigen::Index>(k);
        window.h.noalias() += w * rows_.row(r).head(p).transpose() * rows_.row(r).head(p);
        window.c.noalias() += w * rows_(r, p) * rows_.row(r).head(p).transpose();
        ++window.rows;
    }
    return window;
}

void OnlineIdentifier::reset_pool() {
    r_z_.setZero();
    sum_cc_.setZero();
    for (auto& m : sum_cH_) m.setZero();
    for (auto& row : sum_HH_)
        for (auto& m : row) m.setZero();
    forgotten_windows_ = 0.0;
    sum_scale_sq_ = 0.0;
    have_pooled_ = false;
    pending_count_ = 0;
}

OnlineIdentifier::Vec OnlineIdentifier::solve_weighted(std::size_t rows) const {
    // the normal equations of the weighted rows, in plain loops over the contiguous rows (the IRLS's inner loop)
    const std::size_t p = p_;
    std::array<double, max_p * max_p> h{};
    std::array<double, max_p> c{};
    for (std::size_t k = 0; k < rows; ++k) {
        const double w = weights_[k];
        if (w == 0.0) continue;
        const double* row = rows_.data() + k * (max_p + 1);
        for (std::size_t i = 0; i < p; ++i) {
            const double wi = w * row[i];
            c[i] += wi * row[p];
            for (std::size_t j = 0; j <= i; ++j) h[i * max_p + j] += wi * row[j];
        }
    }
    const auto n = static_cast<Eigen::Index>(p);
    Mat hs(n, n);
    Vec cs(n);
    for (Eigen::Index i = 0; i < n; ++i) {
        cs(i) = column_scale_(i) * c[static_cast<std::size_t>(i)];
        for (Eigen::Index j = 0; j <= i; ++j) {
            hs(i, j) = column_scale_(i) * h[static_cast<std::size_t>(i * max_p + j)] * column_scale_(j);
            hs(j, i) = hs(i, j);
        }
    }
    return column_scale_.asDiagonal() * hs.ldlt().solve(cs);
}

void OnlineIdentifier::residuals(const Vec& theta, std::size_t rows) {
    const std::size_t p = p_;
    for (std::size_t k = 0; k < rows; ++k) {
        const double* row = rows_.data() + k * (max_p + 1);
        double fitted = 0.0;
        for (std::size_t i = 0; i < p; ++i) fitted += row[i] * theta(static_cast<Eigen::Index>(i));
        residual_[k] = row[p] - fitted;
    }
}

OnlineIdentifier::Vec OnlineIdentifier::tukey_fit(const Vec& start, std::size_t rows, double& scale) {
    Vec theta = start;
    for (int iteration = 0; iteration < options_.irls_iterations; ++iteration) {
        residuals(theta, rows);
        scale = std::max(1e-12, 1.4826 * median_absolute(std::span<const double>(residual_.data(), rows), scratch_));
        // a window that a process force dominates would inflate its own scale: the clean windows' scale bounds it
        if (reference_scale_ > 0.0) scale = std::min(scale, options_.scale_cap * reference_scale_);
        const double limit = options_.tukey_c * scale;
        for (std::size_t r = 0; r < rows; ++r) weights_[r] = tukey_weight(residual_[r], limit);
        const Vec next = solve_weighted(rows);
        if (!next.allFinite()) break;
        const bool converged = (next - theta).cwiseAbs().maxCoeff() <= 1e-10 * (theta.cwiseAbs().maxCoeff() + 1e-300);
        theta = next;
        if (converged) break;
    }
    residuals(theta, rows);
    scale = std::max(1e-12, 1.4826 * median_absolute(std::span<const double>(residual_.data(), rows), scratch_));
    return theta;
}

WindowVerdict OnlineIdentifier::admit(std::size_t rows, double scale) {
    const WindowInformation window = information(rows, scale);
    if (!options_.robust) {
        pool(window);
        return WindowVerdict::qualified;
    }
    recent_scales_[recent_count_++ % recent_scales_.size()] = scale;
    if (have_pooled_) {
        update_reference_scale();
        if (scale > options_.maximum_scale_ratio * reference_scale_ || !consistent(window, pooled_theta()))
            return WindowVerdict::process_force;
        pool(window);
        return WindowVerdict::qualified;
    }
    // the first windows wait until the clean windows' scale is known: a process force that dominates one of them
    // must not enter the pool before there is a scale to tell it by
    pending_[pending_count_++] = window;
    if (pending_count_ == pending_.size()) {
        settle_pending();
        settle_deferred();
    }
    return WindowVerdict::pending;
}

// The clean windows' residual scale: the lower quartile of the last 32 windows' robust scales. A cutting force only
// ever adds to a window's scale, so the clean windows are the low ones; the median was a cut window's whenever most
// windows cut (seen: 6 of a trace's first 8, whose median scale of 24 N against a clean 4 N let a cut window found the
// pool, M 35 % high and B -810 N*s/m, and windows judged against that pool then passed).
void OnlineIdentifier::update_reference_scale() {
    const std::size_t n = std::min(recent_count_, recent_scales_.size());
    std::array<double, 32> sorted{};
    std::copy_n(recent_scales_.begin(), n, sorted.begin());
    const std::size_t quartile = n > 0 ? (n - 1) / 4 : 0;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(quartile),
                     sorted.begin() + static_cast<std::ptrdiff_t>(n));
    reference_scale_ = sorted[quartile];
}

void OnlineIdentifier::settle_pending() {
    if (pending_count_ == 0) return;
    update_reference_scale();
    // the first windows' consensus: the median of their estimates, coordinate by coordinate, among those whose
    // scale is that of clean windows; a window then enters when its estimate agrees with the consensus
    const auto p = static_cast<Eigen::Index>(p_);
    std::array<Vec, 8> estimates;
    std::array<double, 8> column{};
    std::size_t clean = 0;
    for (std::size_t k = 0; k < pending_count_; ++k) {
        estimates[k] = pending_[k].h.ldlt().solve(pending_[k].c);
        if (pending_[k].scale <= options_.maximum_scale_ratio * reference_scale_) ++clean;
    }
    Vec consensus = Vec::Zero(p);
    for (Eigen::Index i = 0; i < p; ++i) {
        std::size_t n = 0;
        for (std::size_t k = 0; k < pending_count_; ++k)
            if (pending_[k].scale <= options_.maximum_scale_ratio * reference_scale_) column[n++] = estimates[k](i);
        std::nth_element(column.begin(), column.begin() + static_cast<std::ptrdiff_t>(n / 2),
                         column.begin() + static_cast<std::ptrdiff_t>(n));
        consensus(i) = n > 0 ? column[n / 2] : 0.0;
    }
    if (clean <= 2) {
        // two windows have no median: the coordinate-wise upper one mixes the two estimates (M of one, B of the
        // other) into a point neither agrees with, along B and F_C's correlation (seen: both clean windows of the
        // drilling program's Y axis rejected in 2 of 30 seeds, nothing qualified). Their pooled estimate instead.
        Mat h = Mat::Zero(p, p);
        Vec c = Vec::Zero(p);
        for (std::size_t k = 0; k < pending_count_; ++k) {
            if (!(pending_[k].scale <= options_.maximum_scale_ratio * reference_scale_)) continue;
            h += pending_[k].h;
            c += pending_[k].c;
        }
        if (clean > 0) consensus = h.ldlt().solve(c);
    }
    for (std::size_t k = 0; k < pending_count_; ++k) {
        const bool ok = clean > 0 && pending_[k].scale <= options_.maximum_scale_ratio * reference_scale_ &&
                        consistent(pending_[k], consensus);
        if (ok) pool(pending_[k]);
        ++counts_.by_verdict[static_cast<std::size_t>(ok ? WindowVerdict::qualified : WindowVerdict::process_force)];
    }
    pending_count_ = 0;
}

bool OnlineIdentifier::consistent(const WindowInformation& window, const Vec& reference) const {
    // (theta_w - theta)^T H_w (theta_w - theta) / (s^2 kappa): chi^2 with p degrees of freedom for a window that
    // fits the model, its residuals correlated over kappa samples by the low-pass
    const Vec theta = window.h.ldlt().solve(window.c);
    const Vec d = theta - reference;
    const double kappa = std::max(1.0, 1.0 / (dt_ * cutoff_hz_));
    const double distance = d.dot(window.h * d) / (window.scale * window.scale * kappa);
    return distance <= options_.consistency_chi2;
}

void OnlineIdentifier::pool(const WindowInformation& window) {
    const auto p = static_cast<Eigen::Index>(p_);
    const double lambda = options_.forgetting;
    if (lambda < 1.0) {
        r_z_ *= std::sqrt(lambda);
        sum_cc_ *= lambda * lambda;
        for (auto& m : sum_cH_) m *= lambda * lambda;
        for (auto& row : sum_HH_)
            for (auto& m : row) m *= lambda * lambda;
    }
    forgotten_windows_ = lambda * forgotten_windows_ + 1.0;
    sum_scale_sq_ = lambda * sum_scale_sq_ + window.scale * window.scale;
    rows_used_ += window.rows;
    // the window's information H_w = L L^T enters [R z] as the rows [L^T, L^-1 c_w], by Givens rotations: the
    // square-root information update (R^T R + H_w, R^T z + c_w), never forming R^T R
    // (by its eigen-decomposition H_w = V D V^T: L = V D^1/2, so that a one-speed window's singular H_w enters on the
    // directions it informs)
    const Eigen::SelfAdjointEigenSolver<Mat> eigen(window.h);
    const double top = eigen.eigenvalues().maxCoeff();
    Mat upper = Mat::Zero(p, p);
    Vec rhs = Vec::Zero(p);
    for (Eigen::Index k = 0; k < p; ++k) {
        const double lambda = eigen.eigenvalues()(k);
        if (!(lambda > 1e-12 * top)) continue;
        upper.row(k) = std::sqrt(lambda) * eigen.eigenvectors().col(k).transpose();
        rhs(k) = eigen.eigenvectors().col(k).dot(window.c) / std::sqrt(lambda);
    }
    Eigen::Matrix<double, 1, max_p + 1> row;
    for (Eigen::Index k = 0; k < p; ++k) {
        row.setZero();
        row.head(p) = upper.row(k);
        row(p) = rhs(k);
        for (Eigen::Index i = 0; i < p; ++i) {
            if (row(i) == 0.0) continue;
            const double a = r_z_(i, i);
            const double b = row(i);
            const double hyp = std::hypot(a, b);
            const double c = a / hyp;
            const double s = b / hyp;
            for (Eigen::Index j = i; j < p; ++j) {
                const double rij = r_z_(i, j);
                r_z_(i, j) = c * rij + s * row(j);
                row(j) = -s * rij + c * row(j);
            }
            const double zi = r_z_(i, max_p);
            r_z_(i, max_p) = c * zi + s * row(p);
            row(p) = -s * zi + c * row(p);
        }
    }
    sum_cc_.noalias() += window.c * window.c.transpose();
    for (Eigen::Index i = 0; i < p; ++i) {
        const auto ii = static_cast<std::size_t>(i);
        sum_cH_[ii] += window.c(i) * window.h;
        for (Eigen::Index j = 0; j < p; ++j) sum_HH_[ii][static_cast<std::size_t>(j)] += window.h(i, j) * window.h;
    }
    have_pooled_ = true;
}

OnlineIdentifier::Vec OnlineIdentifier::pooled_theta() const {
    const auto p = static_cast<Eigen::Index>(p_);
    const Mat r = r_z_.topLeftCorner(p, p);
    const Vec z = r_z_.col(max_p).head(p);
    return r.triangularView<Eigen::Upper>().solve(z);
}

void OnlineIdentifier::bin_slow_samples(std::size_t first, std::size_t last) {
    const double low = std::log(options_.stribeck_lowest_speed);
    const double span = std::log(options_.split()) - low;
    for (std::size_t k = first; k < last; ++k) {
        const double speed = std::abs(v_[k]);
        if (use_[k] == 0 || speed <= options_.moving_threshold || speed > options_.split() ||
            speed < options_.stribeck_lowest_speed || std::abs(a_[k]) > options_.quasi_static_acceleration)
            continue;
        // the quasi-static slow samples: the force is friction (and M*x'', small); away from a reversal, where the
        // filtered sgn would not be +-1
        if (std::abs(sf_[k]) < 0.999) continue;
        const double d = v_[k] > 0.0 ? 1.0 : -1.0;
        const auto index = std::min(bins_per_direction - 1,
                                    static_cast<std::size_t>((std::log(speed) - low) / span * bins_per_direction));
        StribeckBin& bin = bins_[d > 0.0 ? 0 : 1][index];
        if (bin.last_window != counts_.total) {
            bin.last_window = counts_.total;
            ++bin.windows;
        }
        bin.n += 1.0;
        bin.speed += speed;
        bin.force += d * ff_[k];
        bin.force_sq += ff_[k] * ff_[k];
        bin.acceleration += d * a_[k];
    }
}

}  // namespace feedid

namespace feedid {

namespace {

// eq. (13) on the bins: ln(F_stri) = ln(F_B - F_C) - |v| / v_s, weighted by each bin's precision.
struct BinPoint {
    double speed, stribeck, standard_error;
};

struct StribeckFit {
    bool ok{false};
    double rise{0.0}, vs{0.0}, rise_se{0.0}, vs_se{0.0};
    std::size_t used{0};
    std::size_t slow{0};  ///< bins below 3 v_s
};

// The bins' points F_stri = friction - B |v| - F_C (- F_0 sgn) above twice their noise; bins with too few samples or
// from too few windows (one slow move is one realisation of the noise and of any cutting force) are left out.
template <class Bins, class Theta>
std::size_t stribeck_points(const Bins& bins, const Theta& theta, bool offset, double correlation,
                            const OnlineOptions& options, std::span<BinPoint> points, std::size_t& slow_samples,
                            std::size_t& populated) {
    std::size_t used = 0;
    slow_samples = 0;
    populated = 0;
    for (std::size_t direction = 0; direction < 2; ++direction) {
        for (const auto& bin : bins[direction]) {
            slow_samples += static_cast<std::size_t>(bin.n);
            if (bin.n < static_cast<double>(options.minimum_bin_samples) ||
                bin.windows < options.minimum_stribeck_windows)
                continue;
            ++populated;
            const double speed = bin.speed / bin.n;
            const double mean = bin.force / bin.n;
            double stribeck = mean - theta(0) * bin.acceleration / bin.n - theta(1) * speed - theta(2);
            if (offset) stribeck -= (direction == 0 ? 1.0 : -1.0) * theta(3);
            const double se = std::sqrt(std::max(0.0, bin.force_sq / bin.n - mean * mean) * correlation / bin.n);
            if (stribeck > 2.0 * se + 1e-12 && used < points.size()) points[used++] = {speed, stribeck, se + 1e-12};
        }
    }
    return used;
}

StribeckFit fit_stribeck(std::span<const BinPoint> points, std::size_t minimum_bins) {
    StribeckFit f;
    f.used = points.size();
    if (points.size() < minimum_bins) return f;
    Eigen::Matrix2d normal = Eigen::Matrix2d::Zero();
    Eigen::Vector2d right = Eigen::Vector2d::Zero();
    for (const auto& point : points) {
        const double w = std::pow(point.stribeck / point.standard_error, 2);  // 1 / var(ln F_stri)
        const Eigen::Vector2d phi(1.0, point.speed);
        normal += w * phi * phi.transpose();
        right += w * std::log(point.stribeck) * phi;
    }
    const Eigen::Vector2d line = normal.inverse() * right;
    // the bins' scatter about the fitted line beyond their own noise (the log-linear law's misfit, bins correlated by
    // the filter) widens the covariance: reduced chi^2, when above 1
    double chi2 = 0.0;
    for (const auto& point : points) {
        const double w = std::pow(point.stribeck / point.standard_error, 2);
        chi2 += w * std::pow(std::log(point.stribeck) - line(0) - line(1) * point.speed, 2);
    }
    const double inflation = points.size() > 2 ? std::max(1.0, chi2 / static_cast<double>(points.size() - 2)) : 1.0;
    const Eigen::Matrix2d cov = inflation * normal.inverse();
    if (!(line(1) < 0.0)) return f;
    f.ok = true;
    f.rise = std::exp(line(0));
    f.vs = -1.0 / line(1);
    f.vs_se = std::sqrt(cov(1, 1)) / (line(1) * line(1));
    f.rise_se = f.rise * std::sqrt(cov(0, 0));
    for (const auto& point : points) f.slow += point.speed < 3.0 * f.vs ? 1 : 0;
    return f;
}

}  // namespace

std::string OnlineIdentifier::no_value_reason() const {
    if (!have_pooled_)
        return fmt::format("no window qualified ({} of {} windows; see the rejection counts)", counts_.qualified(),
                           counts_.total);
    if (counts_.qualified() < 2) {
        // one window is checked against no other: its robust fit may have followed a process force over most of it
        // (seen: M 33 % high and B -806 N*s/m from the one window of a trace, with a small model-based error)
        return fmt::format(
            "only {} window qualified (of {}): one window cannot be checked against another, and a process force "
            "over most of it would pass for the axis; 2 or more needed",
            counts_.qualified(), counts_.total);
    }
    // Windows that fit the model on their own (few outlying rows) but not the pool. When they are a fair share of the
    // windows that fit (a quarter, and 2 or more), the pool is only of the windows that happen to agree, and which
    // ones those are decides the value: the EMPS recording gave B 141 +- 9 N*s/m from the 5 of its 13 windows that
    // agreed, against the 203.5 published (its friction differs by direction). No value then, but why.
    const std::size_t inconsistent = counts_.count(WindowVerdict::inconsistent);
    if (options_.forgetting >= 1.0 && inconsistent >= 2 && 4 * inconsistent >= counts_.qualified() + inconsistent) {
        return fmt::format(
            "{} of the {} windows that fit the model on their own disagree with what the other {} pool to: the "
            "model does not describe this axis the same way throughout (friction that differs by direction or is "
            "not linear in the speed, or a change of the axis: --forgetting follows a change); identify it from a "
            "dedicated test (feedid plan)",
            inconsistent, counts_.qualified() + inconsistent, counts_.qualified());
    }
    return {};
}

OnlineEstimate OnlineIdentifier::estimate() const {
    OnlineEstimate e;
    e.windows = counts_;
    e.changes = changes_;
    e.samples = pushed_;
    e.rows_used = rows_used_;
    const auto p = static_cast<Eigen::Index>(p_);
    e.mass_reason = no_value_reason();
    if (!e.mass_reason.empty()) {
        e.friction_reason = e.mass_reason;
        e.stribeck_reason = e.mass_reason;
        return e;
    }
    e.residual_std = std::sqrt(sum_scale_sq_ / forgotten_windows_);
    const Mat r = r_z_.topLeftCorner(p, p);
    const Vec theta = pooled_theta();
    const Mat h = r.transpose() * r;
    // the clusters' meat at the final theta: sum_w (c_w - H_w theta)(c_w - H_w theta)^T from the moment sums
    Mat cross = Mat::Zero(p, p);      // sum_w c_w (H_w theta)^T
    Mat quadratic = Mat::Zero(p, p);  // sum_w (H_w theta)(H_w theta)^T
    for (Eigen::Index i = 0; i < p; ++i) {
        cross.row(i) = (sum_cH_[static_cast<std::size_t>(i)] * theta).transpose();
        for (Eigen::Index j = 0; j < p; ++j)
            quadratic.row(i) +=
                theta(j) * (sum_HH_[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)] * theta).transpose();
    }
    Mat meat = sum_cc_ - cross - cross.transpose() + quadratic;
    // the small-sample factor G / (G - p) (CR1). CR2 (Bell-McCaffrey) would need each window's leverage against the
    // final H, i.e. every window's H_w kept (not O(1)); on the part programs with 7-11 windows the scatter over seeds
    // / standard error is 0.81-1.08 (drilling over 30 seeds 0.75-1.09): no downward bias left for it to remove.
    const double clusters = forgotten_windows_;
    if (clusters > static_cast<double>(p_)) meat *= clusters / (clusters - static_cast<double>(p_));
    const Mat h_inverse = h.inverse();
    e.covariance = h_inverse * meat * h_inverse;
    // with fewer than p + 2 windows the cluster covariance is not honest (its meat has the rank of the number of
    // windows): the model-based one instead, s^2 kappa H^-1, the residuals' variance times their integrated
    // autocorrelation after the zero-phase low-pass (about fs / (2 f_c) samples for white noise)
    const bool few = forgotten_windows_ < static_cast<double>(p_) + 2.0;
    if (few) e.covariance = (e.residual_std * e.residual_std * std::max(1.0, 0.5 / (dt_ * cutoff_hz_))) * h_inverse;
    const Vec se = e.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    e.information = e.covariance.diagonal().cwiseInverse();
    const Vec d = se;
    const Mat scaled_information = d.asDiagonal() * e.covariance.inverse() * d.asDiagonal();
    e.information_eigenvalues =
        Eigen::SelfAdjointEigenSolver<Mat>(scaled_information, Eigen::EigenvaluesOnly).eigenvalues();
    e.mass = Estimate::of(theta(0), se(0));
    e.viscous = Estimate::of(theta(1), se(1));
    e.coulomb = Estimate::of(theta(2), se(2));
    if (p_ == 4) e.offset = Estimate::of(theta(3), se(3));
    if (few)
        e.friction_reason = fmt::format(
            "only {} window(s) qualified: standard errors model-based (residual scale and the filter's correlation), "
            "not from the scatter between windows ({} or more)",
            counts_.qualified(), p_ + 2);
    estimate_stribeck(theta, se, e);
    return e;
}

void OnlineIdentifier::estimate_stribeck(const Vec& theta, const Vec& standard_error, OnlineEstimate& e) const {
    // the quasi-static bins: F_stri = friction - B |v| - F_C per bin, eq. (13) on those above their noise
    std::array<BinPoint, 2 * bins_per_direction> points{};
    const double correlation = std::max(1.0, 1.0 / (dt_ * cutoff_hz_));
    std::size_t slow_samples = 0;
    std::size_t populated = 0;
    // the bins' points for B + db and F_C + dc (F_B and v_s extrapolate the rise above F_C to zero speed: an error
    // of F_C or B moves them, and their uncertainty must say so)
    const auto fit = [&](double db, double dc) {
        Vec moved = theta;
        moved(1) += db;
        moved(2) += dc;
        const std::size_t used =
            stribeck_points(bins_, moved, p_ == 4, correlation, options_, points, slow_samples, populated);
        return fit_stribeck(std::span<const BinPoint>(points.data(), used), options_.minimum_stribeck_bins);
    };
    const StribeckFit nominal = fit(0.0, 0.0);
    const ParameterNaming naming{options_.rotary};
    const double scale = naming.display_velocity_scale();
    const std::string unit = naming.display_velocity_unit();
    if (nominal.used < options_.minimum_stribeck_bins) {
        e.stribeck_reason =
            populated < options_.minimum_stribeck_bins
                ? fmt::format(
                      "the trace has no moves slow enough to determine F_B and v_s: its quasi-static samples "
                      "below {:.3g} {} ({}) fill {} speed bin(s) of {} or more from {} or more windows; {} needed",
                      options_.split() * scale, unit, slow_samples, populated, options_.minimum_bin_samples,
                      options_.minimum_stribeck_windows, options_.minimum_stribeck_bins)
                : fmt::format(
                      "the slow moves ({} quasi-static samples below {:.3g} {}) show a friction rise above "
                      "F_C in only {} speed bin(s); {} needed",
                      slow_samples, options_.split() * scale, unit, nominal.used, options_.minimum_stribeck_bins);
        return;
    }
    if (!nominal.ok) {
        e.stribeck_reason = "the slow moves' friction does not fall with speed: no Stribeck term to determine";
        return;
    }
    // the decay must be seen: several bins below 3 v_s (above it the rise is under 5 % of its size)
    if (nominal.slow < options_.minimum_stribeck_bins) {
        e.stribeck_reason = fmt::format(
            "v_s = {:.3g} {} is not determined by the slow moves: only {} speed bin(s) below 3 v_s; {} needed",
            nominal.vs * scale, unit, nominal.slow, options_.minimum_stribeck_bins);
        return;
    }
    // F_C's and B's standard errors carried through: the fit again with each moved by one standard error
    double vs_shift = 0.0;
    double rise_shift = 0.0;
    for (const auto& [db, dc] : {std::pair{standard_error(1), 0.0}, std::pair{-standard_error(1), 0.0},
                                 std::pair{0.0, standard_error(2)}, std::pair{0.0, -standard_error(2)}}) {
        const StribeckFit moved = fit(db, dc);
        if (!moved.ok) {
            e.stribeck_reason = fmt::format(
                "v_s = {:.3g} {} is not determined: the slow moves' rise above F_C vanishes within F_C's and B's "
                "standard errors",
                nominal.vs * scale, unit);
            return;
        }
        vs_shift = std::max(vs_shift, std::abs(moved.vs - nominal.vs));
        rise_shift = std::max(rise_shift, std::abs(moved.rise + dc - nominal.rise));  // F_B = F_C + rise
    }
    const double vs_se = std::hypot(nominal.vs_se, vs_shift);
    const double fb_se = std::hypot(nominal.rise_se, rise_shift);
    if (!(vs_se < 0.3 * nominal.vs)) {
        e.stribeck_reason = fmt::format("v_s = {:.3g} {} is not determined by the slow moves (standard error {:.0f} %)",
                                        nominal.vs * scale, unit, 100.0 * vs_se / nominal.vs);
        return;
    }
    e.breakaway = Estimate::of(theta(2) + nominal.rise, fb_se);
    e.stribeck_velocity = Estimate::of(nominal.vs, vs_se);
    e.stribeck_bins_used = nominal.used;
}

}  // namespace feedid
