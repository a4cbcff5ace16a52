#include "feedid/identify/friction_only.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/numeric/signal.hpp"
#include "feedid/identify/model_adequacy.hpp"
#include "feedid/identify/step1.hpp"

namespace feedid {

namespace {

/// Lengths in mm, speeds in mm/s on a linear axis; rad and rad/s on a rotary one.
struct Display {
    bool rotary;
    [[nodiscard]] double length(double x) const { return rotary ? x : x * 1e3; }
    [[nodiscard]] const char* length_unit() const { return rotary ? "rad" : "mm"; }
    [[nodiscard]] const char* speed_unit() const { return rotary ? "rad/s" : "mm/s"; }
};

/// The samples the friction comes from: the logged velocity and force over the whole window when the velocity is
/// logged (unfiltered: no edge lost), else x' and the force of the analysed samples.
struct SteadySource {
    const std::vector<double>& velocity;
    const std::vector<double>& force;
};
SteadySource steady_source(const Derivatives& d) {
    if (d.logged_velocity.empty()) return {d.velocity, d.force};
    return {d.logged_velocity, d.logged_force};
}

/// The rows that belong to runs of at least `minimum` consecutive indices.
std::vector<std::size_t> passes_only(const std::vector<std::size_t>& rows, std::size_t minimum) {
    std::vector<std::size_t> kept;
    for (std::size_t begin = 0; begin < rows.size();) {
        std::size_t end = begin + 1;
        while (end < rows.size() && rows[end] == rows[end - 1] + 1) ++end;
        if (end - begin >= minimum)
            kept.insert(kept.end(), rows.begin() + static_cast<std::ptrdiff_t>(begin),
                        rows.begin() + static_cast<std::ptrdiff_t>(end));
        begin = end;
    }
    return kept;
}

/// Steady samples: moving, and the logged velocity of the sample and both neighbours keeps its sign within a
/// fraction of |v|; without a logged velocity, step 2's quasi-static moving samples.
std::vector<std::size_t> steady_samples(const Derivatives& d, const Selection& s, const FrictionOnlyOptions& options) {
    std::vector<std::size_t> rows;
    if (d.logged_velocity.empty()) {
        for (const auto k : s.moving) {
            if (s.steady(k)) rows.push_back(k);
        }
        return rows;
    }
    const auto& v = d.logged_velocity;
    for (std::size_t k = 1; k + 1 < v.size(); ++k) {
        if (std::abs(v[k]) <= s.moving_threshold()) continue;
        const double low = std::min({v[k - 1], v[k], v[k + 1]}), high = std::max({v[k - 1], v[k], v[k + 1]});
        if ((low > 0.0 || high < 0.0) && high - low <= options.steady_spread_fraction * std::abs(v[k]))
            rows.push_back(k);
    }
    return passes_only(rows, options.minimum_steady_run);
}

/// Per direction, the speeds must differ enough for B (and each direction needs its samples).
std::string speed_spread_problem(const Derivatives& d, const std::vector<std::size_t>& rows, FrictionModelKind model,
                                 const FrictionOnlyOptions& options, std::size_t needed) {
    const auto& v = steady_source(d).velocity;
    const Display display{d.rotary};
    const bool asymmetric = model == FrictionModelKind::asymmetric;
    for (int g = 0; g < (asymmetric ? 2 : 1); ++g) {
        std::vector<double> speeds;
        for (const auto k : rows) {
            if (!asymmetric || (v[k] > 0.0) == (g == 0)) speeds.push_back(std::abs(v[k]));
        }
        const char* which = !asymmetric ? "" : g == 0 ? " forward" : " reverse";
        if (speeds.size() < needed) {
            return fmt::format("only {} steady-speed samples{} ({} needed)", speeds.size(), which, needed);
        }
        const double typical = percentile(speeds, 0.5);
        const auto apart = std::count_if(speeds.begin(), speeds.end(), [&](double speed) {
            return speed >= options.minimum_speed_ratio * typical || speed * options.minimum_speed_ratio <= typical;
        });
        if (static_cast<std::size_t>(apart) < options.minimum_samples_at_another_speed) {
            return fmt::format(
                "the steady speeds{} are nearly all {:.3g} {} ({} samples {:g}x faster or slower, {} needed): viscous "
                "and Coulomb friction need two speeds{}",
                which, display.length(typical), display.speed_unit(), apart, options.minimum_speed_ratio,
                options.minimum_samples_at_another_speed,
                asymmetric ? " in each direction (--model symmetric shares them between the directions)" : "");
        }
    }
    return {};
}


/// Standard errors that count each steady pass's own level once. On a machine's log the residual of a pass keeps
/// one level along it (a load, friction that differs by place or direction): the residual is e = u_pass + w with
/// u_pass ~ (0, s_u^2) per pass and w the within-pass noise, and Cov(theta) = A^-1 (S_w + s_u^2 sum_p g_p g_p^T)
/// A^-1, A = Phi^T Phi, g_p the sum of a pass's regressor rows, S_w the batch-means long-run covariance of w (blocks
/// of `correlation_block` samples). s_u^2 by moments: the passes' mean residuals squared less their within-pass
/// variance (2 tau_w s_w^2 / n_p, tau_w w's integrated autocorrelation time), over P - p (the fit absorbs p of
/// the pass levels). A pass whose level alone sets a parameter (B from one rapid) then carries a level's
/// uncertainty, not that of its n_p samples. Fewer than p + 2 passes: the batch means of e alone.
void account_for_pass_levels(FrictionOnlyFit& fit, const Eigen::MatrixXd& phi, const Eigen::VectorXd& y,
                             const std::vector<std::size_t>& rows) {
    LeastSquaresResult& batch = fit.batch;
    if (batch.rank_deficient || !(batch.residual_std > 0.0)) return;
    const Eigen::VectorXd residual = y - phi * batch.estimate;
    const auto p = phi.cols();
    std::vector<std::size_t> starts;  // of each pass, into rows; a sentinel at the end
    for (std::size_t i = 0; i < rows.size(); ++i)
        if (i == 0 || rows[i] != rows[i - 1] + 1) starts.push_back(i);
    starts.push_back(rows.size());
    const std::size_t passes = starts.size() - 1;
    if (passes < static_cast<std::size_t>(p) + 2) {
        account_for_correlated_residuals(batch, phi, y, rows, fit.correlation_block);
        return;
    }
    std::vector<double> within(rows.size()), mean(passes);
    Eigen::MatrixXd sums(p, static_cast<Eigen::Index>(passes));
    double squares = 0.0;
    for (std::size_t q = 0; q < passes; ++q) {
        const auto first = static_cast<Eigen::Index>(starts[q]), n = static_cast<Eigen::Index>(starts[q + 1]) - first;
        mean[q] = residual.segment(first, n).mean();
        sums.col(static_cast<Eigen::Index>(q)) = phi.middleRows(first, n).colwise().sum().transpose();
        for (std::size_t i = starts[q]; i < starts[q + 1]; ++i) {
            within[i] = residual(static_cast<Eigen::Index>(i)) - mean[q];
            squares += within[i] * within[i];
        }
    }
    const double within_variance = squares / static_cast<double>(rows.size() - passes);
    const double inflation = std::max(1.0, 2.0 * integrated_autocorrelation_time(rows, within));
    double excess = 0.0;
    for (std::size_t q = 0; q < passes; ++q)
        excess += mean[q] * mean[q] - inflation * within_variance / static_cast<double>(starts[q + 1] - starts[q]);
    const double level_variance = std::max(0.0, excess / static_cast<double>(passes - static_cast<std::size_t>(p)));
    LeastSquaresResult blocks = batch;  // the batch means of e alone, for the larger of the two below
    account_for_correlated_residuals(blocks, phi, y, rows, fit.correlation_block);
    const Eigen::VectorXd w = Eigen::Map<const Eigen::VectorXd>(within.data(), static_cast<Eigen::Index>(within.size()));
    const Eigen::MatrixXd inverse_information = batch.covariance / (batch.residual_std * batch.residual_std);
    const Eigen::MatrixXd middle =
        long_run_covariance(phi, w, rows, fit.correlation_block) + level_variance * sums * sums.transpose();
    batch.covariance = inverse_information * middle * inverse_information;
    batch.standard_error = batch.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    // each parameter's standard error the larger of the two (the pass levels' correlations kept): with no scatter
    // of the levels beyond their noise (s_u = 0) the batch means of e count the short correlations the within-pass
    // residual lost with its pass means
    const Eigen::VectorXd scale =
        blocks.standard_error.cwiseMax(batch.standard_error).cwiseQuotient(batch.standard_error.cwiseMax(1e-300));
    batch.covariance = scale.asDiagonal() * batch.covariance * scale.asDiagonal();
    batch.standard_error = batch.standard_error.cwiseProduct(scale);
    fit.passes = passes;
    fit.pass_level_std = std::sqrt(level_variance);
}
}  // namespace

Resolution assess_resolution(const Derivatives& d, const FrictionOnlyOptions& options, double moving_speed) {
    Resolution r;
    const double dt = d.sample_time_s * d.used.decimation;
    r.sample_rate_hz = 1.0 / dt;
    r.position_quantum = d.position_quantum;
    const auto& v = steady_source(d).velocity;
    if (v.size() < 2) return r;
    // one buffer for both percentiles, moved in (a copy of each would be 16 bytes per sample more)
    const auto moving = [&](std::size_t k) { return !(moving_speed > 0.0) || std::abs(v[k]) > moving_speed; };
    std::vector<double> buffer;
    buffer.reserve(v.size());
    for (std::size_t k = 0; k < v.size(); ++k)
        if (moving(k)) buffer.push_back(std::abs(v[k]));
    if (buffer.size() < 2) return r;
    r.typical_speed = percentile(std::move(buffer), 0.95);
    buffer.clear();
    for (std::size_t k = 1; k < v.size(); ++k)
        if (moving(k) || moving(k - 1)) buffer.push_back(std::abs(v[k] - v[k - 1]));
    if (buffer.empty()) return r;
    r.largest_speed_step = percentile(std::move(buffer), 0.99);
    const double travel = r.typical_speed * dt;
    r.position_too_coarse = r.position_quantum > options.coarse_position_fraction * travel;
    r.accelerations_unresolved = r.largest_speed_step > options.unresolved_speed_step_fraction * r.typical_speed;
    const Display display{d.rotary};
    r.description = fmt::format("{:.4g} Hz sampling", r.sample_rate_hz);
    if (r.position_quantum > 0.0) {
        r.description += fmt::format(
            " and {:.3g} {} position resolution ({:.3g} {} of travel per sample at the typical "
            "speed {:.3g} {})",
            display.length(r.position_quantum), display.length_unit(), display.length(travel), display.length_unit(),
            display.length(r.typical_speed), display.speed_unit());
    }
    if (r.accelerations_unresolved) {
        r.description += fmt::format(
            "; the speed changes by up to {:.3g} {} between two samples ({:.0f} % of the typical speed): the "
            "accelerations last only a few samples and are not resolved",
            display.length(r.largest_speed_step), display.speed_unit(), 100.0 * r.largest_speed_step / r.typical_speed);
    }
    return r;
}

Resolution assess_trace_resolution(const Trace& trace, std::span<const double> force,
                                   const PreprocessOptions& preprocess_options, const FrictionOnlyOptions& options,
                                   double moving_speed) {
    Derivatives d;
    try {
        d = preprocess(trace, force, preprocess_options);
    } catch (const InputError&) {
        return {};
    }
    if (!d.failure.empty() || d.velocity.size() < 2) return {};
    return assess_resolution(d, options, moving_speed);
}

FrictionOnlyFit fit_friction_only(const Derivatives& d, const Selection& s, FrictionModelKind model, bool offset,
                                  const FrictionOnlyOptions& options) {
    FrictionOnlyFit fit;
    for (const auto& column : linear_columns(model, offset)) {
        if (column.term != Term::mass) fit.columns.push_back(column);
    }
    const std::vector<std::size_t> rows = steady_samples(d, s, options);
    fit.samples = rows.size();
    for (const auto k : s.moving)
        fit.largest_acceleration = std::max(fit.largest_acceleration, std::abs(d.acceleration[k]));
    const std::size_t needed = options.minimum_samples_per_parameter * fit.columns.size();
    if (rows.size() < needed) {
        fit.failure = fmt::format("only {} steady-speed samples ({} needed)", rows.size(), needed);
        return fit;
    }
    if (auto problem = speed_spread_problem(d, rows, model, options, needed / fit.columns.size() * 2);
        !problem.empty()) {
        fit.failure = std::move(problem);
        return fit;
    }
    const SteadySource source = steady_source(d);
    const auto& v = source.velocity;
    Eigen::MatrixXd phi(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(fit.columns.size()));
    Eigen::VectorXd y(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const double x = v[rows[i]];
        const auto row = static_cast<Eigen::Index>(i);
        y(row) = source.force[rows[i]];
        for (std::size_t c = 0; c < fit.columns.size(); ++c) {
            const auto& column = fit.columns[c];
            const bool forward = column.direction == Direction::forward,
                       reverse = column.direction == Direction::reverse;
            double value = 1.0;  // the offset
            if (column.term == Term::viscous) value = forward ? std::max(x, 0.0) : reverse ? std::min(x, 0.0) : x;
            if (column.term == Term::coulomb) value = forward ? (x > 0.0) : reverse ? -double(x < 0.0) : sign(x);
            phi(row, static_cast<Eigen::Index>(c)) = value;
        }
    }
    fit.batch = solve_least_squares(phi, y);
    fit.correlation_block = correlation_block(d, options.correlation_blocks);
    account_for_pass_levels(fit, phi, y, rows);
    if (fit.batch.rank_deficient) {
        fit.failure =
            "the steady-speed samples cannot separate the friction parameters (one direction only, and an "
            "offset?)";
        return fit;
    }
    if (fit.largest_acceleration > 0.0)
        fit.smallest_detectable_mass =
            options.detectable_force_multiple * fit.batch.residual_std / fit.largest_acceleration;
    return fit;
}

}  // namespace feedid
