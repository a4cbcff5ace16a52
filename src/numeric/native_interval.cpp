#include "feedid/numeric/native_interval.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <fmt/core.h>

#include "feedid/numeric/signal.hpp"

namespace feedid {

namespace {

struct Change {
    std::size_t index;  ///< grid index of the new value
    double step;        ///< |new - old|
};

// Where the value changes (NaN samples skipped: a change is between two finite values).
std::vector<Change> value_changes(std::span<const double> values) {
    std::vector<Change> changes;
    std::optional<double> last;
    for (std::size_t j = 0; j < values.size(); ++j) {
        if (!std::isfinite(values[j])) continue;
        if (last && values[j] != *last) changes.push_back({j, std::abs(values[j] - *last)});
        last = values[j];
    }
    return changes;
}

// The most frequent gap between a moving change (a step above 1.5 smallest steps) and the change before it, and how
// many moving changes there are; {0, 0} without any.
std::pair<std::size_t, std::size_t> moving_gap(const std::vector<Change>& changes) {
    std::vector<double> steps;
    steps.reserve(changes.size());
    for (const auto& change : changes) steps.push_back(change.step);
    // The smallest step, ignoring round-off: the 1st percentile (as position_quantum()).
    const double smallest = percentile(std::move(steps), 0.01);
    std::map<std::size_t, std::size_t> gaps;
    std::size_t moving = 0;
    for (std::size_t c = 1; c < changes.size(); ++c) {
        if (!(changes[c].step > 1.5 * smallest)) continue;
        ++moving;
        ++gaps[changes[c].index - changes[c - 1].index];
    }
    if (gaps.empty()) return {0, 0};
    const auto mode = std::max_element(gaps.begin(), gaps.end(),
                                       [](const auto& a, const auto& b) { return a.second < b.second; });
    return {mode->first, moving};
}

}  // namespace

std::optional<SampleAndHold> detect_sample_and_hold(std::span<const double> values,
                                                    const HoldDetectionOptions& options) {
    const auto changes = value_changes(values);
    if (changes.size() < options.minimum_moving_changes + 1) return std::nullopt;
    const auto [gap, moving] = moving_gap(changes);
    if (moving < options.minimum_moving_changes || gap < 2 || gap > static_cast<std::size_t>(options.max_factor))
        return std::nullopt;
    std::vector<std::size_t> on_residue(gap, 0);
    for (const auto& change : changes) ++on_residue[change.index % gap];
    const auto best = std::max_element(on_residue.begin(), on_residue.end());
    SampleAndHold hold;
    hold.factor = static_cast<int>(gap);
    hold.phase = static_cast<int>(best - on_residue.begin());
    hold.changes = changes.size();
    hold.off_grid = changes.size() - *best;
    if (static_cast<double>(hold.off_grid) > options.exception_fraction * static_cast<double>(hold.changes))
        return std::nullopt;
    return hold;
}

int hold_phase(std::span<const double> values, int factor) {
    if (factor < 2) return 0;
    std::vector<std::size_t> on_residue(static_cast<std::size_t>(factor), 0);
    for (const auto& change : value_changes(values)) ++on_residue[change.index % on_residue.size()];
    return static_cast<int>(std::max_element(on_residue.begin(), on_residue.end()) - on_residue.begin());
}

std::vector<double> interpolate_held(std::span<const double> values, int factor, int phase) {
    std::vector<double> out(values.begin(), values.end());
    if (factor < 2 || values.empty()) return out;
    const auto step = static_cast<std::size_t>(factor);
    const auto first = static_cast<std::size_t>(phase) % step;
    for (std::size_t j = first; j + step < values.size(); j += step) {
        for (std::size_t i = 1; i < step; ++i) {
            const double fraction = static_cast<double>(i) / static_cast<double>(step);
            out[j + i] = values[j] + fraction * (values[j + step] - values[j]);
        }
    }
    return out;
}

void resolve_native_intervals(Trace& trace) {
    if (trace.samples() < 2 || !trace.has(Role::time)) return;
    const double sample_time = trace.time_base().sample_time_s;
    for (auto& channel : trace.channels) {
        if (channel.native_interval_s) continue;
        channel.native_interval_s = sample_time;
        channel.interval_source = IntervalSource::time_base;
        if (channel.role == Role::time) continue;
        if (const auto hold = detect_sample_and_hold(channel.values)) {
            channel.native_interval_s = hold->factor * sample_time;
            channel.interval_source = IntervalSource::detected;
            trace.findings.push_back(fmt::format(
                "channel '{}' changes only every {} samples ({} of {} changes on that grid): a signal sampled every "
                "{:.6g} ms and held on the {:.6g} ms time base",
                channel.name, hold->factor, hold->changes - hold->off_grid, hold->changes,
                *channel.native_interval_s * 1e3, sample_time * 1e3));
        }
    }
}

double native_interval_of(const Trace& trace, Role role) {
    const double sample_time = trace.samples() >= 2 ? trace.time_base().sample_time_s : 0.0;
    const auto* channel = trace.find(role);
    if (channel == nullptr || !channel->native_interval_s) return sample_time;
    return std::max(*channel->native_interval_s, sample_time);
}

}  // namespace feedid
