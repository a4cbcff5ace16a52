#include "feedid/identify/fingerprint.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <span>
#include <vector>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/json_adapters.hpp"
#include "feedid/numeric/least_squares.hpp"
#include "feedid/numeric/signal.hpp"

namespace feedid {

std::string FingerprintOptions::validate() const {
    if (!(settle_s >= 0.0 && settle_s <= 10.0)) return fmt::format("settling time {} s: must be 0 to 10 s", settle_s);
    if (!(reversal_window_s > 0.0 && reversal_window_s <= 60.0))
        return fmt::format("reversal window {} s: must be above 0 and at most 60 s", reversal_window_s);
    if (!(contact_fraction >= 0.0 && contact_fraction < 1.0))
        return fmt::format("contact fraction {}: must be from 0 to below 1", contact_fraction);
    return drive.validate();
}

namespace {

std::string where(const Trace& trace) {
    return trace.source_path.empty() ? std::string("trace") : trace.source_path;
}

// A stretch of commanded motion in one direction: from the sample where the reference first moved that way to the
// sample before it first moved the other way.
struct Stretch {
    std::size_t first{0};
    std::size_t last{0};  // one past
    int direction{0};
};

// The reference's moves, split where it reverses. Increments below `still` (a held or quantised reference) are no
// move.
std::vector<Stretch> commanded_stretches(std::span<const double> reference, double still) {
    std::vector<Stretch> stretches;
    for (std::size_t k = 1; k < reference.size(); ++k) {
        const double step = reference[k] - reference[k - 1];
        if (std::abs(step) <= still) continue;
        const int direction = step > 0.0 ? 1 : -1;
        if (stretches.empty() || stretches.back().direction != direction) {
            if (!stretches.empty()) stretches.back().last = k;
            stretches.push_back({k, reference.size(), direction});
        }
    }
    return stretches;
}

// Settled: over the last `window` samples the reference is a straight line (standing, or constant speed) within what a
// held reference deviates from one, so the axis has stopped accelerating and the drive force is what the transmission
// carries.
std::vector<char> settled_samples(std::span<const double> reference, std::size_t window) {
    std::vector<char> settled(reference.size(), 0);
    if (window < 4) window = 4;
    for (std::size_t k = window; k < reference.size(); ++k) {
        const double start = reference[k - window];
        const double rise = reference[k] - start;
        const double tolerance = 2e-9 + 3.0 * std::abs(rise) / static_cast<double>(window);
        bool straight = true;
        for (const std::size_t quarter : {window / 4, window / 2, 3 * window / 4}) {
            const double expected = start + rise * static_cast<double>(quarter) / static_cast<double>(window);
            if (std::abs(reference[k - window + quarter] - expected) > tolerance) straight = false;
        }
        settled[k] = straight ? 1 : 0;
    }
    return settled;
}

double mean_of(std::span<const double> values) {
    return values.empty() ? 0.0
                          : std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
}

// The mean of the values with its standard error: the scatter's over sqrt(n), or `single` when there is one value.
Estimate aggregate(const std::vector<double>& values, double single) {
    if (values.empty()) return {};
    const double mean = mean_of(values);
    if (values.size() == 1) return Estimate::of(mean, single);
    double squares = 0.0;
    for (const double value : values) squares += (value - mean) * (value - mean);
    const double spread = std::sqrt(squares / static_cast<double>(values.size() - 1));
    return Estimate::of(mean, std::max(spread, single) / std::sqrt(static_cast<double>(values.size())));
}

struct Signals {
    std::vector<double> time;
    std::vector<double> reference;
    std::vector<double> load;
    std::vector<double> motor;  // empty with one measuring system
    std::vector<double> drive;  // force (N, N*m), or the drive signal in its own units when no constant converts it
    bool drive_is_force{false};
    std::string drive_name;
    std::string drive_unit;
    std::string force_problem;  // why the drive signal is not a force
    double sample_time_s{0.0};
};

Signals read_signals(const Trace& trace, const FingerprintOptions& options) {
    Signals s;
    const auto copy = [&](Role role) {
        const auto column = trace.column(role);
        return std::vector<double>(column.begin(), column.end());
    };
    s.time = copy(Role::time);
    s.load = copy(Role::position);
    if (!trace.has(Role::reference_position)) {
        throw InputError(
            fmt::format("{}: no reference position: the fingerprint finds the reversals in the commanded "
                        "motion (--channel reference_position=NAME)",
                        where(trace)));
    }
    s.reference = copy(Role::reference_position);
    if (trace.has(Role::motor_position)) s.motor = copy(Role::motor_position);
    s.sample_time_s = trace.time_base().sample_time_s;
    const Channel* signal = trace.find(Role::force);
    if (signal == nullptr) signal = trace.find(Role::current);
    if (signal == nullptr) return s;
    s.drive_name = signal->name;
    s.drive_unit = signal->unit;
    try {
        s.drive = drive_force(trace, options.drive);
        s.drive_is_force = true;
    } catch (const InputError& e) {
        s.drive = signal->values;
        s.force_problem = e.what();
        // said beside the file's own figures: without the file's name in front
        const std::string prefix = where(trace) + ": ";
        if (s.force_problem.starts_with(prefix)) s.force_problem.erase(0, prefix.size());
    }
    return s;
}

// The direction of the commanded motion each sample belongs to (the stretch it lies in; 0 before the first move).
std::vector<int> held_directions(std::size_t n, const std::vector<Stretch>& stretches) {
    std::vector<int> direction(n, 0);
    for (const auto& stretch : stretches) {
        for (std::size_t k = stretch.first; k < stretch.last; ++k) direction[k] = stretch.direction;
    }
    return direction;
}

// The median of s*F over the settled samples: the force with which the transmission is held in the direction of the
// last move. Negative: the drive signal counts the other way than the position.
double median_held_force(const Signals& s, const std::vector<char>& settled, const std::vector<int>& direction) {
    std::vector<double> held;
    for (std::size_t k = 0; k < s.drive.size(); ++k) {
        if (settled[k] && direction[k] != 0) held.push_back(direction[k] * s.drive[k]);
    }
    return percentile(held, 0.5);
}

// The force-deflection samples: settled, and pushing in the direction of the last move with at least
// contact_fraction of the median held force (inside the dead band, or on the way through it, the transmission carries
// nothing).
std::vector<std::size_t> contact_samples(const Signals& s, const std::vector<char>& settled,
                                         const std::vector<int>& direction, const FingerprintOptions& options) {
    const double threshold = options.contact_fraction * std::max(median_held_force(s, settled, direction), 0.0);
    std::vector<std::size_t> rows;
    for (std::size_t k = 0; k < s.drive.size(); ++k) {
        if (settled[k] && direction[k] != 0 && direction[k] * s.drive[k] > threshold) rows.push_back(k);
    }
    return rows;
}

// Correlation of neighbouring residuals (held signals, filters): the standard errors count a block of samples once.
std::size_t correlation_block(double sample_time_s) {
    return std::max<std::size_t>(8, static_cast<std::size_t>(std::lround(0.05 / std::max(sample_time_s, 1e-6))));
}

// White noise on the force pulls a fitted slope towards zero by var(F) / (var(F) - sigma^2) (errors in the regressor:
// attenuation); this is that factor, with var(F) the spread within each direction and sigma^2 the force's
// sample-to-sample noise. 1 where the spread is not well above the noise.
double attenuation(const Signals& s, const std::vector<std::size_t>& use, const std::vector<int>& direction,
                   double noise_variance) {
    double sum[2] = {0.0, 0.0};
    double squares[2] = {0.0, 0.0};
    double count[2] = {0.0, 0.0};
    for (const auto k : use) {
        const int group = direction[k] > 0 ? 0 : 1;
        sum[group] += s.drive[k];
        squares[group] += s.drive[k] * s.drive[k];
        count[group] += 1.0;
    }
    double spread = 0.0;
    for (int g = 0; g < 2; ++g) {
        if (count[g] > 0.0) spread += squares[g] - sum[g] * sum[g] / count[g];
    }
    spread /= std::max(count[0] + count[1], 1.0);
    return spread > 2.0 * noise_variance ? spread / (spread - noise_variance) : 1.0;
}

// mean F over the forward rows minus mean F over the reverse rows.
double force_difference(const Signals& s, const std::vector<std::size_t>& rows, const std::vector<int>& direction) {
    double sum[2] = {0.0, 0.0};
    double count[2] = {0.0, 0.0};
    for (const auto k : rows) {
        sum[direction[k] > 0 ? 0 : 1] += s.drive[k];
        count[direction[k] > 0 ? 0 : 1] += 1.0;
    }
    return sum[0] / std::max(count[0], 1.0) - sum[1] / std::max(count[1], 1.0);
}

struct DeflectionFit {
    Estimate backlash;    // a_+ - a_- [m]
    Estimate compliance;  // common slope [m per force (or signal) unit]
    Estimate compliance_forward;
    Estimate compliance_reverse;
    std::string reason;
};

// d = a_+ I_+ + a_- I_- + c F (one slope), and d = a + c F in each direction.
DeflectionFit fit_deflection(const Signals& s, const std::vector<std::size_t>& rows, const std::vector<int>& direction,
                             std::size_t block) {
    DeflectionFit fit;
    std::vector<std::size_t> forward;
    std::vector<std::size_t> reverse;
    for (const auto k : rows) (direction[k] > 0 ? forward : reverse).push_back(k);
    if (forward.size() < 20 || reverse.size() < 20) {
        fit.reason = fmt::format(
            "too few settled samples in contact in both directions ({} pushing forward, {} "
            "pulling back; at least 20 each)",
            forward.size(), reverse.size());
        return fit;
    }
    const auto solve = [&](const std::vector<std::size_t>& use, bool two_intercepts) {
        const Eigen::Index columns = two_intercepts ? 3 : 2;
        Eigen::MatrixXd phi(static_cast<Eigen::Index>(use.size()), columns);
        Eigen::VectorXd y(static_cast<Eigen::Index>(use.size()));
        for (std::size_t i = 0; i < use.size(); ++i) {
            const auto k = use[i];
            const auto row = static_cast<Eigen::Index>(i);
            y(row) = s.motor[k] - s.load[k];
            if (two_intercepts) {
                phi(row, 0) = direction[k] > 0 ? 1.0 : 0.0;
                phi(row, 1) = direction[k] > 0 ? 0.0 : 1.0;
            } else {
                phi(row, 0) = 1.0;
            }
            phi(row, columns - 1) = s.drive[k];
        }
        auto result = solve_least_squares(phi, y);
        account_for_correlated_residuals(result, phi, y, use, block);
        return result;
    };
    const auto both = solve(rows, true);
    if (both.rank_deficient) {
        fit.reason = "the settled force does not vary: the force-deflection fit is rank deficient";
        return fit;
    }
    const double noise_variance = std::pow(noise_floor(s.drive), 2);
    const auto undo_attenuation = [&](const std::vector<std::size_t>& use) {
        return attenuation(s, use, direction, noise_variance);
    };
    const double factor = undo_attenuation(rows);
    const double mean_force_difference = force_difference(s, rows, direction);
    const double difference_variance = both.covariance(0, 0) + both.covariance(1, 1) - 2.0 * both.covariance(0, 1);
    // a_+ - a_- = (mean d_+ - mean d_-) - c (mean F_+ - mean F_-): the corrected slope moves it
    const double backlash =
        both.estimate(0) - both.estimate(1) - (factor - 1.0) * both.estimate(2) * mean_force_difference;
    fit.backlash = Estimate::of(backlash, std::sqrt(std::max(difference_variance, 0.0)));
    fit.compliance = Estimate::of(factor * both.estimate(2), factor * both.standard_error(2));
    const auto forward_fit = solve(forward, false);
    const auto reverse_fit = solve(reverse, false);
    if (!forward_fit.rank_deficient) {
        const double f = undo_attenuation(forward);
        fit.compliance_forward = Estimate::of(f * forward_fit.estimate(1), f * forward_fit.standard_error(1));
    }
    if (!reverse_fit.rank_deficient) {
        const double f = undo_attenuation(reverse);
        fit.compliance_reverse = Estimate::of(f * reverse_fit.estimate(1), f * reverse_fit.standard_error(1));
    }
    return fit;
}

// k = 1/c, its standard error sigma_c / c^2; null where the slope is not positive by at least two standard errors
// (the force varied too little to tell a stiffness).
Estimate stiffness_of(const Estimate& compliance) {
    if (!compliance.value || !compliance.standard_error) return {};
    const double c = *compliance.value;
    if (!(c > 2.0 * *compliance.standard_error)) return {};
    return Estimate::of(1.0 / c, *compliance.standard_error / (c * c));
}

struct PerReversal {
    std::vector<double> forward;
    std::vector<double> reverse;
    void add(int direction, double value) { (direction > 0 ? forward : reverse).push_back(value); }
};

DirectionalEstimate directional(const PerReversal& values, double single) {
    DirectionalEstimate estimate;
    estimate.forward = aggregate(values.forward, single);
    estimate.reverse = aggregate(values.reverse, single);
    std::vector<double> all = values.forward;
    all.insert(all.end(), values.reverse.begin(), values.reverse.end());
    estimate.both = aggregate(all, single);
    return estimate;
}

// The mean deflection over the settled samples of the second half of a stretch; nullopt when none is settled.
std::optional<double> settled_deflection(const Signals& s, const std::vector<char>& settled, const Stretch& stretch,
                                         std::size_t& count) {
    double sum = 0.0;
    count = 0;
    for (std::size_t k = stretch.first + (stretch.last - stretch.first) / 2; k < stretch.last; ++k) {
        if (!settled[k]) continue;
        sum += s.motor[k] - s.load[k];
        ++count;
    }
    if (count == 0) return std::nullopt;
    return sum / static_cast<double>(count);
}

DirectionalEstimate lost_motion(const Signals& s, const std::vector<char>& settled,
                                const std::vector<Stretch>& stretches) {
    PerReversal values;
    std::vector<double> deflection(s.load.size());
    for (std::size_t k = 0; k < deflection.size(); ++k) deflection[k] = s.motor[k] - s.load[k];
    const double noise = noise_floor(deflection);
    double single = 0.0;
    for (std::size_t j = 1; j < stretches.size(); ++j) {
        std::size_t before_count = 0;
        std::size_t after_count = 0;
        const auto before = settled_deflection(s, settled, stretches[j - 1], before_count);
        const auto after = settled_deflection(s, settled, stretches[j], after_count);
        if (!before || !after) continue;
        values.add(stretches[j].direction, stretches[j].direction * (*after - *before));
        single = std::max(single, noise * std::sqrt(1.0 / static_cast<double>(before_count) +
                                                    1.0 / static_cast<double>(after_count)));
    }
    return directional(values, single);
}

// Peak following error after each reversal, up to the next one or the window.
DirectionalEstimate reversal_error(const Signals& s, const std::vector<Stretch>& stretches, std::size_t window) {
    PerReversal values;
    for (std::size_t j = 1; j < stretches.size(); ++j) {
        const auto& stretch = stretches[j];
        const std::size_t end = std::min(stretch.last, stretch.first + window);
        double peak = -std::numeric_limits<double>::infinity();
        for (std::size_t k = stretch.first; k < end; ++k)
            peak = std::max(peak, stretch.direction * (s.reference[k] - s.load[k]));
        if (std::isfinite(peak)) values.add(stretch.direction, peak);
    }
    return directional(values, std::numbers::sqrt2 * noise_floor(s.load));
}

// Peak drive force in the new direction after each reversal until the load has moved that way by more than its
// noise allows (or half the stretch's travel, for a short stretch).
DirectionalEstimate breakaway(const Signals& s, const std::vector<Stretch>& stretches) {
    PerReversal values;
    const double noise = noise_floor(s.load);
    for (std::size_t j = 1; j < stretches.size(); ++j) {
        const auto& stretch = stretches[j];
        const double travel = std::abs(s.reference[stretch.last - 1] - s.reference[stretch.first - 1]);
        const double moved = std::max(6.0 * noise, std::min(0.5 * travel, 1e-6));
        const double start = s.load[stretch.first - 1];
        double peak = -std::numeric_limits<double>::infinity();
        for (std::size_t k = stretch.first; k < stretch.last; ++k) {
            peak = std::max(peak, stretch.direction * s.drive[k]);
            if (stretch.direction * (s.load[k] - start) > moved) {
                values.add(stretch.direction, peak);
                break;
            }
        }
    }
    return directional(values, std::numbers::sqrt2 * noise_floor(s.drive));
}

void set_reason(DirectionalEstimate& estimate, const std::string& reason) {
    if (!estimate.forward.value || !estimate.reverse.value || !estimate.both.value) estimate.reason = reason;
}

// Quasi-static: over the last 2m samples motor and load have both moved with the reference's speed, in each half
// (no acceleration, no stick-slip: where the load sticks and slips the transmission goes slack and the motor's
// inertia takes part of the drive force). The tolerance: the encoders' noise over m samples, and 10 % of the speed.
std::vector<char> quasi_static_samples(const Signals& s, const std::vector<char>& settled) {
    constexpr std::size_t m = 10;
    std::vector<char> out(settled.size(), 0);
    const double span = static_cast<double>(m) * s.sample_time_s;
    const double noise = std::max(noise_floor(s.load), noise_floor(s.motor));
    for (std::size_t k = 2 * m; k < settled.size(); ++k) {
        if (!settled[k]) continue;
        const double speed = (s.reference[k] - s.reference[k - m]) / span;
        const double tolerance = (6.0 * noise + 1e-12) / span + 0.03 * std::abs(speed);
        bool quiet = true;
        for (const auto* x : {&s.load, &s.motor}) {
            for (const std::size_t end : {k, k - m}) {
                if (std::abs(((*x)[end] - (*x)[end - m]) / span - speed) > tolerance) quiet = false;
            }
        }
        out[k] = quiet ? 1 : 0;
    }
    return out;
}

// The report's samples, thinned evenly, and the fitted lines: a_+/- = mean d - c mean F over the fit's rows of each
// direction (the corrected slope c, as the backlash takes it).
void fill_curves(FingerprintCurves& curves, const Signals& s, const std::vector<int>& direction,
                 const std::vector<std::size_t>& rows, const std::optional<double>& compliance) {
    const std::size_t n = s.load.size();
    std::vector<char> in_fit(n, 0);
    for (const auto k : rows) in_fit[k] = 1;
    const std::size_t stride = std::max<std::size_t>(1, (n + FingerprintCurves::max_points - 1) /
                                                            FingerprintCurves::max_points);
    for (std::size_t k = 0; k < n; k += stride) {
        curves.position.push_back(s.load[k]);
        curves.deflection.push_back(s.motor[k] - s.load[k]);
        curves.direction.push_back(direction[k]);
        if (!s.drive.empty()) curves.drive.push_back(s.drive[k]);
        curves.in_fit.push_back(in_fit[k]);
    }
    if (!compliance) return;
    curves.compliance = compliance;
    double sum_d[2] = {0.0, 0.0}, sum_f[2] = {0.0, 0.0}, count[2] = {0.0, 0.0};
    for (const auto k : rows) {
        const int g = direction[k] > 0 ? 0 : 1;
        sum_d[g] += s.motor[k] - s.load[k];
        sum_f[g] += s.drive[k];
        count[g] += 1.0;
    }
    if (count[0] > 0.0) curves.intercept_forward = (sum_d[0] - *compliance * sum_f[0]) / count[0];
    if (count[1] > 0.0) curves.intercept_reverse = (sum_d[1] - *compliance * sum_f[1]) / count[1];
}

void fill_deflection_figures(FingerprintResult& result, const Signals& s, const std::vector<char>& settled,
                             const std::vector<int>& direction, const FingerprintOptions& options) {
    const auto rows = contact_samples(s, quasi_static_samples(s, settled), direction, options);
    result.samples_used = static_cast<int>(rows.size());
    const auto fit = fit_deflection(s, rows, direction, correlation_block(s.sample_time_s));
    fill_curves(result.curves, s, direction, rows, fit.compliance.value);
    result.backlash = fit.backlash;
    result.backlash_reason = fit.backlash.value ? std::string() : fit.reason;
    if (!s.drive_is_force) {
        result.deflection_per_signal = fit.compliance.value;
        result.signal_unit = s.drive_unit;
        result.stiffness.reason = fmt::format("{} (the deflection per {} is given instead)", s.force_problem,
                                              s.drive_unit.empty() ? std::string("signal unit") : s.drive_unit);
        return;
    }
    result.stiffness.both = stiffness_of(fit.compliance);
    result.stiffness.forward = stiffness_of(fit.compliance_forward);
    result.stiffness.reverse = stiffness_of(fit.compliance_reverse);
    set_reason(result.stiffness, fit.reason.empty() ? "the settled drive force varies too little in this direction "
                                                      "to tell a stiffness (the slope is within two standard errors "
                                                      "of zero)"
                                                    : fit.reason);
}

constexpr const char* one_system_reason =
    "one measuring system: motor and load are not told apart (give the motor encoder with --channel "
    "motor_position=NAME beside the scale as position)";

}  // namespace

FingerprintResult fingerprint(const Trace& trace, const FingerprintOptions& options) {
    if (const auto problem = options.validate(); !problem.empty()) throw InputError(problem);
    Signals s = read_signals(trace, options);
    FingerprintResult result;
    result.rotary = trace.rotary;
    result.two_measuring_systems = !s.motor.empty();
    const double resolution = std::max(noise_floor(s.reference), 1e-12);
    const auto stretches = commanded_stretches(s.reference, std::max(1e-12, 0.01 * resolution));
    for (std::size_t j = 1; j < stretches.size(); ++j)
        ++(stretches[j].direction > 0 ? result.reversals_forward : result.reversals_reverse);
    const auto per_second = [&](double seconds) {
        return static_cast<std::size_t>(std::lround(seconds / std::max(s.sample_time_s, 1e-9)));
    };
    const auto settled = settled_samples(s.reference, per_second(options.settle_s));
    const auto direction = held_directions(s.reference.size(), stretches);
    if (!s.drive.empty() && median_held_force(s, settled, direction) < 0.0) {
        // The axis holds against its last move with a negative force: the drive signal counts the other way.
        for (double& value : s.drive) value = -value;
        result.diagnostics.emplace_back(
            "the drive signal counts the other way than the position (it holds each move with the opposite sign): "
            "taken negated (--invert current says so for the other commands)");
    }
    const std::string no_reversal = stretches.size() < 2
                                        ? "the reference never reverses: the fingerprint needs moves both ways"
                                        : "the reference reverses into one direction only";
    result.reversal_error = reversal_error(s, stretches, per_second(options.reversal_window_s));
    set_reason(result.reversal_error, no_reversal);
    if (s.drive.empty()) {
        result.breakaway.reason = "no drive signal (--channel current=NAME or force=NAME)";
    } else if (!s.drive_is_force) {
        result.breakaway.reason = s.force_problem;
    } else {
        result.breakaway = breakaway(s, stretches);
        set_reason(result.breakaway,
                   stretches.size() < 3 ? no_reversal : "the load did not move after a reversal in this direction");
    }
    if (!result.two_measuring_systems) {
        result.lost_motion.reason = one_system_reason;
        result.backlash_reason = one_system_reason;
        result.stiffness.reason = one_system_reason;
        result.diagnostics.emplace_back(
            "one measuring system: the reversal error is the following error of that system and the breakaway force "
            "the drive signal's; lost motion, backlash and stiffness need the motor encoder beside the scale");
        return result;
    }
    result.lost_motion = lost_motion(s, settled, stretches);
    if (s.drive.empty()) fill_curves(result.curves, s, direction, {}, std::nullopt);
    set_reason(result.lost_motion,
               stretches.size() < 3 ? no_reversal : "no settled samples on both sides of a reversal in this direction");
    if (s.drive.empty()) {
        result.backlash_reason = "no drive signal: the force-deflection fit needs one";
        result.stiffness.reason = result.backlash_reason;
        return result;
    }
    fill_deflection_figures(result, s, settled, direction, options);
    return result;
}

namespace {

void put(nlohmann::json& figures, nlohmann::json& reasons, const std::string& name, const std::string& unit,
         const DirectionalEstimate& estimate) {
    figures[name + "_" + unit] = estimate.both;
    figures[name + "_forward_" + unit] = estimate.forward;
    figures[name + "_reverse_" + unit] = estimate.reverse;
    if (!estimate.reason.empty()) reasons[name] = estimate.reason;
}

}  // namespace

nlohmann::json fingerprint_document(const FingerprintResult& result) {
    const bool rotary = result.rotary;
    nlohmann::json figures = nlohmann::json::object();
    nlohmann::json reasons = nlohmann::json::object();
    const std::string length = rotary ? "rad" : "m";
    put(figures, reasons, "lost_motion", length, result.lost_motion);
    figures["backlash_" + length] = result.backlash;
    if (!result.backlash_reason.empty()) reasons["backlash"] = result.backlash_reason;
    put(figures, reasons, "stiffness", rotary ? "Nm_per_rad" : "N_per_m", result.stiffness);
    put(figures, reasons, "reversal_error", length, result.reversal_error);
    put(figures, reasons, "breakaway", rotary ? "Nm" : "N", result.breakaway);
    nlohmann::json document{
        {"fingerprint", figures},
        {"reasons", reasons},
        {"reversals", {{"forward", result.reversals_forward}, {"reverse", result.reversals_reverse}}},
        {"two_measuring_systems", result.two_measuring_systems},
        {"samples_used", result.samples_used},
        {"diagnostics", result.diagnostics}};
    if (result.deflection_per_signal) {
        document["deflection_per_signal"] = {{"value", *result.deflection_per_signal},
                                             {"unit", length + "/" + result.signal_unit}};
    }
    return document;
}

}  // namespace feedid
