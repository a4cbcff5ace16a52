#include "feedid/numeric/native_interval.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include <fmt/core.h>

#include "feedid/numeric/signal.hpp"

namespace feedid {

namespace {

// Calls change(index, step) where the value changes (NaN samples skipped: a change is between two finite values):
// index is the grid index of the new value, step |new - old|. Streamed, not gathered: a noisy channel changes on
// every sample, and a list of its changes would be twice the column.
template <class Change>
void for_each_change(std::span<const double> values, Change&& change) {
    double last = 0.0;
    bool have_last = false;
    for (std::size_t j = 0; j < values.size(); ++j) {
        const double value = values[j];
        if (!std::isfinite(value)) continue;
        if (have_last && value != last) change(j, std::abs(value - last));
        last = value;
        have_last = true;
    }
}

// The value changes, and the disjoint pairs of changes at neighbouring indices (a run of r changes in a row holds
// r / 2 of them). Of two neighbouring indices at most one lies on a hold grid of k >= 2 samples, so the pairs bound
// the changes off any hold grid from below: a signal that changes at every sample is ruled out in this one pass.
struct ChangeCount {
    std::size_t changes{0};
    std::size_t neighbouring_pairs{0};
};

ChangeCount count_changes(std::span<const double> values) {
    ChangeCount count;
    std::size_t previous = 0;
    bool paired = true;  // whether the previous change is taken by a pair (true before any: nothing to pair with)
    for_each_change(values, [&](std::size_t index, double) {
        const bool pairs = !paired && index == previous + 1;
        count.neighbouring_pairs += static_cast<std::size_t>(pairs);
        paired = pairs;
        previous = index;
        ++count.changes;
    });
    return count;
}

// The most frequent gap between a moving change (a step above 1.5 smallest steps) and the change before it (the
// smallest gap of those as frequent), and how many moving changes there are; {0, 0} without any.
std::pair<std::size_t, std::size_t> moving_gap(std::span<const double> values, std::size_t changes) {
    std::vector<double> steps;
    steps.reserve(changes);
    for_each_change(values, [&](std::size_t, double step) { steps.push_back(step); });
    // The smallest step, ignoring round-off: the 1st percentile (as position_quantum()).
    const double smallest = percentile_in_place(steps, 0.01);
    // gaps counted in an array up to a bound that covers every hold factor looked for, beyond it in a map
    constexpr std::size_t counted = 4096;
    std::vector<std::size_t> short_gaps(counted, 0);
    std::map<std::size_t, std::size_t> long_gaps;
    std::size_t moving = 0;
    std::size_t previous = 0;
    bool first = true;
    for_each_change(values, [&](std::size_t index, double step) {
        const std::size_t gap = index - previous;
        previous = index;
        if (std::exchange(first, false) || !(step > 1.5 * smallest)) return;
        ++moving;
        if (gap < counted)
            ++short_gaps[gap];
        else
            ++long_gaps[gap];
    });
    if (moving == 0) return {0, 0};
    std::size_t mode = 0;
    std::size_t mode_count = 0;
    for (std::size_t gap = 0; gap < counted; ++gap) {
        if (short_gaps[gap] > mode_count) {
            mode = gap;
            mode_count = short_gaps[gap];
        }
    }
    for (const auto& [gap, count] : long_gaps) {
        if (count > mode_count) {
            mode = gap;
            mode_count = count;
        }
    }
    return {mode, moving};
}

// Changes per residue of their index modulo `factor`.
std::vector<std::size_t> changes_on_residue(std::span<const double> values, std::size_t factor) {
    std::vector<std::size_t> on_residue(factor, 0);
    for_each_change(values, [&](std::size_t index, double) { ++on_residue[index % factor]; });
    return on_residue;
}

}  // namespace

std::optional<SampleAndHold> detect_sample_and_hold(std::span<const double> values,
                                                    const HoldDetectionOptions& options) {
    const auto [changes, neighbouring_pairs] = count_changes(values);
    if (changes < options.minimum_moving_changes + 1) return std::nullopt;
    // at least this many changes are off any grid: more than the exceptions allowed is no hold, whatever the factor
    if (static_cast<double>(neighbouring_pairs) > options.exception_fraction * static_cast<double>(changes))
        return std::nullopt;
    const auto [gap, moving] = moving_gap(values, changes);
    if (moving < options.minimum_moving_changes || gap < 2 || gap > static_cast<std::size_t>(options.max_factor))
        return std::nullopt;
    const auto on_residue = changes_on_residue(values, gap);
    const auto best = std::max_element(on_residue.begin(), on_residue.end());
    SampleAndHold hold;
    hold.factor = static_cast<int>(gap);
    hold.phase = static_cast<int>(best - on_residue.begin());
    hold.changes = changes;
    hold.off_grid = changes - *best;
    if (static_cast<double>(hold.off_grid) > options.exception_fraction * static_cast<double>(hold.changes))
        return std::nullopt;
    return hold;
}

int hold_phase(std::span<const double> values, int factor) {
    if (factor < 2) return 0;
    const auto on_residue = changes_on_residue(values, static_cast<std::size_t>(factor));
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
