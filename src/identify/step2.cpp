#include "feedid/identify/step2.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/core.h>

#include "feedid/numeric/signal.hpp"
#include "feedid/identify/stribeck_fit.hpp"

namespace feedid {

namespace {

/// What step 2 works on: the selected samples and step 1's linear model, per direction group.
struct Step2Data {
    const Derivatives& d;
    const Selection& s;
    const Step1Fit& step1;
    const FrictionFitOptions& options;
    bool asymmetric;
    bool offset;
    std::array<std::size_t, 2> slow_count{0, 0};  ///< quasi-static slow samples per direction
    std::array<double, 2> slow_min{INFINITY, INFINITY};

    [[nodiscard]] std::size_t groups() const { return asymmetric ? 2u : 1u; }
    /// Does sample k belong to direction group g (every sample to the shared group)?
    [[nodiscard]] bool in_group(std::size_t k, std::size_t g) const {
        return !asymmetric || (d.velocity[k] > 0) == (g == 0);
    }
    [[nodiscard]] double offset_value() const {
        return offset ? step1.coefficient(Term::offset, Direction::both) : 0.0;
    }
    /// Step 1's (B, F_C) of direction g (0 forward, 1 reverse).
    [[nodiscard]] std::pair<double, double> linear_branch(std::size_t g) const {
        const Direction direction = !asymmetric ? Direction::both : g == 0 ? Direction::forward : Direction::reverse;
        return {step1.coefficient(Term::viscous, direction), step1.coefficient(Term::coulomb, direction)};
    }
};

Step2Data make_data(const Derivatives& d, const Selection& s, const Step1Fit& step1, const FrictionFitOptions& o) {
    const bool asymmetric = std::any_of(step1.columns.begin(), step1.columns.end(),
                                        [](const RegressorColumn& c) { return c.direction == Direction::forward; });
    const bool offset = !step1.columns.empty() && step1.columns.back().term == Term::offset;
    Step2Data data{d, s, step1, o, asymmetric, offset};
    for (const auto k : s.step2) {
        const std::size_t g = d.velocity[k] > 0 ? 0 : 1;
        ++data.slow_count[g];
        data.slow_min[g] = std::min(data.slow_min[g], std::abs(d.velocity[k]));
    }
    return data;
}

/// The paper's log-linear RLS (eq. 12-14), per direction.
void fit_log_linear_per_direction(const Step2Data& data, FrictionFit& out) {
    const auto& d = data.d;
    for (std::size_t g = 0; g < 2; ++g) {
        // this direction's step-2 samples, as indices (not as gathered columns: a long trace has millions)
        SampleIndices rows;
        rows.reserve(data.slow_count[g]);
        for (const auto k : data.s.step2) {
            if ((d.velocity[k] > 0) == (g == 0)) rows.push_back(k);
        }
        const auto [viscous, coulomb] = data.linear_branch(g);
        out.log_linear[g] = detail::fit_log_linear_over(
            rows.size(),
            [&](std::size_t i) {
                const std::size_t k = rows[i];
                return std::array<double, 3>{d.acceleration[k], d.velocity[k], d.force[k]};
            },
            data.step1.batch.estimate(0), viscous, coulomb, data.offset_value(),
            data.options.log_linear_noise_multiple * data.step1.batch.residual_std, data.step1.rls_options);
    }
}

/// The samples of the curve fit: step 1's and step 2's (each thinned to a bounded count), and the ramp samples that
/// only the Stribeck check kept out of step 1 (the whole curve models them).
detail::FitSamples curve_samples(const Step2Data& data) {
    const auto& d = data.d;
    detail::FitSamples samples;
    samples.correlation_block = correlation_block(d, data.options.correlation_blocks);
    const auto& step1 = data.s.step1;
    const auto& step2 = data.s.step2;
    const std::size_t stride1 = std::max<std::size_t>(1, step1.size() / data.options.max_fit_samples);
    const std::size_t stride2 = std::max<std::size_t>(1, step2.size() / data.options.max_fit_samples);
    for (std::size_t i = 0; i < step1.size(); i += stride1) {
        samples.push(d.acceleration[step1[i]], d.velocity[step1[i]], d.force[step1[i]], step1[i]);
    }
    for (std::size_t i = 0; i < step2.size(); i += stride2) {
        samples.push(d.acceleration[step2[i]], d.velocity[step2[i]], d.force[step2[i]], step2[i]);
    }
    const double split = data.s.split_velocity();
    for (const auto k : data.s.moving) {
        const double speed = std::abs(d.velocity[k]);
        if (speed >= data.s.initial_split && speed < split && !data.s.steady(k) && !data.s.near_rest(k)) {
            samples.push(d.acceleration[k], d.velocity[k], d.force[k], k);
        }
    }
    return samples;
}

/// Can the curve come from the quasi-static samples alone (and M from the transients)? Only when every direction's
/// quasi-static samples span speeds far enough apart to separate B from F_C.
bool curve_separable(const Step2Data& data, std::span<const SampleIndex> quasi_static) {
    const auto& o = data.options;
    for (std::size_t g = 0; g < data.groups(); ++g) {
        std::vector<double> speeds;
        for (const auto k : quasi_static) {
            if (data.in_group(k, g)) speeds.push_back(std::abs(data.d.velocity[k]));
        }
        if (speeds.size() < o.separable_sample_multiple * o.minimum_slow_samples ||
            !percentile_at_least(speeds, 0.9, o.separable_speed_ratio * percentile_in_place(speeds, 0.1))) {
            return false;
        }
    }
    return true;
}

struct CurveResult {
    detail::CurveFit fit;
    double mass{0.0};
    double mass_se{0.0};
};

/// M by least squares on every sample of the joint set, the friction curve (fit, with v_s) held.
bool fit_mass_with_curve_held(const detail::FitSamples& samples, const detail::CurveLayout& layout, bool asymmetric,
                              CurveResult& out) {
    Eigen::VectorXd curve = out.fit.parameters;  // CurveLayout::friction takes ln v_s
    for (const int index : layout.log_vs) {
        if (index >= 0) curve(index) = std::log(curve(index));
    }
    const auto n = static_cast<Eigen::Index>(samples.size());
    Eigen::MatrixXd a(n, 1);
    Eigen::VectorXd r(n);
    for (Eigen::Index k = 0; k < n; ++k) {
        const auto i = static_cast<std::size_t>(k);
        a(k, 0) = samples.acceleration[i];
        r(k) = samples.force[i] - layout.friction(curve, samples.velocity[i], asymmetric);
    }
    LeastSquaresResult mass = solve_least_squares(a, r);
    if (mass.rank_deficient) return false;
    account_for_correlated_residuals(mass, a, r, samples.index, samples.correlation_block);
    out.mass = mass.estimate(0);
    out.mass_se = mass.standard_error(0);
    return true;
}

/// The curve from the quasi-static samples alone, then M with it held. The quasi-static samples' small
/// accelerations take step 1's mass: one round is enough (a second, with the mass of the first, moved no estimate by
/// more than 0.001 of its standard error on 20 synthetic closed-loop traces).
CurveResult fit_separated(const Step2Data& data, const detail::FitSamples& samples,
                          std::span<const SampleIndex> quasi_static, detail::CurveModel model, double vs_low,
                          double vs_high) {
    const auto& d = data.d;
    model.mass = false;
    const detail::CurveLayout layout(model);
    CurveResult out;
    out.mass = data.step1.batch.estimate(0);
    detail::FitSamples quasi;
    quasi.correlation_block = samples.correlation_block;
    const std::size_t stride = std::max<std::size_t>(1, quasi_static.size() / data.options.max_fit_samples);
    const std::size_t stride2 = std::max<std::size_t>(1, data.s.step2.size() / data.options.max_fit_samples);
    for (std::size_t i = 0; i < quasi_static.size(); i += stride) {
        const auto k = quasi_static[i];
        quasi.push(0.0, d.velocity[k], d.force[k] - out.mass * d.acceleration[k], k);
    }
    for (std::size_t i = 0; i < data.s.step2.size(); i += stride2) {
        const auto k = data.s.step2[i];
        quasi.push(0.0, d.velocity[k], d.force[k] - out.mass * d.acceleration[k], k);
    }
    out.fit = detail::fit_curve(quasi, model, vs_low, vs_high);
    if (out.fit.converged && !fit_mass_with_curve_held(samples, layout, data.asymmetric, out)) {
        out.fit.converged = false;
    }
    return out;
}

CurveResult fit_joint(const detail::FitSamples& samples, const detail::CurveModel& model, double vs_low,
                      double vs_high) {
    CurveResult out;
    out.fit = detail::fit_curve(samples, model, vs_low, vs_high);
    const detail::CurveLayout layout(model);
    if (out.fit.converged) {
        out.mass = out.fit.parameters(layout.mass);
        out.mass_se = out.fit.standard_errors(layout.mass);
    }
    return out;
}

}  // namespace

namespace {

struct SearchBounds {
    double low{0.0};   ///< [m/s]
    double high{0.0};  ///< [m/s]
};

/// Is the Stribeck term of group g determined by this fit? Disables it and says why when not.
bool stribeck_determined(const Step2Data& data, const detail::CurveFit& fit, const detail::CurveLayout& layout,
                         std::size_t g, SearchBounds bounds, std::vector<std::string>& diagnostics) {
    const auto& o = data.options;
    const double delta = fit.converged ? fit.parameters(layout.delta[g]) : NAN;
    const double delta_se = fit.converged ? fit.standard_errors(layout.delta[g]) : NAN;
    const double vs = fit.converged ? fit.parameters(layout.log_vs[g]) : NAN;
    const double vs_se = fit.converged ? fit.standard_errors(layout.log_vs[g]) : NAN;
    // the data determines v_s only with quasi-static samples below a few v_s, and F_B and v_s (the height and the
    // width of the rise) only with those at more than one speed: through one speed runs a whole family of curves
    std::vector<double> below;
    for (const auto k : data.s.step2) {
        const double speed = std::abs(data.d.velocity[k]);
        if (data.in_group(k, g) && speed < o.determining_speed_multiple * vs) below.push_back(speed);
    }
    const bool spread = !below.empty() &&
                        percentile_at_least(below, 0.9, o.determining_speed_ratio * percentile_in_place(below, 0.1));
    const bool ok = fit.converged && std::isfinite(vs) && vs > bounds.low * o.bound_margin_low &&
                    vs < bounds.high * o.bound_margin_high && delta > o.rise_significance * delta_se &&
                    vs_se < o.max_stribeck_velocity_relative_error * vs && below.size() >= o.minimum_slow_samples &&
                    spread;
    if (ok) return true;
    const ParameterNaming naming{data.d.rotary};
    const std::string direction = data.asymmetric ? (g == 0 ? " (forward)" : " (reverse)") : "";
    if (!(delta > o.rise_significance * delta_se) && fit.converged && std::isfinite(delta)) {
        diagnostics.push_back(fmt::format(
            "Stribeck{}: the slow samples show no friction rise above Coulomb friction that the noise does not "
            "explain (F_B - F_C = {:.3g} +/- {:.2g} {}); F_B and v_s left null",
            direction, delta, delta_se, naming.force_unit()));
    } else {
        const double scale = naming.display_velocity_scale();
        diagnostics.push_back(fmt::format(
            "Stribeck{}: {} quasi-static samples below 3 v_s{}: F_B and v_s are not determined by this data (fit {}); "
            "add constant-velocity passes spanning about 0.3 to 5 times the expected v_s",
            direction, below.size(), below.empty() || spread ? "" : ", all at about one speed",
            fit.converged
                ? fmt::format("v_s = {:.3g} +/- {:.2g} {}", vs * scale, vs_se * scale, naming.display_velocity_unit())
                : "did not converge"));
    }
    return false;
}

/// The accepted curve into the record: M (and F_0), and B, F_C (, F_B, v_s) per group.
void accept(const CurveResult& curve, const detail::CurveLayout& layout, bool separable, FrictionFit& out) {
    const auto& fit = curve.fit;
    out.mass = Estimate::of(curve.mass, curve.mass_se);
    if (layout.offset >= 0)
        out.offset = Estimate::of(fit.parameters(layout.offset), fit.standard_errors(layout.offset));
    for (std::size_t g = 0; g < 2; ++g) {
        if (layout.viscous[g] < 0) continue;
        BranchEstimates& branch = out.groups[g];
        branch.viscous = Estimate::of(fit.parameters(layout.viscous[g]), fit.standard_errors(layout.viscous[g]));
        branch.coulomb = Estimate::of(fit.parameters(layout.coulomb[g]), fit.standard_errors(layout.coulomb[g]));
        if (layout.delta[g] < 0) continue;
        // F_B = F_C + (F_B - F_C): var = var(F_C) + var(F_B - F_C) + 2 cov
        const int c = layout.coulomb[g], e = layout.delta[g];
        const double se_fb =
            std::sqrt(std::max(0.0, fit.covariance(c, c) + fit.covariance(e, e) + 2.0 * fit.covariance(c, e)));
        branch.breakaway = Estimate::of(fit.parameters(c) + fit.parameters(e), se_fb);
        branch.stribeck_velocity =
            Estimate::of(fit.parameters(layout.log_vs[g]), fit.standard_errors(layout.log_vs[g]));
    }
    out.nonlinear = NonlinearFitReport{separable ? "quasi-static curve, mass from the transients" : "joint",
                                       fit.converged,
                                       fit.relative_error_pct,
                                       fit.residual_std,
                                       fit.samples,
                                       fit.iterations};
}

/// The nonlinear fit of the whole curve, refitted without the Stribeck terms the data does not determine.
void fit_nonlinear(const Step2Data& data, FrictionFit& out) {
    const auto& o = data.options;
    detail::CurveModel model{data.asymmetric, true, data.asymmetric, data.offset};
    if (data.asymmetric) {
        model.stribeck_forward = data.slow_count[0] >= o.minimum_slow_samples;
        model.stribeck_reverse = data.slow_count[1] >= o.minimum_slow_samples;
    } else {
        model.stribeck_forward = data.slow_count[0] + data.slow_count[1] >= o.minimum_slow_samples;
    }
    const double threshold = data.s.moving_threshold();
    const double slowest = std::min(data.slow_min[0], data.slow_min[1]);
    SearchBounds bounds;
    bounds.low = std::isfinite(slowest) ? std::max(slowest / o.stribeck_velocity_search_below, threshold) : threshold;
    // up to a third of the typical constant speed (the initial split is a tenth of it): a Stribeck velocity above
    // the split is still determined by the fast quasi-static samples, and a curve accepted there replaces step 1's
    // B and F_C, which the Stribeck friction above the split biases
    bounds.high =
        std::max({data.s.split_velocity(), o.stribeck_velocity_search_above * data.s.initial_split, 2.0 * bounds.low});
    SampleIndices quasi_static;
    for (const auto k : data.s.step1) {
        if (data.s.steady(k)) quasi_static.push_back(k);
    }
    const bool separable = curve_separable(data, quasi_static);
    std::optional<detail::FitSamples> samples;  // the same for every attempt: formed once
    for (int attempt = 0; attempt < o.max_attempts; ++attempt) {
        if (!model.stribeck_forward && !model.stribeck_reverse) break;
        if (!samples) samples = curve_samples(data);
        const CurveResult curve = separable
                                      ? fit_separated(data, *samples, quasi_static, model, bounds.low, bounds.high)
                                      : fit_joint(*samples, model, bounds.low, bounds.high);
        detail::CurveModel fitted = model;
        fitted.mass = !separable;
        const detail::CurveLayout layout(fitted);
        bool all_ok = true;
        for (std::size_t g = 0; g < data.groups(); ++g) {
            bool& enabled = g == 0 ? model.stribeck_forward : model.stribeck_reverse;
            if (enabled && !stribeck_determined(data, curve.fit, layout, g, bounds, out.diagnostics)) {
                enabled = false;
                all_ok = false;
            }
        }
        if (!all_ok) continue;  // refit without the undetermined terms
        accept(curve, layout, separable, out);
        break;
    }
}

}  // namespace

FrictionFit fit_friction_curve(const Derivatives& derivatives, const Selection& selection, const Step1Fit& step1,
                               const FrictionFitOptions& options) {
    FrictionFit out;
    const Step2Data data = make_data(derivatives, selection, step1, options);
    if (options.log_linear) fit_log_linear_per_direction(data, out);
    fit_nonlinear(data, out);
    const std::size_t slow = data.slow_count[0] + data.slow_count[1];
    if (!out.accepted() && slow < options.minimum_slow_samples) {
        const ParameterNaming naming{derivatives.rotary};
        out.diagnostics.push_back(fmt::format(
            "Stribeck: only {} quasi-static samples below {:.3g} {} (a tenth of the typical constant-velocity speed): "
            "F_B and v_s cannot be determined; add slow constant-velocity passes (e.g. 10 to 1000 {}, see feedid "
            "plan)",
            slow, selection.stribeck_band * naming.display_velocity_scale(), naming.display_velocity_unit(),
            naming.display_feed_unit()));
    }
    return out;
}

}  // namespace feedid
