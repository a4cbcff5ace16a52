// The online identifier's windows that cannot be fitted on their own (one speed, too little acceleration, too few
// rows): judged against the pooled estimate, row by row or from their sufficient statistics.

#include <array>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "online_state.hpp"

namespace feedid {

using State = OnlineIdentifier::State;

// A window of one speed (or too little acceleration, or too few rows) cannot be fitted on its own, but its rows still
// inform the pooled estimate: B and F_C at its speed, M from its accelerations. It is judged against the pooled model
// instead: row by row (judge_rows) when a pooled estimate exists; before, it is held (deferred_, a fixed number) as
// its least-squares sufficient statistics and judged whole from them once one does (judge_one_speed: the rows are
// gone by then). Without robust weighting it is pooled as it is.
WindowVerdict State::one_speed(std::size_t rows, WindowVerdict own) {
    constexpr std::size_t p = max_p;
    std::array<double, max_p * max_p> h{};
    std::array<double, max_p> c{};
    double yy = 0.0;
    for (std::size_t k = 0; k < rows; ++k) {
        const double* row = rows_.data() + k * row_stride;
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
    // held before a pooled estimate exists: no estimate to take the delay's column from, and none is needed (a few
    // one-speed windows at the start)
    if (options_.estimate_delay && have_pooled_) w.timed = timed_sums(rows, false, pooled_theta());
    if (!options_.robust) {
        // plain least squares pools every window; its scale: the residual of its own (minimum-norm) fit of the
        // model in use
        const auto m = static_cast<Eigen::Index>(p_);
        Mat judged = Mat::Zero(m, m);
        for (Eigen::Index i = 0; i < m; ++i)
            for (Eigen::Index j = 0; j < m; ++j) judged(i, j) = h[static_cast<std::size_t>(std::max(i, j) * max_p + std::min(i, j))];
        const Eigen::SelfAdjointEigenSolver<Mat> eigen(judged);
        double explained = 0.0;
        const double top = eigen.eigenvalues().maxCoeff();
        for (Eigen::Index k = 0; k < m; ++k) {
            const double lambda = eigen.eigenvalues()(k);
            if (lambda > 1e-12 * top) explained += std::pow(eigen.eigenvectors().col(k).dot(w.c.head(m)), 2) / lambda;
        }
        pool(WindowInformation{w.h, w.c, std::sqrt(std::max(0.0, yy - explained) / static_cast<double>(rows)), rows,
                               w.timed});
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
WindowVerdict State::judge_one_speed(const OneSpeedWindow& window) {
    const Vec theta = pooled_theta();
    const auto m = static_cast<Eigen::Index>(p_);
    const Mat h = window.h.topLeftCorner(m, m);
    const Vec c = window.c.head(m);
    const double rss = window.yy - 2.0 * theta.dot(c) + theta.dot(h * theta);
    const double rms = std::sqrt(std::max(0.0, rss) / static_cast<double>(window.rows));
    if (!(rms <= options_.maximum_scale_ratio * reference_scale_) || !fits_pool(h, c))
        return WindowVerdict::process_force;
    pool(WindowInformation{window.h, window.c, rms, window.rows, window.timed});
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
WindowVerdict State::judge_rows(std::size_t rows) {
    const Vec theta = pooled_theta();
    residuals(theta, rows);
    const double scale = 1.4826 * median_absolute(std::span<const double>(residual_.data(), rows), scratch_);
    if (!(scale <= options_.maximum_scale_ratio * reference_scale_)) return WindowVerdict::process_force;
    if (!settle_weights(rows, theta, std::min(scale, options_.scale_cap * reference_scale_)))
        return WindowVerdict::process_force;
    const WindowInformation window = information(rows, scale);
    const auto m = static_cast<Eigen::Index>(p_);
    if (window.rows < p_ || !fits_pool(window.h.topLeftCorner(m, m), window.c.head(m)))
        return WindowVerdict::process_force;
    pool(window);
    return WindowVerdict::qualified;
}

bool State::fits_pool(const Mat& h, const Vec& c) const {
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

void State::settle_deferred() {
    for (std::size_t k = 0; k < deferred_count_; ++k) {
        const WindowVerdict v =
            have_pooled_ && reference_scale_ > 0.0 ? judge_one_speed(deferred_[k]) : deferred_[k].own;
        ++counts_.by_verdict[static_cast<std::size_t>(v)];
    }
    deferred_count_ = 0;
}

}  // namespace feedid
