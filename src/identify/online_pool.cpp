// The online identifier's pool: a window's weighted information, the first windows held until the clean windows'
// scale is known, the consistency test, and the square-root information update by Givens rotations.

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "online_state.hpp"

namespace feedid {

using State = OnlineIdentifier::State;

State::WindowInformation State::information(std::size_t rows, double scale) {
    constexpr Eigen::Index p = max_p;
    WindowInformation window;
    window.h = Mat::Zero(p, p);
    window.c = Vec::Zero(p);
    window.scale = scale;
    for (std::size_t k = 0; k < rows; ++k) {
        const double w = weights_[k];
        if (w == 0.0) continue;
        const auto r = static_cast<Eigen::Index>(k);
        window.h.noalias() += w * rows_.row(r).head(p).transpose() * rows_.row(r).head(p);
        window.c.noalias() += w * rows_(r, max_p) * rows_.row(r).head(p).transpose();
        ++window.rows;
    }
    if (options_.estimate_delay) {
        const auto p = static_cast<Eigen::Index>(p_);
        const Vec theta = have_pooled_ ? pooled_theta()
                                       : Vec(window.h.topLeftCorner(p, p).ldlt().solve(window.c.head(p)));
        window.timed = timed_sums(rows, true, theta);
    }
    return window;
}

void State::reset_pool() {
    r_z_.setZero();
    sum_cc_.setZero();
    for (auto& m : sum_cH_) m.setZero();
    for (auto& row : sum_HH_)
        for (auto& m : row) m.setZero();
    timed_pool_ = TimedSums{};
    timed_cc_.setZero();
    for (auto& m : timed_cH_) m.setZero();
    for (auto& row : timed_HH_)
        for (auto& m : row) m.setZero();
    forgotten_windows_ = 0.0;
    sum_scale_sq_ = 0.0;
    have_pooled_ = false;
    pending_count_ = 0;
}

WindowVerdict State::admit(std::size_t rows, double scale) {
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
void State::update_reference_scale() {
    const std::size_t n = std::min(recent_count_, recent_scales_.size());
    std::array<double, 32> sorted{};
    std::copy_n(recent_scales_.begin(), n, sorted.begin());
    const std::size_t quartile = n > 0 ? (n - 1) / 4 : 0;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(quartile),
                     sorted.begin() + static_cast<std::ptrdiff_t>(n));
    reference_scale_ = sorted[quartile];
}

void State::settle_pending() {
    if (pending_count_ == 0) return;
    update_reference_scale();
    // the first windows' consensus: the median of their estimates, coordinate by coordinate, among those whose
    // scale is that of clean windows; a window then enters when its estimate agrees with the consensus
    const auto p = static_cast<Eigen::Index>(p_);
    std::array<Vec, 8> estimates;
    std::array<double, 8> column{};
    std::size_t clean = 0;
    for (std::size_t k = 0; k < pending_count_; ++k) {
        estimates[k] = pending_[k].h.topLeftCorner(p, p).ldlt().solve(pending_[k].c.head(p));
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
            h += pending_[k].h.topLeftCorner(p, p);
            c += pending_[k].c.head(p);
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

bool State::consistent(const WindowInformation& window, const Vec& reference) const {
    // (theta_w - theta)^T H_w (theta_w - theta) / (s^2 kappa): chi^2 with p degrees of freedom for a window that
    // fits the model, its residuals correlated over kappa samples by the low-pass
    const auto p = static_cast<Eigen::Index>(p_);
    const Mat h = window.h.topLeftCorner(p, p);
    const Vec theta = h.ldlt().solve(window.c.head(p));
    const Vec d = theta - reference;
    const double kappa = std::max(1.0, 1.0 / (dt_ * cutoff_hz_));
    const double distance = d.dot(h * d) / (window.scale * window.scale * kappa);
    return distance <= options_.consistency_chi2;
}

void State::pool(const WindowInformation& window) {
    constexpr Eigen::Index p = max_p;
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
    if (options_.estimate_delay) pool_timed(window.timed);
    have_pooled_ = true;
}

State::Vec State::pooled_theta() const {
    const auto p = static_cast<Eigen::Index>(p_);
    const Mat r = r_z_.topLeftCorner(p, p);
    const Vec z = r_z_.col(max_p).head(p);
    return r.triangularView<Eigen::Upper>().solve(z);
}

}  // namespace feedid
