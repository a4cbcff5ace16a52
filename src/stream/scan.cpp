#include "feedid/stream/scan.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>

#include <fmt/core.h>

#include "feedid/io/unit_checks.hpp"
#include "feedid/numeric/native_interval.hpp"
#include "feedid/core/error.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/friction_only.hpp"
#include "feedid/identify/online_selection.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/core/version.hpp"

namespace feedid {

GateCondition parse_gate_condition(const std::string& text) {
    const auto at = text.find_first_of("<>");
    const auto bad = [&] {
        return InputError(
            fmt::format("--only-when '{}': expected NAME<VALUE, NAME>VALUE, NAME<=VALUE or NAME>=VALUE "
                        "(e.g. 'spindle_load<5')",
                        text));
    };
    if (at == std::string::npos || at == 0) throw bad();
    GateCondition c;
    c.channel = text.substr(0, at);
    const bool equal = at + 1 < text.size() && text[at + 1] == '=';
    c.op = text.substr(at, equal ? 2 : 1);
    const std::string number = text.substr(at + c.op.size());
    std::size_t used = 0;
    try {
        c.value = std::stod(number, &used);
    } catch (const std::exception&) {
        throw bad();
    }
    if (used != number.size() || !std::isfinite(c.value)) throw bad();
    while (!c.channel.empty() && c.channel.back() == ' ') c.channel.pop_back();
    return c;
}

std::vector<char> gate_samples(const Trace& trace, std::span<const GateCondition> conditions) {
    std::vector<char> use(trace.samples(), 1);
    for (const auto& c : conditions) {
        const Channel* channel = trace.find(std::string_view(c.channel));
        if (channel == nullptr) {
            std::string names;
            for (const auto& ch : trace.channels) names += (names.empty() ? "" : ", ") + ch.name;
            throw InputError(fmt::format("--only-when: {} has no channel '{}' (its channels: {})", trace.source_path,
                                         c.channel, names));
        }
        for (std::size_t k = 0; k < use.size(); ++k) {
            const double v = channel->values[k];
            const bool holds = c.op == "<"    ? v < c.value
                               : c.op == ">"  ? v > c.value
                               : c.op == "<=" ? v <= c.value
                                              : v >= c.value;
            if (!holds) use[k] = 0;
        }
    }
    return use;
}

namespace {

void set_parameters(ScanResult& s, const OnlineEstimate& e) {
    for (auto& p : s.result.parameters) p.estimate = e.of(p.term);
}

}  // namespace

namespace {

// The identifiers a scan runs: the nominal one and, for the systematic part of each parameter's uncertainty, the same
// with the split speed doubled (friction just above the split speed that is still Stribeck's biases B and F_C, and
// only a second split shows it; the family of identify's preprocessing_family.hpp, reduced to the choice a scan makes).
struct Identifiers {
    OnlineIdentifier nominal;
    std::optional<OnlineIdentifier> variant;

    Identifiers(const OnlineOptions& options, bool systematic) : nominal(options) {
        if (!systematic) return;
        OnlineOptions doubled = options;
        doubled.split_velocity = 2.0 * options.split();
        variant.emplace(doubled);
    }
};

void push_trace(Identifiers& identifiers, const Trace& trace, std::span<const double> force, std::span<const char> use,
                std::size_t block) {
    const auto t = trace.column(Role::time);
    const auto x = trace.column(Role::position);
    for (std::size_t k = 0; k < t.size(); k += block) {
        const std::size_t n = std::min(block, t.size() - k);
        const auto gate = use.empty() ? use : use.subspan(k, n);
        identifiers.nominal.push(t.subspan(k, n), x.subspan(k, n), force.subspan(k, n), gate);
        if (identifiers.variant) identifiers.variant->push(t.subspan(k, n), x.subspan(k, n), force.subspan(k, n), gate);
    }
}

// Each parameter's systematic part: how far it moves when the split speed doubles (unassessed where either is null);
// a finding where that exceeds twice the standard error.
void assess_split(OnlineIdentifier& variant, const OnlineOptions& options, ScanResult& s) {
    variant.flush();
    const OnlineEstimate doubled_estimate = variant.estimate();
    if (doubled_estimate.offset_in_model != s.online.offset_in_model) {
        // the two splits chose different models: their F_C differ by what the offset carries, not by the split
        s.result.diagnostics.push_back(
            "the systematic part is not assessed: with the split speed doubled the offset's selection came out "
            "differently");
        return;
    }
    ScanResult other;
    other.result.parameters = s.result.parameters;
    set_parameters(other, doubled_estimate);
    const ParameterNaming naming{s.result.rotary};
    for (std::size_t i = 0; i < s.result.parameters.size(); ++i) {
        Parameter& p = s.result.parameters[i];
        const Estimate& doubled = other.result.parameters[i].estimate;
        if (!p.estimate.value || !p.estimate.standard_error || !doubled.value) continue;
        const double spread = std::abs(*doubled.value - *p.estimate.value);
        p.estimate.set_systematic(spread);
        if (spread > 2.0 * *p.estimate.standard_error)
            s.result.diagnostics.push_back(fmt::format(
                "{} moves by {:.3g} {} ({:.2g} standard errors) when the split speed doubles from {:.3g} to {:.3g} "
                "{}: the friction just above the split speed is not yet the linear law (Stribeck); its systematic "
                "part and combined uncertainty say so, and a higher --split-velocity may be the better choice",
                p.symbol, spread, p.unit, spread / *p.estimate.standard_error,
                options.split() * naming.display_velocity_scale(),
                2.0 * options.split() * naming.display_velocity_scale(), naming.display_velocity_unit()));
    }
}

ScanResult finish(Identifiers& identifiers, const TraceSummary& summary, const OnlineOptions& options, bool rotary) {
    OnlineIdentifier& online = identifiers.nominal;
    online.flush();
    ScanResult s;
    s.online = online.estimate();
    IdentifyResult& r = s.result;
    r.model = FrictionModelKind::symmetric;
    r.offset = s.online.offset_in_model;
    r.model_choice = model_choice_of(s.online);
    r.rotary = rotary;
    r.axis.rotary = rotary;
    r.feedid_version = version;
    r.trace = summary;
    r.parameters = model_parameters(r.model, r.offset, r.rotary);
    set_parameters(s, s.online);
    const OnlineEstimate& e = s.online;
    for (const std::string* reason : {&e.mass_reason, &e.friction_reason, &e.stribeck_reason, &e.aliased_reason})
        if (!reason->empty() && std::find(r.diagnostics.begin(), r.diagnostics.end(), *reason) == r.diagnostics.end())
            r.diagnostics.push_back(*reason);
    if (e.changes > 0)
        r.diagnostics.push_back(fmt::format(
            "the axis changed {} time(s) during the trace ({} windows in a row fitted the model on their own but not "
            "the pooled estimate): the estimate is of the axis after the last change",
            e.changes, options.change_windows));
    const std::size_t inconsistent = e.windows.count(WindowVerdict::inconsistent);
    if (options.forgetting >= 1.0 && inconsistent >= options.change_windows)
        r.diagnostics.push_back(fmt::format(
            "{} windows fitted the model on their own but disagreed with the pooled estimate: if the axis changed "
            "during the trace, --forgetting (e.g. 0.9 per window) follows the change",
            inconsistent));
    const bool all = std::all_of(r.parameters.begin(), r.parameters.end(),
                                 [](const Parameter& p) { return p.estimate.determined(); });
    r.status = !e.mass.determined() ? Status::failed : all ? Status::ok : Status::partial;
    if (identifiers.variant && r.status != Status::failed) assess_split(*identifiers.variant, options, s);
    r.axis = axis_from_parameters(r.parameters, r.model, r.rotary);
    return s;
}

// The offset selected first, then the windows judged by the model selected: a pass judged by the model without the
// offset (the cheap and usual case: its pool tests the offset and does not take it), and where its pool took the
// offset or could not test it, a second pass over the same samples judged by the model with it (judge_with_offset),
// whose own Wald test decides. Judged without the offset, a vertical axis's windows that move both ways are bent or
// rejected and those that move one way carry the weight in F_C: on the example programs' Z axes B came out 10.7 %
// low (drilling) and the contour and pocket pooled 4 windows, all one way, F_C untestable; judged with it, 9 and 6
// windows qualify, both ways, and the offset is taken. Where the second pass does not take the offset but the first
// did, the model without it is the selected one: a third pass judges by it without the test, and reports the second's.
template <typename Pass>
ScanResult select_and_scan(const OnlineOptions& options, Pass&& pass) {
    ScanResult first = pass(options);
    if (!SelectingIdentifier::judges_twice(options) || !offset_needs_judging(first.online)) return first;
    OnlineOptions with_offset = options;
    with_offset.judge_with_offset = true;
    ScanResult judged = pass(with_offset);
    switch (offset_judgement(first.online, judged.online)) {
        case OffsetJudgement::first: return first;
        case OffsetJudgement::with_offset: return judged;
        case OffsetJudgement::without_offset: break;
    }
    OnlineOptions without = options;
    without.select_offset = false;
    ScanResult third = pass(without);
    take_offset_test(third.online, judged.online);
    third.result.model_choice = model_choice_of(third.online);
    return third;
}

// Widens every parameter's standard error for a delay known only to `standard_error` [s], of which the pass's
// covariance took in `included` already (a pass with a delay applied: its own delay's; as logged: none), by the
// parameters' sensitivities to it (OnlineEstimate::delay_sensitivity).
void widen_for_timing(ScanResult& s, double standard_error, double included) {
    OnlineEstimate& e = s.online;
    if (!(standard_error > included) || e.delay_sensitivity.size() == 0) return;
    const double extra = standard_error * standard_error - included * included;
    Eigen::Index column = 0;
    for (auto& p : s.result.parameters) {
        if (p.term == Term::breakaway || p.term == Term::stribeck_velocity) continue;
        if (column >= e.delay_sensitivity.size()) break;
        const double sensitivity = e.delay_sensitivity(column++);
        Estimate& estimate = p.estimate;
        if (!estimate.value || !estimate.standard_error) continue;
        estimate.standard_error =
            std::sqrt(*estimate.standard_error * *estimate.standard_error + sensitivity * sensitivity * extra);
        if (estimate.systematic) estimate.set_systematic(*estimate.systematic);
    }
    e.delay_standard_error_s = standard_error;
    s.result.model_choice = model_choice_of(e);
}

// The windows cannot tell the drive signal's timing: friction is what a timing error biases (the force lags the
// velocity it opposes: B and F_C, and F_0 with them), so those are null with the reason; M moves with the delay only
// by tau*B (F_log = M x'' + B x' + ... - tau (M x''' + B x'' + ...)): the as-logged pass's M, its first-order
// correction undone, with the spread of the passes' M as its systematic part.
void refuse_timing(ScanResult& s, double mass_spread, const std::string& why) {
    OnlineEstimate& e = s.online;
    if (e.delay_corrected && e.delay_residual_s && e.delay_sensitivity.size() > 0 && e.mass.value)
        e.mass.value = *e.mass.value - *e.delay_residual_s * e.delay_sensitivity(0);
    e.delay_corrected = false;
    e.delay_verdict = why;
    for (auto& p : s.result.parameters) {
        if (p.term == Term::mass) {
            p.estimate = e.mass;
            if (p.estimate.value) p.estimate.set_systematic(mass_spread);
        } else if (p.estimate.value) {
            p.estimate = Estimate{};
        }
    }
    for (Estimate* value : {&e.viscous, &e.coulomb, &e.offset, &e.breakaway, &e.stribeck_velocity}) *value = Estimate{};
    e.friction_reason = e.stribeck_reason = why;
    s.result.diagnostics.push_back(why);
    s.result.model_choice = model_choice_of(e);
    s.result.status = e.mass.determined() ? Status::partial : Status::failed;
    s.result.axis = axis_from_parameters(s.result.parameters, s.result.model, s.result.rotary);
}

// The drive signal's timing. Where the pool of the first pass (the force as logged) shows a delay beyond two of its
// standard errors, the timing is searched: each pass reads the force a delay later in every window, exactly (the
// pool's estimate is first-order, and it is of the windows that qualified at the timing tried, so that process forces
// judged by a wrong timing can shape it: on the pocket program's X axis with the current 0.5 ms late the as-logged
// pool gave -1.3 +- 0.41 ms and F_C 28 % high at 92 standard errors). The search:
//   1. a coarse grid of delays (-2 ... 3 ms and the first pool's estimate): the start is the pass whose windows' robust
//      residual scale is smallest, the timing at which the clean windows fit the model best (3.6 N at the true delay
//      against 6.0-6.5 N at the delays the process-force windows favoured, on that trace);
//   2. from there, the delay the pool leaves applied until what is left is not significant (after the first step by
//      the secant through the last two: what a pass leaves is about proportional to the part of the true delay not
//      applied). Converged when what the last pass leaves is not significant and its delay agrees with the one before
//      within three standard errors: its estimate is reported.
// Otherwise the windows cannot tell the timing, and refuse_timing() says so.
constexpr double explore_statistic = 2.0;
constexpr double settled_range_samples = 0.5;
constexpr double polish_samples = 0.02;
constexpr std::array<double, 6> coarse_delays_s{-2e-3, -1e-3, 0.5e-3, 1e-3, 2e-3, 3e-3};

double total_delay(const OnlineEstimate& e) {
    return e.delay_applied_s + e.delay_residual_s.value_or(0.0);
}

template <typename Pass>
ScanResult pass_at(const OnlineOptions& options, double delay_s, Pass& pass) {
    OnlineOptions timed = options;
    timed.drive_delay_s = std::clamp(delay_s, -options.max_delay_s, options.max_delay_s);
    return select_and_scan(timed, pass);
}

// Step 1: the pass of the smallest residual scale over the grid and the first pool's estimate (the first pass itself
// among them).
template <typename Pass>
ScanResult coarse_start(const OnlineOptions& options, const ScanResult& first, Pass& pass) {
    ScanResult best = first;
    const auto consider = [&](double delay_s) {
        if (std::abs(delay_s - options.drive_delay_s) < 0.2e-3) return;
        ScanResult s = pass_at(options, delay_s, pass);
        if (s.online.mass.determined() &&
            (!best.online.mass.determined() || s.online.residual_std < best.online.residual_std))
            best = std::move(s);
    };
    consider(total_delay(first.online));
    for (const double delay_s : coarse_delays_s)
        if (std::abs(delay_s - total_delay(first.online)) >= 0.2e-3) consider(delay_s);
    return best;
}

struct Refined {
    ScanResult result;
    bool converged{false};
    double lowest{0.0}, highest{0.0}, lowest_mass{0.0}, highest_mass{0.0};  ///< over the passes [s], [kg]
};

// Step 2: from `start`, at most four passes.
template <typename Pass>
Refined refine_timing(const OnlineOptions& options, ScanResult start, Pass& pass) {
    const double sample_time_s = start.result.trace.sample_time_s;
    Refined r;
    r.lowest = r.highest = total_delay(start.online);
    r.lowest_mass = r.highest_mass = start.online.mass.value.value_or(0.0);
    const auto significant = [](const OnlineEstimate& e) {
        return e.delay_statistic && *e.delay_statistic > e.delay_threshold;
    };
    // the grid may have found a timing that leaves nothing significant already
    r.converged = !significant(start.online) && start.online.delay_applied_s != options.drive_delay_s;
    ScanResult s = std::move(start);
    double previous_applied = 0.0, previous_left = 0.0;
    for (int k = 0; k < 4 && !r.converged && s.online.delay_residual_s && s.online.delay_standard_error_s; ++k) {
        const double left = *s.online.delay_residual_s;
        const double applied = s.online.delay_applied_s;
        const double slope = k == 0 ? 0.0 : (left - previous_left) / (applied - previous_applied);
        const double next = k > 0 && slope < -0.05 && slope > -20.0 ? applied - left / slope : applied + left;
        previous_applied = applied;
        previous_left = left;
        const double before = applied + left;
        const double before_se = *s.online.delay_standard_error_s;
        s = pass_at(options, next, pass);
        if (!s.online.delay_residual_s || !s.online.delay_standard_error_s) break;
        const double total = total_delay(s.online);
        r.lowest = std::min(r.lowest, total);
        r.highest = std::max(r.highest, total);
        if (s.online.mass.value) {
            r.lowest_mass = std::min(r.lowest_mass, *s.online.mass.value);
            r.highest_mass = std::max(r.highest_mass, *s.online.mass.value);
        }
        if (!significant(s.online)) {
            r.converged = std::abs(total - before) <= 3.0 * std::max(before_se, *s.online.delay_standard_error_s);
            break;
        }
    }
    // what the last pass leaves is not significant, or not agreed on, but not nothing (a tenth of a millisecond is 1.4
    // standard errors of 0.07 ms, and B moves by 24 N*s/m with it on the drilling program's X axis): one more pass at
    // the delay it gives
    if (s.online.delay_residual_s && std::abs(*s.online.delay_residual_s) > polish_samples * sample_time_s) {
        ScanResult polished = pass_at(options, total_delay(s.online), pass);
        if (polished.online.mass.determined() && polished.online.delay_residual_s) s = std::move(polished);
    }
    r.result = std::move(s);
    return r;
}

template <typename Pass>
ScanResult time_and_scan(const OnlineOptions& options, Pass&& pass) {
    ScanResult first = select_and_scan(options, pass);
    const OnlineEstimate& e = first.online;
    // a first pass without a value is searched too: a force logged a few samples late can make every window's fit
    // poor (the pocket's X axis with the current 2 ms late: 1 window of 133 qualified as logged)
    const bool worth_a_search = !e.mass.determined() || (e.delay_statistic && *e.delay_statistic > explore_statistic &&
                                                         std::abs(total_delay(e)) <= options.max_delay_s);
    if (!options.estimate_delay || !worth_a_search) return first;
    Refined refined = refine_timing(options, coarse_start(options, first, pass), pass);
    // a timing found is taken where it is significant in its own pass; one that is not (the search starts at two
    // standard errors) leaves the force as logged, every parameter's standard error widened by the delay's (on axes
    // logged on time it finds -0.14 +- 0.055 ms on drilling's Y in 2 seeds of 10: applied, it moved B by 4 of its
    // standard errors, and B's scatter over the seeds rose to twice its standard error; on the pocket's Z, 6 windows,
    // the current 0.5 ms late, it finds 0.40 +- 0.16 ms, and B as logged, 10.6 % high, is within 3.2 of its widened
    // standard error)
    const OnlineEstimate& found_e = refined.result.online;
    const bool found = found_e.mass.determined();
    if (found && refined.converged && !e.delay_corrected && found_e.delay_standard_error_s &&
        !(std::abs(total_delay(found_e)) > found_e.delay_threshold * *found_e.delay_standard_error_s)) {
        if (first.online.delay_sensitivity.size() == 0) first.online.delay_sensitivity = found_e.delay_sensitivity;
        first.online.delay_residual_s = total_delay(found_e);
        first.online.delay_statistic = std::abs(total_delay(found_e)) / *found_e.delay_standard_error_s;
        first.online.delay_verdict = "searched, not significant: the force taken as logged, the delay's standard error "
                                     "in every parameter's";
        widen_for_timing(first, *found_e.delay_standard_error_s, 0.0);
        return first;
    }
    if (refined.converged && found) return std::move(refined.result);
    // the delays the passes gave stay within a fraction of a sample of each other (the pool moving by a window or
    // two with each): the last pass, its delay known to half their range
    if (found && refined.highest - refined.lowest <= settled_range_samples * first.result.trace.sample_time_s) {
        const double own = refined.result.online.delay_standard_error_s.value_or(0.0);
        widen_for_timing(refined.result, std::hypot(own, 0.5 * (refined.highest - refined.lowest)), own);
        return std::move(refined.result);
    }
    // the search found no timing whose windows give a value (fewer qualify at the delays tried): the first pass
    // stands where its own pool does not take the delay
    if ((!found && !e.delay_corrected) || !e.mass.determined()) return first;
    refuse_timing(first, refined.highest_mass - refined.lowest_mass,
                  fmt::format("the drive signal's timing cannot be told: applied in turn, the delays the windows "
                              "gave ranged from {:.3g} to {:.3g} ms (the windows that qualify change with the delay: "
                              "process forces?), and B and F_C move with it; --delay TIME applies a known one",
                              refined.lowest * 1e3, refined.highest * 1e3));
    return first;
}

}  // namespace

namespace {

/// The samples the gate keeps, every channel (a gated-out stretch becomes a gap in time, which identify cuts at).
Trace kept_samples(const Trace& trace, std::span<const char> use) {
    Trace kept = trace;
    for (Channel& channel : kept.channels) {
        std::size_t n = 0;
        for (std::size_t k = 0; k < channel.values.size(); ++k)
            if (use[k]) channel.values[n++] = channel.values[k];
        channel.values.resize(n);
    }
    return kept;
}

/// The trace with the drive force as scan formed it (its constants applied) in place of the drive signal.
Trace with_drive_force(Trace trace, std::vector<double> force) {
    std::optional<double> tare;
    std::erase_if(trace.channels, [&](const Channel& c) {
        const bool drive = c.role == Role::current || c.role == Role::force;
        if (drive && c.tare_removed) tare = c.tare_removed;
        return drive || c.role == Role::injection;
    });
    trace.set("drive force", Role::force, trace.rotary ? "N*m" : "N", std::move(force)).tare_removed = tare;
    return trace;
}

/// A log too coarse for a mass (identify's rule, assess_resolution: a machine's own 10 Hz log with positions in whole
/// millimetres) has no window the online identifier can fit: M is not identifiable, and B and F_C are identify's
/// friction-only estimate from the steady-speed samples (of the samples the gate keeps), the same numbers, M null with
/// the reason in figures. Failed, with identify's reason, where the steady-speed samples cannot give them either.
ScanResult friction_only_scan(const Trace& seen, std::span<const double> force, const OnlineOptions& options,
                              const TraceSummary& summary, bool systematic) {
    IdentifyOptions identify_options;
    identify_options.offset = options.offset;
    identify_options.systematic = systematic;  // --no-systematic: identify's preprocessing family skipped too
    identify_options.friction_only.robust = options.robust;  // --no-robust: least squares, as the windows
    ScanResult s;
    s.friction_only = true;
    s.result = identify(with_drive_force(seen, {force.begin(), force.end()}), identify_options);
    s.result.trace = summary;
    OnlineEstimate& e = s.online;
    const auto& diagnostics = s.result.diagnostics;
    e.mass_reason = s.result.friction_only ? s.result.friction_only->reason
                    : diagnostics.empty()  ? std::string("mass not identifiable")
                                           : diagnostics.back();
    e.stribeck_reason = "F_B and v_s not estimated: friction only (no window of the log resolves an acceleration)";
    if (s.result.friction_only) e.rows_used = s.result.friction_only->samples_used;
    return s;
}

/// Where the integration of the logged velocity stands after the samples so far (a file read in blocks continues it).
struct IntegratedPosition {
    bool started{false};
    double t{0.0}, v{0.0}, x{0.0};  ///< the last sample [s, m/s, m]
};

/// The logged velocity integrated (trapezoids) into the position the online identifier differentiates: its central
/// difference is (v[k-1] + 2 v[k] + v[k+1]) / 4, the logged velocity smoothed, not delayed. `at` carries the
/// integral from block to block (the first sample of the first block is at 0).
Trace with_integrated_position(const Trace& trace, IntegratedPosition& at) {
    Trace out = trace;
    const auto t = trace.column(Role::time);
    const auto v = trace.column(Role::velocity);
    std::vector<double> x(v.size(), 0.0);
    for (std::size_t k = 0; k < v.size(); ++k) {
        if (at.started) at.x += 0.5 * (v[k] + at.v) * (t[k] - at.t);
        at = {true, t[k], v[k], at.x};
        x[k] = at.x;
    }
    out.set("position from the logged velocity", Role::position, trace.rotary ? "rad" : "m", std::move(x));
    return out;
}

constexpr const char* velocity_only_note = "no position channel: the windows' motion is the logged velocity, integrated";

/// `run` on the samples the gate keeps (the trace itself where it keeps every one).
template <typename Run>
auto on_kept_samples(const Trace& trace, std::span<const double> force, std::span<const char> use, Run&& run) {
    if (std::find(use.begin(), use.end(), char{0}) == use.end()) return run(trace, force);
    const Trace kept = kept_samples(trace, use);
    std::vector<double> kept_force;
    for (std::size_t k = 0; k < force.size(); ++k)
        if (use[k]) kept_force.push_back(force[k]);
    return run(kept, std::span<const double>(kept_force));
}

/// identify's rule for a log too coarse for a mass, judged on the samples the gate keeps.
bool too_coarse(const Trace& trace, std::span<const double> force, std::span<const char> use,
                const OnlineOptions& options) {
    return on_kept_samples(trace, force, use, [&](const Trace& kept, std::span<const double> kept_force) {
        const IdentifyOptions rule;
        return assess_trace_resolution(kept, kept_force, rule.preprocess, rule.friction_only, options.moving_threshold)
            .coarse();
    });
}

}  // namespace

ScanResult scan(const Trace& trace, std::span<const double> force, std::span<const char> use,
                const OnlineOptions& given, std::size_t block, bool systematic) {
    OnlineOptions options = given;
    options.rotary = trace.rotary;
    if (const auto problem = options.validate(); !problem.empty()) throw InputError("scan: " + problem);
    const bool velocity_only = !trace.has(Role::position);
    if (velocity_only && !trace.has(Role::velocity))
        throw InputError(fmt::format(
            "{}: scan needs a position or a logged velocity (--channel position=NAME or --channel velocity=NAME)",
            trace.source_path));
    if (!velocity_only) require_consistent_units(trace);
    const TimeBase base = trace.samples() >= 2 ? trace.time_base() : TimeBase{};
    const TraceSummary summary{trace.source_path, trace.format, trace.samples(), base.sample_time_s, base.duration_s};
    // identify's rule first, on the samples the gate keeps: a log too coarse for a mass is not scanned by windows
    if (too_coarse(trace, force, use, options))
        return on_kept_samples(trace, force, use, [&](const Trace& kept, std::span<const double> kept_force) {
            return friction_only_scan(kept, kept_force, options, summary, systematic);
        });
    IntegratedPosition start;
    const Trace integrated = velocity_only ? with_integrated_position(trace, start) : Trace{};
    const Trace& moving = velocity_only ? integrated : trace;
    ScanResult s = time_and_scan(options, [&](const OnlineOptions& o) {
        Identifiers identifiers(o, systematic);
        push_trace(identifiers, moving, force, use, block);
        return finish(identifiers, summary, o, trace.rotary);
    });
    if (velocity_only) s.result.diagnostics.push_back(velocity_only_note);
    return s;
}

namespace {

// Reads up to `rows` lines into `text` (each with its '\n'); returns how many.
std::size_t read_lines(std::istream& in, std::size_t rows, std::string& text) {
    std::string line;
    std::size_t n = 0;
    while (n < rows && std::getline(in, line)) {
        text += line;
        text += '\n';
        ++n;
    }
    return n;
}

Trace parse_block(const std::string& text, const std::filesystem::path& path, const ImportOptions& import,
                  std::size_t rows_before) {
    CsvOptions csv;
    csv.skip_rows = import.skip_rows;
    csv.first_index = rows_before;  // a pandas index counts on through the blocks
    for (const auto& [role, name] : import.channels) csv.numeric_columns.push_back(name);
    Trace trace = parse_csv(text, path.string(), csv);
    trace.source_path = path.string();
    trace.format = "csv";
    prepare_trace(trace, import);
    if (!trace.has(Role::position) && !trace.has(Role::velocity))
        throw InputError(fmt::format(
            "{}: scan needs a position or a logged velocity (--channel position=NAME or --channel velocity=NAME)",
            path.string()));
    // block by block: a unit mix-up (or a position that jumps) shows in any block that moves
    if (trace.has(Role::position)) require_consistent_units(trace);
    return trace;
}

/// A time channel made from --sample-time starts at 0 in every block: moved on by the rows before the block.
void continue_sample_time(Trace& block, const ImportOptions& import, std::size_t rows_before) {
    if (!import.sample_time_s || rows_before == 0) return;
    const bool made = std::any_of(block.findings.begin(), block.findings.end(), [](const std::string& finding) {
        return finding.starts_with("no time column: channel '");
    });
    if (!made) return;
    auto& time = block.find(Role::time)->values;  // as the whole file's: (row) * dt, not a sum that rounds otherwise
    for (std::size_t k = 0; k < time.size(); ++k) time[k] = static_cast<double>(rows_before + k) * *import.sample_time_s;
}

/// The CSV file read in blocks, each block as scan_csv_pass parses it (the same values as the whole file's), `each`
/// called with every block in order. Returns the first block's import findings.
template <typename Each>
std::vector<std::string> for_each_block(const std::filesystem::path& path, const ImportOptions& import,
                                        std::size_t block_rows, Each&& each) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(fmt::format("{}: cannot open the file", path.string()));
    std::string text;
    const std::size_t first_lines = read_lines(in, block_rows, text);
    Trace block = parse_block(text, path, import, 0);
    const std::vector<std::string> findings = block.findings;
    // the lines before the first data row: the header (and comments, constants, skipped rows) of every block
    if (block.samples() > first_lines) throw InputError(fmt::format("{}: unexpected CSV layout", path.string()));
    std::size_t preamble_end = 0;
    for (std::size_t line = 0; line < first_lines - block.samples(); ++line)
        preamble_end = text.find('\n', preamble_end) + 1;
    const std::string preamble = text.substr(0, preamble_end);
    for (std::size_t rows = 0;;) {
        const std::size_t samples = block.samples();
        if (!each(block)) break;
        rows += samples;
        text = preamble;
        if (read_lines(in, block_rows, text) == 0) break;
        block = parse_block(text, path, import, rows);
        continue_sample_time(block, import, rows);
    }
    return findings;
}

// One pass of the identifiers over a CSV file read in blocks (scan_csv_stream). Without a position, the logged
// velocity integrated from block to block is the motion, as scan() integrates it over the whole trace.
ScanResult scan_csv_pass(const std::filesystem::path& path, const ImportOptions& import, const DriveConstants& drive,
                         std::span<const GateCondition> gates, const OnlineOptions& options, std::size_t block_rows,
                         std::vector<std::string>& findings, bool systematic) {
    std::optional<Identifiers> identifiers;
    OnlineOptions axis_options = options;
    TraceSummary summary{path.string(), "csv", 0, 0.0, 0.0};
    double start = 0.0, end = 0.0;
    bool velocity_only = false;
    IntegratedPosition integral;
    findings = for_each_block(path, import, block_rows, [&](const Trace& block) {
        if (!identifiers) {
            axis_options.rotary = block.rotary;
            identifiers.emplace(axis_options, systematic);
            summary.sample_time_s = block.samples() >= 2 ? block.time_base().sample_time_s : 0.0;
            start = end = block.samples() > 0 ? block.column(Role::time).front() : 0.0;
            velocity_only = !block.has(Role::position);
        }
        const std::vector<double> force = drive_force(block, drive);
        const std::vector<char> use = gate_samples(block, gates);
        push_trace(*identifiers, velocity_only ? with_integrated_position(block, integral) : block, force, use, 65536);
        summary.samples += block.samples();
        if (block.samples() > 0) end = block.column(Role::time).back();
        return true;
    });
    summary.duration_s = end - start;
    ScanResult s = finish(*identifiers, summary, axis_options, axis_options.rotary);
    if (velocity_only) s.result.diagnostics.push_back(velocity_only_note);
    return s;
}

/// A coarse log's first block says so (identify's rule, as scan() judges the whole trace): the whole file is then
/// read, its blocks joined (a log of 10 Hz holds a week in 256 MB), and scanned as scan() scans a file read whole, so
/// that both give the same result. Empty where the first block is not coarse.
std::optional<ScanResult> scan_coarse_log(const std::filesystem::path& path, const ImportOptions& import,
                                          const DriveConstants& drive, std::span<const GateCondition> gates,
                                          const OnlineOptions& options, std::size_t block_rows,
                                          std::vector<std::string>& findings, bool systematic) {
    std::optional<Trace> whole;
    findings = for_each_block(path, import, block_rows, [&](const Trace& block) {
        if (!whole) {
            const std::vector<double> force = drive_force(block, drive);
            OnlineOptions axis_options = options;
            axis_options.rotary = block.rotary;
            if (!too_coarse(block, force, gate_samples(block, gates), axis_options)) return false;
            whole = block;
            return true;
        }
        for (std::size_t c = 0; c < whole->channels.size(); ++c) {
            auto& values = whole->channels[c].values;
            values.insert(values.end(), block.channels[c].values.begin(), block.channels[c].values.end());
        }
        return true;
    });
    if (!whole) return std::nullopt;
    // the native intervals (and the holds detected) of the whole file, not of its first block: identify's low-pass
    // and edges follow them
    std::erase_if(findings, [](const std::string& finding) {
        return finding.starts_with("channel '") && finding.find("changes only every") != std::string::npos;
    });
    whole->findings = findings;
    for (Channel& channel : whole->channels)
        if (channel.interval_source != IntervalSource::format) channel.native_interval_s.reset();
    resolve_native_intervals(*whole);
    findings = whole->findings;
    const std::vector<double> force = drive_force(*whole, drive);
    return scan(*whole, force, gate_samples(*whole, gates), options, 65536, systematic);
}

}  // namespace

ScanResult scan_csv_stream(const std::filesystem::path& path, const ImportOptions& import, const DriveConstants& drive,
                           std::span<const GateCondition> gates, const OnlineOptions& options, std::size_t block_rows,
                           std::vector<std::string>& findings, bool systematic) {
    if (const auto problem = options.validate(); !problem.empty()) throw InputError("scan: " + problem);
    if (import.join || !import.tare.empty() || !import.invert.empty())
        throw InputError(fmt::format("{}: --join, --tare and --invert need the whole file; it is read in blocks",
                                     path.string()));
    if (auto coarse = scan_coarse_log(path, import, drive, gates, options, block_rows, findings, systematic))
        return std::move(*coarse);
    // no timing search: every pass reads and parses the whole file again (20 CPU s for 8 hours at 1 kHz, and the
    // search takes up to 11 passes); the pool's delay is corrected to first order where significant, as watch does,
    // and its uncertainty carried into every parameter
    return select_and_scan(options, [&](const OnlineOptions& o) {
        return scan_csv_pass(path, import, drive, gates, o, block_rows, findings, systematic);
    });
}

nlohmann::json scan_document(const ScanResult& s) {
    nlohmann::json document = s.result;
    document["kind"] = "scan";
    const OnlineEstimate& e = s.online;
    nlohmann::json rejected = nlohmann::json::object();
    for (std::size_t v = 1; v < window_verdicts; ++v)
        rejected[verdict_name(static_cast<WindowVerdict>(v))] = e.windows.by_verdict[v];
    document["windows"] = {{"total", e.windows.total},       {"qualified", e.windows.qualified()},
                           {"rejected", rejected},           {"rows_used", e.rows_used},
                           {"residual_std", e.residual_std}, {"stribeck_bins_used", e.stribeck_bins_used}};
    nlohmann::json information = nlohmann::json::object();
    std::size_t column = 0;
    for (const auto& p : s.result.parameters) {
        if (p.term == Term::breakaway || p.term == Term::stribeck_velocity) continue;
        const bool known = column < static_cast<std::size_t>(e.information.size());
        double value = known ? e.information(static_cast<Eigen::Index>(column)) : NAN;
        if (s.friction_only && p.estimate.standard_error)  // no windows: the friction-only fit's own variance
            value = 1.0 / (*p.estimate.standard_error * *p.estimate.standard_error);
        information[p.key] = {{"inverse_variance", std::isfinite(value) ? nlohmann::json(value) : nlohmann::json()}};
        ++column;
    }
    std::vector<double> eigenvalues(e.information_eigenvalues.data(),
                                    e.information_eigenvalues.data() + e.information_eigenvalues.size());
    information["eigenvalues"] = eigenvalues;
    document["information"] = information;
    return document;
}

namespace {

// Why a parameter of an online estimate is null.
const std::string& null_reason(const OnlineEstimate& e, Term term) {
    if (term == Term::breakaway || term == Term::stribeck_velocity) return e.stribeck_reason;
    if ((term == Term::coulomb || term == Term::offset) && !e.aliased_reason.empty()) return e.aliased_reason;
    if (term != Term::mass && !e.mass.determined() == false && !e.friction_reason.empty()) return e.friction_reason;
    return e.mass_reason.empty() ? e.friction_reason : e.mass_reason;
}

}  // namespace

std::vector<std::string> scan_verdicts(const ScanResult& s) {
    std::vector<std::string> lines;
    const std::size_t windows = s.online.windows.qualified();
    for (const auto& p : s.result.parameters) {
        const Estimate& e = p.estimate;
        const std::string from = s.friction_only ? fmt::format("{} steady-speed samples", s.online.rows_used)
                                                 : fmt::format("{} windows", windows);
        if (e.value && e.standard_error && *e.value != 0.0) {
            lines.push_back(fmt::format("{} from {}, σ {:.2g} %", p.symbol, from,
                                        100.0 * *e.standard_error / std::abs(*e.value)));
        } else if (e.value) {
            lines.push_back(fmt::format("{} from {}, no standard error", p.symbol, from));
        } else {
            const std::string& why = null_reason(s.online, p.term);
            // a reason that already names the parameter ("F_C not determined: the qualified windows move in one
            // direction only ...") is not prefixed twice
            lines.push_back(why.starts_with(p.symbol + " not determined") ? why
                                                                          : fmt::format("{} not determined: {}",
                                                                                        p.symbol, why));
        }
    }
    return lines;
}

}  // namespace feedid
