// Identification of the cascaded P-PI gains from a trace (the paper's validation step; its Ref. 6).
//   with a logged velocity command:  v_cmd(k) = K_v*e(k - d) [+ k_ff*x_ref'(k - d)],    e = x_ref - x
//                                    F(k) = L[K_p*e_v + K_i*E_v + c](k),  e_v = v_cmd - v,  E_v = sum(e_v*T)
//   without it (the structure only): F(k) = L[K_p*(K_v*e - v) + K_i*sum(T*(K_v*e - v)) + c](k)
//                                        = L[th1*e + th2*(-v) + th3*sum(T*e) + th4*(-sum(T*v)) + c](k),
//                                    K_v = th1/th2, K_p = th2, K_i = th4   (th3 = K_i*K_v is left free)
// v is the controller's velocity measurement (x_k - x_{k-n})/(n*T); c is the integrator's initial state (it holds a
// weight or an offset); L is what lies between the force command and the logged drive signal: the current loop as
// a first-order lag with a fractional sample of delay,
//   y(k) = a*y(k-1) + (1-a)*((1-mu)*u(k) + mu*u(k-1)),  a = exp(-T/tau),
// which is exact for a lag sampled one integration step after the command. L commutes with the linear regression,
// so it filters every regressor column. The structure (n, reference delay d, tau, mu) is chosen by the smallest
// residual; the gains are then estimated by RLS on the normalised columns, with standard errors from the batch
// least-squares residuals.

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <fmt/core.h>
#include <Eigen/Dense>

#include "feedid/error.hpp"
#include "feedid/gains.hpp"
#include "feedid/least_squares.hpp"

namespace feedid {

std::string GainOptions::validate() const {
    if (velocity_difference_samples && (*velocity_difference_samples < 1 || *velocity_difference_samples > 8)) {
        return "--velocity-difference must be between 1 and 8 samples";
    }
    if (current_lag_s && !(*current_lag_s >= 0.0 && std::isfinite(*current_lag_s))) {
        return "--current-lag must be a time >= 0";
    }
    if (saturation_N && !(*saturation_N > 0.0)) return "--saturation must be positive";
    if (!(rls.forgetting_factor > 0.0 && rls.forgetting_factor <= 1.0))
        return "the forgetting factor must be in (0, 1]";
    return {};
}

namespace {

using Column = std::vector<double>;

// The lag-and-delay filter L above, applied in place; starts in steady state at the column's first value.
void apply_drive_filter(Column& column, double a, double mu) {
    if (column.empty() || (a == 0.0 && mu == 0.0)) return;
    double previous_in = column.front();
    double previous_out = column.front();
    for (double& value : column) {
        const double in = value;
        const double out = a * previous_out + (1.0 - a) * ((1.0 - mu) * in + mu * previous_in);
        previous_in = in;
        previous_out = out;
        value = out;
    }
}

struct Structure {
    int difference{1};       // n; 0 = the logged velocity channel
    int reference_delay{0};  // d
    double lag_s{0.0};       // tau
    double mu{0.0};
};

struct Problem {
    std::vector<Column> columns;  // regressors, filtered
    const std::vector<double>* y{nullptr};
    const std::vector<char>* use{nullptr};
};

// Residual sum of squares of the least-squares fit on the selected rows (normal equations on normalised columns:
// fast enough for the structure search; the final estimate uses QR and RLS).
double residual_sum_of_squares(const Problem& problem) {
    const auto p = static_cast<Eigen::Index>(problem.columns.size());
    const auto& y = *problem.y;
    const auto& use = *problem.use;
    const std::size_t n = y.size();
    Eigen::VectorXd scale(p);
    for (Eigen::Index j = 0; j < p; ++j) {
        double sum = 0.0;
        for (std::size_t k = 0; k < n; ++k) {
            if (use[k])
                sum +=
                    problem.columns[static_cast<std::size_t>(j)][k] * problem.columns[static_cast<std::size_t>(j)][k];
        }
        scale(j) = sum > 0.0 ? 1.0 / std::sqrt(sum) : 1.0;
    }
    Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(p, p);
    Eigen::VectorXd right = Eigen::VectorXd::Zero(p);
    Eigen::VectorXd phi(p);
    for (std::size_t k = 0; k < n; ++k) {
        if (!use[k]) continue;
        for (Eigen::Index j = 0; j < p; ++j) phi(j) = problem.columns[static_cast<std::size_t>(j)][k] * scale(j);
        normal.selfadjointView<Eigen::Lower>().rankUpdate(phi);
        right += phi * y[k];
    }
    normal = normal.selfadjointView<Eigen::Lower>();
    const Eigen::VectorXd theta = normal.ldlt().solve(right);
    double rss = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        if (!use[k]) continue;
        double fitted = 0.0;
        for (Eigen::Index j = 0; j < p; ++j)
            fitted += problem.columns[static_cast<std::size_t>(j)][k] * scale(j) * theta(j);
        rss += (y[k] - fitted) * (y[k] - fitted);
    }
    return std::isfinite(rss) ? rss : std::numeric_limits<double>::infinity();
}

struct Fit {
    Eigen::VectorXd estimate;    // RLS, unscaled
    Eigen::VectorXd batch;       // batch LS, unscaled
    Eigen::MatrixXd covariance;  // batch, unscaled
    double relative_error_pct{0.0};
    std::size_t samples{0};
    bool rank_deficient{false};
};

template <int N>
Eigen::VectorXd run_rls(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const RlsOptions& options) {
    Rls<N> rls(options);
    typename Rls<N>::Vector row;
    for (Eigen::Index k = 0; k < phi.rows(); ++k) {
        row = phi.row(k).transpose();
        rls.update(row, y(k));
    }
    return rls.estimate();
}

// RLS (the paper) and batch QR on normalised columns; returns both in the original scaling.
Fit fit(const Problem& problem, const RlsOptions& options) {
    const auto p = static_cast<Eigen::Index>(problem.columns.size());
    const auto& y = *problem.y;
    const auto& use = *problem.use;
    const auto rows = static_cast<Eigen::Index>(std::count(use.begin(), use.end(), char{1}));
    Eigen::MatrixXd phi(rows, p);
    Eigen::VectorXd target(rows);
    Eigen::Index row = 0;
    for (std::size_t k = 0; k < y.size(); ++k) {
        if (!use[k]) continue;
        for (Eigen::Index j = 0; j < p; ++j) phi(row, j) = problem.columns[static_cast<std::size_t>(j)][k];
        target(row) = y[k];
        ++row;
    }
    Eigen::VectorXd scale(p);
    for (Eigen::Index j = 0; j < p; ++j) {
        const double rms = phi.col(j).norm() / std::sqrt(static_cast<double>(std::max<Eigen::Index>(rows, 1)));
        scale(j) = rms > 0.0 ? rms : 1.0;
        phi.col(j) /= scale(j);
    }
    const double y_scale =
        std::max(target.norm() / std::sqrt(static_cast<double>(std::max<Eigen::Index>(rows, 1))), 1e-300);
    const LeastSquaresResult batch = solve_least_squares(phi, target / y_scale);
    Fit result;
    result.samples = static_cast<std::size_t>(rows);
    result.rank_deficient = batch.rank_deficient;
    result.relative_error_pct = batch.relative_error_pct;
    Eigen::VectorXd rls;
    const Eigen::VectorXd scaled_target = target / y_scale;
    switch (p) {
        case 1: rls = run_rls<1>(phi, scaled_target, options); break;
        case 2: rls = run_rls<2>(phi, scaled_target, options); break;
        case 3: rls = run_rls<3>(phi, scaled_target, options); break;
        case 4: rls = run_rls<4>(phi, scaled_target, options); break;
        default: rls = run_rls<5>(phi, scaled_target, options); break;
    }
    const Eigen::VectorXd unscale = scale.cwiseInverse() * y_scale;
    result.estimate = rls.cwiseProduct(unscale);
    result.batch = batch.estimate.cwiseProduct(unscale);
    result.covariance = unscale.asDiagonal() * batch.covariance * unscale.asDiagonal();
    return result;
}

Estimate make_estimate(double value, double variance) {
    Estimate estimate;
    estimate.value = value;
    estimate.standard_error = variance >= 0.0 && std::isfinite(variance) ? std::sqrt(variance) : std::nan("");
    return estimate;
}

// Var(a/b) by the delta method from the covariance of (a, b).
double ratio_variance(double a, double b, double var_a, double var_b, double cov_ab) {
    const double r = a / b;
    return (var_a - 2.0 * r * cov_ab + r * r * var_b) / (b * b);
}

// Velocity measurement with n-sample difference: (x_k - x_{k-n})/(n*T); the first samples use what exists.
Column difference_velocity(std::span<const double> x, int n, double dt) {
    Column v(x.size(), 0.0);
    for (std::size_t k = 0; k < x.size(); ++k) {
        const std::size_t back = k >= static_cast<std::size_t>(n) ? k - static_cast<std::size_t>(n) : 0;
        v[k] = (x[k] - x[back]) / (n * dt);
    }
    return v;
}

Column delayed(std::span<const double> x, int d) {
    Column out(x.size());
    for (std::size_t k = 0; k < x.size(); ++k)
        out[k] = x[k >= static_cast<std::size_t>(d) ? k - static_cast<std::size_t>(d) : 0];
    return out;
}

Column running_sum(const Column& x, double dt) {
    Column out(x.size());
    double sum = 0.0;
    for (std::size_t k = 0; k < x.size(); ++k) {
        sum += x[k] * dt;
        out[k] = sum;
    }
    return out;
}

// The candidate lag time constants [in samples] and fractional delays of the coarse search.
constexpr std::array<double, 12> lag_grid{0.0, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0, 1.4, 2.0, 3.0, 5.0};
constexpr std::array<double, 5> mu_grid{0.0, 0.25, 0.5, 0.75, 1.0};

double lag_coefficient(double lag_s, double dt) {
    return lag_s > 0.0 ? std::exp(-dt / lag_s) : 0.0;
}

}  // namespace

GainResult identify_gains(const Trace& trace, std::span<const double> drive_force, const GainOptions& options) {
    if (const auto problem = options.validate(); !problem.empty()) throw InputError(problem);
    const std::string source = trace.source_path.empty() ? std::string("trace") : trace.source_path;
    const auto* reference_channel = trace.find(Role::reference_position);
    const auto* position_channel = trace.find(Role::position);
    if (position_channel == nullptr) {
        throw InputError(fmt::format("{}: no position channel: map one with --channel position=NAME", source));
    }
    if (reference_channel == nullptr) {
        throw InputError(
            fmt::format("{}: no reference position channel, which the position loop's following error "
                        "needs: map one with --channel reference_position=NAME",
                        source));
    }
    const std::size_t n = trace.samples();
    if (drive_force.size() != n)
        throw InputError(
            fmt::format("{}: the drive force has {} samples, the trace {}", source, drive_force.size(), n));
    if (n < 50) throw AnalysisError(fmt::format("{}: {} samples are too few to identify controller gains", source, n));
    const double dt = trace.time_base().sample_time_s;
    const std::span<const double> x = position_channel->values;
    const std::span<const double> reference = reference_channel->values;
    const auto* command_channel = trace.find(Role::velocity_command);
    const auto* velocity_channel = trace.find(Role::velocity);

    GainResult result;
    result.method = command_channel != nullptr ? "velocity_command" : "structure";
    const std::vector<double> y(drive_force.begin(), drive_force.end());

    // Following error: it must carry signal, or no position gain can be seen.
    double following_rms = 0.0;
    for (std::size_t k = 0; k < n; ++k) following_rms += (reference[k] - x[k]) * (reference[k] - x[k]);
    following_rms = std::sqrt(following_rms / static_cast<double>(n));
    if (!(following_rms > 0.0)) {
        throw AnalysisError(
            fmt::format("{}: the position equals the reference everywhere (no following error), so the "
                        "position gain cannot be identified; a trace of a motion with the position "
                        "loop closed would",
                        source));
    }

    // Rows used: past the start-up of the differences and filters, not at the force limit.
    std::vector<char> use(n, 1);
    for (std::size_t k = 0; k < std::min<std::size_t>(n, 10); ++k) use[k] = 0;
    std::size_t saturated = 0;
    if (options.saturation_N) {
        for (std::size_t k = 0; k < n; ++k) {
            if (std::abs(y[k]) >= 0.999 * *options.saturation_N) {
                use[k] = 0;
                ++saturated;
            }
        }
        if (saturated > 0) {
            result.diagnostics.push_back(fmt::format("{} samples at the force limit left out", saturated));
        }
    }
    for (std::size_t k = 0; k < n; ++k) {
        if (!std::isfinite(y[k])) use[k] = 0;
    }

    std::vector<int> differences;
    if (options.velocity_difference_samples)
        differences.push_back(*options.velocity_difference_samples);
    else
        differences = {1, 2, 3, 4};
    if (velocity_channel != nullptr && !options.velocity_difference_samples) differences.push_back(0);
    const std::vector<int> reference_delays =
        command_channel != nullptr ? std::vector<int>{0} : std::vector<int>{0, 1, 2};
    std::vector<double> lags;
    if (options.current_lag_s)
        lags.push_back(*options.current_lag_s);
    else
        for (const double samples : lag_grid) lags.push_back(samples * dt);

    const auto velocity_for = [&](int difference) {
        return difference == 0 ? Column(velocity_channel->values.begin(), velocity_channel->values.end())
                               : difference_velocity(x, difference, dt);
    };

    // Position loop (only with a logged velocity command): v_cmd = K_v*e(k-d) [+ k_ff*x_ref'(k-d)].
    Column velocity_command;
    if (command_channel != nullptr) {
        velocity_command.assign(command_channel->values.begin(), command_channel->values.end());
        const Column reference_velocity = difference_velocity(reference, 1, dt);
        double best_rss = std::numeric_limits<double>::infinity();
        Problem best;
        std::vector<char> position_use(n, 1);
        for (std::size_t k = 0; k < std::min<std::size_t>(n, 10); ++k) position_use[k] = 0;
        for (int d : {0, 1, 2}) {
            Problem problem;
            Column error(n);
            for (std::size_t k = 0; k < n; ++k) {
                const std::size_t j = k >= static_cast<std::size_t>(d) ? k - static_cast<std::size_t>(d) : 0;
                error[k] = reference[j] - x[k];
            }
            problem.columns.push_back(std::move(error));
            if (options.feedforward) problem.columns.push_back(delayed(reference_velocity, d));
            problem.y = &velocity_command;
            problem.use = &position_use;
            const double rss = residual_sum_of_squares(problem);
            if (rss < best_rss) {
                best_rss = rss;
                best = std::move(problem);
                result.reference_delay_samples = d;
            }
        }
        const Fit position_fit = fit(best, options.rls);
        if (position_fit.rank_deficient) {
            throw AnalysisError(fmt::format("{}: the following error does not determine the position gain", source));
        }
        result.position_gain_per_s = make_estimate(position_fit.estimate(0), position_fit.covariance(0, 0));
        result.position_loop_relative_error_pct = position_fit.relative_error_pct;
        if (options.feedforward) {
            result.velocity_feedforward = make_estimate(position_fit.estimate(1), position_fit.covariance(1, 1));
        }
    }

    const auto build = [&](const Structure& s, bool integral) {
        Problem problem;
        const Column v = velocity_for(s.difference);
        if (command_channel != nullptr) {
            Column error(n);
            for (std::size_t k = 0; k < n; ++k) error[k] = velocity_command[k] - v[k];
            if (integral) {
                problem.columns.push_back(running_sum(error, dt));
                problem.columns.push_back(Column(n, 1.0));
            }
            problem.columns.insert(problem.columns.begin(), std::move(error));
        } else {
            Column error(n), minus_v(n);
            for (std::size_t k = 0; k < n; ++k) {
                const std::size_t j = k >= static_cast<std::size_t>(s.reference_delay)
                                          ? k - static_cast<std::size_t>(s.reference_delay)
                                          : 0;
                error[k] = reference[j] - x[k];
                minus_v[k] = -v[k];
            }
            if (integral) {
                Column error_sum = running_sum(error, dt);
                Column minus_v_sum = running_sum(minus_v, dt);
                problem.columns.push_back(std::move(error));
                problem.columns.push_back(std::move(minus_v));
                problem.columns.push_back(std::move(error_sum));
                problem.columns.push_back(std::move(minus_v_sum));
                problem.columns.push_back(Column(n, 1.0));
            } else {
                problem.columns.push_back(std::move(error));
                problem.columns.push_back(std::move(minus_v));
            }
        }
        const double a = lag_coefficient(s.lag_s, dt);
        for (auto& column : problem.columns) apply_drive_filter(column, a, s.mu);
        problem.y = &y;
        problem.use = &use;
        return problem;
    };

    const auto search = [&](bool integral) {
        Structure best;
        double best_rss = std::numeric_limits<double>::infinity();
        const auto consider = [&](const Structure& s) {
            const double rss = residual_sum_of_squares(build(s, integral));
            if (rss < best_rss) {
                best_rss = rss;
                best = s;
            }
        };
        // Staged: the velocity measurement and reference delay first (no lag, a few delays), then the lag and the
        // fractional delay for them, then the first stage again with the lag found.
        const double first_lag = options.current_lag_s.value_or(0.0);
        for (int difference : differences) {
            for (int d : reference_delays) {
                for (double mu : {0.0, 0.5, 1.0}) consider({difference, d, first_lag, mu});
            }
        }
        for (double lag : lags) {
            for (double mu : mu_grid) consider({best.difference, best.reference_delay, lag, mu});
        }
        const Structure lagged = best;
        for (int difference : differences) {
            for (int d : reference_delays) consider({difference, d, lagged.lag_s, lagged.mu});
        }
        // Refine tau and mu by coordinate search with shrinking steps (the residual is smooth in both).
        double lag_step = options.current_lag_s ? 0.0 : 0.1 * dt;
        double mu_step = 0.1;
        for (int round = 0; round < 12; ++round) {
            bool improved = false;
            for (const auto& [dl, dm] : {std::pair{lag_step, 0.0}, std::pair{-lag_step, 0.0}, std::pair{0.0, mu_step},
                                         std::pair{0.0, -mu_step}}) {
                Structure s = best;
                s.lag_s = std::max(0.0, s.lag_s + dl);
                s.mu = std::clamp(s.mu + dm, 0.0, 1.0);
                if (s.lag_s == best.lag_s && s.mu == best.mu) continue;
                const double rss = residual_sum_of_squares(build(s, integral));
                if (rss < best_rss) {
                    best_rss = rss;
                    best = s;
                    improved = true;
                }
            }
            if (!improved) {
                lag_step *= 0.5;
                mu_step *= 0.5;
            }
        }
        return best;
    };

    bool integral = options.velocity_loop != VelocityLoopStructure::p;
    Structure structure = search(integral);
    Fit force_fit = fit(build(structure, integral), options.rls);
    const int integral_index = command_channel != nullptr ? 1 : 3;
    if (integral && options.velocity_loop == VelocityLoopStructure::automatic) {
        const double ki = force_fit.estimate(integral_index);
        const double se = std::sqrt(std::max(0.0, force_fit.covariance(integral_index, integral_index)));
        if (force_fit.rank_deficient || !(ki > 3.0 * se)) {
            result.diagnostics.push_back(
                fmt::format("no significant integral action in the velocity loop (K_i = {:.4g} +- {:.2g} N/m): "
                            "identified as P only",
                            force_fit.rank_deficient ? 0.0 : ki, force_fit.rank_deficient ? 0.0 : se));
            integral = false;
            structure = search(false);
            force_fit = fit(build(structure, false), options.rls);
        }
    }
    if (force_fit.rank_deficient) {
        throw AnalysisError(
            fmt::format("{}: the velocity error does not determine the velocity-loop gains (the axis "
                        "barely moved); a trace of a motion would",
                        source));
    }

    const auto& theta = force_fit.estimate;
    const auto& covariance = force_fit.covariance;
    if (command_channel != nullptr) {
        result.velocity_gain_N_s_per_m = make_estimate(theta(0), covariance(0, 0));
        if (integral) result.velocity_integral_gain_N_per_m = make_estimate(theta(1), covariance(1, 1));
    } else {
        // th1 = K_p*K_v, th2 = K_p
        const double kv = theta(0) / theta(1);
        result.position_gain_per_s =
            make_estimate(kv, ratio_variance(theta(0), theta(1), covariance(0, 0), covariance(1, 1), covariance(0, 1)));
        result.velocity_gain_N_s_per_m = make_estimate(theta(1), covariance(1, 1));
        if (integral) result.velocity_integral_gain_N_per_m = make_estimate(theta(3), covariance(3, 3));
        result.reference_delay_samples = structure.reference_delay;
    }
    if (integral) {
        const int kp = command_channel != nullptr ? 0 : 1;
        const int ki = integral_index;
        result.reset_time_s = make_estimate(
            theta(kp) / theta(ki),
            ratio_variance(theta(kp), theta(ki), covariance(kp, kp), covariance(ki, ki), covariance(kp, ki)));
    }
    result.velocity_difference_samples = structure.difference == 0 ? 1 : structure.difference;
    if (structure.difference == 0) result.diagnostics.push_back("velocity loop fitted on the logged velocity channel");
    result.current_lag_s = structure.lag_s;
    result.drive_delay_samples = structure.mu > 0.5 ? 1 : 0;
    result.relative_error_pct = force_fit.relative_error_pct;
    result.samples_used = force_fit.samples;
    if (!(result.position_gain_per_s.value.value_or(0.0) > 0.0) || !(theta(command_channel != nullptr ? 0 : 1) > 0.0)) {
        result.diagnostics.push_back(
            "a gain came out negative: the channels' signs or roles may be wrong (is the "
            "reference mapped to the reference, the drive signal to the current?)");
    }

    ControllerModel& controller = result.controller;
    controller.position_gain_per_s = result.position_gain_per_s.value.value_or(0.0);
    controller.velocity_gain_N_s_per_m = result.velocity_gain_N_s_per_m.value.value_or(0.0);
    controller.velocity_integral_gain_N_per_m = result.velocity_integral_gain_N_per_m.value.value_or(0.0);
    controller.velocity_feedforward = result.velocity_feedforward.value.value_or(0.0);
    controller.saturation_N = options.saturation_N;
    controller.current_lag_s = structure.lag_s;
    controller.position_cycle_s = dt;
    controller.velocity_cycle_s = dt;
    controller.velocity_difference_samples = result.velocity_difference_samples;
    return result;
}

}  // namespace feedid
