#include "feedid/stream/watcher.hpp"

#include <algorithm>
#include <cmath>
#include <exception>

#include <fmt/core.h>

#include "feedid/core/terminal_text.hpp"
#include "feedid/core/version.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/stream/scan.hpp"

namespace feedid::watch {

std::string WatchOptions::validate() const {
    if (auto e = online.validate(); !e.empty()) return e;
    if (max_axes == 0) return "max_axes must be at least 1";
    if (axes_bytes == 0 || held_bytes == 0 || max_window_samples < 100)
        return "axes_mb and held_mb must be positive, max_window_samples at least 100";
    if (!(run_period_s >= 0.0) || !std::isfinite(run_period_s)) return "run period must be a finite time >= 0 s";
    if (!(run_gap_s > 0.0)) return "run gap must be a time > 0 s";
    if (!(reorder_s >= 0.0) || !std::isfinite(reorder_s)) return "reorder time must be a finite time >= 0 s";
    if (!(limits.min_dt_s > 0.0 && limits.min_dt_s <= 10.0)) return "the shortest sample time must lie in (0, 10] s";
    for (const auto& [name, k] : force_constants)
        if (!std::isfinite(k) || k == 0.0)
            return fmt::format("force constant of '{}' must be finite and non-zero", name);
    return "";
}

Watcher::Watcher(WatchOptions options) : options_(std::move(options)) {}

double Watcher::force_constant(const Batch& batch, const std::string& machine, const std::string& axis) const {
    if (batch.force_constant) return *batch.force_constant;
    if (auto it = options_.force_constants.find(machine + "/" + axis); it != options_.force_constants.end())
        return it->second;
    if (auto it = options_.force_constants.find(axis); it != options_.force_constants.end()) return it->second;
    return std::nan("");
}

std::string Watcher::names_of(std::string_view topic, std::string& machine, std::string& axis) {
    const auto names = machine_axis_of_topic(topic);
    machine = batch_.machine;
    axis = batch_.axis;
    if (options_.trust_payload_names) {
        if (names && machine.empty()) machine = names->first;
        if (names && axis.empty()) axis = names->second;
    } else if (names) {
        // the broker's access control guards the topic, not what a payload says
        if ((!machine.empty() && machine != names->first) || (!axis.empty() && axis != names->second)) {
            ++foreign_names_;
            return fmt::format(
                "the payload names machine '{}' axis '{}', its topic machine '{}' axis '{}': refused (machine and "
                "axis come from the topic; trust_payload_names = true lets a payload name them)",
                terminal_text(machine), terminal_text(axis), terminal_text(names->first), terminal_text(names->second));
        }
        machine = names->first;
        axis = names->second;
    } else {
        machine.clear();
    }
    if (machine.empty() || axis.empty())
        return options_.trust_payload_names
                   ? "the topic names no machine and axis (plant/<machine>/<axis>/...) and the payload neither"
                   : "the topic names no machine and axis (plant/<machine>/<axis>/...)";
    for (const auto& [name, what] : {std::pair{&machine, "machine"}, std::pair{&axis, "axis"}})
        if (auto problem = name_problem(*name, options_.limits.max_name_bytes); !problem.empty())
            return fmt::format("the {} name '{}' of topic '{}' is refused: {}", what, terminal_text(*name),
                               terminal_text(topic.substr(0, 200)), problem);
    return "";
}

std::string Watcher::admit(const std::string& machine, const std::string& axis, double dt) {
    const std::string name = terminal_text(machine + "/" + axis);
    const std::size_t samples = OnlineIdentifier::buffer_samples(options_.online, dt);
    const std::size_t memory = SelectingIdentifier::memory_bytes(options_.online, dt) + sizeof(Axis) + 2 * name.size();
    std::string why;
    if (axes_.size() >= options_.max_axes)
        why = fmt::format("more than max_axes = {} axes", options_.max_axes);
    else if (samples > options_.max_window_samples)
        why = fmt::format("dt = {:g} s gives windows of {} samples, more than max_window_samples = {}", dt, samples,
                          options_.max_window_samples);
    else if (axes_bytes_ + memory > options_.axes_bytes)
        why = fmt::format("its identifier ({:.1f} MB at dt = {:g} s) would take the axes beyond axes_mb = {:g}",
                          static_cast<double>(memory) / (1 << 20), dt,
                          static_cast<double>(options_.axes_bytes) / (1 << 20));
    if (!why.empty()) {
        ++refused_axes_;
        return fmt::format("new axis '{}' refused: {}", name, why);
    }
    auto state = std::make_unique<Axis>();
    state->machine = machine;
    state->axis = axis;
    state->online = std::make_unique<SelectingIdentifier>(options_.online);
    state->memory = memory;
    axes_bytes_ += memory;
    axes_.emplace(machine + "/" + axis, std::move(state));
    return "";
}

std::string Watcher::ingest(std::string_view topic, std::span<const std::byte> payload) {
    ++messages_;
    try {
        std::string error = decode_batch(payload, batch_, options_.limits);
        std::string machine, axis;
        if (error.empty()) error = names_of(topic, machine, axis);
        if (error.empty()) {
            const std::string key = machine + "/" + axis;
            auto it = axes_.find(key);
            if (it == axes_.end()) {
                error = admit(machine, axis, batch_.dt);
                it = axes_.find(key);
            }
            if (error.empty()) error = push(*it->second, batch_);
        }
        if (!error.empty()) ++malformed_;
        return error;
    } catch (const std::exception& e) {  // out of memory on a huge message, and the like: dropped, never fatal
        ++malformed_;
        return fmt::format("cannot take the message: {}", terminal_text(e.what()));
    }
}

std::string Watcher::push(Axis& axis, const Batch& batch) {
    const double k = batch.drive_is_force ? 1.0 : force_constant(batch, axis.machine, axis.axis);
    if (!std::isfinite(k))
        return fmt::format(
            "current without a force constant for {}/{} (give force_constant in the payload or "
            "[force_constants] in the configuration)",
            terminal_text(axis.machine), terminal_text(axis.axis));
    const std::size_t n = batch.samples();
    if (axis.dt == 0.0) {  // its first batch
        axis.dt = batch.dt;
        axis.next_t = batch.t0;
        axis.counters.recordings = 1;
    } else if (std::abs(batch.dt - axis.dt) > 1e-6 * axis.dt) {
        return fmt::format("dt = {} s, but {}/{} streams at {} s", batch.dt, terminal_text(axis.machine),
                           terminal_text(axis.axis), axis.dt);
    }
    force_.resize(n);
    for (std::size_t i = 0; i < n; ++i) force_[i] = k * batch.drive[i];
    ++arrivals_;
    if (!axis.started) {
        const auto last = axis.held.rbegin();
        const double held_end =
            axis.held.empty() ? batch.t0 : last->first + static_cast<double>(last->second.columns.size() / 2) * axis.dt;
        // a pause longer than run_gap_s after what is held: that was a recording of its own
        if (batch.t0 - held_end <= options_.run_gap_s) {
            hold(axis, batch.t0, batch.position, force_);
            return "";
        }
        start(axis);
    }
    const double ahead = batch.t0 - axis.next_t;  // > 0: a hole or a pause; < 0: a repeat
    if (ahead > options_.run_gap_s) {
        // a new recording: what is held belongs to the last one
        release_held(axis);
        ++axis.counters.recordings;
        if (axis.run_samples > 0) complete_run(axis);
        axis.next_t = batch.t0;
    } else if (ahead > 0.5 * axis.dt) {
        // a hole: held until the batches that fill it come, or reorder_s of stream has come after it
        hold(axis, batch.t0, batch.position, force_);
        return "";
    }
    feed(axis, batch.t0, batch.position, force_, arrivals_);
    feed_held(axis);
    return "";
}

void Watcher::hold(Axis& axis, double t0, std::span<const double> position, std::span<const double> force) {
    auto [it, inserted] = axis.held.try_emplace(t0);
    if (!inserted) {  // a repeat of a held batch
        axis.counters.repeated_samples += position.size();
        return;
    }
    it->second.columns.reserve(2 * position.size());
    it->second.columns.assign(position.begin(), position.end());
    it->second.columns.insert(it->second.columns.end(), force.begin(), force.end());
    it->second.arrival = arrivals_;
    const std::size_t bytes = it->second.columns.capacity() * sizeof(double) + sizeof(*it) + 48;
    if (axis.held_bytes == 0) {
        axis.holding_since = arrivals_;
        holding_.emplace(axis.holding_since, &axis);
    }
    axis.held_samples += position.size();
    axis.held_bytes += bytes;
    held_bytes_ += bytes;
    if (!axis.started) axis.next_t = std::min(axis.next_t, t0);
    enforce_holding_limits(axis);
}

std::pair<double, Watcher::Held> Watcher::take_first_held(Axis& axis) {
    auto node = axis.held.extract(axis.held.begin());
    const std::size_t bytes =
        node.mapped().columns.capacity() * sizeof(double) + sizeof(std::pair<const double, Held>) + 48;
    axis.held_samples -= node.mapped().columns.size() / 2;
    axis.held_bytes -= bytes;
    held_bytes_ -= bytes;
    if (axis.held.empty()) {
        holding_.erase({axis.holding_since, &axis});
        axis.held_bytes = 0;
    }
    return {node.key(), std::move(node.mapped())};
}

void Watcher::enforce_holding_limits(Axis& axis) {
    while (!axis.held.empty()) {
        const auto& [last_t0, last] = *axis.held.rbegin();
        const double held_until = last_t0 + static_cast<double>(last.columns.size() / 2) * axis.dt;
        if (held_until - axis.next_t <= options_.reorder_s) break;
        if (axis.started)
            declare_hole(axis);
        else
            start(axis);
    }
    // beyond held_bytes, the axis that has held longest gives up its first hole (or its start) now
    while (held_bytes_ > options_.held_bytes && !holding_.empty()) {
        Axis& oldest = *holding_.begin()->second;
        ++evicted_holds_;
        if (oldest.started)
            declare_hole(oldest);
        else
            start(oldest);
    }
}

void Watcher::start(Axis& axis) {
    axis.started = true;
    if (axis.held.empty()) return;
    axis.next_t = axis.held.begin()->first;
    axis.first_t = axis.next_t;
    axis.run_start_t = axis.next_t;
    feed_held(axis);
}

void Watcher::declare_hole(Axis& axis) {
    const double t0 = axis.held.begin()->first;
    axis.counters.missing_samples += static_cast<std::size_t>(std::llround((t0 - axis.next_t) / axis.dt));
    axis.hole_start = axis.next_t;
    axis.hole_end = t0;
    if (axis.holes.size() < 16) axis.holes.emplace_back(axis.next_t, t0);
    axis.online->flush();  // the hole ends the window: none bridges it
    axis.next_t = t0;
    const auto [key, batch] = take_first_held(axis);
    const std::size_t n = batch.columns.size() / 2;
    feed(axis, key, std::span(batch.columns).first(n), std::span(batch.columns).subspan(n), batch.arrival);
    feed_held(axis);
}

void Watcher::release_held(Axis& axis) {
    if (!axis.started) start(axis);
    while (!axis.held.empty()) declare_hole(axis);
}

void Watcher::feed(Axis& axis, double t0, std::span<const double> position, std::span<const double> force,
                   std::uint64_t arrival) {
    const std::size_t n = position.size();
    std::size_t skip = 0;
    if (const double behind = axis.next_t - t0; behind > 0.5 * axis.dt) {
        skip = static_cast<std::size_t>(std::min<double>(static_cast<double>(n), std::ceil(behind / axis.dt - 0.5)));
        // never pushed, so not repeats: before the stream's start (a loss, counted now) or in a hole given up on
        // (counted missing then)
        const auto before_start = static_cast<std::size_t>(
            std::clamp(std::ceil((axis.first_t - t0) / axis.dt - 0.5), 0.0, static_cast<double>(skip)));
        const bool in_lost_hole = t0 >= axis.hole_start - 0.5 * axis.dt && t0 < axis.hole_end - 0.5 * axis.dt;
        if (before_start > 0 || in_lost_hole) ++axis.counters.late_batches;
        axis.counters.missing_samples += before_start;
        if (!in_lost_hole) axis.counters.repeated_samples += skip - before_start;
    }
    if (skip < n) {
        if (axis.run_samples == 0) axis.run_start_t = t0 + static_cast<double>(skip) * axis.dt;
        if (arrival < axis.fed_arrival) ++axis.counters.reordered_batches;  // it came before one it follows
        axis.fed_arrival = std::max(axis.fed_arrival, arrival);
        times_.resize(n - skip);
        for (std::size_t i = skip; i < n; ++i) times_[i - skip] = t0 + static_cast<double>(i) * axis.dt;
        axis.online->push(times_, position.subspan(skip), force.subspan(skip));
        axis.next_t = t0 + static_cast<double>(n) * axis.dt;
        ++axis.counters.batches;
        axis.counters.samples += n - skip;
        axis.run_samples += n - skip;
        mark_changed(axis);
        // a completed identification: by period, or by information (checked once per window's worth of samples)
        if (options_.run_period_s > 0.0 && axis.next_t - axis.run_start_t >= options_.run_period_s) {
            complete_run(axis);
        } else if (options_.run_windows > 0) {
            const auto window_samples = static_cast<std::size_t>(std::max(1.0, options_.online.window_s / axis.dt));
            if (axis.run_samples / window_samples > axis.checked_windows) {
                axis.checked_windows = axis.run_samples / window_samples;
                if (axis.online->estimate().windows.qualified() >= options_.run_windows) complete_run(axis);
            }
        }
    }
}

void Watcher::mark_changed(Axis& axis) {
    if (axis.changed) return;
    axis.changed = true;
    changed_.push_back(&axis);
}

void Watcher::feed_held(Axis& axis) {
    // the held batches that the last one made contiguous (or that it covers), in order
    while (!axis.held.empty() && axis.held.begin()->first <= axis.next_t + 0.5 * axis.dt) {
        const auto [key, batch] = take_first_held(axis);
        const std::size_t m = batch.columns.size() / 2;
        feed(axis, key, std::span(batch.columns).first(m), std::span(batch.columns).subspan(m), batch.arrival);
    }
}

void Watcher::complete_run(Axis& axis) {
    axis.online->flush();
    CompletedRun run;
    run.machine = axis.machine;
    run.axis = axis.axis;
    run.estimate = axis.online->estimate();
    run.t_start = axis.run_start_t;
    run.t_end = axis.next_t;
    run.samples = axis.run_samples;
    run.sequence = ++axis.counters.runs;
    completed_.push_back(std::move(run));
    axis.online = std::make_unique<SelectingIdentifier>(options_.online);
    axis.run_samples = 0;
    axis.checked_windows = 0;
}

void Watcher::flush() {
    for (auto& [key, axis] : axes_) {
        release_held(*axis);  // the holes nobody filled are losses now
        axis->online->flush();
        mark_changed(*axis);  // the flushed tail may change every estimate
    }
}

std::vector<CompletedRun> Watcher::take_completed_runs() {
    std::vector<CompletedRun> out;
    out.swap(completed_);
    return out;
}

std::vector<std::pair<std::string, std::string>> Watcher::take_changed() {
    std::vector<std::pair<std::string, std::string>> out;
    out.reserve(changed_.size());
    for (Axis* axis : changed_) {
        axis->changed = false;
        out.emplace_back(axis->machine, axis->axis);
    }
    changed_.clear();
    std::sort(out.begin(), out.end());
    return out;
}

std::optional<OnlineEstimate> Watcher::estimate(const std::string& machine, const std::string& axis) const {
    const auto it = axes_.find(machine + "/" + axis);
    if (it == axes_.end()) return std::nullopt;
    return it->second->online->estimate();
}

nlohmann::json online_result_document(const OnlineEstimate& e, const OnlineOptions& options, const std::string& source,
                                      double duration_s) {
    IdentifyResult result;
    result.model = FrictionModelKind::symmetric;
    result.offset = e.offset_in_model || options.offset;
    // which model (the offset's selection) and timing the estimate used: the document's model_selection and timing
    result.model_choice = model_choice_of(e);
    result.feedid_version = std::string(version);
    result.trace.path = source;
    result.trace.format = "mqtt";
    result.trace.samples = e.samples;
    result.trace.duration_s = duration_s;
    result.trace.sample_time_s = e.samples > 0 ? duration_s / static_cast<double>(e.samples) : 0.0;
    result.parameters = model_parameters(result.model, result.offset, false);
    for (const auto* reason : {&e.mass_reason, &e.friction_reason, &e.stribeck_reason, &e.aliased_reason})
        if (!reason->empty()) result.diagnostics.push_back(*reason);
    for (auto& p : result.parameters) {
        p.estimate = e.of(p.term);
        // a value without a standard error is not published (nor recorded): nothing says how far off it may be
        if (p.estimate.value && !p.estimate.standard_error) {
            p.estimate = {};
            result.diagnostics.push_back(p.key + " is null: the identifier gives no standard error for it");
        }
    }
    const auto value = [&](Term term) { return result.find(term) && result.find(term)->estimate.value; };
    const bool determined = value(Term::mass) && value(Term::viscous) && value(Term::coulomb);
    // a Coulomb friction the windows cannot tell from a weight is null while M and B stand: partial, as scan's
    result.status = !value(Term::mass)                     ? Status::failed
                    : determined && value(Term::breakaway) ? Status::ok
                                                           : Status::partial;
    // the scan's document (windows, information per parameter), marked as the watch's
    ScanResult scan;
    scan.result = std::move(result);
    scan.online = e;
    nlohmann::json document = scan_document(scan);
    document["kind"] = "watch";
    return document;
}

nlohmann::json Watcher::estimate_document(const std::string& machine, const std::string& axis_name) const {
    const auto it = axes_.find(machine + "/" + axis_name);
    if (it == axes_.end()) return nullptr;
    const Axis& axis = *it->second;
    const OnlineEstimate e = axis.online->estimate();
    nlohmann::json document =
        online_result_document(e, options_.online, machine + "/" + axis_name, axis.next_t - axis.run_start_t);
    document["machine"] = machine;
    document["axis"] = axis_name;
    document["stream"] = {{"batches", axis.counters.batches},
                          {"samples", axis.counters.samples},
                          {"repeated_samples", axis.counters.repeated_samples},
                          {"missing_samples", axis.counters.missing_samples},
                          {"late_batches", axis.counters.late_batches},
                          {"reordered_batches", axis.counters.reordered_batches},
                          {"held_samples", axis.held_samples},
                          {"holes_s", axis.holes},
                          {"recordings", axis.counters.recordings},
                          {"time_s", axis.next_t}};
    document["run"] = {
        {"sequence", axis.counters.runs + 1}, {"started_s", axis.run_start_t}, {"samples", axis.run_samples}};
    return document;
}

}  // namespace feedid::watch
