#include "feedid/identify/stick_slip.hpp"

#include <algorithm>
#include <cmath>

#include "feedid/numeric/signal.hpp"

namespace feedid {

namespace {

int direction_of(double v, double threshold) {
    return v > threshold ? 1 : (v < -threshold ? -1 : 0);
}

/// Runs of commanded motion in one direction: [first, last) where the reference speed stays above the threshold
/// with one sign.
std::vector<MotionPass> reference_passes(const std::vector<double>& reference, double threshold) {
    std::vector<MotionPass> passes;
    std::size_t k = 0;
    while (k < reference.size()) {
        const int direction = direction_of(reference[k], threshold);
        if (direction == 0) {
            ++k;
            continue;
        }
        MotionPass pass{k, k, direction, 0.0, false};
        while (k < reference.size() && direction_of(reference[k], threshold) == direction) ++k;
        pass.last = k;
        std::vector<double> speeds;
        for (std::size_t j = pass.first; j < pass.last; ++j) speeds.push_back(std::abs(reference[j]));
        pass.speed = percentile(std::move(speeds), 0.5);
        passes.push_back(pass);
    }
    return passes;
}

/// Whether the axis stuck or swung about the command while the command ran steadily through the pass, after it
/// first caught up with the command (a slow start after a dwell, the breakaway, is no stick-slip).
bool sticks_against_reference(const Derivatives& d, const MotionPass& pass, const StickSlipOptions& options) {
    const auto& v = d.velocity;
    const auto& reference = d.reference_velocity;
    double steady_since = NAN;
    bool caught_up = false, in_swing = false;
    int swings = 0;
    for (std::size_t k = pass.first; k < pass.last; ++k) {
        const bool steady =
            std::abs(std::abs(reference[k]) - pass.speed) <= options.steady_reference_fraction * pass.speed;
        if (!steady) {
            steady_since = NAN;
            in_swing = false;
            continue;
        }
        if (std::isnan(steady_since)) steady_since = d.time[k];
        if (d.time[k] - steady_since < options.settle_s) continue;
        const bool swing = std::abs(v[k] - reference[k]) > options.swing_fraction * pass.speed;
        if (!caught_up) {
            caught_up = !swing;
            continue;
        }
        if (v[k] * pass.direction < options.stop_fraction * pass.speed) return true;  // back to (nearly) zero
        if (swing && !in_swing) ++swings;
        in_swing = swing;
    }
    return swings >= options.swings;
}

/// Runs of motion in one direction, with the stops inside them: [first, last) from the first to the last moving
/// sample before the motion reverses.
std::vector<MotionPass> motion_passes(const std::vector<double>& v, double threshold) {
    std::vector<MotionPass> passes;
    std::size_t k = 0;
    while (k < v.size()) {
        const int direction = direction_of(v[k], threshold);
        if (direction == 0) {
            ++k;
            continue;
        }
        MotionPass pass{k, k + 1, direction, 0.0, false};
        for (; k < v.size(); ++k) {
            const int here = direction_of(v[k], threshold);
            if (here == -direction) break;
            if (here == direction) pass.last = k + 1;
        }
        k = pass.last;
        std::vector<double> speeds;
        for (std::size_t j = pass.first; j < pass.last; ++j) {
            if (direction_of(v[j], threshold) == direction) speeds.push_back(std::abs(v[j]));
        }
        pass.speed = percentile(std::move(speeds), 0.5);
        passes.push_back(pass);
    }
    return passes;
}

/// Whether the axis stopped and restarted in the same direction, briefly and repeatedly, within the pass.
bool sticks_without_reference(const Derivatives& d, const MotionPass& pass, double threshold,
                              const StickSlipOptions& options) {
    const double stop_level = std::max(threshold, options.stop_fraction * pass.speed);
    int brief_stops = 0;
    std::size_t k = pass.first;
    double burst_start = d.time[pass.first];
    double longest_burst = 0.0;
    while (k < pass.last) {
        if (std::abs(d.velocity[k]) > stop_level) {
            ++k;
            continue;
        }
        const std::size_t stop_start = k;
        while (k < pass.last && std::abs(d.velocity[k]) <= stop_level) ++k;
        if (k == pass.last) break;  // the pass ends in this stop
        longest_burst = std::max(longest_burst, d.time[stop_start] - burst_start);
        burst_start = d.time[k];
        if (d.time[k] - d.time[stop_start] < options.max_stick_s) ++brief_stops;
    }
    return brief_stops >= options.stops_without_reference && longest_burst < options.max_stick_s;
}

}  // namespace

StickSlip detect_stick_slip(const Derivatives& d, double moving_threshold, const StickSlipOptions& options) {
    StickSlip out;
    out.flags.assign(d.size(), 0);
    out.by_reference = !d.reference_velocity.empty();
    if (d.size() < 3) return out;
    const double judged_speed = options.noise_multiple * d.velocity_noise / options.stop_fraction;
    if (out.by_reference) {
        double fastest = 0.0;
        for (const double r : d.reference_velocity) fastest = std::max(fastest, std::abs(r));
        out.passes = reference_passes(d.reference_velocity, std::max(moving_threshold, 1e-3 * fastest));
        for (std::size_t p = 0; p < out.passes.size(); ++p) {
            MotionPass& pass = out.passes[p];
            pass.stick_slip = pass.speed > judged_speed && sticks_against_reference(d, pass, options);
            if (!pass.stick_slip) continue;
            // the slip may outlast the command: the pass reaches to where the next one starts
            const std::size_t end = p + 1 < out.passes.size() ? out.passes[p + 1].first : d.size();
            std::fill(out.flags.begin() + static_cast<std::ptrdiff_t>(pass.first),
                      out.flags.begin() + static_cast<std::ptrdiff_t>(end), 1);
        }
    } else {
        out.passes = motion_passes(d.velocity, moving_threshold);
        for (MotionPass& pass : out.passes) {
            pass.stick_slip = sticks_without_reference(d, pass, moving_threshold, options);
            if (!pass.stick_slip) continue;
            std::fill(out.flags.begin() + static_cast<std::ptrdiff_t>(pass.first),
                      out.flags.begin() + static_cast<std::ptrdiff_t>(pass.last), 1);
        }
    }
    for (const MotionPass& pass : out.passes) out.stick_slip_passes += pass.stick_slip ? 1 : 0;
    out.samples = static_cast<std::size_t>(std::count(out.flags.begin(), out.flags.end(), 1));
    return out;
}

}  // namespace feedid
