#include "feedid/io/join.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/units.hpp"

namespace feedid {

namespace {

std::string where(const Trace& trace) {
    return trace.source_path.empty() ? std::string("trace") : trace.source_path;
}

/// "4ms", "-0.004 s", "-0.004" (seconds) -> seconds.
double parse_shift(std::string_view text, std::string_view whole) {
    const auto unit_start = text.find_first_not_of("+-0123456789.eE ");
    const std::string number(text.substr(0, unit_start));
    const std::string_view unit =
        unit_start == std::string_view::npos ? std::string_view("s") : text.substr(unit_start);
    double value = 0.0;
    std::size_t used = 0;
    try {
        value = std::stod(number, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    const auto conversion = parse_unit(unit);
    if (used == 0 || number.find_first_not_of(' ', used) != std::string::npos || !conversion ||
        conversion->quantity != Quantity::time || !std::isfinite(value)) {
        throw InputError(fmt::format(
            "--join {}: the shift '{}' is not a time (write e.g. @4ms, @-0.004s, @auto or @auto:OURS=THEIRS)", whole,
            text));
    }
    return conversion->scale * value;
}

/// Pearson correlation of a and b over the samples where both are finite; NaN with fewer than 3.
double correlation(std::span<const double> a, std::span<const double> b) {
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    std::size_t n = 0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        if (!std::isfinite(a[k]) || !std::isfinite(b[k])) continue;
        sa += a[k];
        sb += b[k];
        saa += a[k] * a[k];
        sbb += b[k] * b[k];
        sab += a[k] * b[k];
        ++n;
    }
    if (n < 3) return std::numeric_limits<double>::quiet_NaN();
    const double m = static_cast<double>(n);
    const double cov = sab - sa * sb / m, va = saa - sa * sa / m, vb = sbb - sb * sb / m;
    if (!(va > 0.0) || !(vb > 0.0)) return std::numeric_limits<double>::quiet_NaN();
    return cov / std::sqrt(va * vb);
}

/// The channels to correlate: named, or the first role both recordings hold (other than time).
std::pair<const Channel*, const Channel*> correlation_channels(const Trace& first, const Trace& second,
                                                               const JoinOptions& options) {
    if (!options.ours.empty()) {
        const Channel* ours = first.find(options.ours);
        const Channel* theirs = second.find(options.theirs);
        if (ours == nullptr)
            throw InputError(fmt::format("--join @auto:{}={}: {} has no channel named '{}'", options.ours,
                                         options.theirs, where(first), options.ours));
        if (theirs == nullptr)
            throw InputError(fmt::format("--join @auto:{}={}: {} has no channel named '{}'", options.ours,
                                         options.theirs, where(second), options.theirs));
        return {ours, theirs};
    }
    for (const auto& channel : first.channels) {
        if (channel.role == Role::other || channel.role == Role::time) continue;
        if (const Channel* theirs = second.find(channel.role)) return {&channel, theirs};
    }
    throw InputError(fmt::format(
        "--join {}@auto: no role is held by a channel in both recordings; name the channels to cross-correlate "
        "with @auto:OURS=THEIRS",
        where(second)));
}

/// The unique name of a channel of the second recording among the first's.
std::string unique_name(const Trace& joined, const std::string& name) {
    if (joined.find(name) == nullptr) return name;
    for (int n = 2;; ++n) {
        std::string candidate = fmt::format("{}_{}", name, n);
        if (joined.find(candidate) == nullptr) return candidate;
    }
}

}  // namespace

JoinSpec parse_join_spec(std::string_view text) {
    JoinSpec spec;
    const auto at = text.rfind('@');
    spec.path = std::string(text.substr(0, at));
    if (spec.path.empty()) throw InputError(fmt::format("--join {}: expected FILE[@SHIFT]", text));
    if (at == std::string_view::npos) {
        spec.options.shift_s = 0.0;
        return spec;
    }
    const std::string_view shift = text.substr(at + 1);
    if (shift == "auto") return spec;
    if (shift.starts_with("auto:")) {
        const std::string_view pair = shift.substr(5);
        const auto equals = pair.find('=');
        if (equals == std::string_view::npos || equals == 0 || equals + 1 == pair.size())
            throw InputError(fmt::format("--join {}: expected @auto:OURS=THEIRS (a channel of each recording)", text));
        spec.options.ours = std::string(pair.substr(0, equals));
        spec.options.theirs = std::string(pair.substr(equals + 1));
        return spec;
    }
    spec.options.shift_s = parse_shift(shift, text);
    return spec;
}

std::vector<double> interpolate_linear(std::span<const double> time, std::span<const double> values,
                                       std::span<const double> at) {
    std::vector<double> out(at.size(), std::numeric_limits<double>::quiet_NaN());
    if (time.empty()) return out;
    for (std::size_t k = 0; k < at.size(); ++k) {
        const double t = at[k];
        if (!(t >= time.front() && t <= time.back())) continue;
        const auto upper = std::upper_bound(time.begin(), time.end(), t);
        if (upper == time.end()) {
            out[k] = values.back();
            continue;
        }
        const auto i = static_cast<std::size_t>(upper - time.begin());  // time[i-1] <= t < time[i]
        const double w = (t - time[i - 1]) / (time[i] - time[i - 1]);
        out[k] = values[i - 1] + w * (values[i] - values[i - 1]);
    }
    return out;
}

std::pair<double, double> find_shift(std::span<const double> our_time, std::span<const double> ours,
                                     std::span<const double> their_time, std::span<const double> theirs,
                                     double max_shift_s) {
    if (our_time.size() < 3 || their_time.size() < 3) return {0.0, std::numeric_limits<double>::quiet_NaN()};
    const double dt = (our_time.back() - our_time.front()) / static_cast<double>(our_time.size() - 1);
    const auto steps = static_cast<long>(std::floor(max_shift_s / dt));
    std::vector<double> scores;
    std::vector<double> shifted(our_time.size());
    for (long s = -steps; s <= steps; ++s) {
        // theirs at t - shift, on our time stamps
        for (std::size_t k = 0; k < our_time.size(); ++k) shifted[k] = our_time[k] - static_cast<double>(s) * dt;
        scores.push_back(correlation(ours, interpolate_linear(their_time, theirs, shifted)));
    }
    std::size_t best = 0;
    for (std::size_t i = 0; i < scores.size(); ++i) {
        if (std::isfinite(scores[i]) && (!std::isfinite(scores[best]) || std::abs(scores[i]) > std::abs(scores[best])))
            best = i;
    }
    double offset = 0.0;  // a parabola through the peak and its neighbours, in samples
    if (best > 0 && best + 1 < scores.size() && std::isfinite(scores[best - 1]) && std::isfinite(scores[best + 1])) {
        const double l = std::abs(scores[best - 1]), c = std::abs(scores[best]), r = std::abs(scores[best + 1]);
        const double curvature = l - 2.0 * c + r;
        if (curvature < 0.0) offset = std::clamp(0.5 * (l - r) / curvature, -0.5, 0.5);
    }
    return {(static_cast<double>(static_cast<long>(best) - steps) + offset) * dt, scores[best]};
}

Trace join_traces(const Trace& first, const Trace& second, const JoinOptions& options, JoinReport* report) {
    JoinReport done;
    const auto our_time = first.column(Role::time);
    const auto their_time = second.column(Role::time);
    if (options.shift_s) {
        done.shift_s = *options.shift_s;
    } else {
        const auto [ours, theirs] = correlation_channels(first, second, options);
        const auto [shift, r] = find_shift(our_time, ours->values, their_time, theirs->values, options.max_shift_s);
        if (!std::isfinite(r)) {
            throw InputError(fmt::format("--join {}@auto: '{}' and '{}' do not overlap or do not vary: no shift found",
                                         where(second), ours->name, theirs->name));
        }
        done.shift_s = shift;
        done.automatic = true;
        done.correlation = r;
    }
    // the first trace's samples inside the second's shifted span
    const double begin = their_time.front() + done.shift_s, end = their_time.back() + done.shift_s;
    const auto first_in =
        static_cast<std::size_t>(std::lower_bound(our_time.begin(), our_time.end(), begin) - our_time.begin());
    const auto last_in =
        static_cast<std::size_t>(std::upper_bound(our_time.begin(), our_time.end(), end) - our_time.begin());
    if (last_in <= first_in + 1) {
        throw InputError(
            fmt::format("--join {}: its time span ({:.6g} to {:.6g} s after the shift) does not overlap "
                        "that of {} ({:.6g} to {:.6g} s)",
                        where(second), begin, end, where(first), our_time.front(), our_time.back()));
    }
    done.dropped_before = first_in;
    done.dropped_after = our_time.size() - last_in;
    Trace joined = first.slice(first_in, last_in);
    const auto joined_time = joined.column(Role::time);
    std::vector<double> at(joined_time.begin(), joined_time.end());
    for (double& t : at) t -= done.shift_s;
    for (const auto& channel : second.channels) {
        if (channel.role == Role::time) continue;
        Channel copy{unique_name(joined, channel.name), channel.role, channel.unit, channel.source_unit,
                     interpolate_linear(their_time, channel.values, at)};
        if (copy.name != channel.name) {
            joined.findings.push_back(fmt::format("channel '{}' of {} renamed '{}' (the name is taken in {})",
                                                  channel.name, where(second), copy.name, where(first)));
        }
        joined.channels.push_back(std::move(copy));
    }
    for (const auto& [name, value] : second.constants) joined.constants.emplace(name, value);
    for (const auto& finding : second.findings)
        joined.findings.push_back(fmt::format("{}: {}", where(second), finding));
    if (done.automatic) {
        joined.findings.push_back(fmt::format(
            "joined {}: shift {:.4g} ms found by cross-correlation (correlation coefficient {:.3f}); give it with "
            "--join FILE@SHIFT if the physics says otherwise",
            where(second), done.shift_s * 1e3, done.correlation));
    } else {
        joined.findings.push_back(
            fmt::format("joined {}: its time stamps shifted by {:.4g} ms", where(second), done.shift_s * 1e3));
    }
    if (done.dropped_before + done.dropped_after > 0) {
        joined.findings.push_back(
            fmt::format("{} samples of {} outside the span of {} dropped ({} before, {} after; never extrapolated)",
                        done.dropped_before + done.dropped_after, where(first), where(second), done.dropped_before,
                        done.dropped_after));
    }
    if (report != nullptr) *report = done;
    return joined;
}

}  // namespace feedid
