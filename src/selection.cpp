#include "feedid/selection.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/core.h>

#include "feedid/signal.hpp"

namespace feedid {

namespace {

struct Units {
    ParameterNaming naming;
    [[nodiscard]] double speed(double v) const { return v * naming.display_velocity_scale(); }
    [[nodiscard]] std::string unit() const { return naming.display_velocity_unit(); }
};

/// Quasi-static flags: within the half-window around a sample the velocity keeps its sign and spreads by at most
/// the tolerated fraction of it (plus noise).
std::vector<char> quasi_static_flags(const Derivatives& d, const SelectionOptions& options) {
    const auto& v = d.velocity;
    const double dt = d.sample_time_s * d.used.decimation;
    const auto half = static_cast<std::size_t>(std::max(1.0, std::round(options.steady_half_window_s / dt)));
    const auto low = running_minimum(v, half);
    const auto high = running_maximum(v, half);
    std::vector<char> flags(v.size(), 0);
    for (std::size_t k = 0; k < v.size(); ++k) {
        flags[k] =
            (low[k] > 0.0 || high[k] < 0.0) && high[k] - low[k] <= options.steady_spread_fraction * std::abs(v[k]) +
                                                                       options.steady_noise_multiple * d.velocity_noise;
    }
    return flags;
}

/// Mean of the residuals of `rows` from the fit, signed with the direction of motion: the friction they carry above
/// the fitted model.
double friction_rise(const Regressors& r, const Derivatives& d, const std::vector<std::size_t>& rows,
                     const Eigen::VectorXd& estimate) {
    const Eigen::VectorXd residual = r.outputs(rows) - r.matrix(rows) * estimate;
    double rise = 0.0;
    for (std::size_t i = 0; i < rows.size(); ++i) {
        rise += (d.velocity[rows[i]] > 0 ? 1.0 : -1.0) * residual(static_cast<Eigen::Index>(i));
    }
    return rise / static_cast<double>(rows.size());
}

/// Step 1 must see no Stribeck friction. The speeds just above the split are checked against a fit on the faster
/// samples: while they carry more friction than their noise explains (mean residual above 3 standard errors), the
/// split doubles (only while the faster samples remain plenty). A mean is a weak witness: a small average rise can
/// sit on the ramp samples nearest the split, correlated with the acceleration, and bias M and B far more than its
/// size suggests.
double raise_split_above_stribeck(const Derivatives& d, const Regressors& r, const SelectionOptions& options,
                                  const std::vector<std::size_t>& moving, double split, SelectionReport& report) {
    const Units units{ParameterNaming{d.rotary}};
    for (int doubling = 0; doubling < options.max_split_doublings; ++doubling) {
        std::vector<std::size_t> band, faster;
        for (const auto k : moving) {
            const double speed = std::abs(d.velocity[k]);
            if (speed >= 2.0 * split)
                faster.push_back(k);
            else if (speed >= split)
                band.push_back(k);
        }
        const std::size_t plenty =
            std::max<std::size_t>(2 * options.minimum_step1_samples_per_parameter * r.parameters(), moving.size() / 5);
        if (band.size() < options.minimum_slow_samples || faster.size() < plenty) break;
        const LeastSquaresResult fit = solve_least_squares(r.matrix(faster), r.outputs(faster));
        if (fit.rank_deficient) break;
        const double rise = friction_rise(r, d, band, fit.estimate);
        const double noise = 3.0 * fit.residual_std / std::sqrt(static_cast<double>(band.size()));
        if (!(rise > noise)) break;
        report.notes.push_back(fmt::format(
            "{} samples between {:.3g} and {:.3g} {} carry {:.3g} {} more friction than the faster ones: still "
            "Stribeck, so step 1 starts at {:.3g} {}",
            band.size(), units.speed(split), units.speed(2.0 * split), units.unit(), rise, units.naming.force_unit(),
            units.speed(2.0 * split), units.unit()));
        split *= 2.0;
    }
    return split;
}

/// Holding the slow samples back from step 1 pays only when step 2 can use them. Without quasi-static samples (no
/// slow constant-velocity passes) the slow samples are the ramps through reversals: step 1 takes them too (the IDIM
/// practice) unless they show a friction rise above the step-1 model, a Stribeck effect that would bias B and F_C.
void merge_slow_ramps(const Derivatives& d, const Regressors& r, const SelectionOptions& options, Selection& s) {
    const Units units{ParameterNaming{d.rotary}};
    const double split = s.report.split_velocity;
    std::vector<std::size_t> slow;
    for (const auto k : s.moving) {
        if (std::abs(d.velocity[k]) < split) slow.push_back(k);
    }
    const LeastSquaresResult fast_fit = solve_least_squares(r.matrix(s.step1), r.outputs(s.step1));
    if (slow.size() < options.minimum_slow_samples || fast_fit.rank_deficient) return;
    const double rise = friction_rise(r, d, slow, fast_fit.estimate);
    const bool consistent = rise <= fast_fit.residual_std;  // a Stribeck effect only ever adds friction
    s.report.notes.push_back(fmt::format(
        "{} slow samples below {:.3g} {} (ramps, no quasi-static passes): friction above the fast-sample model {:.3g} "
        "{} (residual std {:.3g}): {}",
        slow.size(), units.speed(split), units.unit(), rise, units.naming.force_unit(), fast_fit.residual_std,
        consistent ? "no Stribeck rise, step 1 uses them" : "a Stribeck rise, left out of step 1"));
    if (!consistent) return;
    s.step1.insert(s.step1.end(), slow.begin(), slow.end());
    std::sort(s.step1.begin(), s.step1.end());
    s.report.split_velocity = s.report.moving_threshold;
    s.report.step1 = s.step1.size();
    s.report.notes.push_back(fmt::format("step 1 now: {} moving samples at |v| >= {:.3g} {}", s.step1.size(),
                                         units.speed(s.report.split_velocity), units.unit()));
}

/// The largest |x'| of the analysed samples.
double max_speed(const Derivatives& d) {
    double fastest = 0.0;
    for (const double v : d.velocity) fastest = std::max(fastest, std::abs(v));
    return fastest;
}

/// The moving threshold and the moving samples, with the notes on what was dropped before them.
void select_moving(const Derivatives& d, const SelectionOptions& options, double fastest, Selection& s) {
    const Units units{ParameterNaming{d.rotary}};
    const double threshold = options.moving_threshold.value_or(
        std::max({options.rest_noise_multiple * d.velocity_noise,
                  d.velocity_from_position() ? d.position_quantum * d.used.cutoff_hz : 0.0,
                  options.rest_fraction_of_max_speed * fastest}));
    s.report.moving_threshold = threshold;
    for (std::size_t k = 0; k < d.size(); ++k) {
        if (std::abs(d.velocity[k]) > threshold) s.moving.push_back(k);
    }
    s.report.moving = s.moving.size();
    if (d.total > d.window) {
        s.report.notes.push_back(fmt::format("{} samples outside the time window or within {} samples of its edges",
                                             d.total - d.window, d.used.edge_samples));
    }
    if (d.used.decimation > 1) {
        s.report.notes.push_back(fmt::format("decimated by {}: {} samples remain", d.used.decimation, d.size()));
    }
    s.report.notes.push_back(fmt::format("{} samples at rest (|v| <= {:.3g} {}, {:g}x the velocity noise floor {:.3g})",
                                         d.size() - s.moving.size(), units.speed(threshold), units.unit(),
                                         options.rest_noise_multiple, units.speed(d.velocity_noise)));
}

/// The default split: a fraction of the typical constant-velocity speed (or of the largest speed without any).
double default_split(const Derivatives& d, const SelectionOptions& options, double fastest, const Selection& s) {
    std::vector<double> steady_speeds;
    for (const auto k : s.moving) {
        if (s.steady(k)) steady_speeds.push_back(std::abs(d.velocity[k]));
    }
    const double typical = percentile(steady_speeds.empty() ? std::vector<double>{fastest} : steady_speeds,
                                      options.typical_speed_percentile);
    return options.stribeck ? options.split_fraction * typical : 0.0;
}

}  // namespace

Selection select_samples(const Derivatives& d, const Regressors& r, const SelectionOptions& options) {
    const Units units{ParameterNaming{d.rotary}};
    Selection s;
    s.report.total = d.total;
    s.report.window = d.window;
    const double fastest = max_speed(d);
    select_moving(d, options, fastest, s);
    s.quasi_static = quasi_static_flags(d, options);
    const double threshold = s.report.moving_threshold;
    double split =
        std::max(options.split_velocity ? *options.split_velocity : default_split(d, options, fastest, s), threshold);
    s.initial_split = split;
    if (!options.split_velocity && options.stribeck && split > threshold) {
        split = raise_split_above_stribeck(d, r, options, s.moving, split, s.report);
    }
    s.stribeck_band = split;
    s.report.split_velocity = split;
    for (const auto k : s.moving) {
        if (std::abs(d.velocity[k]) >= split)
            s.step1.push_back(k);
        else if (s.steady(k))
            s.step2.push_back(k);
    }
    s.report.step1 = s.step1.size();
    s.report.step2 = s.step2.size();
    s.report.notes.push_back(fmt::format("step 1: {} moving samples at |v| >= {:.3g} {} (Stribeck negligible)",
                                         s.step1.size(), units.speed(split), units.unit()));
    s.report.notes.push_back(fmt::format("step 2: {} quasi-static samples below {:.3g} {}", s.step2.size(),
                                         units.speed(split), units.unit()));
    const bool step1_possible = s.step1.size() >= options.minimum_step1_samples_per_parameter * r.parameters();
    if (step1_possible && !options.split_velocity && s.step2.size() < options.minimum_slow_samples &&
        split > threshold) {
        merge_slow_ramps(d, r, options, s);
    }
    return s;
}

}  // namespace feedid
