// The online identifier's estimate: theta = R^-1 z with the cluster covariance from the moment sums (or the
// model-based one for few windows), and why the pool gives no value when it does not.

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/core.h>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "feedid/core/parameters.hpp"
#include "online_state.hpp"

namespace feedid {

using State = OnlineIdentifier::State;

namespace {

// The two-sided standard normal quantile of a test level: z with erfc(z / sqrt 2) = level (bisection).
double normal_quantile(double level) {
    double low = 0.0;
    double high = 40.0;
    for (int k = 0; k < 100; ++k) {
        const double middle = 0.5 * (low + high);
        (std::erfc(middle / std::sqrt(2.0)) > level ? low : high) = middle;
    }
    return 0.5 * (low + high);
}

// The symmetric square root of a symmetric positive definite matrix, or of its inverse; its eigenvalues clamped below
// at `floor` times the largest.
State::Mat symmetric_root(const State::Mat& a, bool inverse, double floor = 0.0) {
    const Eigen::SelfAdjointEigenSolver<State::Mat> eigen(a);
    const double top = eigen.eigenvalues().maxCoeff();
    State::Vec root = eigen.eigenvalues().cwiseMax(floor * top).cwiseSqrt();
    if (inverse) root = root.cwiseInverse();
    return eigen.eigenvectors() * root.asDiagonal() * eigen.eigenvectors().transpose();
}

// The clusters' sandwich H^-1 M H^-1 corrected for the bias of scores taken at the pooled estimate. Where each window's
// score has the covariance s^2 H_w (the working model: the windows' residuals alike), E[M] = s^2 (H - Q) with
// Q = sum_w H_w H^-1 H_w (each window's leverage on the pooled estimate), against the s^2 H that the sandwich needs:
// M is taken to A M A^T with A (H - Q) A^T = H, A = H^1/2 C^-1/2 H^-1/2, C = H^-1/2 (H - Q) H^-1/2, so that the
// covariance is S M S, S = H^-1/2 C^-1/2 H^-1/2, unbiased under the working model whatever the windows' leverages,
// and still the clusters' where the residuals are not alike. With G windows of equal information Q = H / G, the
// scalar G / (G - 1); the G / (G - p) used before over-corrected by (G - 1) / (G - p): 1.6 in variance on the contour
// program's Z axis (9 windows, p = 4), whose B and F_C came out with standard errors 1.6 times their scatter over
// 30 seeds. Then pooled with the model-based covariance by degrees of freedom, ((G - p) V_cluster + p V_model) / G
// (the model-based one weighs as much as p windows; the clusters take over as the windows grow in number): corrected
// exactly, a variance from the clusters has about G - p degrees of freedom, and from few of them a standard error is
// often far off. The contour's Z with the servo at 8 kHz (seed 2, 9 windows) gave M 90.112 kg with a cluster standard
// error of 0.026 against a model-based 0.085 (4.4 of the one off the truth, 1.3 of the other), the pocket's Z (6
// windows) a scatter over 10 seeds up to 1.55 of the mean standard error; CR1's G / (G - p) (1.8 and 3) hid both.
// Computed on the matrices scaled to a unit diagonal (the parameters' units differ by orders).
State::Mat bias_corrected_sandwich(const State::Mat& h, const State::Mat& q, const State::Mat& meat) {
    const State::Vec d = h.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
    const State::Mat hs = d.asDiagonal() * h * d.asDiagonal();
    const State::Mat qs = d.asDiagonal() * q * d.asDiagonal();
    const State::Mat h_half_inverse = symmetric_root(hs, true);
    const State::Mat c = h_half_inverse * (hs - qs) * h_half_inverse;
    // a window that holds nearly all the information in a direction (leverage near 1) leaves no scatter between
    // windows to tell its noise by there: its inflation is bounded (C's eigenvalues at 1e-3: at most 32 times)
    const State::Mat s = h_half_inverse * symmetric_root(0.5 * (c + c.transpose()), true, 1e-3) * h_half_inverse;
    const State::Mat scaled = s * (d.asDiagonal() * meat * d.asDiagonal()) * s;
    return d.asDiagonal() * scaled * d.asDiagonal();
}

}  // namespace

// Q = sum_w H_w H^-1 H_w of the leading p columns, from the moment sums (sum_HH_[i][j] = sum_w H_w[i][j] H_w):
// Q(i, k) = sum_{j,l} H^-1(j, l) sum_HH_[i][j](l, k).
State::Mat State::clusters_leverage(const Mat& h_inverse, std::size_t columns) const {
    const auto p = static_cast<Eigen::Index>(columns);
    Mat q = Mat::Zero(p, p);
    for (Eigen::Index i = 0; i < p; ++i)
        for (Eigen::Index j = 0; j < p; ++j)
            q.row(i) += (h_inverse.row(j) *
                         sum_HH_[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)].topLeftCorner(p, p));
    return q;
}

std::string State::no_value_reason() const {
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

// The pooled fit of the leading p columns. The pool's R is upper triangular, so its leading p x p block and z's
// first p entries are the square-root information of the model of those columns alone (R11^T R11 = H11,
// R11^T z1 = c1), as the moment sums' leading blocks are its cluster moments: the model without the offset is read
// from the same pool as the one with it.
State::PooledFit State::pooled_fit(std::size_t columns) const {
    const auto p = static_cast<Eigen::Index>(columns);
    PooledFit fit;
    double largest = 0.0;
    double smallest = std::numeric_limits<double>::max();
    for (Eigen::Index i = 0; i < p; ++i) {
        largest = std::max(largest, std::abs(r_z_(i, i)));
        smallest = std::min(smallest, std::abs(r_z_(i, i)));
    }
    fit.separable = smallest > 1e-9 * largest;
    if (!fit.separable) return fit;
    const Mat r = r_z_.topLeftCorner(p, p);
    fit.theta = r.triangularView<Eigen::Upper>().solve(r_z_.col(max_p).head(p));
    const Vec& theta = fit.theta;
    const Mat h = r.transpose() * r;
    // the clusters' meat at the final theta: sum_w (c_w - H_w theta)(c_w - H_w theta)^T from the moment sums
    Mat cross = Mat::Zero(p, p);      // sum_w c_w (H_w theta)^T
    Mat quadratic = Mat::Zero(p, p);  // sum_w (H_w theta)(H_w theta)^T
    for (Eigen::Index i = 0; i < p; ++i) {
        cross.row(i) = (sum_cH_[static_cast<std::size_t>(i)].topLeftCorner(p, p) * theta).transpose();
        for (Eigen::Index j = 0; j < p; ++j)
            quadratic.row(i) +=
                theta(j) *
                (sum_HH_[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)].topLeftCorner(p, p) * theta)
                    .transpose();
    }
    Mat meat = sum_cc_.topLeftCorner(p, p) - cross - cross.transpose() + quadratic;
    const double clusters = forgotten_windows_;
    const auto parameters = static_cast<double>(columns);
    const Mat h_inverse = h.inverse();
    if (options_.forgetting < 1.0) {
        // the small-sample factor G / (G - p) (CR1): with forgetting the windows weigh unequally, and the exact
        // correction below is not derived for that
        if (clusters > parameters) meat *= clusters / (clusters - parameters);
        fit.covariance = h_inverse * meat * h_inverse;
    } else {
        fit.covariance = bias_corrected_sandwich(h, clusters_leverage(h_inverse, columns), meat);
    }
    // the model-based covariance s^2 kappa H^-1: the residuals' variance times their integrated autocorrelation after
    // the zero-phase low-pass (about fs / (2 f_c) samples for white noise). With fewer than p + 2 windows the cluster
    // covariance is not honest (its meat has the rank of the number of windows): the model-based one instead. Else
    // the two pooled by their degrees of freedom (see bias_corrected_sandwich)
    const double variance = sum_scale_sq_ / forgotten_windows_;
    const Mat model = (variance * std::max(1.0, 0.5 / (dt_ * cutoff_hz_))) * h_inverse;
    fit.model_based = clusters < parameters + 2.0;
    if (fit.model_based) {
        fit.covariance = model;
    } else if (options_.forgetting >= 1.0) {
        fit.covariance = ((clusters - parameters) * fit.covariance + parameters * model) / clusters;
    }
    return fit;
}

std::optional<double> State::offset_statistic(const PooledFit& full) const {
    if (!full.separable) return std::nullopt;
    const double variance = full.covariance(3, 3);
    const double coulomb_variance = full.covariance(2, 2);
    if (!(variance > 0.0) || !(coulomb_variance > 0.0)) return std::nullopt;
    // F_0 and F_C are one number on moves in one direction (sgn(x') constant): the windows must separate them
    const double correlation = full.covariance(2, 3) / std::sqrt(variance * coulomb_variance);
    if (!(std::abs(correlation) < 0.999)) return std::nullopt;
    return std::abs(full.theta(3)) / std::sqrt(variance);
}

OnlineEstimate State::estimate(bool select_offset) const {
    OnlineEstimate e;
    e.windows = counts_;
    e.changes = changes_;
    e.samples = pushed_;
    e.rows_used = rows_used_;
    e.mass_reason = no_value_reason();
    if (!e.mass_reason.empty()) {
        e.friction_reason = e.mass_reason;
        e.stribeck_reason = e.mass_reason;
        e.offset_in_model = options_.offset;
        return e;
    }
    e.residual_std = std::sqrt(sum_scale_sq_ / forgotten_windows_);
    describe_offset(e, select_offset);
    const std::size_t columns = e.offset_in_model ? max_p : 3;
    const auto p = static_cast<Eigen::Index>(columns);
    const PooledFit fit = pooled_fit(columns);
    if (!fit.separable) {
        e.mass_reason = "the qualified windows do not separate the model's parameters (one speed, one direction)";
        e.friction_reason = e.stribeck_reason = e.mass_reason;
        return e;
    }
    Vec theta = fit.theta;
    Mat covariance = fit.covariance;
    estimate_timing(e, theta, covariance);
    e.covariance = covariance;
    const Vec se = e.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    e.information = e.covariance.diagonal().cwiseInverse();
    const Mat scaled_information = se.asDiagonal() * e.covariance.inverse() * se.asDiagonal();
    e.information_eigenvalues =
        Eigen::SelfAdjointEigenSolver<Mat>(scaled_information, Eigen::EigenvaluesOnly).eigenvalues();
    e.mass = Estimate::of(theta(0), se(0));
    e.viscous = Estimate::of(theta(1), se(1));
    e.coulomb = Estimate::of(theta(2), se(2));
    if (p == max_p) e.offset = Estimate::of(theta(3), se(3));
    if (fit.model_based)
        e.friction_reason = fmt::format(
            "only {} window(s) qualified: standard errors model-based (residual scale and the filter's correlation), "
            "not from the scatter between windows ({} or more)",
            counts_.qualified(), columns + 2);
    estimate_stribeck(theta, se, e);
    judge_plausibility(e, select_offset);
    return e;
}

// Evidence before numbers: too few rows for a value, a value the physics forbids, or a Coulomb friction the windows
// cannot tell from a constant force (a weight): null with the reason, never printed.
void State::judge_plausibility(OnlineEstimate& e, bool select_offset) const {
    const ParameterNaming naming{options_.rotary};
    const auto refuse = [&](Estimate& value, std::string& reason, const std::string& why) {
        value = Estimate{};
        reason = reason.empty() ? why : reason + "; " + why;
    };
    if (rows_used_ < options_.minimum_rows) {
        const std::string why = fmt::format(
            "only {} step-1 rows qualified ({} or more needed for a value: --window, a longer trace)", rows_used_,
            options_.minimum_rows);
        for (Estimate* value : {&e.mass, &e.viscous, &e.coulomb, &e.offset, &e.breakaway, &e.stribeck_velocity})
            *value = Estimate{};
        e.mass_reason = e.friction_reason = e.stribeck_reason = why;
        return;
    }
    if (!e.offset_in_model && select_offset && !e.offset_statistic) {
        e.aliased_reason = fmt::format(
            "{} not determined: the qualified windows move in one direction only, where a constant force (the weight "
            "a vertical axis carries, a sensor's zero) and the Coulomb friction are one number; windows that move both "
            "ways separate them",
            ParameterNaming::symbol(Term::coulomb, Direction::both));
        refuse(e.coulomb, e.friction_reason, e.aliased_reason);
        refuse(e.breakaway, e.stribeck_reason, e.aliased_reason);
        e.stribeck_velocity = Estimate{};
    }
    if (e.mass.value && !(*e.mass.value > 0.0)) {
        e.mass_reason = fmt::format("the pooled {} is {:.4g} {}: not a mass; the windows do not determine it",
                                    ParameterNaming::symbol(Term::mass, Direction::both), *e.mass.value, naming.unit(Term::mass));
        e.mass = Estimate{};
    }
    if (e.coulomb.value && !(*e.coulomb.value > 0.0))
        refuse(e.coulomb, e.friction_reason,
               fmt::format("the pooled {} is {:.4g} {}: a Coulomb friction of the wrong sign for this model",
                           ParameterNaming::symbol(Term::coulomb, Direction::both), *e.coulomb.value, naming.unit(Term::coulomb)));
    if (e.viscous.value && e.viscous.standard_error && *e.viscous.value < -2.0 * *e.viscous.standard_error)
        refuse(e.viscous, e.friction_reason,
               fmt::format("the pooled {} is {:.4g} {}, negative beyond twice its standard error",
                           ParameterNaming::symbol(Term::viscous, Direction::both), *e.viscous.value, naming.unit(Term::viscous)));
}

ModelChoice model_choice_of(const OnlineEstimate& e) {
    ModelChoice choice;
    choice.offset = e.offset_in_model;
    choice.automatic = e.offset_selected;
    ModelCandidate candidate;
    candidate.name = "offset";
    candidate.tested = "F_0";
    candidate.estimate = e.offset_in_model && e.offset.value ? e.offset.value : e.offset_estimate;
    candidate.standard_error =
        e.offset_in_model && e.offset.standard_error ? e.offset.standard_error : e.offset_standard_error;
    candidate.statistic = e.offset_statistic;
    candidate.threshold = e.offset_threshold;
    candidate.taken = e.offset_in_model;
    candidate.verdict = e.offset_verdict;
    choice.candidates.push_back(std::move(candidate));
    choice.aliased_friction = e.aliased_reason;
    // the timing: the delay applied to every window plus what the pool says is left (scan's timing pass applies the
    // estimated one, so that what is left is not significant)
    const double total = e.delay_applied_s + e.delay_residual_s.value_or(0.0);
    if (e.delay_residual_s || e.delay_applied_s != 0.0) choice.delay_s = total;
    choice.delay_standard_error = e.delay_standard_error_s;
    choice.delay_applied = e.delay_applied_s != 0.0 || e.delay_corrected;
    choice.delay_uncertain = e.delay_statistic && *e.delay_statistic <= e.delay_threshold;
    choice.delay_source = e.delay_given ? "given" : choice.delay_applied ? "estimated" : "";
    if (!e.delay_given) {
        ModelCandidate delay;
        delay.name = "delay";
        delay.tested = "tau";
        if (e.delay_residual_s) delay.estimate = total;
        delay.standard_error = e.delay_standard_error_s;
        delay.statistic = e.delay_statistic;
        delay.threshold = e.delay_threshold;
        delay.taken = choice.delay_applied;
        delay.verdict = e.delay_applied_s != 0.0
                            ? fmt::format("taken: the drive signal read {:.4g} ms later in every window; left beyond it: "
                                          "{}",
                                          e.delay_applied_s * 1e3, e.delay_verdict)
                            : e.delay_verdict;
        choice.candidates.push_back(std::move(delay));
    }
    return choice;
}

// Which model the estimate is of, and why: forced, or the offset's Wald test on the pool of all columns.
void State::describe_offset(OnlineEstimate& e, bool select_offset) const {
    e.offset_threshold = normal_quantile(options_.offset_test_level);
    e.offset_in_model = p_ == max_p;
    e.offset_selected = select_offset && !options_.offset;
    if (options_.offset) {
        e.offset_verdict = "forced (--offset)";
        return;
    }
    const PooledFit full = pooled_fit(max_p);
    e.offset_statistic = offset_statistic(full);
    if (full.separable) {
        e.offset_estimate = full.theta(3);
        e.offset_standard_error = std::sqrt(std::max(0.0, full.covariance(3, 3)));
    }
    e.offset_in_model = select_offset && e.offset_statistic && *e.offset_statistic > e.offset_threshold;
    e.offset_judged = options_.judge_with_offset;
    const char* judged = options_.judge_with_offset ? " (windows judged by the model with the offset)" : "";
    if (!select_offset) {
        e.offset_verdict = "not tested (--no-offset)";
    } else if (e.offset_in_model) {
        e.offset_verdict =
            fmt::format("taken: |F_0| / SE = {:.3g} > {:.3g}{}", *e.offset_statistic, e.offset_threshold, judged);
    } else if (!e.offset_statistic) {
        e.offset_verdict = fmt::format(
            "not testable: the qualified windows do not separate a constant force from the Coulomb friction (moves "
            "in one direction){}",
            judged);
    } else {
        e.offset_verdict =
            fmt::format("not taken: |F_0| / SE = {:.3g} <= {:.3g}{}", *e.offset_statistic, e.offset_threshold, judged);
    }
}

}  // namespace feedid
