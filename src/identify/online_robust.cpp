// The online identifier's robust weighting: Tukey's biweight by IRLS (from several starts before a pooled estimate
// exists), the weights settled against an estimate, and the test of a rejected window for a change of the axis.

#include <algorithm>
#include <cmath>
#include <limits>

#include "online_state.hpp"

namespace feedid {

using State = OnlineIdentifier::State;

namespace {

double tukey_weight(double r, double limit) {
    if (!(std::abs(r) < limit)) return 0.0;
    const double u = r / limit;
    return (1.0 - u * u) * (1.0 - u * u);
}

}  // namespace

// Median of |values| by selection in `scratch` (no allocation: scratch holds at least values.size()).
double State::median_absolute(std::span<const double> values, std::vector<double>& scratch) {
    if (values.empty()) return 0.0;
    std::transform(values.begin(), values.end(), scratch.begin(), [](double v) { return std::abs(v); });
    const auto middle = scratch.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
    std::nth_element(scratch.begin(), middle, scratch.begin() + static_cast<std::ptrdiff_t>(values.size()));
    return *middle;
}

State::Vec State::tukey_fit(const Vec& start, std::size_t rows, double& scale) {
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

State::Vec State::independent_fit(std::size_t rows, const Vec& least_squares, double fast, double& best_scale) {
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

bool State::settle_weights(std::size_t rows, const Vec& theta, double scale) {
    residuals(theta, rows);
    std::size_t rejected = 0;
    for (std::size_t r = 0; r < rows; ++r) {
        weights_[r] = tukey_weight(residual_[r], options_.tukey_c * scale);
        rejected += weights_[r] == 0.0 ? 1 : 0;
    }
    last_outlier_fraction_ = static_cast<double>(rejected) / static_cast<double>(rows);
    return last_outlier_fraction_ <= options_.maximum_outlier_fraction;
}

WindowVerdict State::judge_change(std::size_t rows, const Vec& least_squares, double fast) {
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

}  // namespace feedid
