#include "feedid/identify/identify.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <exception>
#include <memory>
#include <thread>

#include <fmt/core.h>
#include <fmt/ranges.h>

#include "feedid/io/tare.hpp"
#include "feedid/io/unit_checks.hpp"
#include "feedid/core/error.hpp"
#include "feedid/numeric/native_interval.hpp"
#include "feedid/numeric/signal.hpp"
#include "feedid/core/version.hpp"

namespace feedid {

std::string IdentifyOptions::validate() const {
    if (const auto problem = drive.validate(); !problem.empty()) return problem;
    if (const auto problem = model_selection.validate(); !problem.empty()) return problem;
    const auto& p = preprocess;
    if (p.filter_order < 1 || p.filter_order > 12) return "--filter-order must be between 1 and 12";
    if (p.cutoff_hz && !(*p.cutoff_hz > 0.0 && std::isfinite(*p.cutoff_hz)))
        return "--cutoff must be a positive frequency [Hz]";
    if (p.decimation < 0 || p.decimation > 1000) return "--decimate must be between 1 and 1000 (0 = automatic)";
    if (p.savitzky_golay_window != 0 && (p.savitzky_golay_window < 5 || p.savitzky_golay_window % 2 == 0)) {
        return "--sg-window must be an odd number of samples >= 5";
    }
    if (p.savitzky_golay_order < 2 || p.savitzky_golay_order > 6) return "--sg-order must be between 2 and 6";
    if (p.savitzky_golay_window != 0 && p.savitzky_golay_order >= p.savitzky_golay_window) {
        return fmt::format("--sg-order {} must be below --sg-window {} (a polynomial of that order needs more samples)",
                           p.savitzky_golay_order, p.savitzky_golay_window);
    }
    for (const auto& [bound, name] : {std::pair{p.from_s, "--from"}, std::pair{p.to_s, "--to"}}) {
        if (bound && !std::isfinite(*bound)) return fmt::format("{} must be a finite time [s]", name);
    }
    if (p.from_s && p.to_s && !(*p.to_s > *p.from_s)) return "--to must be later than --from";
    if (selection.split_velocity && !(*selection.split_velocity >= 0.0 && std::isfinite(*selection.split_velocity)))
        return "--split-velocity must be a finite speed >= 0";
    if (selection.moving_threshold &&
        !(*selection.moving_threshold >= 0.0 && std::isfinite(*selection.moving_threshold)))
        return "--moving-threshold must be a finite speed >= 0";
    const auto& rls = step1.rls;
    if (!(rls.forgetting_factor > 0.0 && rls.forgetting_factor <= 1.0)) return "--lambda must lie in (0, 1]";
    if (!(rls.initial_covariance > 0.0 && std::isfinite(rls.initial_covariance))) return "--p0 must be positive";
    return {};
}

const Parameter* IdentifyResult::find(const std::string& key) const {
    for (const auto& parameter : parameters) {
        if (parameter.key == key) return &parameter;
    }
    return nullptr;
}

const Parameter* IdentifyResult::find(Term term, Direction direction) const {
    for (const auto& parameter : parameters) {
        if (parameter.term == term && parameter.direction == direction) return &parameter;
    }
    return nullptr;
}

std::string IdentifyResult::model_name() const {
    return model == FrictionModelKind::asymmetric ? "asymmetric" : "symmetric";
}

std::vector<Parameter> model_parameters(FrictionModelKind model, bool offset, bool rotary) {
    const ParameterNaming naming{rotary};
    std::vector<Parameter> parameters;
    const auto add = [&](Term term, Direction direction) {
        parameters.push_back(Parameter{naming.key(term, direction),
                                       ParameterNaming::symbol(term, direction),
                                       naming.unit(term),
                                       {},
                                       term,
                                       direction});
    };
    const auto directions = model == FrictionModelKind::asymmetric
                                ? std::vector<Direction>{Direction::forward, Direction::reverse}
                                : std::vector<Direction>{Direction::both};
    add(Term::mass, Direction::both);
    for (const auto direction : directions) {
        add(Term::viscous, direction);
        add(Term::coulomb, direction);
    }
    if (offset) add(Term::offset, Direction::both);
    for (const auto direction : directions) {
        add(Term::breakaway, direction);
        add(Term::stribeck_velocity, direction);
    }
    return parameters;
}

AxisModel axis_from_parameters(const std::vector<Parameter>& parameters, FrictionModelKind model, bool rotary) {
    const auto value = [&](Term term, Direction direction) -> std::optional<double> {
        for (const auto& p : parameters) {
            if (p.term == term && p.direction == direction) return p.estimate.value;
        }
        return std::nullopt;
    };
    const auto branch = [&](Direction direction) {
        FrictionBranch b;
        b.viscous = value(Term::viscous, direction).value_or(0.0);
        b.coulomb = value(Term::coulomb, direction).value_or(0.0);
        const auto breakaway = value(Term::breakaway, direction);
        const auto stribeck_velocity = value(Term::stribeck_velocity, direction);
        if (breakaway && stribeck_velocity) {
            b.breakaway = breakaway;
            b.stribeck_velocity = stribeck_velocity;
        }
        return b;
    };
    AxisModel axis;
    axis.rotary = rotary;
    axis.mass = value(Term::mass, Direction::both).value_or(0.0);
    axis.offset = value(Term::offset, Direction::both).value_or(0.0);
    if (model == FrictionModelKind::asymmetric) {
        axis.friction = Friction{branch(Direction::forward), branch(Direction::reverse)};
    } else {
        axis.friction = Friction::symmetric(branch(Direction::both));
    }
    return axis;
}

namespace {

IdentifyResult start_result(const Trace& trace, const IdentifyOptions& options) {
    IdentifyResult result;
    result.model = options.model;
    result.offset = options.offset;
    result.rotary = trace.rotary;
    result.axis.rotary = trace.rotary;
    result.feedid_version = version;
    const TimeBase base = trace.samples() >= 2 ? trace.time_base() : TimeBase{};
    result.trace = TraceSummary{trace.source_path, trace.format, trace.samples(), base.sample_time_s, base.duration_s};
    result.parameters = model_parameters(options.model, options.offset, trace.rotary);
    return result;
}

IdentifyResult failed(IdentifyResult result, const std::string& why) {
    result.diagnostics.push_back(why);
    result.status = Status::failed;
    return result;
}

Parameter& parameter(IdentifyResult& result, Term term, Direction direction) {
    for (auto& p : result.parameters) {
        if (p.term == term && p.direction == direction) return p;
    }
    throw std::logic_error("identify: the model has no such parameter");
}

/// A batch least-squares fit as reported: per column its key and estimate, the figures of merit and the
/// estimates' correlations.
Step1Report batch_report(const std::vector<RegressorColumn>& columns, const LeastSquaresResult& batch,
                         const ParameterNaming& naming) {
    Step1Report report;
    const auto p = static_cast<Eigen::Index>(columns.size());
    for (Eigen::Index i = 0; i < p; ++i) {
        const auto& column = columns[static_cast<std::size_t>(i)];
        report.keys.push_back(naming.key(column.term, column.direction));
        report.batch.push_back(Estimate::of(batch.estimate(i), batch.standard_error(i)));
    }
    report.relative_error_pct = batch.relative_error_pct;
    report.condition_number = batch.condition_number;
    report.samples_used = batch.samples;
    report.residual_std = batch.residual_std;
    report.r_diagonal.assign(batch.r_diagonal.data(), batch.r_diagonal.data() + batch.r_diagonal.size());
    report.white_noise_standard_error.assign(
        batch.white_noise_standard_error.data(),
        batch.white_noise_standard_error.data() + batch.white_noise_standard_error.size());
    if (batch.covariance.rows() == p && batch.covariance.allFinite()) {
        report.correlation.assign(static_cast<std::size_t>(p), std::vector<double>(static_cast<std::size_t>(p), 0.0));
        for (Eigen::Index i = 0; i < p; ++i) {
            for (Eigen::Index j = 0; j < p; ++j) {
                // from the symmetrised covariance, and within [-1, 1]: rounding in a near-singular sandwich must not
                // print a correlation of 1.0027
                const double scale = std::sqrt(batch.covariance(i, i) * batch.covariance(j, j));
                const double covariance = 0.5 * (batch.covariance(i, j) + batch.covariance(j, i));
                report.correlation[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)] =
                    i == j ? 1.0 : scale > 0.0 ? std::clamp(covariance / scale, -1.0, 1.0) : 0.0;
            }
        }
    }
    return report;
}

/// Correlations above the threshold between M and B, and between B and F_C (per direction), said with the test
/// that would separate them.
void flag_correlations(const Step1Report& report, const std::vector<RegressorColumn>& columns, double threshold,
                       std::vector<std::string>& diagnostics) {
    if (report.correlation.empty()) return;
    for (std::size_t i = 0; i < columns.size(); ++i) {
        for (std::size_t j = i + 1; j < columns.size(); ++j) {
            const Term a = columns[i].term, b = columns[j].term;
            const bool mass_viscous = a == Term::mass && b == Term::viscous;
            const bool viscous_coulomb =
                a == Term::viscous && b == Term::coulomb && columns[i].direction == columns[j].direction;
            const double r = report.correlation[i][j];
            if (!(mass_viscous || viscous_coulomb) || !(std::abs(r) > threshold)) continue;
            const std::string pair = fmt::format("{} and {}", ParameterNaming::symbol(a, columns[i].direction),
                                                 ParameterNaming::symbol(b, columns[j].direction));
            diagnostics.push_back(
                viscous_coulomb
                    ? fmt::format("{} are {:.3f} correlated: the trace holds too few distinct constant speeds to tell "
                                  "viscous from Coulomb friction; record constant-velocity passes at several "
                                  "feedrates (feedid plan designs them)",
                                  pair, r)
                    : fmt::format("{} are {:.3f} correlated: the axis accelerates at too few speeds to tell inertia "
                                  "from viscous friction; record strokes that accelerate at several feedrates, with "
                                  "reversals (feedid plan designs them)",
                                  pair, r));
        }
    }
}

Step1Report step1_report(const Step1Fit& fit, const ParameterNaming& naming) {
    return batch_report(fit.columns, fit.batch, naming);
}

RlsReport rls_report(const Step1Fit& fit, const std::vector<std::string>& keys) {
    const RlsRun& run = *fit.rls;
    RlsReport report;
    report.options = fit.rls_options;
    report.keys = keys;
    report.final_estimate.assign(run.final_estimate.data(), run.final_estimate.data() + run.final_estimate.size());
    report.averaged.assign(run.averaged.data(), run.averaged.data() + run.averaged.size());
    report.settled = run.settled;
    report.transient_end_s = run.transient_end_s;
    report.history_time = run.history_time;
    report.history.assign(keys.size(), {});
    for (std::size_t c = 0; c < keys.size(); ++c) {
        report.history[c].reserve(run.history.size());
        for (const auto& h : run.history) report.history[c].push_back(h(static_cast<Eigen::Index>(c)));
    }
    return report;
}

/// Step 1's estimates into the result, with what the RLS run says about itself.
void apply_step1(const Step1Fit& fit, IdentifyResult& result) {
    if (!fit.residual_finding.empty()) result.diagnostics.push_back(fit.residual_finding);
    for (std::size_t c = 0; c < fit.columns.size(); ++c) {
        const auto i = static_cast<Eigen::Index>(c);
        parameter(result, fit.columns[c].term, fit.columns[c].direction).estimate =
            Estimate::of(fit.batch.estimate(i), fit.batch.standard_error(i));
    }
    if (!fit.rls) return;
    result.rls = rls_report(fit, result.step1->keys);
    if (!fit.rls->settled) {
        result.diagnostics.push_back(
            "RLS: the estimates did not settle within 2 % (or 3 standard errors) of their final values before the "
            "last tenth of the data; rls.averaged is the final value");
    }
    if (fit.rls->wound_up || !fit.rls->covariance_ok) {
        result.diagnostics.push_back(
            "RLS (the paper's exponential forgetting): the covariance wound up in directions the data does not "
            "excite; its estimates are unreliable (use the directional variant)");
    }
}

/// Step 2's accepted curve (if any) replaces step 1's linear values.
void apply_step2(const FrictionFit& fit, IdentifyResult& result) {
    result.stribeck = StribeckReport{fit.log_linear, fit.nonlinear};
    result.diagnostics.insert(result.diagnostics.end(), fit.diagnostics.begin(), fit.diagnostics.end());
    if (!fit.accepted()) return;
    parameter(result, Term::mass, Direction::both).estimate = fit.mass;
    if (result.offset) parameter(result, Term::offset, Direction::both).estimate = fit.offset;
    const bool asymmetric = result.model == FrictionModelKind::asymmetric;
    for (std::size_t g = 0; g < (asymmetric ? 2u : 1u); ++g) {
        const Direction d = !asymmetric ? Direction::both : g == 0 ? Direction::forward : Direction::reverse;
        const BranchEstimates& branch = fit.groups[g];
        parameter(result, Term::viscous, d).estimate = branch.viscous;
        parameter(result, Term::coulomb, d).estimate = branch.coulomb;
        parameter(result, Term::breakaway, d).estimate = branch.breakaway;
        parameter(result, Term::stribeck_velocity, d).estimate = branch.stribeck_velocity;
    }
}

/// A value whose standard error exceeds its magnitude is not determined: say so (the offset may be near zero).
void flag_undetermined(IdentifyResult& result) {
    for (const auto& p : result.parameters) {
        if (p.estimate.value && p.estimate.standard_error && p.term != Term::offset &&
            *p.estimate.standard_error > std::abs(*p.estimate.value)) {
            result.diagnostics.push_back(fmt::format(
                "{} = {:.4g} +/- {:.2g} {}: not determined by this data (standard error larger than the value)",
                p.symbol, *p.estimate.value, *p.estimate.standard_error, p.unit));
        }
    }
}

/// The quasi-static samples' friction (force less M*x'' and the offset), in 40 bins equally spaced in log speed,
/// filled in one pass (no sort: a million-sample trace), per direction; fewer than 5 samples give no curve.
std::optional<FrictionCurvePoints> bin_friction_curve(const Derivatives& d, const Selection& s, const AxisModel& axis,
                                                      bool forward) {
    constexpr int bins = 40;
    constexpr std::size_t minimum_points = 5;
    std::vector<std::pair<double, double>> points;  // |v|, friction magnitude
    for (const auto k : s.moving) {
        if (!s.steady(k) || (d.velocity[k] > 0) != forward) continue;
        const double friction = (d.force[k] - axis.mass * d.acceleration[k] - axis.offset) * (forward ? 1.0 : -1.0);
        points.emplace_back(std::abs(d.velocity[k]), friction);
    }
    if (points.size() < minimum_points) return std::nullopt;
    double low = INFINITY, high = 0.0;
    for (const auto& [speed, force] : points) {
        low = std::min(low, speed);
        high = std::max(high, speed);
    }
    low = std::max(low, 1e-9);
    const double span = std::log(std::max(high, low * (1.0 + 1e-12)) / low);
    std::array<double, bins> sum_v{}, sum_f{};
    std::array<std::size_t, bins> count{};
    for (const auto& [speed, force] : points) {
        const auto b = static_cast<std::size_t>(
            std::clamp(static_cast<int>(bins * std::log(std::max(speed, low) / low) / span), 0, bins - 1));
        sum_v[b] += speed;
        sum_f[b] += force;
        ++count[b];
    }
    const FrictionBranch& branch = forward ? axis.friction.forward : axis.friction.reverse;
    FrictionCurvePoints curve;
    for (std::size_t b = 0; b < bins; ++b) {
        if (count[b] == 0) continue;
        const double speed = sum_v[b] / static_cast<double>(count[b]);
        curve.speed.push_back(speed);
        curve.force.push_back(sum_f[b] / static_cast<double>(count[b]));
        curve.fitted.push_back(branch.magnitude(speed));
    }
    return curve;
}

/// The reason in figures why M is null, from the resolution and the friction-only fit.
std::string mass_reason(const Derivatives& d, const Resolution& resolution, const FrictionOnlyFit& fit,
                        const std::string& step1_failure) {
    const ParameterNaming naming{d.rotary};
    std::string reason = fmt::format("{}: mass not identifiable: {}", d.source, resolution.description);
    if (!resolution.coarse() && !step1_failure.empty())
        reason += "; the acceleration explains too little of the drive force";
    if (fit.largest_acceleration > 0.0) {
        reason += fmt::format(
            "; the largest acceleration the samples resolve, {:.3g} {}/s^2, would lift the inertial force of a mass "
            "below {:.3g} {} no higher than {:g}x the friction scatter {:.3g} {}",
            fit.largest_acceleration, d.rotary ? "rad" : "m", fit.smallest_detectable_mass, naming.unit(Term::mass),
            FrictionOnlyOptions{}.detectable_force_multiple, fit.batch.residual_std, naming.force_unit());
    }
    return reason;
}

/// M (and the Stribeck terms) null, B and F_C from the steady-speed samples; failed when those cannot give them
/// either.
IdentifyResult friction_only_result(IdentifyResult result, const Derivatives& d, const Selection& s,
                                    const Resolution& resolution, const std::string& step1_failure,
                                    const IdentifyOptions& options) {
    const FrictionOnlyFit fit = fit_friction_only(d, s, options.model, options.offset, options.friction_only);
    if (fit.failed()) {
        std::string why = step1_failure;
        if (why.empty()) {
            why = fmt::format("{}: the trace carries no usable mass information: {}", d.source, resolution.description);
            if (d.travel < options.step1.creep_travel) {
                why += fmt::format("; a micro-step or creep test (the axis travelled {:.3g} {}) cannot determine mass",
                                   d.travel * (d.rotary ? 1.0 : 1e6), d.rotary ? "rad" : "um");
            }
        }
        return failed(std::move(result),
                      fmt::format("{}; friction alone cannot be identified either: {}", why, fit.failure));
    }
    if (auto opposed = opposed_drive_signal(fit.columns, fit.batch, d, options.step1.sign_standard_errors))
        return failed(std::move(result), *opposed);
    const ParameterNaming naming{d.rotary};
    Step1Report report = batch_report(fit.columns, fit.batch, naming);
    for (std::size_t c = 0; c < fit.columns.size(); ++c)
        parameter(result, fit.columns[c].term, fit.columns[c].direction).estimate = report.batch[c];
    flag_correlations(report, fit.columns, options.correlation_finding, result.diagnostics);
    result.step1 = std::move(report);
    const std::string reason = mass_reason(d, resolution, fit, step1_failure);
    result.friction_only = FrictionOnlyReport{reason, fit.samples, fit.batch.relative_error_pct,
                                              fit.batch.residual_std, fit.rejected};
    result.diagnostics.push_back(reason);
    result.diagnostics.push_back(fmt::format(
        "friction only: B and F_C from {} steady-speed samples (the drive force there is friction){}; F_B and v_s not "
        "estimated",
        fit.samples,
        fit.rejected == 0 ? std::string()
                          : fmt::format(", {} of them rejected by the robust weights (a load the model has no term "
                                        "for: cutting?)",
                                        fit.rejected)));
    if (fit.level_correlation > 0.0)
        result.diagnostics.push_back(fmt::format(
            "friction only: the steady passes' friction levels carry over from pass to pass (correlation {:.2f} from "
            "one to the next, {} passes: the friction drifts during the log, warming up?); the standard errors count "
            "it",
            fit.level_correlation, fit.passes));
    flag_undetermined(result);
    result.axis = axis_from_parameters(result.parameters, result.model, result.rotary);
    result.friction_curve =
        FrictionCurveReport{bin_friction_curve(d, s, result.axis, true), bin_friction_curve(d, s, result.axis, false)};
    result.status = Status::partial;
    return result;
}

/// B and F_C of a direction group whose constant-speed samples all run at about one speed (their 90th percentile
/// below separable_speed_ratio times their 10th) and make most of step 1's samples: then the friction at that speed,
/// F_C + B*v, is well determined, and what splits it into B and F_C is the ramps' few samples, where anything step 1
/// does not model (a Stribeck tail, the current loop's lag) decides it. Both null, and the friction the speed does
/// determine said in figures. A single long move whose ramps are most of the samples keeps them (the rig's drive:
/// 22 % of step 1 steady).
void null_inseparable_friction(IdentifyResult& result, const Derivatives& d, const Selection& s,
                               const IdentifyOptions& options) {
    const ParameterNaming naming{d.rotary};
    const bool asymmetric = result.model == FrictionModelKind::asymmetric;
    for (int g = 0; g < (asymmetric ? 2 : 1); ++g) {
        const Direction direction = !asymmetric ? Direction::both : g == 0 ? Direction::forward : Direction::reverse;
        std::vector<double> speeds;
        for (const auto k : s.moving) {
            if (s.steady(k) && (!asymmetric || (d.velocity[k] > 0.0) == (g == 0)))
                speeds.push_back(std::abs(d.velocity[k]));
        }
        const double low = percentile_in_place(speeds, 0.1);
        if (speeds.empty() || percentile_at_least(speeds, 0.9, options.separable_speed_ratio * low)) continue;
        // B rests on the ramps: trusted where they are most of step 1's samples (a single long move), not where a
        // few ramp samples decide it against many at the one speed
        std::size_t in_group = 0, steady = 0;
        for (const auto k : s.step1) {
            if (asymmetric && (d.velocity[k] > 0.0) != (g == 0)) continue;
            ++in_group;
            if (s.steady(k)) ++steady;
        }
        const bool mostly_steady =
            static_cast<double>(steady) > options.inseparable_steady_fraction * static_cast<double>(in_group);
        if (!mostly_steady) continue;
        Estimate& viscous = parameter(result, Term::viscous, direction).estimate;
        Estimate& coulomb = parameter(result, Term::coulomb, direction).estimate;
        if (!viscous.value || !coulomb.value) continue;
        const double high = percentile_in_place(speeds, 0.9), speed = percentile_in_place(speeds, 0.5);
        result.diagnostics.push_back(fmt::format(
            "{} and {}: the constant-speed samples all run at about {:.4g} {} (10th to 90th percentile {:.4g} to "
            "{:.4g}): one speed determines only the friction there, {:.5g} {}, not how it splits into viscous and "
            "Coulomb friction; both left null. Record constant-velocity passes at several feedrates (feedid plan "
            "designs them)",
            ParameterNaming::symbol(Term::viscous, direction), ParameterNaming::symbol(Term::coulomb, direction),
            speed * naming.display_velocity_scale(), naming.display_velocity_unit(),
            low * naming.display_velocity_scale(), high * naming.display_velocity_scale(),
            *coulomb.value + *viscous.value * speed, naming.force_unit()));
        viscous = Estimate{};
        coulomb = Estimate{};
    }
}

/// The parameter of (term, direction), or nullptr when the model has none.
Parameter* find_parameter(IdentifyResult& result, Term term, Direction direction) {
    for (auto& p : result.parameters) {
        if (p.term == term && p.direction == direction) return &p;
    }
    return nullptr;
}

/// Pairs of step-1 estimates correlated beyond the limit: the data determine only a combination of them, so both
/// are null, with the reason.
void null_collinear(IdentifyResult& result, const std::vector<RegressorColumn>& columns, double limit) {
    if (!result.step1 || result.step1->correlation.empty()) return;
    const auto& correlation = result.step1->correlation;
    for (std::size_t i = 0; i < columns.size(); ++i) {
        for (std::size_t j = i + 1; j < columns.size(); ++j) {
            if (!(std::abs(correlation[i][j]) > limit)) continue;
            Parameter* a = find_parameter(result, columns[i].term, columns[i].direction);
            Parameter* b = find_parameter(result, columns[j].term, columns[j].direction);
            if (a == nullptr || b == nullptr || (!a->estimate.value && !b->estimate.value)) continue;
            result.diagnostics.push_back(fmt::format(
                "{} and {} are {:.4f} correlated (beyond {:g}): the data determine only a combination of them, not "
                "each; both left null",
                a->symbol, b->symbol, correlation[i][j], limit));
            a->estimate = Estimate{};
            b->estimate = Estimate{};
        }
    }
}

/// The RLS report without the columns `drop` names (a number the data cannot determine is not printed, not even as
/// the recursive estimate's).
template <typename Drop>
void drop_rls_columns(RlsReport& rls, Drop drop) {
    for (std::size_t c = rls.keys.size(); c-- > 0;) {
        if (!drop(rls.keys[c])) continue;
        const auto at = static_cast<std::ptrdiff_t>(c);
        rls.keys.erase(rls.keys.begin() + at);
        if (c < rls.final_estimate.size()) rls.final_estimate.erase(rls.final_estimate.begin() + at);
        if (c < rls.averaged.size()) rls.averaged.erase(rls.averaged.begin() + at);
        if (c < rls.history.size()) rls.history.erase(rls.history.begin() + at);
    }
}

/// What the model-adequacy stage found, into the result: friction that a constant force aliases null; the delay's
/// standard error carried into the linear parameters it moves.
void apply_model_choice(IdentifyResult& result, const ModelChoice& choice, const std::vector<RegressorColumn>& columns) {
    if (!choice.aliased_friction.empty()) {
        result.diagnostics.push_back(choice.aliased_friction);
        const auto aliased = [](Term term) {
            return term == Term::coulomb || term == Term::breakaway || term == Term::offset;
        };
        for (auto& p : result.parameters) {
            if (aliased(p.term)) p.estimate = Estimate{};
        }
        if (result.rls) drop_rls_columns(*result.rls, [&](const std::string& key) {
            const auto parsed = parse_parameter_key(key);
            return parsed && aliased(parsed->term);
        });
    }
    if (!(choice.delay_applied || choice.delay_uncertain) || !choice.delay_standard_error ||
        choice.delay_sensitivity.size() != columns.size())
        return;
    std::vector<std::string> widened;
    for (std::size_t c = 0; c < columns.size(); ++c) {
        Parameter* p = find_parameter(result, columns[c].term, columns[c].direction);
        if (p == nullptr || !p->estimate.value || !p->estimate.standard_error) continue;
        // d theta / d tau * sigma_tau, in quadrature with the fit's own standard error
        const double own = *p->estimate.standard_error;
        p->estimate.standard_error = std::hypot(own, choice.delay_sensitivity[c] * *choice.delay_standard_error);
        if (*p->estimate.standard_error > 2.0 * own)
            widened.push_back(fmt::format("{} from {:.2g} to {:.2g} {}", p->symbol, own, *p->estimate.standard_error,
                                          p->unit));
    }
    if (!choice.delay_applied && choice.delay_s && !widened.empty()) {
        // the user sees why a standard error is wide, and what test would narrow it
        result.diagnostics.push_back(fmt::format(
            "the drive signal's timing is not determined by these samples ({:.3g} ms +/- {:.2g}, not significant: "
            "no delay applied); its uncertainty widens the standard error of {}. Passes at constant speed at several "
            "feedrates, or reversals at speed, determine it (--delay TIME applies a known one)",
            *choice.delay_s * 1e3, *choice.delay_standard_error * 1e3, fmt::join(widened, ", ")));
    }
}

/// Where to look when the residual shows structure by `grouping`.
std::string lack_of_fit_hint(const std::string& grouping) {
    if (grouping == "speed")
        return "the friction at those speeds is not the model's (a Stribeck rise step 2 could not fit, friction that "
               "is not linear in the speed)";
    if (grouping == "acceleration")
        return "a force goes with the acceleration that the mass does not explain (a drive signal out of step with "
               "the position: --delay auto; an elastic transmission; a current loop's lag)";
    return "a force changes over the recording (a load, warm-up, friction that changes along the axis: "
           "--by-location)";
}

/// The lack-of-fit checks of the identified model (where its mass and friction were identified; without a Stribeck
/// term on step 1's samples only), into the model choice. Where one fails, the standard errors are scaled by the
/// largest Birge ratio sqrt(chi-square / groups) of the failed checks, and the diagnostics say so. False when one
/// failed: the standard errors are those of a model the data reject.
bool check_model_fit(IdentifyResult& result, const Derivatives& derivatives, const Selection& selection,
                     const IdentifyOptions& options) {
    const bool core_null = std::any_of(result.parameters.begin(), result.parameters.end(), [](const Parameter& p) {
        return !p.estimate.value && p.term != Term::breakaway && p.term != Term::stribeck_velocity;
    });
    if (!result.model_choice || core_null) return true;
    auto& checks = result.model_choice->fit_checks;
    checks = check_fit(derivatives, selection, result.axis, options.model_selection);
    const ParameterNaming naming{derivatives.rotary};
    double scale = 1.0;
    for (const FitCheck& check : checks) {
        if (check.passed) continue;
        const double ratio = std::sqrt(check.chi_square / static_cast<double>(check.groups));
        scale = std::max(scale, ratio);
        result.diagnostics.push_back(fmt::format(
            "the model does not fit the data: its residual by {} holds {:.3g} +/- {:.2g} {} {} ({:.1f} % of the "
            "typical drive force; {:.1f} standard deviates over {} groups, chi-square per group {:.3g}), which no "
            "parameter of the model explains; {}",
            check.name, check.largest, check.largest_standard_error, naming.force_unit(), check.where,
            100.0 * check.relative, *check.statistic, check.groups, ratio * ratio, lack_of_fit_hint(check.name)));
    }
    if (scale == 1.0) return true;
    for (auto& p : result.parameters) {
        if (p.estimate.standard_error) *p.estimate.standard_error *= scale;
    }
    result.diagnostics.push_back(fmt::format(
        "standard errors scaled by {:.3g}, the square root of the largest chi-square per group of the failed fit "
        "checks: they hold for the model only as far as its lack of fit is random",
        scale));
    return false;
}

/// Steps 1 and 2 on the selected samples, and the result's final touches.
IdentifyResult fit_steps(IdentifyResult result, const Derivatives& derivatives, const Regressors& regressors,
                         const Selection& selection, const IdentifyOptions& options, const ModelChoice& choice) {
    Step1Options step1_options = options.step1;
    step1_options.run_rls = step1_options.run_rls && !options.estimates_only;
    const Step1Fit step1 = fit_step1(regressors, derivatives, selection.step1, step1_options);
    if (step1.batch.samples > 0) result.step1 = step1_report(step1, ParameterNaming{derivatives.rotary});
    if (step1.failed()) {
        if (!step1.mass_unidentifiable) return failed(std::move(result), step1.failure);
        return friction_only_result(std::move(result), derivatives, selection,
                                    assess_resolution(derivatives, options.friction_only), step1.failure, options);
    }
    apply_step1(step1, result);
    flag_correlations(*result.step1, step1.columns, options.correlation_finding, result.diagnostics);

    if (options.stribeck) {
        FrictionFitOptions friction_options = options.friction;
        friction_options.minimum_slow_samples = options.selection.minimum_slow_samples;
        friction_options.correlation_blocks = options.step1.correlation_blocks;
        friction_options.log_linear = friction_options.log_linear && !options.estimates_only;
        apply_step2(fit_friction_curve(derivatives, selection, step1, friction_options), result);
    } else {
        result.stribeck = StribeckReport{};
        result.diagnostics.push_back("Stribeck step skipped (--no-stribeck): F_B and v_s not estimated");
    }
    null_inseparable_friction(result, derivatives, selection, options);
    apply_model_choice(result, choice, step1.columns);
    null_collinear(result, step1.columns, options.model_selection.collinearity_limit);
    flag_undetermined(result);
    result.axis = axis_from_parameters(result.parameters, result.model, result.rotary);
    if (!options.estimates_only) {
        result.friction_curve = FrictionCurveReport{bin_friction_curve(derivatives, selection, result.axis, true),
                                                    bin_friction_curve(derivatives, selection, result.axis, false)};
    }
    const bool any_null = std::any_of(result.parameters.begin(), result.parameters.end(),
                                      [](const Parameter& p) { return !p.estimate.value; });
    // the family's reruns report their estimates alone: the fit checks would only scale standard errors nobody reads
    const bool fits = options.estimates_only || check_model_fit(result, derivatives, selection, options);
    result.status = any_null || !fits ? Status::partial : Status::ok;
    return result;
}

/// The first stage's output and the regressors that view it: what runs with the same preprocessing share. With it,
/// the part of the selection that no split speed and no model changes (the moving samples, the quasi-static flags,
/// the stick-slip passes), kept by a run for the next one on these samples (the family's split variant).
struct Preprocessed {
    Derivatives derivatives;
    Regressors regressors;
    std::optional<MovingSamples> moving{};
};

/// What the model-adequacy stage needs to know of the drive signal beyond the Derivatives: whether its zero was
/// removed at import (--tare), and its level at rest before the move.
struct DriveSignalFacts {
    bool tared{false};
    std::optional<RestLevel> rest;
};

/// Standard errors over blocks long enough for step 1's residual: where the residual stays correlated beyond the
/// low-pass's reach (a force the model misses that varies slowly), the blocks of both steps lengthen to
/// autocorrelation_blocks integrated autocorrelation times, and the result records it.
void widen_correlation_block(const Derivatives& d, const Regressors& regressors, const Selection& selection,
                             IdentifyOptions& options, std::optional<ModelChoice>& choice) {
    const double tau = residual_autocorrelation_time(d, regressors, selection.step1);
    const double needed = options.model_selection.autocorrelation_blocks * tau;
    const double current = options.step1.correlation_blocks * static_cast<double>(d.correlation_samples);
    if (choice) choice->residual_autocorrelation_samples = tau;
    if (needed <= current || d.correlation_samples == 0) return;
    options.step1.correlation_blocks = needed / static_cast<double>(d.correlation_samples);
    if (choice) choice->correlation_block_samples = static_cast<std::size_t>(std::ceil(needed));
}

bool drive_tared(const Trace& trace) {
    const Channel* drive = trace.has(Role::force) ? trace.find(Role::force) : trace.find(Role::current);
    return drive != nullptr && drive->tare_removed.has_value();
}

DriveSignalFacts drive_signal_facts(const Trace& trace, std::span<const double> force) {
    return DriveSignalFacts{drive_tared(trace), rest_level(force, leading_rest_samples(trace))};
}

/// Stages 2 to 4 (selection, resolution check, model adequacy, steps 1 and 2) on preprocessed samples. The
/// model-adequacy stage may read the drive force later (a delay) and choose another model than the regressors were
/// built for: the force in `p` is then shifted and the regressors rebuilt. The selection starts from the moving
/// samples `p` holds, when an earlier run kept them; with `keep_moving`, this run's go back into `p`.
IdentifyResult run_stages_on(IdentifyResult result, Preprocessed& p, const IdentifyOptions& options,
                             const DriveSignalFacts& drive, bool keep_moving = false) {
    Derivatives& derivatives = p.derivatives;
    SelectionOptions selection_options = options.selection;
    selection_options.stribeck = options.stribeck;
    selection_options.minimum_step1_samples_per_parameter = options.step1.minimum_samples_per_parameter;
    MovingSamples moving = p.moving ? std::move(*p.moving) : select_moving_samples(derivatives, selection_options);
    p.moving.reset();
    Selection selection = select_samples(derivatives, p.regressors, selection_options, std::move(moving));
    result.preprocessing = derivatives.used;
    result.selection = selection.report;
    // what was left out because the data there is not the model's, said where every reader looks
    for (const auto& note : selection.report.notes) {
        if (note.find("stick-slip") != std::string::npos || note.find("clipped or saturated") != std::string::npos)
            result.diagnostics.push_back(note);
    }
    if (const Resolution resolution = assess_resolution(derivatives, options.friction_only); resolution.coarse())
        return friction_only_result(std::move(result), derivatives, selection, resolution, {}, options);
    // the models the stage fits share their low-passed columns with the regressor built and the one chosen; the
    // others are released before the fit
    auto columns = std::make_unique<RegressorColumnCache>();
    columns->remember(p.regressors);
    const ModelChoice choice = choose_model(derivatives, selection, options.model, options.offset, drive.tared,
                                            drive.rest, options.model_selection, options.step1.correlation_blocks,
                                            columns.get());
    if (!choice.process_forces.empty()) {
        result.model_choice = choice;
        return failed(std::move(result), choice.process_forces);
    }
    IdentifyOptions chosen = options;
    chosen.model = choice.model;
    chosen.offset = choice.offset;
    const auto wanted = linear_columns(choice.model, choice.offset);
    const bool same_columns = std::equal(wanted.begin(), wanted.end(), p.regressors.columns.begin(),
                                         p.regressors.columns.end(), [](const auto& a, const auto& b) {
                                             return a.term == b.term && a.direction == b.direction;
                                         });
    if (!same_columns) {
        // the Stribeck checks of the selection fit the step-1 model: the chosen one. The old regressor, the columns
        // the new one does not take and the old selection are released first (identify's peak is here then)
        p.regressors = Regressors{};
        if (choice.model == FrictionModelKind::asymmetric) columns.reset();
        p.regressors = build_regressors(derivatives, choice.model, choice.offset, columns.get());
        columns.reset();
        MovingSamples again = release_moving_samples(std::move(selection));  // no model changes them
        selection = Selection{};
        selection = select_samples(derivatives, p.regressors, selection_options, std::move(again));
        result.selection = selection.report;
    }
    if (result.model != choice.model || result.offset != choice.offset) {
        result.model = choice.model;
        result.offset = choice.offset;
        result.parameters = model_parameters(choice.model, choice.offset, result.rotary);
    }
    columns.reset();
    result.diagnostics.insert(result.diagnostics.end(), choice.findings.begin(), choice.findings.end());
    result.model_choice = choice;
    widen_correlation_block(derivatives, p.regressors, selection, chosen, result.model_choice);
    const ModelChoice final_choice = *result.model_choice;  // result moves into fit_steps
    result = fit_steps(std::move(result), derivatives, p.regressors, selection, chosen, final_choice);
    if (keep_moving) p.moving = release_moving_samples(std::move(selection));
    return result;
}

/// The four stages on a drive force (N, or the drive signal's own unit when no constant is known). A trace too
/// coarse for a mass (its figures say so before any fit: a mass fitted to it would be noise) gives a friction-only
/// result, or fails saying why in figures. With `keep`, the preprocessed samples are handed back (for runs that
/// share them) when the stages got that far. The drive force is formed from `drive` for the first stage alone and
/// released after it: the later stages read the filtered force in the Derivatives, and every run forms its own
/// (the same values) rather than all of them holding one for the whole of identify.
/// `facts`, when given, are the drive signal's (the same force in every run of one identify: found once).
IdentifyResult run_stages(const Trace& trace, const DriveConstants& drive, const IdentifyOptions& options,
                          std::optional<Preprocessed>* keep = nullptr, DriveSignalFacts* facts_found = nullptr,
                          const DriveSignalFacts* facts_given = nullptr) {
    std::vector<double> force = drive_force(trace, drive);  // throws without a constant
    const DriveSignalFacts facts = facts_given != nullptr ? *facts_given : drive_signal_facts(trace, force);
    if (facts_found != nullptr) *facts_found = facts;
    IdentifyResult result = start_result(trace, options);
    Preprocessed p{preprocess(trace, force, options.preprocess), {}};
    std::vector<double>().swap(force);
    result.diagnostics.insert(result.diagnostics.end(), p.derivatives.notes.begin(), p.derivatives.notes.end());
    if (p.derivatives.failed()) return failed(std::move(result), p.derivatives.failure);
    p.regressors = build_regressors(p.derivatives, options.model, options.offset);
    result = run_stages_on(std::move(result), p, options, facts, keep != nullptr);
    if (keep != nullptr) keep->emplace(std::move(p));
    return result;
}

/// The options of a family member: the nominal run's with its preprocessing (and split).
IdentifyOptions member_options(const IdentifyOptions& base, const PreprocessingVariant& variant) {
    IdentifyOptions options = base;
    options.preprocess = variant.options;
    if (variant.split_velocity) options.selection.split_velocity = variant.split_velocity;
    return options;
}

/// Bytes per sample a rerun of the stages holds at its peak (the Derivatives' four columns, the filtered sgn(x')
/// column, the selection's indices and flags, step 2's index lists: about 70, measured with heaptrack and the peak
/// resident set on bench_identify_scaling's trace), what all runs share (the trace's time, position and current),
/// and the budget per sample identify keeps to (issue 14).
constexpr double rerun_bytes_per_sample = 72.0;
constexpr double shared_bytes_per_sample = 24.0;
constexpr double budget_bytes_per_sample = 100.0;

/// The stages over each member of the family whose preprocessing differs from the nominal run's; as many at a time
/// as the memory budget and the cores allow (the runs share nothing but the trace, read only); a
/// member the trace cannot take (InputError) is empty. Members with the nominal preprocessing (the split variant)
/// are not run here.
std::vector<std::optional<IdentifyResult>> run_family(const Trace& trace, const IdentifyOptions& base,
                                                      const std::vector<PreprocessingVariant>& family,
                                                      const DriveSignalFacts& facts) {
    std::vector<std::optional<IdentifyResult>> runs(family.size());
    std::vector<std::exception_ptr> errors(family.size());
    std::vector<std::size_t> todo;
    for (std::size_t v = 0; v < family.size(); ++v) {
        if (!family[v].split_velocity) todo.push_back(v);
    }
    std::atomic<std::size_t> next{0};
    const auto work = [&] {
        for (std::size_t i = next++; i < todo.size(); i = next++) {
            const std::size_t v = todo[i];
            try {
                runs[v] = run_stages(trace, base.drive, member_options(base, family[v]), nullptr, nullptr, &facts);
            } catch (const InputError&) {
                runs[v].reset();
            } catch (...) {
                errors[v] = std::current_exception();  // an internal error: raised again on the calling thread
            }
        }
    };
    const unsigned cores = base.threads > 0 ? base.threads : std::max(1u, std::thread::hardware_concurrency());
    // reruns in parallel only while their buffers fit the budget (the same count at every trace length: the time
    // stays linear in it)
    const auto fitting =
        static_cast<std::size_t>((budget_bytes_per_sample - shared_bytes_per_sample) / rerun_bytes_per_sample);
    const std::size_t threads = std::min<std::size_t>({todo.size(), cores, std::max<std::size_t>(1, fitting)});
    std::vector<std::thread> pool;
    for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work);
    work();
    for (auto& thread : pool) thread.join();
    for (const auto& error : errors) {
        if (error) std::rethrow_exception(error);
    }
    return runs;
}

/// The preprocessing family's estimates (preprocessing_family.hpp): each parameter's systematic part is the largest deviation
/// of a variant's estimate from the nominal one (variants that leave it undetermined do not count; with none left it
/// stays unassessed), said in a finding where it exceeds the multiple of the standard error.
/// The samples step 1 takes depend on the model the selection assumed (its Stribeck checks fit it): where the model
/// chosen from the data made the selection run again, how far the final linear estimates lie from the chosen model's
/// on the first selection's samples counts with the preprocessing family's spread.
void add_selection_sensitivity(const IdentifyResult& result, std::vector<std::optional<double>>& spread,
                               std::vector<std::string>& widest) {
    if (!result.model_choice || result.model_choice->first_selection_estimate.empty()) return;
    const auto& first = result.model_choice->first_selection_estimate;
    const auto columns = linear_columns(result.model, result.offset);
    if (columns.size() != first.size()) return;
    for (std::size_t c = 0; c < columns.size(); ++c) {
        for (std::size_t i = 0; i < result.parameters.size(); ++i) {
            const Parameter& p = result.parameters[i];
            if (p.term != columns[c].term || p.direction != columns[c].direction || !p.estimate.value) continue;
            const double deviation = std::abs(*p.estimate.value - first[c]);
            if (!spread[i] || deviation > *spread[i]) widest[i] = "the samples selected under the symmetric model";
            spread[i] = std::max(spread[i].value_or(0.0), deviation);
        }
    }
}

void assess_systematic(const Trace& trace, const IdentifyOptions& options, std::optional<Preprocessed>& nominal,
                       const DriveSignalFacts& facts, IdentifyResult& result) {
    const bool from_velocity = result.preprocessing->velocity_source == "velocity";
    const double interval = native_interval_of(trace, from_velocity ? Role::velocity : Role::position);
    // every member fits the nominal run's model: the family measures the preprocessing, not the model choice
    IdentifyOptions variant_options = options;
    variant_options.systematic = false;
    variant_options.estimates_only = true;
    variant_options.model = result.model;
    variant_options.offset = result.offset;
    variant_options.model_selection.automatic = false;
    variant_options.model_selection.delay = ModelSelectionOptions::Delay::none;
    variant_options.model_selection.test_forced = false;
    // members with their own preprocessing read the drive force as late as the nominal run did; the split variants
    // share the nominal run's samples, already aligned
    IdentifyOptions shared_options = variant_options;
    shared_options.model_selection.known_delay_s.reset();
    if (result.model_choice && result.model_choice->delay_applied)
        variant_options.model_selection.known_delay_s = result.model_choice->delay_s;
    SystematicReport report;
    std::vector<std::optional<double>> spread(result.parameters.size());
    std::vector<std::string> widest(result.parameters.size());
    const ParameterNaming naming{result.rotary};
    // the larger of the split used and the one chosen before slow ramps joined step 1: doubling a split that fell to
    // the moving threshold would test nothing
    const double split =
        result.selection ? std::max(result.selection->split_velocity, result.selection->initial_split) : 0.0;
    const auto family = preprocessing_family(options.preprocess, *result.preprocessing, interval, split,
                                             naming.display_velocity_scale(), naming.display_velocity_unit());
    // the members with the nominal preprocessing first, on the nominal run's samples and moving samples (no split
    // changes those), which are then released
    std::vector<std::optional<IdentifyResult>> shared(family.size());
    const DriveSignalFacts aligned{drive_tared(trace), result.model_choice ? result.model_choice->rest : std::nullopt};
    for (std::size_t v = 0; v < family.size(); ++v) {
        if (!family[v].split_velocity || !nominal) continue;
        IdentifyResult start = start_result(trace, shared_options);
        start.diagnostics = nominal->derivatives.notes;  // as the stages would have noted them again
        shared[v] = run_stages_on(std::move(start), *nominal, member_options(shared_options, family[v]), aligned, true);
    }
    nominal.reset();
    auto runs = run_family(trace, variant_options, family, facts);
    for (std::size_t v = 0; v < family.size(); ++v) {
        if (family[v].split_velocity) runs[v] = std::move(shared[v]);
    }
    for (std::size_t v = 0; v < family.size(); ++v) {
        if (!runs[v]) continue;  // a variant this trace cannot take (a window longer than the trace)
        const auto& variant = family[v];
        const IdentifyResult& other = *runs[v];
        SystematicVariant record{variant.label, other.status, {}, {}};
        for (std::size_t i = 0; i < result.parameters.size(); ++i) {
            const Parameter& nominal = result.parameters[i];
            const Parameter* found = other.find(nominal.key);
            const std::optional<double> value = found != nullptr ? found->estimate.value : std::nullopt;
            record.keys.push_back(nominal.key);
            record.values.push_back(value);
            if (!nominal.estimate.value || !value) continue;
            const double deviation = std::abs(*value - *nominal.estimate.value);
            if (!spread[i] || deviation > *spread[i]) widest[i] = variant.label;
            spread[i] = std::max(spread[i].value_or(0.0), deviation);
        }
        report.variants.push_back(std::move(record));
    }
    add_selection_sensitivity(result, spread, widest);
    for (std::size_t i = 0; i < result.parameters.size(); ++i) {
        Parameter& p = result.parameters[i];
        if (!spread[i]) continue;
        p.estimate.set_systematic(*spread[i]);
        const double statistical = p.estimate.standard_error.value_or(0.0);
        if (*spread[i] > options.systematic_finding_multiple * statistical) {
            result.diagnostics.push_back(fmt::format(
                "{} = {:.4g} {}: other reasonable preprocessing moves it by up to {:.2g} (most with {}), more than "
                "{:g} times its standard error {:.2g}: the choice of filter and split decides this value as much as "
                "the noise does; its uncertainty {:.2g} includes that",
                p.symbol, *p.estimate.value, p.unit, *spread[i], widest[i], options.systematic_finding_multiple,
                statistical, *p.estimate.uncertainty));
        }
    }
    result.systematic = std::move(report);
}

/// A drive signal without a constant that turns it into force (a current in A, no --kt/--lead).
const Channel* signal_without_force_constant(const Trace& trace, const DriveConstants& drive) {
    const Channel* current = trace.find(Role::current);
    if (trace.has(Role::force) || current == nullptr || current->unit == "N" || current->unit == "N*m") return nullptr;
    if (!drive.validate().empty() || drive.force_per_signal(trace)) return nullptr;
    return current;
}

}  // namespace

IdentifyResult identify(const Trace& trace, const IdentifyOptions& options) {
    if (const auto problem = options.validate(); !problem.empty()) throw InputError(problem);
    const TimeBaseMemo time_base(trace);  // one pass over the time column, not one per stage and run
    require_consistent_units(trace);
    if (const Channel* signal = signal_without_force_constant(trace, options.drive)) {
        // Whether the data can identify anything at all does not depend on the force constant: find out in signal
        // units first, so that a trace that cannot identify a mass says so (exit 1) instead of asking for a constant
        // that would not help.
        DriveConstants unit_constant;
        unit_constant.force_constant = 1.0;
        IdentifyResult provisional = run_stages(trace, unit_constant, options);
        if (provisional.status == Status::failed) {
            provisional.diagnostics.push_back(
                fmt::format("{}: (figures above in units of the drive signal '{}': no force constant was given)",
                            trace.source_path.empty() ? std::string("trace") : trace.source_path, signal->name));
            return provisional;
        }
    }
    std::optional<Preprocessed> nominal;
    DriveSignalFacts facts;
    IdentifyResult result =
        run_stages(trace, options.drive, options, options.systematic ? &nominal : nullptr, &facts);
    if (options.systematic && result.status != Status::failed && result.preprocessing)
        assess_systematic(trace, options, nominal, facts, result);
    // Drive constants outside what feed drives have: the figures are right for the constants given, which may not be.
    for (auto& warning : options.drive.warnings()) result.diagnostics.push_back(std::move(warning));
    return result;
}

}  // namespace feedid
