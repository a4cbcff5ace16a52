// The online identifier's face (online_identifier.hpp) and the stream cut into windows: each pushed sample goes into
// buffers of margin + window + margin samples, allocated once; a full buffer is processed as one window
// (online_window.cpp) and its last two margins start the next, so that every sample lies in the core of one window.

#include "feedid/identify/online_identifier.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <fmt/core.h>

#include "online_state.hpp"

namespace feedid {

namespace {

constexpr std::size_t startup_samples = 101;  // time stamps that give the sample time when none is stated

}  // namespace

using State = OnlineIdentifier::State;

const char* verdict_name(WindowVerdict verdict) {
    switch (verdict) {
        case WindowVerdict::qualified: return "qualified";
        case WindowVerdict::at_rest: return "at_rest";
        case WindowVerdict::low_excitation: return "low_excitation";
        case WindowVerdict::ill_conditioned: return "ill_conditioned";
        case WindowVerdict::process_force: return "process_force";
        case WindowVerdict::stick_slip: return "stick_slip";
        case WindowVerdict::saturation: return "saturation";
        case WindowVerdict::gap: return "gap";
        case WindowVerdict::gated_out: return "gated_out";
        case WindowVerdict::inconsistent: return "inconsistent";
        case WindowVerdict::pending: return "pending";
    }
    return "?";
}

std::string OnlineOptions::validate() const {
    const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
    if (!positive(window_s)) return fmt::format("window length must be positive (got {} s)", window_s);
    if (sample_time_s && !positive(*sample_time_s)) return "sample time must be positive";
    if (cutoff_hz && !positive(*cutoff_hz)) return "cut-off must be positive";
    if (filter_order < 1 || filter_order > 12) return "filter order must be 1..12";
    if (!(forgetting > 0.0 && forgetting <= 1.0))
        return fmt::format("forgetting factor must lie in (0, 1] (got {})", forgetting);
    if (!positive(split()) || !positive(moving_threshold) || !positive(stribeck_lowest_speed))
        return "speeds must be positive";
    if (stribeck_lowest_speed >= split()) return "the lowest Stribeck speed must lie below the split speed";
    if (!positive(tukey_c) || irls_iterations < 1) return "Tukey constant and IRLS iterations must be positive";
    if (force_limit && !positive(*force_limit)) return "force limit must be positive";
    if (!(max_delay_s > 0.0 && max_delay_s <= 0.02))
        return fmt::format("the largest drive-signal delay must lie in (0, 20] ms (got {} ms)", max_delay_s * 1e3);
    if (!(std::abs(drive_delay_s) <= max_delay_s))
        return fmt::format("the drive signal's delay must lie within +-{:g} ms (got {:.4g} ms)", max_delay_s * 1e3,
                           drive_delay_s * 1e3);
    if (!(offset_test_level > 0.0 && offset_test_level < 0.5))
        return fmt::format("the offset's test level must lie in (0, 0.5) (got {})", offset_test_level);
    return "";
}

OnlineIdentifier::OnlineIdentifier(OnlineOptions options) : state_(std::make_unique<State>(std::move(options))) {}
OnlineIdentifier::~OnlineIdentifier() = default;
OnlineIdentifier::OnlineIdentifier(OnlineIdentifier&&) noexcept = default;
OnlineIdentifier& OnlineIdentifier::operator=(OnlineIdentifier&&) noexcept = default;

void OnlineIdentifier::push(double t, double x, double force, bool use) {
    state_->push(t, x, force, use);
}

void OnlineIdentifier::push(std::span<const double> t, std::span<const double> x, std::span<const double> force,
                            std::span<const char> use) {
    const std::size_t n = std::min({t.size(), x.size(), force.size()});
    State& state = *state_;
    for (std::size_t k = 0; k < n; ++k) state.push(t[k], x[k], force[k], use.empty() || use[k] != 0);
}

void OnlineIdentifier::flush() {
    state_->flush();
}

OnlineEstimate OnlineIdentifier::estimate() const {
    return state_->estimate(state_->options_.select_offset);
}

OnlineEstimate OnlineIdentifier::estimate_without_offset() const {
    return state_->estimate(false);
}

std::optional<WindowRecord> OnlineIdentifier::last_window() const {
    if (state_->counts_.total == 0) return std::nullopt;
    return state_->last_window_;
}

const OnlineOptions& OnlineIdentifier::options() const {
    return state_->options_;
}

std::size_t OnlineIdentifier::parameters() const {
    return state_->p_;
}

State::State(OnlineOptions options)
    : options_(std::move(options)), stick_slip_(options_.moving_threshold, options_.stick_slip) {
    p_ = options_.offset || options_.judge_with_offset ? max_p : 3;
    counts_ = {};
    sum_cc_ = Mat::Zero(max_p, max_p);
    for (auto& m : sum_cH_) m = sum_cc_;
    for (auto& row : sum_HH_)
        for (auto& m : row) m = sum_cc_;
    r_z_.setZero();
    reset_pool();
    for (auto& b : bins_) b.assign(bins_per_direction, StribeckBin{});
    deferred_.assign(options_.deferred_windows, OneSpeedWindow{});
    // the start-up buffer: enough for the sample time from the first time stamps
    const std::size_t start = options_.sample_time_s ? 0 : startup_samples;
    if (options_.sample_time_s) {
        setup(*options_.sample_time_s);
    } else {
        t_.resize(start);
        x_.resize(start);
        f_.resize(start);
        use_.resize(start);
    }
}

State::Layout State::layout(const OnlineOptions& options, double sample_time_s) {
    const double fs = 1.0 / sample_time_s;
    Layout l;
    l.cutoff_hz = options.cutoff_hz.value_or(std::min(100.0, 0.1 * fs));
    l.window = std::max<std::size_t>(20, static_cast<std::size_t>(std::llround(options.window_s / sample_time_s)));
    l.margin = std::max<std::size_t>(
        3, static_cast<std::size_t>(std::ceil(options.filter_settling_periods * fs / l.cutoff_hz)));
    return l;
}

std::size_t OnlineIdentifier::buffer_samples(const OnlineOptions& options, double sample_time_s) {
    const State::Layout l = State::layout(options, sample_time_s);
    return l.window + 2 * l.margin;
}

std::size_t OnlineIdentifier::memory_bytes(const OnlineOptions& options, double sample_time_s) {
    // the state behind the pointer, the buffers of setup() (13 of doubles, one of flags, the workspace, the rows),
    // the start-up buffers they grow from, the deferred windows and the Stribeck bins
    const std::size_t capacity = std::max(buffer_samples(options, sample_time_s), startup_samples);
    const std::size_t per_sample =
        13 * sizeof(double) + sizeof(char) + sizeof(double) + State::row_stride * sizeof(double);
    return sizeof(OnlineIdentifier) + sizeof(State) + capacity * per_sample + 64 * sizeof(double) +
           options.deferred_windows * sizeof(State::OneSpeedWindow) +
           2 * State::bins_per_direction * sizeof(State::StribeckBin);
}

void State::setup(double sample_time_s) {
    dt_ = sample_time_s;
    const double fs = 1.0 / dt_;
    const Layout l = layout(options_, dt_);
    cutoff_hz_ = l.cutoff_hz;
    filter_ = butterworth_lowpass(options_.filter_order, std::min(l.cutoff_hz, 0.45 * fs), fs);
    window_ = l.window;
    margin_ = l.margin;
    const std::size_t capacity = window_ + 2 * margin_;
    for (auto* b : {&t_, &x_, &f_, &xf_, &ff_, &v_, &a_, &s_, &sf_, &residual_, &scratch_, &weights_, &shifted_})
        b->resize(capacity);
    use_.resize(capacity);
    workspace_.resize(capacity + 64);
    rows_.resize(static_cast<Eigen::Index>(capacity), row_stride);
    ready_ = true;
}

void State::push(double t, double x, double force, bool use) {
    ++pushed_;
    if (!ready_) {
        t_[filled_] = t;
        x_[filled_] = x;
        f_[filled_] = force;
        use_[filled_] = use ? 1 : 0;
        if (++filled_ < t_.size()) return;
        // the median step of the first time stamps (robust to a gap among them); allocates once, at start-up
        std::vector<double> steps(filled_ - 1);
        for (std::size_t k = 1; k < filled_; ++k) steps[k - 1] = t_[k] - t_[k - 1];
        std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
        const double step = steps[steps.size() / 2];
        const std::vector<double> t0 = t_, x0 = x_, f0 = f_;
        const std::vector<char> u0 = use_;
        filled_ = 0;
        pushed_ -= t0.size();
        setup(step > 0.0 && std::isfinite(step) ? step : 1e-3);
        for (std::size_t k = 0; k < t0.size(); ++k) push(t0[k], x0[k], f0[k], u0[k] != 0);
        return;
    }
    t_[filled_] = t;
    x_[filled_] = x;
    f_[filled_] = force;
    use_[filled_] = use ? 1 : 0;
    if (++filled_ == t_.size()) {
        process_window(filled_);
        // the last 2 margins start the next buffer: every sample is in the core of one window
        const std::size_t keep = 2 * margin_;
        const std::size_t from = filled_ - keep;
        for (auto* b : {&t_, &x_, &f_}) std::copy(b->begin() + static_cast<std::ptrdiff_t>(from), b->end(), b->begin());
        std::copy(use_.begin() + static_cast<std::ptrdiff_t>(from), use_.end(), use_.begin());
        filled_ = keep;
    }
}

void State::flush() {
    if (ready_ && filled_ >= 2 * margin_ + window_ / 4) {
        process_window(filled_);
        filled_ = 0;
    }
    settle_pending();
    settle_deferred();
}

}  // namespace feedid
