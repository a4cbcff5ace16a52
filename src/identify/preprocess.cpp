#include "feedid/identify/preprocess.hpp"

#include <algorithm>
#include <cmath>

#include <optional>
#include <string>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/numeric/native_interval.hpp"
#include "feedid/numeric/signal.hpp"

namespace feedid {

double position_quantum(std::span<const double> position) {
    double range = 0.0;
    if (!position.empty()) {
        const auto [low, high] = std::minmax_element(position.begin(), position.end());
        range = *high - *low;
    }
    // the steps of an evenly spread sample above robust_sample_size (a quantum is a threshold: the 1st percentile of
    // an encoder's steps is the quantum itself, in any sample of them)
    const std::size_t stride = position.empty() ? 1 : robust_sample_stride(position.size() - 1);
    std::vector<double> steps;
    steps.reserve(position.size() / stride + 1);
    for (std::size_t k = 1; k < position.size(); k += stride) {
        const double d = std::abs(position[k] - position[k - 1]);
        if (d > 1e-12 * std::max(range, 1e-300)) steps.push_back(d);
    }
    if (steps.empty()) return 0.0;
    return percentile(std::move(steps), 0.01);
}

namespace {

struct Differentiated {
    std::vector<double> velocity, acceleration;
    std::size_t default_edge{2};  ///< central differences: one-sided at the ends
};

/// A Butterworth cut-off must lie below half the sample rate.
void require_cutoff_below_nyquist(double cutoff_hz, double fs) {
    if (!(cutoff_hz < 0.5 * fs)) {
        throw InputError(fmt::format("--cutoff {} Hz must be below half the sample rate ({} Hz)", cutoff_hz, 0.5 * fs));
    }
}

/// The samples a zero-phase Butterworth's start-up transient spoils at each edge.
std::size_t butterworth_edge(const PreprocessOptions& options, double cutoff_hz, double fs) {
    return static_cast<std::size_t>(std::ceil(options.filter_settling_periods * fs / cutoff_hz));
}

/// The Savitzky-Golay window [samples]: as given, or the default span at this rate (odd, at least 5).
int savitzky_golay_window(const PreprocessOptions& options, double fs) {
    if (options.savitzky_golay_window != 0) return options.savitzky_golay_window;
    // odd, at least 5 and above the polynomial order (a window of the order's size fits the samples exactly)
    const int above_order = (options.savitzky_golay_order + 2) | 1;
    return std::max({5, above_order, static_cast<int>(std::lround(options.savitzky_golay_span_s * fs)) | 1});
}

/// x' and x'' of the window's position by the chosen method, and the edge trim that method needs.
Differentiated differentiate(std::span<const double> x, double dt, const PreprocessOptions& options,
                             PreprocessReport& used) {
    const double fs = 1.0 / dt;
    Differentiated out;
    switch (options.differentiation) {
        case Differentiation::central:
            used.differentiation = "central";
            out.velocity = central_difference(x, dt);
            out.acceleration = central_difference(out.velocity, dt);
            break;
        case Differentiation::butterworth: {
            used.differentiation = "butterworth";
            require_cutoff_below_nyquist(used.cutoff_hz, fs);
            const auto filtered = filtfilt(butterworth_lowpass(options.filter_order, used.cutoff_hz, fs), x);
            out.velocity = central_difference(filtered, dt);
            out.acceleration = central_difference(out.velocity, dt);
            out.default_edge = butterworth_edge(options, used.cutoff_hz, fs);
            break;
        }
        case Differentiation::savitzky_golay: {
            used.differentiation = "savitzky-golay";
            const int window = savitzky_golay_window(options, fs);
            used.savitzky_golay_window = window;
            used.savitzky_golay_order = options.savitzky_golay_order;
            if (static_cast<std::size_t>(window) > x.size()) return out;  // the caller reports it
            // smoothed, then differentiated as the Butterworth's output is: the force goes through the same
            // smoothing, and x'' is then exactly the central second difference of a signal filtered like it (the
            // Savitzky-Golay derivative filters are other low-passes than its smoothing filter: with them M came out
            // 1.1 % low on the demo axis)
            const auto smoothed = savitzky_golay(x, window, options.savitzky_golay_order, 0, dt);
            out.velocity = central_difference(smoothed, dt);
            out.acceleration = central_difference(out.velocity, dt);
            out.default_edge = static_cast<std::size_t>(window / 2 + 3);
            break;
        }
    }
    return out;
}

/// x' and x'' from a logged velocity: the same filter the position would get (zero-phase), then its derivative.
Differentiated differentiate_velocity(std::span<const double> v, double dt, const PreprocessOptions& options,
                                      PreprocessReport& used) {
    const double fs = 1.0 / dt;
    Differentiated out;
    switch (options.differentiation) {
        case Differentiation::central:
            used.differentiation = "central";
            out.velocity.assign(v.begin(), v.end());
            break;
        case Differentiation::butterworth:
            used.differentiation = "butterworth";
            require_cutoff_below_nyquist(used.cutoff_hz, fs);
            out.velocity = filtfilt(butterworth_lowpass(options.filter_order, used.cutoff_hz, fs), v);
            out.default_edge = butterworth_edge(options, used.cutoff_hz, fs);
            break;
        case Differentiation::savitzky_golay: {
            used.differentiation = "savitzky-golay";
            const int window = savitzky_golay_window(options, fs);
            used.savitzky_golay_window = window;
            used.savitzky_golay_order = options.savitzky_golay_order;
            if (static_cast<std::size_t>(window) > v.size()) return out;  // the caller reports it
            out.velocity = savitzky_golay(v, window, options.savitzky_golay_order, 0, dt);
            out.default_edge = static_cast<std::size_t>(window / 2 + 1);
            break;
        }
    }
    out.acceleration = central_difference(out.velocity, dt);
    return out;
}

/// Whether x' comes from the logged velocity: asked for, or automatic and the position is missing or too coarse
/// (its quantum above a fraction of the travel per sample at the typical logged speed).
bool use_logged_velocity(const Trace& trace, std::span<const double> logged, double quantum, double dt,
                         const PreprocessOptions& options) {
    if (options.velocity_source == VelocitySource::position) return false;
    if (!trace.has(Role::velocity)) {
        if (options.velocity_source == VelocitySource::logged) {
            throw InputError(
                fmt::format("{}: --velocity-source velocity: the trace has no velocity channel (map one "
                            "with --channel velocity=NAME)",
                            trace.source_path.empty() ? "trace" : trace.source_path));
        }
        return false;
    }
    if (options.velocity_source == VelocitySource::logged || !trace.has(Role::position)) return true;
    std::vector<double> speeds;
    for (const double v : logged) speeds.push_back(std::abs(v));
    const double typical = speeds.empty() ? 0.0 : percentile(std::move(speeds), 0.95);
    return quantum > options.coarse_position_fraction * typical * dt;
}

/// Where a held position takes new values: every `factor`-th sample from `phase` (factor 1: not held).
struct PositionHold {
    int factor{1};
    int phase{0};
};

PositionHold position_hold(const Trace& trace, std::span<const double> position) {
    const double interval = native_interval_of(trace, Role::position);
    const auto factor = static_cast<int>(std::lround(interval / trace.time_base().sample_time_s));
    if (factor < 2) return {};
    return {factor, hold_phase(position, factor)};
}

/// The drive force through the low-pass the position (or the logged velocity) went through before it was
/// differentiated: zero-phase, the same cut-off, or the same Savitzky-Golay window (IDIM's parallel filtering of y and
/// phi). A force with content above the band that the filtered acceleration cannot have biases M: on a stick-slip
/// axis, whose slip bursts are short, M came out 17 % high with the force left unfiltered, and on the rotary
/// SINUMERIK-like synthetic axis 1.25 % high. Central differences filter nothing, so neither is the force.
/// The three-tap kernel that gives a low-passed column the response of the central differences x'' went through, in
/// place.
void match_central_differences(std::vector<double>& filtered, const PreprocessReport& used) {
    // Central differences are low-passes too: x'' = D_c(D_c(x)) has the response -w^2 * sinc^2(w*dt) of the true
    // second derivative, x'' = D_c(v) of a logged velocity iw * sinc(w*dt). The three-tap kernels [1 1 1]/3 and
    // [1 4 1]/6 match sinc^2 and sinc to second order (at a tenth of the sample rate sinc^2 is 0.87: the force
    // would otherwise carry 13 % more of that frequency than M*x'' does).
    const bool from_velocity = used.velocity_source == "velocity";
    const double centre = from_velocity ? 4.0 / 6.0 : 1.0 / 3.0, side = from_velocity ? 1.0 / 6.0 : 1.0 / 3.0;
    // in place: `before` keeps the value the previous sample had before it was overwritten
    double before = filtered.empty() ? 0.0 : filtered[0];
    for (std::size_t k = 0; k < filtered.size(); ++k) {
        const double here = filtered[k], after = filtered[k + 1 < filtered.size() ? k + 1 : k];
        filtered[k] = side * before + centre * here + side * after;
        before = here;
    }
}

bool butterworth(const PreprocessReport& used) {
    return used.differentiation == "butterworth";
}

std::vector<double> filter_like_position(std::span<const double> force, const PreprocessReport& used, double dt) {
    std::vector<double> filtered;
    if (butterworth(used))
        filtered = filtfilt(butterworth_lowpass(used.filter_order, used.cutoff_hz, 1.0 / dt), force);
    else if (used.differentiation == "savitzky-golay" &&
             static_cast<std::size_t>(used.savitzky_golay_window) <= force.size())
        filtered = savitzky_golay(force, used.savitzky_golay_window, used.savitzky_golay_order, 0, dt);
    else
        filtered.assign(force.begin(), force.end());
    match_central_differences(filtered, used);
    return filtered;
}

/// filter_like_position() on a column it may overwrite: a Butterworth filters it in its own storage (no second
/// column when its capacity holds the padding: filter_like_force_capacity()).
void filter_like_position_in_place(std::vector<double>& values, const PreprocessReport& used, double dt) {
    if (butterworth(used))
        filtfilt_in_place(butterworth_lowpass(used.filter_order, used.cutoff_hz, 1.0 / dt), values);
    else if (used.differentiation == "savitzky-golay" &&
             static_cast<std::size_t>(used.savitzky_golay_window) <= values.size())
        values = savitzky_golay(values, used.savitzky_golay_window, used.savitzky_golay_order, 0, dt);
    match_central_differences(values, used);
}

/// filter_like_force() filters the column as a whole: one stretch, not decimated.
bool filtered_whole(const Derivatives& d) {
    return d.segment_starts.size() == 1 && d.used.decimation <= 1;
}

/// min(100 Hz, fs/10) of the position signal's native rate.
double default_cutoff_hz(const PreprocessOptions& options, double position_interval_s) {
    const double fs = 1.0 / position_interval_s;  // as fs/10, not 0.1/T: the same last bit as ever
    return std::min(options.max_default_cutoff_hz, options.default_cutoff_fraction * fs);
}

/// Said when the position signal is slower than the time base: which interval the defaults used, and why.
std::optional<std::string> held_position_note(const Derivatives& d, const PreprocessOptions& options) {
    const double ratio = d.position_interval_s / d.sample_time_s;
    if (!(ratio > 1.5)) return std::nullopt;
    std::string note = fmt::format(
        "the position signal's native interval is {:.6g} ms ({:.0f} samples of the {:.6g} ms time base; it holds each "
        "value that long, so it is interpolated between its own samples before it is differentiated, and the drive "
        "force goes through the same low-pass)",
        d.position_interval_s * 1e3, ratio, d.sample_time_s * 1e3);
    if (options.cutoff_hz) return note + fmt::format(": the cut-off {:.6g} Hz is as given", d.used.cutoff_hz);
    return note + fmt::format(
                      ": the default cut-off is min({:.6g} Hz, fs/{:.0f}) of its {:.6g} Hz, {:.6g} Hz, not of the "
                      "time base's {:.6g} Hz",
                      options.max_default_cutoff_hz, 1.0 / options.default_cutoff_fraction, 1.0 / d.position_interval_s,
                      d.used.cutoff_hz, 1.0 / d.sample_time_s);
}


/// The analysis window [first, last) from --from/--to; sets `failure` when it is too short.
std::pair<std::size_t, std::size_t> analysis_window(std::span<const double> time, const PreprocessOptions& options,
                                                    Derivatives& d) {
    std::size_t first = 0, last = d.total;
    if (options.from_s)
        first = static_cast<std::size_t>(std::lower_bound(time.begin(), time.end(), *options.from_s) - time.begin());
    if (options.to_s)
        last = static_cast<std::size_t>(std::upper_bound(time.begin(), time.end(), *options.to_s) - time.begin());
    if (last <= first + options.minimum_samples) {
        d.failure = fmt::format(
            "{}: only {} samples in the analysis window: too short to identify anything (record "
            "at least a few seconds of motion)",
            d.source, last > first ? last - first : 0);
    } else if (last - first > max_analysed_samples) {
        d.failure = fmt::format(
            "{}: {} samples in the analysis window, more than the {} identify analyses at once: take a part with "
            "--from/--to, or `feedid scan` the whole",
            d.source, last - first, max_analysed_samples);
    }
    return {first, last};
}

/// Largest minus smallest position: of the position, or of the integrated velocity without one.
double travel(std::span<const double> position, std::span<const double> velocity, double dt) {
    std::vector<double> integrated;
    if (position.empty()) {
        double x = 0.0;
        for (const double v : velocity) integrated.push_back(x += v * dt);
        position = integrated;
    }
    if (position.empty()) return 0.0;
    const auto [low, high] = std::minmax_element(position.begin(), position.end());
    return *high - *low;
}

/// The signal x' comes from, over the window: the position, or the logged velocity (said in d.used).
/// A held position (a position loop logged at its own, slower cycle) is interpolated between its own samples into
/// `held`, which the returned span then views.
std::span<const double> velocity_signal(const Trace& trace, std::size_t first, std::size_t last,
                                        const PreprocessOptions& options, Derivatives& d, PositionHold& hold,
                                        std::vector<double>& held) {
    const auto* position = trace.find(Role::position);
    const auto* logged = trace.find(Role::velocity);
    if (position == nullptr && logged == nullptr) {
        throw InputError(
            fmt::format("{}: no position and no velocity channel: map one with --channel position=NAME "
                        "or --channel velocity=NAME",
                        d.source));
    }
    const auto window = [&](const Channel* c) {
        return std::span<const double>(c->values.data() + first, last - first);
    };
    if (position != nullptr) d.position_quantum = position_quantum(window(position));
    const bool from_velocity =
        use_logged_velocity(trace, logged != nullptr ? window(logged) : std::span<const double>{}, d.position_quantum,
                            d.sample_time_s, options);
    d.used.velocity_source = from_velocity ? "velocity" : "position";
    if (!from_velocity) {
        hold = position_hold(trace, position->values);
        if (hold.factor > 1) held = interpolate_held(position->values, hold.factor, hold.phase);
    }
    const std::span<const double> x =
        held.empty() ? window(from_velocity ? logged : position) : std::span<const double>(held.data() + first, last - first);
    d.travel = travel(position != nullptr ? window(position) : std::span<const double>{}, x, d.sample_time_s);
    const auto [low, high] = std::minmax_element(x.begin(), x.end());
    const bool still = from_velocity ? !(std::max(std::abs(*low), std::abs(*high)) > 0.0) : !(*high > *low);
    if (still) {
        d.failure =
            fmt::format("{}: the {} in the analysis window: the axis did not move, so nothing can be identified",
                        d.source, from_velocity ? "logged velocity is zero throughout" : "position never changes");
    }
    return x;
}

/// A stretch of the analysis window without time-stamp jumps, [first, last) relative to the window.
struct Segment {
    std::size_t first{0};
    std::size_t last{0};
};

/// The window cut at every step longer than gap_factor sample times (samples the recorder dropped): differentiating
/// across one would turn the travel during the gap into a velocity spike.
std::vector<Segment> contiguous_segments(std::span<const double> time, double dt, double gap_factor) {
    std::vector<Segment> segments;
    std::size_t begin = 0;
    for (std::size_t k = 1; k < time.size(); ++k) {
        if (time[k] - time[k - 1] > gap_factor * dt) {
            segments.push_back({begin, k});
            begin = k;
        }
    }
    segments.push_back({begin, time.size()});
    return segments;
}

std::string gap_note(std::span<const double> time, const std::vector<Segment>& segments, const Derivatives& d) {
    double largest = 0.0;
    for (std::size_t s = 1; s < segments.size(); ++s) {
        largest = std::max(largest, time[segments[s].first] - time[segments[s].first - 1]);
    }
    return fmt::format(
        "{}: the time stamps jump at {} place(s) (samples missing; the longest gap {:.6g} s): each stretch between "
        "jumps is filtered and differentiated on its own, its edges trimmed",
        d.source, segments.size() - 1, largest);
}

/// The commanded motion over the window, for telling a commanded stop from a stuck axis: the reference position
/// (differentiated after the position's low-pass) or, without one, the velocity command.
struct Reference {
    std::span<const double> values;  ///< over the window; empty without a reference
    bool is_position{false};
};

Reference reference_of(const Trace& trace, std::size_t first, std::size_t last) {
    for (const Role role : {Role::reference_position, Role::velocity_command}) {
        if (const Channel* channel = trace.find(role)) {
            return {std::span<const double>(channel->values).subspan(first, last - first),
                    role == Role::reference_position};
        }
    }
    return {};
}

/// The reference velocity over one stretch [m/s]: the velocity command as logged, or the reference position through
/// the Butterworth at the cut-off used (whatever the differentiation: a reference held over a slower cycle is a
/// staircase), then central differences.
std::vector<double> reference_velocity(const Reference& reference, const Segment& segment, const Derivatives& d,
                                       const PreprocessOptions& options) {
    const auto part = reference.values.subspan(segment.first, segment.last - segment.first);
    if (!reference.is_position) return {part.begin(), part.end()};
    const double fs = 1.0 / d.sample_time_s;
    if (!(d.used.cutoff_hz < 0.5 * fs)) return central_difference(part, d.sample_time_s);
    return central_difference(filtfilt(butterworth_lowpass(options.filter_order, d.used.cutoff_hz, fs), part),
                              d.sample_time_s);
}

/// One stretch: differentiate, filter the force alike, trim the edges, append to d.
void append_segment(std::span<const double> x, std::span<const double> force, std::span<const double> time,
                    const Reference& reference, const Segment& segment, const PreprocessOptions& options,
                    Derivatives& d, std::vector<std::size_t>& window_index, bool need_index) {
    const std::size_t length = segment.last - segment.first;
    const auto part = x.subspan(segment.first, length);
    Differentiated derivatives = d.velocity_from_position()
                                     ? differentiate(part, d.sample_time_s, options, d.used)
                                     : differentiate_velocity(part, d.sample_time_s, options, d.used);
    const std::size_t edge = options.edge_samples.value_or(derivatives.default_edge);
    d.used.edge_samples = edge;
    if (derivatives.velocity.empty() || length <= 2 * edge + options.minimum_samples) return;
    std::vector<double> filtered_force =
        filter_like_position(force.subspan(segment.first, length), d.used, d.sample_time_s);
    std::vector<double> commanded =
        reference.values.empty() ? std::vector<double>{} : reference_velocity(reference, segment, d, options);
    if (need_index) {
        window_index.reserve(window_index.size() + length - 2 * edge);
        for (std::size_t k = edge; k < length - edge; ++k) window_index.push_back(segment.first + k);
    }
    if (d.time.empty()) {
        // the first stretch (most often the only one): its columns become the Derivatives', trimmed in place, not
        // copied (a copy would hold each column twice at the stage's peak)
        const auto trimmed = [&](std::vector<double>& column) {
            column.erase(column.begin(), column.begin() + static_cast<std::ptrdiff_t>(edge));
            column.resize(length - 2 * edge);
            return std::move(column);
        };
        d.segment_starts.push_back(0);
        const auto part_time = time.subspan(segment.first + edge, length - 2 * edge);
        d.time.assign(part_time.begin(), part_time.end());
        d.velocity = trimmed(derivatives.velocity);
        d.acceleration = trimmed(derivatives.acceleration);
        d.force = trimmed(filtered_force);
        if (!commanded.empty()) d.reference_velocity = trimmed(commanded);
        return;
    }
    d.segment_starts.push_back(d.time.size());
    const std::size_t room = d.time.size() + length - 2 * edge;
    for (auto* column : {&d.time, &d.velocity, &d.acceleration, &d.force}) column->reserve(room);
    if (!commanded.empty()) d.reference_velocity.reserve(room);
    for (std::size_t k = edge; k < length - edge; ++k) {
        d.time.push_back(time[segment.first + k]);
        d.velocity.push_back(derivatives.velocity[k]);
        d.acceleration.push_back(derivatives.acceleration[k]);
        d.force.push_back(filtered_force[k]);
        if (!commanded.empty()) d.reference_velocity.push_back(commanded[k]);
    }
}

/// Every column through the same anti-alias filter, then every N-th sample (IDIM practice), stretch by stretch.
void decimate_columns(Derivatives& d, int factor, std::vector<std::size_t>& window_index) {
    d.full_rate_velocity = std::move(d.velocity);
    d.full_rate_acceleration = std::move(d.acceleration);
    d.full_rate_segment_starts = d.segment_starts;
    d.velocity = decimate_segments(d.full_rate_velocity, d.segment_starts, factor);
    d.acceleration = decimate_segments(d.full_rate_acceleration, d.segment_starts, factor);
    d.force = decimate_segments(d.force, d.segment_starts, factor);
    std::vector<double> time, reference;
    std::vector<std::size_t> kept, starts;
    for (std::size_t s = 0; s < d.segment_starts.size(); ++s) {
        const std::size_t begin = d.segment_starts[s];
        const std::size_t end = s + 1 < d.segment_starts.size() ? d.segment_starts[s + 1] : d.time.size();
        starts.push_back(time.size());
        for (const auto k : decimation_indices(end - begin, factor)) {
            time.push_back(d.time[begin + k]);
            if (!d.reference_velocity.empty()) reference.push_back(d.reference_velocity[begin + k]);
            kept.push_back(window_index[begin + k]);
        }
    }
    d.time = std::move(time);
    d.reference_velocity = std::move(reference);
    d.segment_starts = std::move(starts);
    window_index = std::move(kept);
}

/// Samples where the drive signal sits at its largest or smallest value as a clipped or saturated signal does:
/// runs of at least three samples at the extreme, where the samples pile up (at least three times as many as in the
/// band of three quanta just inside it). A signal that merely peaks there tapers off: its extreme is as rare as the
/// levels next to it.
std::vector<char> clipped_samples(std::span<const double> force, Derivatives& d) {
    if (force.size() < 10) return {};
    const auto [low, high] = std::minmax_element(force.begin(), force.end());
    // a clipped signal repeats its extreme exactly; most signals reach it once (cheap test before the quantum's sort)
    const auto at_extremes = std::count_if(force.begin(), force.end(),
                                           [low = *low, high = *high](double f) { return f == low || f == high; });
    if (at_extremes < 5) return {};
    const double quantum = std::max(position_quantum(force), 1e-12);
    std::vector<char> clipped(force.size(), 0);
    std::size_t count = 0;
    for (const double extreme : {*low, *high}) {
        const double inward = extreme == *high ? -1.0 : 1.0;
        std::size_t at = 0, inside = 0;
        for (const double f : force) {
            const double depth = (f - extreme) * inward;  // how far inside the extreme [N]
            if (depth <= 0.25 * quantum)
                ++at;
            else if (depth <= 3.0 * quantum)
                ++inside;
        }
        if (at < 5 || at < 3 * inside) continue;
        std::size_t run = 0;
        for (std::size_t k = 0; k <= force.size(); ++k) {
            if (k < force.size() && std::abs(force[k] - extreme) <= 0.25 * quantum) {
                ++run;
                continue;
            }
            if (run >= 3) {
                for (std::size_t j = k - run; j < k; ++j) clipped[j] = 1;
                count += run;
            }
            run = 0;
        }
    }
    if (count == 0) return {};
    d.clipped_samples = count;
    d.clip_levels = {*low, *high};
    return clipped;
}

/// The span of the low-pass in analysed samples (Derivatives::correlation_samples).
std::size_t correlation_samples(const PreprocessOptions& options, const Derivatives& d) {
    const double fs = 1.0 / d.sample_time_s;
    double span = 5.0;  // central differences of central differences
    if (options.differentiation == Differentiation::butterworth) span = fs / d.used.cutoff_hz;
    if (options.differentiation == Differentiation::savitzky_golay) span = savitzky_golay_window(options, fs);
    if (d.used.decimation > 1) {
        // the anti-alias filter's cut-off, 0.8 of the new Nyquist frequency, also correlates the kept samples
        span = std::max(span / d.used.decimation, 1.0 / (0.8 * 0.5));
    }
    return static_cast<std::size_t>(std::max(1.0, std::ceil(span)));
}

/// Analysed samples whose filtered force a clipped sample reaches (within the filter's edge, and the decimation
/// filter's span) are unusable.
void mark_unusable(const std::vector<char>& clipped, const std::vector<std::size_t>& window_index, Derivatives& d) {
    if (clipped.empty()) return;
    const std::size_t reach = d.used.edge_samples + 10 * static_cast<std::size_t>(d.used.decimation);
    std::vector<char> near(clipped.size(), 0);
    for (std::size_t k = 0; k < clipped.size(); ++k) {
        if (!clipped[k]) continue;
        const std::size_t from = k > reach ? k - reach : 0, to = std::min(clipped.size(), k + reach + 1);
        std::fill(near.begin() + static_cast<std::ptrdiff_t>(from), near.begin() + static_cast<std::ptrdiff_t>(to), 1);
    }
    d.unusable.assign(window_index.size(), 0);
    for (std::size_t i = 0; i < window_index.size(); ++i) d.unusable[i] = near[window_index[i]];
}

}  // namespace

Derivatives preprocess(const Trace& trace, std::span<const double> force, const PreprocessOptions& options) {
    Derivatives d;
    d.rotary = trace.rotary;
    d.source = trace.source_path.empty() ? "trace" : trace.source_path;
    d.total = trace.samples();
    d.used.filter_order = options.filter_order;
    const auto time = trace.column(Role::time);
    d.sample_time_s = d.total >= 2 ? trace.time_base().sample_time_s : 0.0;

    const auto [first, last] = analysis_window(time, options, d);
    if (d.failed()) return d;
    PositionHold hold;
    std::vector<double> held;
    const std::span<const double> x = velocity_signal(trace, first, last, options, d, hold, held);
    if (d.failed()) return d;

    // ---- derivatives: the rate-dependent defaults from the native interval of the signal differentiated
    const bool from_velocity = !d.velocity_from_position();
    d.position_interval_s = native_interval_of(trace, from_velocity ? Role::velocity : Role::position);
    d.used.cutoff_hz = options.cutoff_hz.value_or(default_cutoff_hz(options, d.position_interval_s));
    if (!from_velocity) {
        if (auto note = held_position_note(d, options)) d.notes.push_back(std::move(*note));
    }
    const std::span<const double> window_force = force.subspan(first, last - first);
    const std::vector<char> clipped = clipped_samples(window_force, d);
    const std::vector<Segment> segments =
        contiguous_segments(time.subspan(first, last - first), d.sample_time_s, options.gap_factor);
    if (segments.size() > 1) d.notes.push_back(gap_note(time.subspan(first, last - first), segments, d));
    std::vector<std::size_t> window_index;  // of each analysed sample, into the window (for clipping, decimation)
    const bool need_index = !clipped.empty() || std::max(1, options.decimation) > 1;
    const Reference reference = reference_of(trace, first, last);
    for (const Segment& segment : segments) {
        append_segment(x, window_force, time.subspan(first, last - first), reference, segment, options, d, window_index,
                       need_index);
    }
    if (d.velocity.empty()) {
        std::size_t longest = 0;
        for (const Segment& segment : segments) longest = std::max(longest, segment.last - segment.first);
        const bool shorter_than_window =
            options.differentiation == Differentiation::savitzky_golay &&
            static_cast<std::size_t>(savitzky_golay_window(options, 1.0 / d.sample_time_s)) > longest;
        d.failure = shorter_than_window
                        ? fmt::format("{}: the trace is shorter than the Savitzky-Golay window", d.source)
                        : fmt::format(
                              "{}: {} samples in the window, {} dropped at each edge{}: too short to "
                              "identify anything",
                              d.source, x.size(), d.used.edge_samples,
                              segments.size() > 1 ? " of each stretch between time-stamp jumps" : "");
        return d;
    }
    d.window = d.velocity.size();
    if (from_velocity) {
        d.logged_velocity.assign(x.begin(), x.end());
        d.logged_force.assign(window_force.begin(), window_force.end());
    }
    d.velocity_noise = noise_floor(d.velocity);

    // ---- decimation, stretch by stretch
    d.used.decimation = std::max(1, options.decimation);
    if (d.used.decimation > 1) decimate_columns(d, d.used.decimation, window_index);
    d.correlation_samples = correlation_samples(options, d);
    mark_unusable(clipped, window_index, d);
    return d;
}

std::vector<double> filter_like_force(std::span<const double> full_rate, const Derivatives& d) {
    const auto& starts = d.used.decimation > 1 ? d.full_rate_segment_starts : d.segment_starts;
    if (filtered_whole(d)) return filter_like_position(full_rate, d.used, d.sample_time_s);
    std::vector<double> filtered;
    filtered.reserve(full_rate.size());
    for (std::size_t s = 0; s < starts.size(); ++s) {
        const std::size_t begin = starts[s], end = s + 1 < starts.size() ? starts[s + 1] : full_rate.size();
        const auto part = filter_like_position(full_rate.subspan(begin, end - begin), d.used, d.sample_time_s);
        filtered.insert(filtered.end(), part.begin(), part.end());
    }
    return d.used.decimation > 1 ? decimate_segments(filtered, starts, d.used.decimation) : filtered;
}

std::vector<double> filter_like_force(std::vector<double>&& full_rate, const Derivatives& d) {
    if (d.used.decimation > 1) return filter_like_force(std::span<const double>(full_rate), d);
    if (filtered_whole(d)) {
        filter_like_position_in_place(full_rate, d.used, d.sample_time_s);
        return std::move(full_rate);
    }
    // stretch by stretch through one workspace, each filtered stretch written back where it came from
    std::vector<double> part;
    const auto& starts = d.segment_starts;
    for (std::size_t s = 0; s < starts.size(); ++s) {
        const std::size_t begin = starts[s], end = s + 1 < starts.size() ? starts[s + 1] : full_rate.size();
        const auto first = full_rate.begin() + static_cast<std::ptrdiff_t>(begin);
        part.assign(first, full_rate.begin() + static_cast<std::ptrdiff_t>(end));
        filter_like_position_in_place(part, d.used, d.sample_time_s);
        std::copy(part.begin(), part.end(), first);
    }
    return std::move(full_rate);
}

std::size_t filter_like_force_capacity(const Derivatives& d, std::size_t n) {
    if (!filtered_whole(d) || !butterworth(d.used)) return n;
    return filtfilt_capacity(butterworth_lowpass(d.used.filter_order, d.used.cutoff_hz, 1.0 / d.sample_time_s), n);
}

std::vector<double> decimate_segments(std::span<const double> values, std::span<const std::size_t> starts, int factor) {
    std::vector<double> out;
    for (std::size_t s = 0; s < starts.size(); ++s) {
        const std::size_t begin = starts[s], end = s + 1 < starts.size() ? starts[s + 1] : values.size();
        const auto part = decimate(values.subspan(begin, end - begin), factor);
        out.insert(out.end(), part.begin(), part.end());
    }
    // the anti-alias filter's gain at 0 Hz taken out: step 1's columns scale alike either way, but step 2 fits the
    // force as a function of the speed (both would come out 1.1 % small: F_C and F_B 46 standard errors low on the
    // demo trace decimated by 2)
    const double gain = decimation_dc_gain(factor);
    for (double& value : out) value /= gain;
    return out;
}

}  // namespace feedid
