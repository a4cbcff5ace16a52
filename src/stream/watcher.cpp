#include "feedid/stream/watcher.hpp"

#include <algorithm>
#include <cmath>
#include <exception>

#include <fmt/core.h>

#include "feedid/identify/identify.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/stream/scan.hpp"
#include "feedid/core/version.hpp"

namespace feedid::watch {

std::string WatchOptions::validate() const {
    if (auto e = online.validate(); !e.empty()) return e;
    if (max_axes == 0) return "max_axes must be at least 1";
    if (!(run_period_s >= 0.0) || !std::isfinite(run_period_s)) return "run period must be a finite time >= 0 s";
    if (!(run_gap_s > 0.0)) return "run gap must be a time > 0 s";
    if (!(reorder_s >= 0.0) || !std::isfinite(reorder_s)) return "reorder time must be a finite time >= 0 s";
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

std::string Watcher::ingest(std::string_view topic, std::span<const std::byte> payload) {
    ++messages_;
    try {
        std::string error = decode_batch(payload, batch_, options_.limits);
        if (error.empty()) {
            std::string machine = batch_.machine, axis = batch_.axis;
            if (machine.empty() || axis.empty()) {
                const auto names = machine_axis_of_topic(topic);
                if (!names) {
                    error = "the topic names no machine and axis (plant/<machine>/<axis>/...) and the payload neither";
                } else {
                    if (machine.empty()) machine = names->first;
                    if (axis.empty()) axis = names->second;
                }
            }
            if (error.empty()) {
                const std::string key = machine + "/" + axis;
                auto it = axes_.find(key);
                if (it == axes_.end()) {
                    if (axes_.size() >= options_.max_axes) {
                        error = fmt::format("more than {} axes: '{}' refused", options_.max_axes, key);
                    } else {
                        auto state = std::make_unique<Axis>();
                        state->machine = machine;
                        state->axis = axis;
                        state->online = std::make_unique<OnlineIdentifier>(options_.online);
                        it = axes_.emplace(key, std::move(state)).first;
                    }
                }
                if (error.empty()) error = push(*it->second, batch_);
            }
        }
        if (!error.empty()) ++malformed_;
        return error;
    } catch (const std::exception& e) {  // out of memory on a huge message, and the like: dropped, never fatal
        ++malformed_;
        return fmt::format("cannot take the message: {}", e.what());
    }
}

std::string Watcher::push(Axis& axis, const Batch& batch) {
    const double k = batch.drive_is_force ? 1.0 : force_constant(batch, axis.machine, axis.axis);
    if (!std::isfinite(k))
        return fmt::format(
            "current without a force constant for {}/{} (give force_constant in the payload or "
            "[force_constants] in the configuration)",
            axis.machine, axis.axis);
    const std::size_t n = batch.samples();
    if (axis.counters.batches == 0 && axis.held.empty()) {
        axis.dt = batch.dt;
        axis.next_t = batch.t0;
        axis.counters.recordings = 1;
    } else if (std::abs(batch.dt - axis.dt) > 1e-6 * axis.dt) {
        return fmt::format("dt = {} s, but {}/{} streams at {} s", batch.dt, axis.machine, axis.axis, axis.dt);
    }
    force_.resize(n);
    for (std::size_t i = 0; i < n; ++i) force_[i] = k * batch.drive[i];
    const double ahead = batch.t0 - axis.next_t;  // > 0: a hole or a pause; < 0: a repeat
    if (ahead > options_.run_gap_s) {
        // a new recording: what is held belongs to the last one
        release_held(axis);
        ++axis.counters.recordings;
        if (axis.run_samples > 0) complete_run(axis);
        axis.next_t = batch.t0;
    } else if (ahead > 0.5 * axis.dt) {
        // a hole: held until the batches that fill it come, or reorder_s of stream has come after it
        auto [it, inserted] = axis.held.try_emplace(batch.t0);
        if (!inserted) {  // a repeat of a held batch
            axis.counters.repeated_samples += n;
            return "";
        }
        it->second.assign(batch.position.begin(), batch.position.end());
        it->second.insert(it->second.end(), force_.begin(), force_.end());
        axis.held_samples += n;
        while (!axis.held.empty()) {
            const auto& [last_t0, last] = *axis.held.rbegin();
            const double held_until = last_t0 + static_cast<double>(last.size() / 2) * axis.dt;
            if (held_until - axis.next_t <= options_.reorder_s) break;
            declare_hole(axis, axis.held.begin()->first);
        }
        return "";
    }
    feed(axis, batch.t0, batch.position, force_);
    feed_held(axis);
    return "";
}

void Watcher::declare_hole(Axis& axis, double t0) {
    axis.counters.missing_samples += static_cast<std::size_t>(std::llround((t0 - axis.next_t) / axis.dt));
    axis.hole_start = axis.next_t;
    axis.hole_end = t0;
    if (axis.holes.size() < 16) axis.holes.emplace_back(axis.next_t, t0);
    axis.online->flush();  // the hole ends the window: none bridges it
    axis.next_t = t0;
    auto node = axis.held.extract(axis.held.begin());
    const std::vector<double>& columns = node.mapped();
    const std::size_t n = columns.size() / 2;
    axis.held_samples -= n;
    feed(axis, t0, std::span(columns).first(n), std::span(columns).subspan(n));
    feed_held(axis);
}

void Watcher::release_held(Axis& axis) {
    while (!axis.held.empty()) declare_hole(axis, axis.held.begin()->first);
}

void Watcher::feed(Axis& axis, double t0, std::span<const double> position, std::span<const double> force) {
    const std::size_t n = position.size();
    std::size_t skip = 0;
    if (const double behind = axis.next_t - t0; behind > 0.5 * axis.dt) {
        if (t0 >= axis.hole_start - 0.5 * axis.dt && t0 < axis.hole_end - 0.5 * axis.dt)
            ++axis.counters.late_batches;  // it belonged in a hole given up on: it came after later samples
        skip = static_cast<std::size_t>(std::min<double>(static_cast<double>(n), std::ceil(behind / axis.dt - 0.5)));
        axis.counters.repeated_samples += skip;
    }
    if (skip < n) {
        if (axis.run_samples == 0) axis.run_start_t = t0 + static_cast<double>(skip) * axis.dt;
        axis.t.resize(n - skip);
        for (std::size_t i = skip; i < n; ++i) axis.t[i - skip] = t0 + static_cast<double>(i) * axis.dt;
        axis.online->push(axis.t, position.subspan(skip), force.subspan(skip));
        axis.next_t = t0 + static_cast<double>(n) * axis.dt;
        ++axis.counters.batches;
        axis.counters.samples += n - skip;
        axis.run_samples += n - skip;
        if (changed_.empty() || changed_.back() != axis.machine + "/" + axis.axis)
            changed_.push_back(axis.machine + "/" + axis.axis);
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

void Watcher::feed_held(Axis& axis) {
    // the held batches that the last one made contiguous (or that it covers), in order
    while (!axis.held.empty() && axis.held.begin()->first <= axis.next_t + 0.5 * axis.dt) {
        auto node = axis.held.extract(axis.held.begin());
        const std::vector<double>& columns = node.mapped();
        const std::size_t m = columns.size() / 2;
        axis.held_samples -= m;
        ++axis.counters.reordered_batches;
        feed(axis, node.key(), std::span(columns).first(m), std::span(columns).subspan(m));
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
    axis.online = std::make_unique<OnlineIdentifier>(options_.online);
    axis.run_samples = 0;
    axis.checked_windows = 0;
}

void Watcher::flush() {
    for (auto& [key, axis] : axes_) {
        release_held(*axis);  // the holes nobody filled are losses now
        axis->online->flush();
        changed_.push_back(key);  // the flushed tail may change every estimate
    }
}

std::vector<CompletedRun> Watcher::take_completed_runs() {
    std::vector<CompletedRun> out;
    out.swap(completed_);
    return out;
}

std::vector<std::pair<std::string, std::string>> Watcher::take_changed() {
    std::sort(changed_.begin(), changed_.end());
    changed_.erase(std::unique(changed_.begin(), changed_.end()), changed_.end());
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& key : changed_) {
        const auto& axis = *axes_.at(key);
        out.emplace_back(axis.machine, axis.axis);
    }
    changed_.clear();
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
    result.offset = options.offset;
    result.feedid_version = std::string(version);
    result.trace.path = source;
    result.trace.format = "mqtt";
    result.trace.samples = e.samples;
    result.trace.duration_s = duration_s;
    result.trace.sample_time_s = e.samples > 0 ? duration_s / static_cast<double>(e.samples) : 0.0;
    result.parameters = model_parameters(result.model, result.offset, false);
    for (const auto* reason : {&e.mass_reason, &e.friction_reason, &e.stribeck_reason})
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
    result.status = !value(Term::coulomb)                  ? Status::failed
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
