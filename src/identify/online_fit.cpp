// The online identifier's fit of one window on its own: the excitation and conditioning gates, weighted least squares
// in plain loops over the contiguous rows, and the residuals (robust weighting: online_robust.cpp).

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "online_state.hpp"

namespace feedid {

using State = OnlineIdentifier::State;

WindowVerdict State::fit_window(std::size_t rows) {
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

State::Vec State::solve_weighted(std::size_t rows) const {
    // the normal equations of the weighted rows, in plain loops over the contiguous rows (the IRLS's inner loop)
    const std::size_t p = p_;
    std::array<double, max_p * max_p> h{};
    std::array<double, max_p> c{};
    for (std::size_t k = 0; k < rows; ++k) {
        const double w = weights_[k];
        if (w == 0.0) continue;
        const double* row = rows_.data() + k * row_stride;
        for (std::size_t i = 0; i < p; ++i) {
            const double wi = w * row[i];
            c[i] += wi * row[max_p];
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

void State::residuals(const Vec& theta, std::size_t rows) {
    const std::size_t p = p_;
    for (std::size_t k = 0; k < rows; ++k) {
        const double* row = rows_.data() + k * row_stride;
        double fitted = 0.0;
        for (std::size_t i = 0; i < p; ++i) fitted += row[i] * theta(static_cast<Eigen::Index>(i));
        residual_[k] = row[max_p] - fitted;
    }
}

}  // namespace feedid
