#include "feedid/identify/selection.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>

#include <fmt/core.h>

#include "feedid/numeric/signal.hpp"

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
    std::vector<char> flags(v.size(), 0);
    window_extremes(v, half, [&](std::size_t k, double low, double high) {
        flags[k] = (low > 0.0 || high < 0.0) && high - low <= options.steady_spread_fraction * std::abs(v[k]) +
                                                                  options.steady_noise_multiple * d.velocity_noise;
    });
    return flags;
}

/// Mean of the residuals of `rows` from the fit, signed with the direction of motion: the friction they carry above
/// the fitted model.
double friction_rise(const Regressors& r, const Derivatives& d, std::span<const SampleIndex> rows,
                     const Eigen::VectorXd& estimate) {
    Eigen::VectorXd phi(static_cast<Eigen::Index>(r.parameters()));
    double rise = 0.0;
    for (const auto k : rows) {
        const double y = r.row(k, phi.data());
        rise += (d.velocity[k] > 0 ? 1.0 : -1.0) * (y - phi.dot(estimate));
    }
    return rise / static_cast<double>(rows.size());
}

/// The step-1 model fitted on `rows`, straight from the regressors' columns (no matrix of the rows).
LeastSquaresResult fit_rows(const Regressors& r, std::span<const SampleIndex> rows) {
    return solve_least_squares_rows(
        rows.size(), static_cast<Eigen::Index>(r.parameters()),
        [&](std::size_t i, double* phi) { return r.row(rows[i], phi); }, [&](std::size_t i) { return rows[i]; }, 1);
}

/// Step 1 must see no Stribeck friction. The speeds just above the split are checked against a fit on the faster
/// samples: while they carry more friction than their noise explains (mean residual above 3 standard errors), the
/// split doubles (only while the faster samples remain plenty). A mean is a weak witness: a small average rise can
/// sit on the ramp samples nearest the split, correlated with the acceleration, and bias M and B far more than its
/// size suggests.
double raise_split_above_stribeck(const Derivatives& d, const Regressors& r, const SelectionOptions& options,
                                  std::span<const SampleIndex> moving, double split, SelectionReport& report) {
    const Units units{ParameterNaming{d.rotary}};
    for (int doubling = 0; doubling < options.max_split_doublings; ++doubling) {
        SampleIndices band, faster;
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
        const LeastSquaresResult fit = fit_rows(r, faster);
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
    SampleIndices slow;
    for (const auto k : s.moving) {
        if (std::abs(d.velocity[k]) < split && !(s.near_rest(k) && d.used.differentiation != "central"))
            slow.push_back(k);
    }
    const LeastSquaresResult fast_fit = fit_rows(r, s.step1);
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

/// How far a stop's static force reaches into the filtered force [analysed samples]: the low-pass smears it over its
/// half-width, and the stop itself, seen in the filtered velocity, ends that much before the axis moves: twice the
/// half-width (1.25 periods of a Butterworth's cut-off, half a Savitzky-Golay window), plus the central
/// differences' two samples and the three-tap kernel's one.
std::size_t stop_reach(const Derivatives& d) {
    double half_width = 0.0;
    if (d.used.differentiation == "butterworth") half_width = 1.25 / (d.used.cutoff_hz * d.sample_time_s);
    if (d.used.differentiation == "savitzky-golay") half_width = 0.5 * d.used.savitzky_golay_window;
    const double reach = 2.0 * half_width + 3.0;
    return std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(reach / std::max(1, d.used.decimation))));
}

/// Samples within a stop's reach (stop_reach): a stop is a run of resting samples lasting at least a quarter of
/// that reach, long enough for the drive to hold a static force that the low-pass then smears over its neighbours.
/// A reversal through zero speed is no stop: the sgn(x') columns go through the same low-pass as the force and model
/// it.
std::vector<char> resting_reach(const Derivatives& d, double threshold) {
    const std::size_t n = d.size();
    const std::size_t reach = stop_reach(d);
    const std::size_t shortest_stop = std::max<std::size_t>(1, reach / 4);
    std::vector<char> flags(n, 0);
    std::size_t k = 0;
    while (k < n) {
        if (std::abs(d.velocity[k]) > threshold) {
            ++k;
            continue;
        }
        const std::size_t first = k;
        while (k < n && !(std::abs(d.velocity[k]) > threshold)) ++k;
        if (k - first < shortest_stop) continue;
        const std::size_t from = first > reach ? first - reach : 0, to = std::min(n, k + reach);
        std::fill(flags.begin() + static_cast<std::ptrdiff_t>(from), flags.begin() + static_cast<std::ptrdiff_t>(to),
                  1);
    }
    return flags;
}

/// What stick-slip detection found, in words: how many passes, at which commanded speeds.
std::string stick_slip_note(const StickSlip& found, const Units& units) {
    double slowest = INFINITY, fastest = 0.0;
    for (const MotionPass& pass : found.passes) {
        if (!pass.stick_slip) continue;
        slowest = std::min(slowest, pass.speed);
        fastest = std::max(fastest, pass.speed);
    }
    return fmt::format(
        "{} of {} passes stick-slip ({} {:.3g} to {:.3g} {}: the axis {}): their {} samples are left out of both "
        "steps",
        found.stick_slip_passes, found.passes.size(), found.by_reference ? "commanded at" : "moving at",
        units.speed(slowest), units.speed(fastest), units.unit(),
        found.by_reference ? "stops or swings by more than half the commanded speed while the command runs steadily"
                           : "stops and restarts in the same direction again and again",
        found.samples);
}

/// The moving threshold and the moving samples, with the notes on what was dropped before them: at rest, the drive
/// signal at its limit nearby, stick-slip passes.
void select_moving(const Derivatives& d, const SelectionOptions& options, double fastest, Selection& s) {
    const Units units{ParameterNaming{d.rotary}};
    const double threshold = options.moving_threshold.value_or(
        std::max({options.rest_noise_multiple * d.velocity_noise,
                  d.velocity_from_position() ? d.position_quantum * d.used.cutoff_hz : 0.0,
                  options.rest_fraction_of_max_speed * fastest}));
    s.report.moving_threshold = threshold;
    s.stick_slip = detect_stick_slip(d, threshold, options.stick_slip);
    s.report.passes = s.stick_slip.passes.size();
    s.report.stick_slip_passes = s.stick_slip.stick_slip_passes;
    s.report.stick_slip_samples = s.stick_slip.samples;
    const auto is_moving = [&](std::size_t k) {
        return std::abs(d.velocity[k]) > threshold && (d.unusable.empty() || !d.unusable[k]) && !s.stick_slip.flags[k];
    };
    std::size_t count = 0;
    for (std::size_t k = 0; k < d.size(); ++k) count += is_moving(k) ? 1 : 0;
    s.moving.reserve(count);  // exactly: grown by doubling, the indices would hold up to twice their size
    for (std::size_t k = 0; k < d.size(); ++k) {
        if (!(std::abs(d.velocity[k]) > threshold)) continue;
        if (!d.unusable.empty() && d.unusable[k]) {
            ++s.report.clipped;
        } else if (!s.stick_slip.flags[k]) {
            s.moving.push_back(static_cast<SampleIndex>(k));
        }
    }
    s.report.moving = s.moving.size();
    if (s.report.clipped > 0) {
        s.report.notes.push_back(fmt::format(
            "{} moving samples left out: the drive signal sits at its limit near them ({} samples at {:.4g} or {:.4g} "
            "{}: clipped or saturated), so their force is not the axis's",
            s.report.clipped, d.clipped_samples, d.clip_levels[0], d.clip_levels[1], units.naming.force_unit()));
    }
    if (s.stick_slip.stick_slip_passes > 0) s.report.notes.push_back(stick_slip_note(s.stick_slip, units));
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
    const auto each_steady = [&](const auto& f) {
        for (const auto k : s.moving) {
            if (s.steady(k)) f(d.velocity[k]);
        }
    };
    const std::size_t steady = visited_count(each_steady);
    const double typical =
        steady == 0 ? fastest : absolute_percentile_of(steady, each_steady, options.typical_speed_percentile);
    return options.stribeck ? options.split_fraction * typical : 0.0;
}

}  // namespace

MovingSamples select_moving_samples(const Derivatives& d, const SelectionOptions& options) {
    Selection s;
    s.report.total = d.total;
    s.report.window = d.window;
    select_moving(d, options, max_speed(d), s);
    return MovingSamples{std::move(s.report), std::move(s.moving), quasi_static_flags(d, options),
                         std::move(s.stick_slip)};
}

MovingSamples release_moving_samples(Selection&& selection) {
    MovingSamples moving;
    moving.report.total = selection.report.total;
    moving.report.window = selection.report.window;
    moving.report.moving = selection.report.moving;
    moving.report.passes = selection.report.passes;
    moving.report.stick_slip_passes = selection.report.stick_slip_passes;
    moving.report.stick_slip_samples = selection.report.stick_slip_samples;
    moving.report.clipped = selection.report.clipped;
    moving.report.moving_threshold = selection.report.moving_threshold;
    auto& notes = selection.report.notes;
    const auto kept = static_cast<std::ptrdiff_t>(std::min(selection.moving_notes, notes.size()));
    moving.report.notes.assign(std::make_move_iterator(notes.begin()), std::make_move_iterator(notes.begin() + kept));
    moving.moving = std::move(selection.moving);
    moving.quasi_static = std::move(selection.quasi_static);
    moving.stick_slip = std::move(selection.stick_slip);
    return moving;
}

Selection select_samples(const Derivatives& d, const Regressors& r, const SelectionOptions& options) {
    return select_samples(d, r, options, select_moving_samples(d, options));
}

Selection select_samples(const Derivatives& d, const Regressors& r, const SelectionOptions& options,
                         MovingSamples moving) {
    const Units units{ParameterNaming{d.rotary}};
    Selection s;
    s.report = std::move(moving.report);
    s.moving_notes = s.report.notes.size();
    s.moving = std::move(moving.moving);
    s.quasi_static = std::move(moving.quasi_static);
    s.stick_slip = std::move(moving.stick_slip);
    const double fastest = max_speed(d);
    const double threshold = s.report.moving_threshold;
    double split =
        std::max(options.split_velocity ? *options.split_velocity : default_split(d, options, fastest, s), threshold);
    s.initial_split = split;
    s.report.initial_split = split;
    // stopped: slower than a small fraction of the split (a dwell's creep and noise included), or than the threshold
    s.resting_reach = resting_reach(d, std::max(threshold, options.rest_split_fraction * split));
    if (!options.split_velocity && options.stribeck && split > threshold) {
        split = raise_split_above_stribeck(d, r, options, s.moving, split, s.report);
    }
    s.stribeck_band = split;
    s.report.split_velocity = split;
    std::size_t fast = 0, slow = 0;
    const bool central = d.used.differentiation == "central";
    for (const auto k : s.moving) {
        if (std::abs(d.velocity[k]) >= split)
            fast += s.near_rest(k) && !central ? 0 : 1;
        else
            slow += s.steady(k) ? 1 : 0;
    }
    s.step1.reserve(fast);
    s.step2.reserve(slow);
    for (const auto k : s.moving) {
        if (std::abs(d.velocity[k]) >= split) {
            if (s.near_rest(k) && d.used.differentiation != "central") {
                ++s.report.near_rest;
                continue;
            }
            s.step1.push_back(k);
        } else if (s.steady(k)) {
            s.step2.push_back(k);
        }
    }
    s.report.step1 = s.step1.size();
    s.report.step2 = s.step2.size();
    if (s.report.near_rest > 0) {
        s.report.notes.push_back(fmt::format(
            "{} fast samples within {} samples of a stop left out of step 1: the force went through the position's "
            "low-pass, so there it carries the smeared force of the stop, which no friction law of x' models",
            s.report.near_rest, stop_reach(d)));
    }
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
