#include "feedid/step1.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "feedid/signal.hpp"

namespace feedid {

std::vector<RegressorColumn> linear_columns(FrictionModelKind model, bool offset) {
    std::vector<RegressorColumn> columns{{Term::mass, Direction::both}};
    if (model == FrictionModelKind::asymmetric) {
        columns.push_back({Term::viscous, Direction::forward});
        columns.push_back({Term::viscous, Direction::reverse});
        columns.push_back({Term::coulomb, Direction::forward});
        columns.push_back({Term::coulomb, Direction::reverse});
    } else {
        columns.push_back({Term::viscous, Direction::both});
        columns.push_back({Term::coulomb, Direction::both});
    }
    if (offset) columns.push_back({Term::offset, Direction::both});
    return columns;
}

namespace {

/// RegressorColumn c of eq. (11) at every sample of (a, v).
std::vector<double> regressor_column(const RegressorColumn& column, std::span<const double> a,
                                     std::span<const double> v) {
    std::vector<double> out(v.size());
    for (std::size_t k = 0; k < v.size(); ++k) {
        switch (column.term) {
            case Term::mass: out[k] = a[k]; break;
            case Term::viscous:
                out[k] = column.direction == Direction::forward   ? std::max(v[k], 0.0)
                         : column.direction == Direction::reverse ? std::min(v[k], 0.0)
                                                                  : v[k];
                break;
            case Term::coulomb:
                out[k] = column.direction == Direction::forward   ? (v[k] > 0.0 ? 1.0 : 0.0)
                         : column.direction == Direction::reverse ? (v[k] < 0.0 ? -1.0 : 0.0)
                                                                  : sign(v[k]);
                break;
            default: out[k] = 1.0; break;
        }
    }
    return out;
}

template <int N>
RlsRun run_rls_fixed(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const std::vector<double>& time,
                     const RlsOptions& options, const Eigen::VectorXd& tolerance, std::size_t history_points) {
    Rls<N> rls(options);
    const auto n = static_cast<std::size_t>(phi.rows());
    const std::size_t stride = std::max<std::size_t>(1, n / history_points);
    std::vector<Eigen::VectorXd> trajectory;
    trajectory.reserve(n / stride + 2);
    std::vector<std::size_t> trajectory_index;
    typename Rls<N>::Vector row;
    for (std::size_t k = 0; k < n; ++k) {
        row = phi.row(static_cast<Eigen::Index>(k)).transpose();
        rls.update(row, y(static_cast<Eigen::Index>(k)));
        if (k % stride == 0 || k + 1 == n) {
            trajectory.emplace_back(rls.estimate());
            trajectory_index.push_back(k);
        }
    }
    RlsRun run;
    run.final_estimate = rls.estimate();
    run.wound_up = rls.wound_up();
    const auto& p = rls.covariance();
    run.covariance_ok = p.allFinite() && (p - p.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * p.cwiseAbs().maxCoeff();
    // Transient: the first point after which every parameter stays within its tolerance of the final estimate.
    std::size_t first_settled = trajectory.size();
    for (std::size_t i = trajectory.size(); i-- > 0;) {
        const Eigen::VectorXd deviation = (trajectory[i] - run.final_estimate).cwiseAbs();
        if ((deviation.array() <= tolerance.array()).all())
            first_settled = i;
        else
            break;
    }
    run.settled = first_settled + 1 < trajectory.size() && first_settled < trajectory.size() * 9 / 10;
    run.settled_index = first_settled < trajectory.size() ? trajectory_index[first_settled] : n;
    // The paper's value: the average of the estimate after the transient (over the thinned trajectory, uniformly
    // spaced in samples).
    if (run.settled) {
        Eigen::VectorXd sum = Eigen::VectorXd::Zero(N);
        for (std::size_t i = first_settled; i < trajectory.size(); ++i) sum += trajectory[i];
        run.averaged = sum / static_cast<double>(trajectory.size() - first_settled);
    } else {
        run.averaged = run.final_estimate;
    }
    for (std::size_t i = 0; i < trajectory.size(); ++i) run.history_time.push_back(time[trajectory_index[i]]);
    run.history = std::move(trajectory);
    run.transient_end_s =
        run.settled_index < time.size() ? time[run.settled_index] : (time.empty() ? 0.0 : time.back());
    return run;
}

}  // namespace

RlsRun run_rls(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const std::vector<double>& time,
               const RlsOptions& options, const Eigen::VectorXd& tolerance, std::size_t history_points) {
    switch (phi.cols()) {
        case 3: return run_rls_fixed<3>(phi, y, time, options, tolerance, history_points);
        case 4: return run_rls_fixed<4>(phi, y, time, options, tolerance, history_points);
        case 5: return run_rls_fixed<5>(phi, y, time, options, tolerance, history_points);
        case 6: return run_rls_fixed<6>(phi, y, time, options, tolerance, history_points);
        default: throw std::logic_error("unsupported RLS size");
    }
}

Regressors build_regressors(const Derivatives& derivatives, FrictionModelKind model, bool offset) {
    Regressors r;
    r.columns = linear_columns(model, offset);
    r.output = derivatives.force;
    const int factor = derivatives.used.decimation;
    const bool decimated = factor > 1;
    const auto& a = decimated ? derivatives.full_rate_acceleration : derivatives.acceleration;
    const auto& v = decimated ? derivatives.full_rate_velocity : derivatives.velocity;
    for (const auto& column : r.columns) {
        std::vector<double> values = regressor_column(column, a, v);
        // every column through the same anti-alias filter, the constant one too: the filter passes a constant scaled
        // by its DC gain squared (-0.1 dB for the order-8 Chebyshev, forwards and backwards), as it scales the force
        if (decimated) values = decimate(values, factor);
        r.values.push_back(std::move(values));
    }
    return r;
}

Eigen::MatrixXd Regressors::matrix(const std::vector<std::size_t>& rows) const {
    Eigen::MatrixXd m(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(columns.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) {
        for (std::size_t c = 0; c < columns.size(); ++c) {
            m(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(c)) = values[c][rows[i]];
        }
    }
    return m;
}

Eigen::VectorXd Regressors::outputs(const std::vector<std::size_t>& rows) const {
    Eigen::VectorXd out(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) out(static_cast<Eigen::Index>(i)) = output[rows[i]];
    return out;
}

double Step1Fit::coefficient(Term term, Direction direction) const {
    for (std::size_t c = 0; c < columns.size(); ++c) {
        if (columns[c].term == term && columns[c].direction == direction) {
            return batch.estimate(static_cast<Eigen::Index>(c));
        }
    }
    return 0.0;
}

namespace {

/// Which parameter is missing its excitation, when the regressors are linearly dependent.
std::string rank_deficiency_message(const Step1Fit& fit, const Eigen::MatrixXd& phi, const Derivatives& derivatives,
                                    bool offset) {
    std::vector<std::string> silent;
    for (std::size_t c = 0; c < fit.columns.size(); ++c) {
        if (phi.col(static_cast<Eigen::Index>(c)).norm() == 0.0) {
            silent.push_back(ParameterNaming::symbol(fit.columns[c].term, fit.columns[c].direction));
        }
    }
    return fmt::format(
        "{}: the step-1 regressors are linearly dependent{}: the data cannot separate the parameters (does the axis "
        "move in both directions{}?)",
        derivatives.source, silent.empty() ? "" : fmt::format(" (no excitation of {})", fmt::join(silent, ", ")),
        offset ? ", and is the offset separable from Coulomb friction" : "");
}

}  // namespace

Step1Fit fit_step1(const Regressors& regressors, const Derivatives& derivatives, const std::vector<std::size_t>& rows,
                   const Step1Options& options) {
    Step1Fit fit;
    fit.columns = regressors.columns;
    fit.samples = rows.size();
    fit.rls_options = options.rls;
    const std::size_t p = fit.columns.size();
    if (rows.size() < options.minimum_samples_per_parameter * p) {
        fit.failure = fmt::format(
            "{}: only {} moving samples fast enough for step 1 (need at least {}): the axis barely moves; record "
            "constant-velocity strokes (see feedid plan)",
            derivatives.source, rows.size(), options.minimum_samples_per_parameter * p);
        return fit;
    }
    const Eigen::MatrixXd phi = regressors.matrix(rows);
    const Eigen::VectorXd y = regressors.outputs(rows);
    fit.batch = solve_least_squares(phi, y);
    for (const auto k : rows)
        fit.max_acceleration = std::max(fit.max_acceleration, std::abs(derivatives.acceleration[k]));
    const bool offset = !fit.columns.empty() && fit.columns.back().term == Term::offset;
    if (fit.batch.rank_deficient) {
        fit.failure = rank_deficiency_message(fit, phi, derivatives, offset);
        return fit;
    }
    // Mass: identifiable only when acceleration explains a significant part of the force.
    const double mass = fit.batch.estimate(0), mass_se = fit.batch.standard_error(0);
    if (!(mass > 0.0) || !(mass_se < options.mass_relative_standard_error * mass)) {
        const ParameterNaming naming{derivatives.rotary};
        fit.mass_unidentifiable = true;
        const std::string why =
            derivatives.travel < options.creep_travel
                ? fmt::format("a micro-step or creep test (the axis travelled {:.3g} {}) cannot determine mass",
                              derivatives.travel * (derivatives.rotary ? 1.0 : 1e6), derivatives.rotary ? "rad" : "um")
                : std::string("the strokes hold too little acceleration against the force's scatter");
        fit.failure = fmt::format(
            "{}: the trace carries no usable mass information: the acceleration (at most {:.3g} {}/s^2 in the samples "
            "used) explains too little of the drive force (estimate {:.4g} +/- {:.2g} {}); {}. Record strokes with "
            "real accelerations and reversals (see feedid plan)",
            derivatives.source, fit.max_acceleration, derivatives.rotary ? "rad" : "m", mass, mass_se,
            naming.unit(Term::mass), why);
        return fit;
    }
    // RLS on the same samples, in time order.
    std::vector<double> time(rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) time[i] = derivatives.time[rows[i]];
    const Eigen::VectorXd tolerance = (fit.batch.estimate.cwiseAbs() * options.rls_settle_fraction)
                                          .cwiseMax(options.rls_settle_standard_errors * fit.batch.standard_error);
    fit.rls = run_rls(phi, y, time, options.rls, tolerance, options.rls_history_points);
    return fit;
}

}  // namespace feedid
