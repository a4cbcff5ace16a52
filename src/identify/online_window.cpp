// The online identifier's window: the buffered samples preprocessed as identify does (zero-phase low-pass of the
// position and of the force, central differences, sgn(x') through the same low-pass) and the tests that come before
// any fit (a gap, saturation, at rest, stick-slip, too few step-1 rows), then the step-1 rows.

#include <algorithm>
#include <cmath>

#include "online_state.hpp"

namespace feedid {

using State = OnlineIdentifier::State;

void State::filter(std::span<const double> in, std::span<double> out, std::size_t count) {
    filtfilt(filter_, in.first(count), out.first(count), workspace_);
}

void State::process_window(std::size_t count) {
    ++counts_.total;
    last_window_ = {t_[margin_], t_[count - margin_ - 1], WindowVerdict::gap, false};
    const auto verdict = [&](WindowVerdict v) {
        last_window_.verdict = v;
        ++counts_.by_verdict[static_cast<std::size_t>(v)];
    };
    for (std::size_t k = 1; k < count; ++k) {
        // a gap, time running backwards, or a value that is not a number: the window is not used
        if (t_[k] - t_[k - 1] > 1.5 * dt_ || !(t_[k] > t_[k - 1]) || !std::isfinite(x_[k]) || !std::isfinite(f_[k])) {
            stick_slip_ = StickSlipTracker(options_.moving_threshold, options_.stick_slip);  // a pass ends at a gap
            return verdict(WindowVerdict::gap);
        }
    }
    filter(x_, xf_, count);
    filter(f_, ff_, count);
    if (options_.drive_delay_s != 0.0) shift_force(count);
    // central differences of the filtered position, and of the velocity for the acceleration
    for (std::size_t k = 1; k + 1 < count; ++k) v_[k] = (xf_[k + 1] - xf_[k - 1]) / (2.0 * dt_);
    v_[0] = v_[1];
    v_[count - 1] = v_[count - 2];
    for (std::size_t k = 1; k + 1 < count; ++k) a_[k] = (v_[k + 1] - v_[k - 1]) / (2.0 * dt_);
    a_[0] = a_[1];
    a_[count - 1] = a_[count - 2];
    // sgn(x') through the force's low-pass (IDIM's parallel filtering): the filtered force has the Coulomb step
    // smoothed, and so must its regressor
    for (std::size_t k = 0; k < count; ++k) s_[k] = sign(v_[k]);
    filter(s_, sf_, count);
    const std::size_t first = margin_;
    const std::size_t last = count - margin_;
    const std::size_t deferred_before = deferred_count_;
    last_window_.stick_slip = stick_slips(first, last);
    const WindowVerdict v = judge_window(first, last);
    last_window_.verdict = v;
    if (v != WindowVerdict::pending) verdict(v);
    // the slow samples only of windows whose fast rows fit the model: a slow cutting move (a helix, an arc's slow
    // stretch) adds a force opposing the motion that the bins cannot tell from Stribeck friction (a deferred window,
    // judged later from its sums, has no samples left to bin then: none)
    if (v != WindowVerdict::qualified && v != WindowVerdict::pending) return;
    if (deferred_count_ > deferred_before) return;
    bin_slow_samples(first, last);
}

WindowVerdict State::judge_window(std::size_t first, std::size_t last) {
    const std::size_t n = last - first;
    std::size_t moving = 0;
    for (std::size_t k = first; k < last; ++k) {
        if (options_.force_limit && std::abs(f_[k]) >= 0.99 * *options_.force_limit) return WindowVerdict::saturation;
        if (std::abs(v_[k]) > options_.moving_threshold) ++moving;
    }
    if (static_cast<double>(moving) < options_.minimum_moving_fraction * static_cast<double>(n))
        return WindowVerdict::at_rest;
    if (last_window_.stick_slip) return WindowVerdict::stick_slip;
    const std::size_t rows = build_rows(first, last);
    if (static_cast<double>(rows) < options_.minimum_row_fraction * static_cast<double>(window_)) {
        std::size_t ungated = 0;
        for (std::size_t k = first; k < last; ++k) ungated += std::abs(v_[k]) > options_.split() ? 1 : 0;
        if (static_cast<double>(ungated) >= options_.minimum_row_fraction * static_cast<double>(window_))
            return WindowVerdict::gated_out;
        // a short stretch of motion (a rapid between two holes): too few rows for a fit of its own, judged against
        // the pooled model
        return rows >= std::max(options_.minimum_pool_rows, p_) ? one_speed(rows, WindowVerdict::low_excitation)
                                                                : WindowVerdict::low_excitation;
    }
    return fit_window(rows);
}

// Stick-slip: identify's rule without a reference (stick_slip.hpp), run over the stream's window cores in order, so
// that a pass that began in an earlier window is judged whole. The window stick-slips when a pass with moving samples
// in it stick-slips (the pass in progress: on what has been seen of it).
bool State::stick_slips(std::size_t first, std::size_t last) {
    const std::size_t start = stick_slip_.samples();
    bool found = false;
    for (std::size_t k = first; k < last; ++k) {
        const auto ended = stick_slip_.add(t_[k], v_[k]);
        found = found || (ended && ended->stick_slip && ended->last > start);
    }
    const auto open = stick_slip_.current();
    return found || (open && open->stick_slip && open->last > start);
}

std::size_t State::build_rows(std::size_t first, std::size_t last) {
    std::size_t rows = 0;
    for (std::size_t k = first; k < last; ++k) {
        if (use_[k] == 0 || !(std::abs(v_[k]) > options_.split())) continue;
        const auto r = static_cast<Eigen::Index>(rows++);
        rows_(r, 0) = a_[k];
        rows_(r, 1) = v_[k];
        rows_(r, 2) = sf_[k];
        rows_(r, 3) = 1.0;
        rows_(r, max_p) = ff_[k];
        rows_(r, max_p + 2) = (a_[k + 1] - a_[k - 1]) / (2.0 * dt_);    // x'''
        rows_(r, max_p + 3) = (sf_[k + 1] - sf_[k - 1]) / (2.0 * dt_);  // the filtered sgn's derivative
    }
    return rows;
}

}  // namespace feedid
