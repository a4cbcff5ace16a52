// The online identifier's drive-signal timing: the filtered force read a given delay later in each window, and the
// delay left beyond it estimated from the pool as one more parameter of step 1 (model_adequacy.hpp's first-order
// model F_log = Phi*theta - tau*F_log'), its uncertainty carried into every parameter.

#include <algorithm>
#include <cmath>

#include <fmt/core.h>
#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "online_state.hpp"

namespace feedid {

using State = OnlineIdentifier::State;

namespace {

// Two-sided standard normal quantile (as the offset's test).
double two_sided_quantile(double level) {
    double low = 0.0;
    double high = 40.0;
    for (int k = 0; k < 100; ++k) {
        const double middle = 0.5 * (low + high);
        (std::erfc(middle / std::sqrt(2.0)) > level ? low : high) = middle;
    }
    return 0.5 * (low + high);
}

// The index in the timed columns [x'', x', s, 1, -F'] of the fit's k-th column: the model's first `columns`, then the
// delay's.
Eigen::Index timed_index(Eigen::Index k, Eigen::Index columns) {
    return k < columns ? k : State::timed_p - 1;
}

}  // namespace

// F_aligned(t) = F_log(t + tau): the filtered force at k + tau/T by the cubic through its four neighbouring samples
// (Lagrange), held at the buffer's ends (only the core's rows are used, and tau is far inside the filter margin).
void State::shift_force(std::size_t count) {
    const double shift = options_.drive_delay_s / dt_;
    const auto last = static_cast<std::ptrdiff_t>(count) - 1;
    const auto at = [&](std::ptrdiff_t i) { return ff_[static_cast<std::size_t>(std::clamp<std::ptrdiff_t>(i, 0, last))]; };
    for (std::size_t k = 0; k < count; ++k) {
        const double u = static_cast<double>(k) + shift;
        const double floor = std::floor(u);
        const double f = u - floor;
        const auto i = static_cast<std::ptrdiff_t>(floor);
        const double w0 = -f * (f - 1.0) * (f - 2.0) / 6.0;
        const double w1 = (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0;
        const double w2 = -(f + 1.0) * f * (f - 2.0) / 2.0;
        const double w3 = (f + 1.0) * f * (f - 1.0) / 6.0;
        shifted_[k] = w0 * at(i - 1) + w1 * at(i) + w2 * at(i + 1) + w3 * at(i + 2);
    }
    std::copy_n(shifted_.begin(), count, ff_.begin());
}

// The delay's column is -F', the derivative of the force, but of the model's force, Phi' theta (theta the pooled
// estimate, or the window's own before there is one): the logged force's own derivative carries its noise, amplified
// by the differentiation, and a regressor with noise in it gives a coefficient shrunk towards zero (errors in
// variables: on a production trace with the current 0.5 ms late, 0.15 ms). The model's derivative is x''' and the
// filtered sgn's, from the position alone (x'' is its own column's: B x'' moves into M, the known M - tau*B).
State::TimedSums State::timed_sums(std::size_t rows, bool weighted, const Vec& theta) {
    TimedSums sums;
    Eigen::Matrix<double, timed_p, 1> phi;
    for (std::size_t k = 0; k < rows; ++k) {
        double* row = rows_.data() + k * row_stride;
        row[max_p + 1] = -(theta(0) * row[max_p + 2] + theta(1) * row[0] + theta(2) * row[max_p + 3]);
        const double w = weighted ? weights_[k] : 1.0;
        if (w == 0.0) continue;
        for (Eigen::Index i = 0; i < max_p; ++i) phi(i) = row[i];
        phi(max_p) = row[max_p + 1];
        sums.h.noalias() += w * phi * phi.transpose();
        sums.c.noalias() += (w * row[max_p]) * phi;
    }
    return sums;
}

void State::pool_timed(const TimedSums& window) {
    const double lambda = options_.forgetting;
    if (lambda < 1.0) {
        timed_pool_.h *= lambda;
        timed_pool_.c *= lambda;
        timed_cc_ *= lambda * lambda;
        for (auto& m : timed_cH_) m *= lambda * lambda;
        for (auto& row : timed_HH_)
            for (auto& m : row) m *= lambda * lambda;
    }
    timed_pool_.h += window.h;
    timed_pool_.c += window.c;
    timed_cc_.noalias() += window.c * window.c.transpose();
    for (std::size_t i = 0; i < static_cast<std::size_t>(timed_p); ++i) {
        timed_cH_[i] += window.c(static_cast<Eigen::Index>(i)) * window.h;
        for (std::size_t j = 0; j < static_cast<std::size_t>(timed_p); ++j)
            timed_HH_[i][j] += window.h(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) * window.h;
    }
}

// The delay as one more parameter of the model of the leading `columns` columns, from the timed pool: the delay's
// estimate and standard error, and how the model's estimates move with it. Its standard error is the clusters'
// sandwich (CR1) of the model with the delay, but never below the model-based one (s^2 kappa H^-1): windows that are
// replicas of one move (the drilling program's rapids) give scores nearly along one direction, a sandwich of nearly
// rank one, and a standard error that says more than the data do.
State::TimedFit State::timed_fit(std::size_t columns) const {
    using Small = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, timed_p, timed_p>;
    using SmallVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, timed_p, 1>;
    const auto m = static_cast<Eigen::Index>(columns);
    const Eigen::Index n = m + 1;
    TimedFit fit;
    fit.columns = columns;
    Small h(n, n);
    SmallVec c(n);
    for (Eigen::Index i = 0; i < n; ++i) {
        c(i) = timed_pool_.c(timed_index(i, m));
        for (Eigen::Index j = 0; j < n; ++j) h(i, j) = timed_pool_.h(timed_index(i, m), timed_index(j, m));
    }
    const SmallVec scale = h.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
    const Small scaled = scale.asDiagonal() * h * scale.asDiagonal();
    const Eigen::LDLT<Small> ldlt(scaled);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-10 * ldlt.vectorD().maxCoeff())) return fit;
    const Small h_inverse = scale.asDiagonal() * ldlt.solve(Small::Identity(n, n)) * scale.asDiagonal();
    const SmallVec theta = h_inverse * c;
    // the clusters' meat of the delay's score at theta: sum_w g_w g_w^T (its last entry), g_w = c_w - H_w theta, and
    // the delay's row of H^-1: var(tau) = u^T meat u with u = (H^-1)_{tau,.}
    const SmallVec u = h_inverse.col(m);
    double meat = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
        const auto ii = static_cast<std::size_t>(timed_index(i, m));
        for (Eigen::Index j = 0; j < n; ++j) {
            const auto jj = static_cast<std::size_t>(timed_index(j, m));
            double cross_ij = 0.0, cross_ji = 0.0, quadratic = 0.0;
            for (Eigen::Index k = 0; k < n; ++k) {
                const Eigen::Index kk = timed_index(k, m);
                cross_ij += timed_cH_[ii](static_cast<Eigen::Index>(jj), kk) * theta(k);
                cross_ji += timed_cH_[jj](static_cast<Eigen::Index>(ii), kk) * theta(k);
                for (Eigen::Index l = 0; l < n; ++l)
                    quadratic += theta(k) * theta(l) *
                                 timed_HH_[ii][static_cast<std::size_t>(kk)](static_cast<Eigen::Index>(jj),
                                                                             timed_index(l, m));
            }
            const double g = timed_cc_(static_cast<Eigen::Index>(ii), static_cast<Eigen::Index>(jj)) - cross_ij -
                             cross_ji + quadratic;
            meat += u(i) * g * u(j);
        }
    }
    const double clusters = forgotten_windows_;
    const auto parameters = static_cast<double>(n);
    double variance = clusters >= parameters + 2.0 ? meat * clusters / (clusters - parameters) : 0.0;
    const double residual_variance = sum_scale_sq_ / forgotten_windows_;
    variance = std::max(variance, residual_variance * std::max(1.0, 0.5 / (dt_ * cutoff_hz_)) * h_inverse(m, m));
    fit.valid = variance > 0.0 && std::isfinite(variance);
    fit.delay = theta(m);
    fit.standard_error = std::sqrt(variance);
    // d theta / d tau = -H_mm^-1 h_m,tau (Frisch-Waugh: the joint fit's theta is the model's plus tau times it), and
    // how much of the delay's column the model's columns explain (near 1: a shift in time is a change of M, B, F_C)
    const Small h_model = h.topLeftCorner(m, m);
    const SmallVec h_delay = h.col(m).head(m);
    const SmallVec solved = h_model.ldlt().solve(h_delay);
    fit.sensitivity = Vec(-solved);
    fit.correlation = std::sqrt(std::clamp(h_delay.dot(solved) / h(m, m), 0.0, 1.0));
    return fit;
}

// The delay left beyond the applied one, from the pool: its estimate, standard error and Wald statistic. Where the
// delay is significant, plausible and separable from the model's parameters, the estimate is the model with the
// delay's (to first order; scan applies it exactly), and since the delay is then known only to its standard error,
// the covariance of M, B and F_C takes in s s^T var(tau), s their sensitivity to it.
void State::estimate_timing(OnlineEstimate& e, Vec& theta, Mat& covariance) const {
    e.delay_applied_s = options_.drive_delay_s;
    e.delay_given = !options_.estimate_delay && options_.drive_delay_s != 0.0;
    e.delay_threshold = two_sided_quantile(options_.offset_test_level);
    if (!options_.estimate_delay) {
        e.delay_verdict = "not estimated (--delay none or a given delay)";
        return;
    }
    const TimedFit fit = timed_fit(static_cast<std::size_t>(theta.size()));
    if (!fit.valid) {
        e.delay_verdict = "not estimable from the pooled windows";
        return;
    }
    e.delay_residual_s = fit.delay;
    e.delay_standard_error_s = fit.standard_error;
    e.delay_statistic = std::abs(fit.delay) / fit.standard_error;
    e.delay_sensitivity = fit.sensitivity;
    const bool significant = *e.delay_statistic > e.delay_threshold;
    const double total = e.delay_applied_s + fit.delay;
    if (!significant) {
        e.delay_verdict = "not significant";
    } else if (std::abs(total) > options_.max_delay_s) {
        e.delay_verdict = fmt::format("{:.3g} ms is beyond +-{:g} ms: not a timing offset within the servo cycle",
                                      total * 1e3, options_.max_delay_s * 1e3);
    } else if (fit.correlation > 0.999) {
        e.delay_verdict = fmt::format(
            "not separable from the model's parameters on these windows (correlated {:.4f} with them)",
            fit.correlation);
    } else {
        theta += fit.delay * fit.sensitivity;
        e.delay_corrected = true;
        e.delay_verdict = "taken: the estimate is of the model with the delay (to first order)";
    }
    // a delay taken from the data is known to its standard error, and M, B and F_C move with it; one that is not
    // significant is not applied, as the offset that is not taken: the estimate is then of the model without it,
    // whose standard errors hold where the drive signal is on time (on the example programs the scatter of B over
    // seeds was 0.42-0.62 of standard errors that took in the delay's)
    if (e.delay_corrected || e.delay_applied_s != 0.0)
        covariance += (fit.standard_error * fit.standard_error) * fit.sensitivity * fit.sensitivity.transpose();
}

}  // namespace feedid
