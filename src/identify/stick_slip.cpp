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
        const auto each = [&](const auto& f) {
            for (std::size_t j = pass.first; j < pass.last; ++j) f(reference[j]);
        };
        pass.speed = absolute_percentile_of(pass.last - pass.first, each, 0.5);
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

/// The passes without a reference, and which of them stick-slip (StickSlipTracker); each pass's speed the median of
/// its moving samples' |v|, as with a reference.
std::vector<MotionPass> tracked_passes(const Derivatives& d, double threshold, const StickSlipOptions& options) {
    std::vector<MotionPass> passes;
    StickSlipTracker tracker(threshold, options);
    for (std::size_t k = 0; k < d.size(); ++k) {
        if (auto ended = tracker.add(d.time[k], d.velocity[k])) passes.push_back(*ended);
    }
    if (auto ended = tracker.finish()) passes.push_back(*ended);
    for (MotionPass& pass : passes) {
        const auto each = [&](const auto& f) {
            for (std::size_t j = pass.first; j < pass.last; ++j) {
                if (direction_of(d.velocity[j], threshold) == pass.direction) f(d.velocity[j]);
            }
        };
        pass.speed = absolute_percentile_of(visited_count(each), each, 0.5);
    }
    return passes;
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
        out.passes = tracked_passes(d, moving_threshold, options);
        for (const MotionPass& pass : out.passes) {
            if (!pass.stick_slip) continue;
            std::fill(out.flags.begin() + static_cast<std::ptrdiff_t>(pass.first),
                      out.flags.begin() + static_cast<std::ptrdiff_t>(pass.last), 1);
        }
    }
    for (const MotionPass& pass : out.passes) out.stick_slip_passes += pass.stick_slip ? 1 : 0;
    out.samples = static_cast<std::size_t>(std::count(out.flags.begin(), out.flags.end(), 1));
    return out;
}

StickSlipTracker::StickSlipTracker(double moving_threshold, const StickSlipOptions& options)
    : moving_threshold_(moving_threshold), options_(options) {}

std::optional<MotionPass> StickSlipTracker::add(double time, double velocity) {
    const std::size_t k = samples_++;
    const int direction = direction_of(velocity, moving_threshold_);
    std::optional<MotionPass> ended;
    if (pass_.direction != 0 && direction == -pass_.direction) {
        ended = closed();
        pass_.direction = 0;
    }
    const double speed = std::abs(velocity);
    if (pass_.direction == 0) {
        if (direction == 0) return ended;
        pass_ = MotionPass{k, k + 1, direction, 0.0, false};
        stopped_ = false;
        burst_start_s_ = time;
        burst_peak_ = pass_peak_ = speed;
        longest_burst_s_ = 0.0;
        brief_stops_ = 0;
        return ended;
    }
    if (direction == pass_.direction) pass_.last = k + 1;
    pass_peak_ = std::max(pass_peak_, speed);
    if (!stopped_) {
        const double level = std::max(moving_threshold_, options_.stop_fraction * burst_peak_);
        if (speed > level) {
            burst_peak_ = std::max(burst_peak_, speed);
        } else {
            stopped_ = true;
            stop_start_s_ = time;
            stop_level_ = level;
        }
    } else if (speed > stop_level_) {  // moving on in the same direction: a reversal ended the pass above
        longest_burst_s_ = std::max(longest_burst_s_, stop_start_s_ - burst_start_s_);
        if (time - stop_start_s_ < options_.max_stick_s) ++brief_stops_;
        stopped_ = false;
        burst_start_s_ = time;
        burst_peak_ = speed;
    }
    return ended;
}

std::optional<MotionPass> StickSlipTracker::finish() {
    if (pass_.direction == 0) return std::nullopt;
    const MotionPass ended = closed();
    pass_.direction = 0;
    return ended;
}

bool StickSlipTracker::stick_slipping() const {
    return pass_.direction != 0 && brief_stops_ >= options_.stops_without_reference &&
           longest_burst_s_ < options_.max_stick_s;
}

std::optional<MotionPass> StickSlipTracker::current() const {
    if (pass_.direction == 0) return std::nullopt;
    return closed();
}

MotionPass StickSlipTracker::closed() const {
    MotionPass pass = pass_;
    pass.speed = pass_peak_;
    pass.stick_slip = stick_slipping();
    return pass;
}

}  // namespace feedid
