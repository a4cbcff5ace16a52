#include "feedid/identify/stribeck_fit.hpp"

#include "feedid/numeric/least_squares.hpp"

#include "feedid/model/friction.hpp"
#include "feedid/core/parameters.hpp"

#include <cmath>
#include <limits>

#include <Eigen/Dense>
#include <unsupported/Eigen/LevenbergMarquardt>

namespace feedid::detail {

LogLinearStribeck fit_log_linear(const FitSamples& samples, double mass, double viscous, double coulomb, double offset,
                                 double noise_level, const RlsOptions& rls_options) {
    return fit_log_linear_over(
        samples.size(),
        [&](std::size_t k) {
            return std::array<double, 3>{samples.acceleration[k], samples.velocity[k], samples.force[k]};
        },
        mass, viscous, coulomb, offset, noise_level, rls_options);
}

CurveLayout::CurveLayout(const CurveModel& model) {
    int next = 0;
    if (model.mass) mass = next++;
    const int groups = model.asymmetric ? 2 : 1;
    for (int g = 0; g < groups; ++g) {
        viscous[g] = next++;
        coulomb[g] = next++;
        const bool stribeck = g == 0 ? model.stribeck_forward : model.stribeck_reverse;
        if (stribeck) {
            delta[g] = next++;
            log_vs[g] = next++;
        }
    }
    if (model.offset) offset = next++;
    size = next;
}

double CurveLayout::friction(const Eigen::VectorXd& x, double velocity, bool asymmetric) const {
    const int g = group(velocity, asymmetric);
    const bool stribeck = delta[g] >= 0;
    const double rise = stribeck ? x(delta[g]) : 0.0;
    const double inverse_vs = stribeck ? std::exp(-x(log_vs[g])) : 0.0;
    const FrictionLaw law{x(viscous[g]), x(coulomb[g]), rise, inverse_vs};
    double f = sign(velocity) * law.magnitude(std::abs(velocity));
    if (offset >= 0) f += x(offset);
    return f;
}

namespace {

struct CurveFunctor : Eigen::DenseFunctor<double> {
    CurveFunctor(const FitSamples& samples, const CurveModel& model, const CurveLayout& layout)
        : Eigen::DenseFunctor<double>(layout.size, static_cast<int>(samples.size())),
          samples_(samples),
          model_(model),
          layout_(layout) {}

    int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& residual) const {
        for (std::size_t k = 0; k < samples_.size(); ++k) {
            residual(static_cast<Eigen::Index>(k)) = predict(x, k) - samples_.force[k];
        }
        return 0;
    }

    int df(const Eigen::VectorXd& x, Eigen::MatrixXd& jacobian) const {
        jacobian.setZero();
        for (std::size_t k = 0; k < samples_.size(); ++k) {
            const auto row = static_cast<Eigen::Index>(k);
            const double v = samples_.velocity[k];
            const double s = sign(v);
            const int g = layout_.group(v, model_.asymmetric);
            if (layout_.mass >= 0) jacobian(row, layout_.mass) = samples_.acceleration[k];
            jacobian(row, layout_.viscous[g]) = v;
            jacobian(row, layout_.coulomb[g]) = s;
            if (layout_.delta[g] >= 0) {
                const double vs = std::exp(x(layout_.log_vs[g]));
                const double decay = std::exp(-std::abs(v) / vs);
                jacobian(row, layout_.delta[g]) = s * decay;
                // d/d(ln v_s) exp(-|v|/v_s) = exp(-|v|/v_s) * |v|/v_s
                jacobian(row, layout_.log_vs[g]) = s * x(layout_.delta[g]) * decay * std::abs(v) / vs;
            }
            if (layout_.offset >= 0) jacobian(row, layout_.offset) = 1.0;
        }
        return 0;
    }

    [[nodiscard]] double predict(const Eigen::VectorXd& x, std::size_t k) const {
        const double inertia = layout_.mass >= 0 ? x(layout_.mass) * samples_.acceleration[k] : 0.0;
        return inertia + layout_.friction(x, samples_.velocity[k], model_.asymmetric);
    }

    const FitSamples& samples_;
    const CurveModel& model_;
    const CurveLayout& layout_;
};

// Variable projection: for fixed v_s per group the model is linear in the rest; solve it by normal equations and
// return the residual sum of squares, filling the linear parameters of x.
double solve_linear_part(const FitSamples& samples, const CurveModel& model, const CurveLayout& layout,
                         Eigen::VectorXd& x) {
    const int p = layout.size;
    Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(p, p);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(p);
    Eigen::VectorXd row(p);
    double yy = 0.0;
    for (std::size_t k = 0; k < samples.size(); ++k) {
        row.setZero();
        const double v = samples.velocity[k];
        const double s = sign(v);
        const int g = layout.group(v, model.asymmetric);
        if (layout.mass >= 0) row(layout.mass) = samples.acceleration[k];
        row(layout.viscous[g]) = v;
        row(layout.coulomb[g]) = s;
        if (layout.delta[g] >= 0) row(layout.delta[g]) = s * std::exp(-std::abs(v) / std::exp(x(layout.log_vs[g])));
        if (layout.offset >= 0) row(layout.offset) = 1.0;
        normal.selfadjointView<Eigen::Lower>().rankUpdate(row);
        rhs += row * samples.force[k];
        yy += samples.force[k] * samples.force[k];
    }
    // the ln v_s entries are not linear parameters: pin them (unit diagonal, zero right-hand side)
    for (int g = 0; g < 2; ++g) {
        if (layout.log_vs[g] >= 0) {
            normal.row(layout.log_vs[g]).setZero();
            normal.col(layout.log_vs[g]).setZero();
            normal(layout.log_vs[g], layout.log_vs[g]) = 1.0;
            rhs(layout.log_vs[g]) = 0.0;
        }
    }
    const Eigen::MatrixXd full = normal.selfadjointView<Eigen::Lower>();
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(full);
    if (ldlt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
    Eigen::VectorXd solution = ldlt.solve(rhs);
    double rss = yy - 2.0 * solution.dot(rhs) + solution.dot(full * solution);
    for (int g = 0; g < 2; ++g) {
        if (layout.log_vs[g] >= 0) solution(layout.log_vs[g]) = x(layout.log_vs[g]);
    }
    x = solution;
    return rss;
}

}  // namespace

namespace {

/// Starting values for Levenberg-Marquardt: a grid search over ln v_s, one group at a time (twice round for two
/// groups), on an evenly spread subsample of at most 20000 samples, with the linear parameters projected out. It only
/// has to find the basin; Levenberg-Marquardt then uses every sample.
Eigen::VectorXd grid_search(const FitSamples& samples, const CurveModel& model, const CurveLayout& layout,
                            double vs_low, double vs_high) {
    constexpr std::size_t coarse_samples = 20000;
    constexpr int grid_points = 41;
    Eigen::VectorXd x = Eigen::VectorXd::Zero(layout.size);
    const double mid = std::sqrt(vs_low * vs_high);
    for (int g = 0; g < 2; ++g) {
        if (layout.log_vs[g] >= 0) x(layout.log_vs[g]) = std::log(mid);
    }
    FitSamples coarse;
    const std::size_t coarse_stride = std::max<std::size_t>(1, samples.size() / coarse_samples);
    for (std::size_t k = 0; k < samples.size(); k += coarse_stride) {
        coarse.push(samples.acceleration[k], samples.velocity[k], samples.force[k], samples.index[k]);
    }
    const int rounds = model.asymmetric ? 2 : 1;
    double best_rss = solve_linear_part(coarse, model, layout, x);
    for (int round = 0; round < rounds; ++round) {
        for (int g = 0; g < 2; ++g) {
            if (layout.log_vs[g] < 0) continue;
            Eigen::VectorXd best = x;
            for (int i = 0; i < grid_points; ++i) {
                Eigen::VectorXd trial = x;
                trial(layout.log_vs[g]) =
                    std::log(vs_low) + (std::log(vs_high) - std::log(vs_low)) * i / (grid_points - 1.0);
                const double rss = solve_linear_part(coarse, model, layout, trial);
                if (rss < best_rss) {
                    best_rss = rss;
                    best = trial;
                }
            }
            x = best;
        }
    }
    return x;
}

/// Residual statistics and the covariance sigma^2 (J^T J)^-1 at the solution x (with ln v_s); the v_s entries are
/// turned into v_s by the delta method.
void fill_statistics(const FitSamples& samples, const CurveModel& model, const CurveLayout& layout,
                     const Eigen::VectorXd& x, CurveFit& fit) {
    const int p = layout.size;
    CurveFunctor functor(samples, model, layout);
    Eigen::VectorXd residual(static_cast<Eigen::Index>(samples.size()));
    functor(x, residual);
    Eigen::MatrixXd jacobian(static_cast<Eigen::Index>(samples.size()), p);
    functor.df(x, jacobian);
    const double rss = residual.squaredNorm();
    double yy = 0.0;
    for (const double f : samples.force) yy += f * f;
    fit.residual_std = std::sqrt(rss / static_cast<double>(samples.size() - static_cast<std::size_t>(p)));
    fit.relative_error_pct = yy > 0.0 ? 100.0 * std::sqrt(rss / yy) : 0.0;
    const Eigen::MatrixXd information = jacobian.transpose() * jacobian;
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(information);
    fit.covariance = Eigen::MatrixXd::Constant(p, p, std::numeric_limits<double>::infinity());
    if (qr.rank() == p) {
        const Eigen::MatrixXd inverse = qr.inverse();
        fit.covariance =
            samples.correlation_block > 1
                ? Eigen::MatrixXd(inverse *
                                  long_run_covariance(jacobian, residual, samples.index, samples.correlation_block) *
                                  inverse)
                : Eigen::MatrixXd(fit.residual_std * fit.residual_std * inverse);
    }
    fit.parameters = x;
    for (int g = 0; g < 2; ++g) {
        if (layout.log_vs[g] >= 0) {
            // delta method: v_s = exp(ln v_s), so its row and column of the covariance scale by v_s
            const double vs = std::exp(x(layout.log_vs[g]));
            fit.parameters(layout.log_vs[g]) = vs;
            fit.covariance.row(layout.log_vs[g]) *= vs;
            fit.covariance.col(layout.log_vs[g]) *= vs;
        }
    }
    fit.standard_errors = fit.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
}

}  // namespace

Eigen::VectorXd curve_residuals(const FitSamples& samples, const CurveModel& model, const Eigen::VectorXd& x) {
    const CurveLayout layout(model);
    Eigen::VectorXd residual(static_cast<Eigen::Index>(samples.size()));
    CurveFunctor(samples, model, layout)(x, residual);
    return residual;
}

Eigen::MatrixXd curve_jacobian(const FitSamples& samples, const CurveModel& model, const Eigen::VectorXd& x) {
    const CurveLayout layout(model);
    Eigen::MatrixXd jacobian(static_cast<Eigen::Index>(samples.size()), layout.size);
    CurveFunctor(samples, model, layout).df(x, jacobian);
    return jacobian;
}

CurveFit fit_curve(const FitSamples& samples, const CurveModel& model, double vs_low, double vs_high) {
    const CurveLayout layout(model);
    CurveFit fit;
    fit.samples = samples.size();
    if (samples.size() <= static_cast<std::size_t>(layout.size) + 2 || !(vs_low > 0.0) || !(vs_high > vs_low)) {
        return fit;
    }
    Eigen::VectorXd x = grid_search(samples, model, layout, vs_low, vs_high);
    if (layout.log_vs[0] < 0 && layout.log_vs[1] < 0) {
        // linear model: the projection is the answer
        (void)solve_linear_part(samples, model, layout, x);
        fit.converged = true;
    } else {
        CurveFunctor functor(samples, model, layout);
        Eigen::LevenbergMarquardt<CurveFunctor> solver(functor);
        solver.setMaxfev(400);
        const auto status = solver.minimize(x);
        fit.iterations = static_cast<int>(solver.nfev());
        fit.converged = status == Eigen::LevenbergMarquardtSpace::RelativeReductionTooSmall ||
                        status == Eigen::LevenbergMarquardtSpace::RelativeErrorTooSmall ||
                        status == Eigen::LevenbergMarquardtSpace::RelativeErrorAndReductionTooSmall ||
                        status == Eigen::LevenbergMarquardtSpace::CosinusTooSmall;
        if (!x.allFinite()) fit.converged = false;
    }
    fill_statistics(samples, model, layout, x, fit);
    return fit;
}

}  // namespace feedid::detail
