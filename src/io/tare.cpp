#include "feedid/io/tare.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/core.h>

#include "feedid/core/error.hpp"

namespace feedid {

namespace {

std::string where(const Trace& trace) {
    return trace.source_path.empty() ? std::string("trace") : trace.source_path;
}

/// The speed at every sample: the logged velocity, or the position's central difference.
std::vector<double> speed(const Trace& trace, Role role) {
    if (const auto* velocity = trace.find(Role::velocity)) return velocity->values;
    if (const auto* position = trace.find(Role::position)) {
        const auto time = trace.column(Role::time);
        std::vector<double> v(position->values.size(), 0.0);
        for (std::size_t k = 1; k + 1 < v.size(); ++k)
            v[k] = (position->values[k + 1] - position->values[k - 1]) / (time[k + 1] - time[k - 1]);
        if (v.size() >= 2) {
            v.front() = v[1];
            v.back() = v[v.size() - 2];
        }
        return v;
    }
    throw InputError(fmt::format("{}: --tare {}: no velocity or position channel tells when the axis is at rest",
                                 where(trace), role_name(role)));
}

}  // namespace

std::size_t leading_rest_samples(const Trace& trace, const TareOptions& options) {
    // the speed at sample k without holding a column of it (a long trace): the logged velocity, or the position's
    // central difference
    const Channel* velocity = trace.find(Role::velocity);
    const Channel* position = trace.find(Role::position);
    if (velocity == nullptr && position == nullptr) return 0;
    const auto time = trace.column(Role::time);
    const std::size_t n = trace.samples();
    const auto speed = [&](std::size_t k) {
        if (velocity != nullptr) return std::abs(velocity->values[k]);
        if (n < 3) return 0.0;
        k = std::clamp<std::size_t>(k, 1, n - 2);  // the ends take their neighbour's central difference
        return std::abs((position->values[k + 1] - position->values[k - 1]) / (time[k + 1] - time[k - 1]));
    };
    double fastest = 0.0;
    for (std::size_t k = 0; k < n; ++k) fastest = std::max(fastest, speed(k));
    const double threshold = options.rest_fraction_of_max_speed * fastest;
    std::size_t rest = 0;
    while (rest < n && speed(rest) <= threshold) ++rest;
    return static_cast<std::size_t>(std::floor(static_cast<double>(rest) * (1.0 - options.margin_fraction)));
}

TareReport tare(Trace& trace, Role role, const TareOptions& options) {
    Channel* channel = trace.find(role);
    if (channel == nullptr) {
        throw InputError(fmt::format("{}: --tare {}: the trace has no {} channel (map one with --channel {}=NAME)",
                                     where(trace), role_name(role), role_name(role), role_name(role)));
    }
    const std::vector<double> v = speed(trace, role);  // throws, naming the role, without a speed signal
    double fastest = 0.0;
    for (const double x : v) fastest = std::max(fastest, std::abs(x));
    const double threshold = options.rest_fraction_of_max_speed * fastest;
    const std::size_t used = leading_rest_samples(trace, options);
    if (used < options.minimum_samples) {
        throw InputError(fmt::format(
            "{}: --tare {}: only {} samples at rest (|v| <= {:.3g} {}) before the move starts, {} needed: record "
            "a moment at rest before the move",
            where(trace), role_name(role), used, threshold, trace.rotary ? "rad/s" : "m/s", options.minimum_samples));
    }
    double sum = 0.0;
    for (std::size_t k = 0; k < used; ++k) sum += channel->values[k];
    TareReport report;
    report.removed = sum / static_cast<double>(used);
    report.samples = used;
    report.rest_end_s = trace.column(Role::time)[used - 1];
    for (double& x : channel->values) x -= report.removed;
    channel->tare_removed = channel->tare_removed.value_or(0.0) + report.removed;
    trace.findings.push_back(
        fmt::format("--tare {}: {:.6g} {} removed from '{}' (its mean over the {} samples at rest up to {:.4g} s)",
                    role_name(role), report.removed, channel->unit.empty() ? std::string("(no unit)") : channel->unit,
                    channel->name, used, report.rest_end_s));
    return report;
}

}  // namespace feedid
