// The online identifier's estimate: theta = R^-1 z with the cluster covariance from the moment sums (or the
// model-based one for few windows), and why the pool gives no value when it does not.

#include <cmath>

#include <fmt/core.h>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "online_state.hpp"

namespace feedid {

using State = OnlineIdentifier::State;

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

OnlineEstimate State::estimate() const {
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

}  // namespace feedid
