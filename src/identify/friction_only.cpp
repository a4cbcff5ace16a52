#include "feedid/identify/friction_only.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/numeric/signal.hpp"
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

}  // namespace

Resolution assess_resolution(const Derivatives& d, const FrictionOnlyOptions& options) {
    Resolution r;
    const double dt = d.sample_time_s * d.used.decimation;
    r.sample_rate_hz = 1.0 / dt;
    r.position_quantum = d.position_quantum;
    const auto& v = steady_source(d).velocity;
    if (v.size() < 2) return r;
    // one buffer for both percentiles, moved in (a copy of each would be 16 bytes per sample more)
    std::vector<double> buffer(v.size());
    for (std::size_t k = 0; k < v.size(); ++k) buffer[k] = std::abs(v[k]);
    r.typical_speed = percentile(std::move(buffer), 0.95);
    buffer.assign(v.size() - 1, 0.0);
    for (std::size_t k = 1; k < v.size(); ++k) buffer[k - 1] = std::abs(v[k] - v[k - 1]);
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
                                   const PreprocessOptions& preprocess_options, const FrictionOnlyOptions& options) {
    Derivatives d;
    try {
        d = preprocess(trace, force, preprocess_options);
    } catch (const InputError&) {
        return {};
    }
    if (!d.failure.empty() || d.velocity.size() < 2) return {};
    return assess_resolution(d, options);
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
    account_for_correlated_residuals(fit.batch, phi, y, rows, correlation_block(d, options.correlation_blocks));
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
