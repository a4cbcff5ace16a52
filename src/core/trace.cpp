#include "feedid/core/trace.hpp"

#include "feedid/core/large_columns.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include <fmt/core.h>

#include "feedid/core/error.hpp"

namespace feedid {

namespace {
constexpr std::array<std::pair<Role, std::string_view>, 11> role_names{{
    {Role::other, "other"},
    {Role::time, "time"},
    {Role::position, "position"},
    {Role::reference_position, "reference_position"},
    {Role::velocity, "velocity"},
    {Role::velocity_command, "velocity_command"},
    {Role::current, "current"},
    {Role::force, "force"},
    {Role::external_force, "external_force"},
    {Role::injection, "injection"},
    {Role::motor_position, "motor_position"},
}};

std::string where(const Trace& trace) {
    return trace.source_path.empty() ? std::string("trace") : trace.source_path;
}
}  // namespace

std::string_view role_name(Role role) {
    for (const auto& [r, name] : role_names) {
        if (r == role) return name;
    }
    return "other";
}

std::string_view interval_source_name(IntervalSource source) {
    switch (source) {
        case IntervalSource::format: return "format";
        case IntervalSource::detected: return "detected";
        case IntervalSource::time_base: break;
    }
    return "time base";
}

std::optional<Role> parse_role(std::string_view name) {
    for (const auto& [r, role_string] : role_names) {
        if (role_string == name) return r;
    }
    return std::nullopt;
}

std::size_t Trace::samples() const {
    if (const auto* time = find(Role::time)) return time->values.size();
    return channels.empty() ? 0 : channels.front().values.size();
}

const Channel* Trace::find(Role role) const {
    if (role == Role::other) return nullptr;
    for (const auto& channel : channels) {
        if (channel.role == role) return &channel;
    }
    return nullptr;
}

Channel* Trace::find(Role role) {
    return const_cast<Channel*>(std::as_const(*this).find(role));
}

const Channel* Trace::find(std::string_view name) const {
    for (const auto& channel : channels) {
        if (channel.name == name) return &channel;
    }
    return nullptr;
}

Channel* Trace::find(std::string_view name) {
    return const_cast<Channel*>(std::as_const(*this).find(name));
}

std::span<const double> Trace::column(Role role) const {
    const auto* channel = find(role);
    if (channel == nullptr) {
        throw InputError(fmt::format("{}: no {} channel (map one with --channel {}=NAME)", where(*this),
                                     role_name(role), role_name(role)));
    }
    return channel->values;
}

Channel& Trace::set(std::string name, Role role, std::string unit, std::vector<double> values) {
    if (role != Role::other) {
        for (auto& channel : channels) {
            if (channel.role == role && channel.name != name) channel.role = Role::other;
        }
    }
    if (auto* existing = find(name)) {
        existing->role = role;
        existing->unit = std::move(unit);
        existing->values = std::move(values);
        existing->native_interval_s.reset();  // new values: what was known of the old ones no longer holds
        existing->interval_source = IntervalSource::time_base;
        return *existing;
    }
    channels.push_back(Channel{std::move(name), role, unit, unit, std::move(values)});
    return channels.back();
}

namespace {

/// The time bases remembered by live TimeBaseMemos: the trace, its time column's storage (a replaced column is not
/// the remembered one), the statistics once the first request computed them, and how many memos hold it.
struct RememberedTimeBase {
    const Trace* trace;
    const double* data;
    std::size_t size;
    std::optional<TimeBase> base;
    int holders;
};

std::mutex remembered_mutex;
std::vector<RememberedTimeBase> remembered;

RememberedTimeBase* find_remembered(const Trace* trace, std::span<const double> time) {
    for (auto& r : remembered) {
        if (r.trace == trace && r.data == time.data() && r.size == time.size()) return &r;
    }
    return nullptr;
}

std::optional<TimeBase> remembered_time_base(const Trace* trace, std::span<const double> time) {
    const std::lock_guard lock(remembered_mutex);
    const auto* r = find_remembered(trace, time);
    return r != nullptr ? r->base : std::nullopt;
}

// Keeps what the first request computed, where a memo holds this time column.
void remember_time_base(const Trace* trace, std::span<const double> time, const TimeBase& base) {
    const std::lock_guard lock(remembered_mutex);
    if (auto* r = find_remembered(trace, time); r != nullptr && !r->base) r->base = base;
}

}  // namespace

TimeBaseMemo::TimeBaseMemo(const Trace& trace) {
    const Channel* time = trace.find(Role::time);
    if (time == nullptr || time->values.size() < 2) return;
    trace_ = &trace;
    const std::lock_guard lock(remembered_mutex);
    if (auto* r = find_remembered(trace_, time->values); r != nullptr) {
        ++r->holders;
        return;
    }
    remembered.push_back({trace_, time->values.data(), time->values.size(), std::nullopt, 1});
}

TimeBaseMemo::~TimeBaseMemo() {
    if (trace_ == nullptr) return;
    const std::lock_guard lock(remembered_mutex);
    for (auto r = remembered.begin(); r != remembered.end(); ++r) {
        if (r->trace == trace_ && --r->holders == 0) {
            remembered.erase(r);
            return;
        }
        if (r->trace == trace_) return;
    }
}

TimeBase Trace::time_base() const {
    const auto time = column(Role::time);
    if (const auto known = remembered_time_base(this, time)) return *known;
    TimeBase base;
    if (time.size() < 2) return base;
    std::vector<double> steps;
    steps.reserve(time.size() - 1);
    prefer_huge_pages(steps);
    for (std::size_t k = 0; k + 1 < time.size(); ++k) steps.push_back(time[k + 1] - time[k]);
    auto middle = steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2);
    std::nth_element(steps.begin(), middle, steps.end());
    const double median = *middle;
    // The sample time is the mean of the regular steps (within half a median step of it): the median alone is biased
    // when time stamps are rounded (EMPS's t steps by 0.99998 ms and 1.00002 ms, and the median picks one of them),
    // and the plain mean is pulled by gaps of dropped samples.
    double sum = 0.0;
    std::size_t regular = 0;
    for (const double step : steps) {
        if (std::abs(step - median) <= 0.5 * std::abs(median)) {
            sum += step;
            ++regular;
        }
    }
    base.sample_time_s = regular > 0 ? sum / static_cast<double>(regular) : median;
    for (std::size_t k = 0; k + 1 < time.size(); ++k) {
        base.max_deviation_s = std::max(base.max_deviation_s, std::abs(time[k + 1] - time[k] - base.sample_time_s));
    }
    base.duration_s = time.back() - time.front();
    base.jittery = base.max_deviation_s > 0.01 * base.sample_time_s;
    remember_time_base(this, time, base);
    return base;
}

void Trace::validate() {
    const auto* time = find(Role::time);
    if (time == nullptr) throw InputError(fmt::format("{}: no time channel", where(*this)));
    const std::size_t n = time->values.size();
    if (n == 0) throw InputError(fmt::format("{}: the trace holds no samples", where(*this)));
    for (const auto& channel : channels) {
        if (channel.values.size() != n) {
            throw InputError(fmt::format("{}: channel '{}' has {} samples, the time channel {}", where(*this),
                                         channel.name, channel.values.size(), n));
        }
    }
    for (const auto& channel : channels) {
        if (channel.role == Role::other) continue;
        for (std::size_t k = 0; k < n; ++k) {
            if (!std::isfinite(channel.values[k])) {
                throw InputError(fmt::format("{}: channel '{}' ({}) has a missing or non-finite value at sample {}",
                                             where(*this), channel.name, role_name(channel.role), k + 1));
            }
        }
    }
    for (std::size_t k = 1; k < n; ++k) {
        if (!(time->values[k] > time->values[k - 1])) {
            throw InputError(fmt::format("{}: time is not strictly increasing at sample {} ({} s after {} s)",
                                         where(*this), k + 1, time->values[k], time->values[k - 1]));
        }
    }
    if (n >= 2) {
        const TimeBase base = time_base();
        if (base.jittery) {
            findings.push_back(fmt::format(
                "jittery time base: sample time {:.6g} s, largest deviation {:.3g} s "
                "({:.1f} % of a sample)",
                base.sample_time_s, base.max_deviation_s, 100.0 * base.max_deviation_s / base.sample_time_s));
        }
    }
}

Trace Trace::slice(std::size_t first, std::size_t last) const {
    Trace out;
    out.source_path = source_path;
    out.format = format;
    out.constants = constants;
    out.findings = findings;
    out.rotary = rotary;
    out.axes = axes;
    last = std::min(last, samples());
    first = std::min(first, last);
    for (const auto& channel : channels) {
        Channel copy{channel.name, channel.role, channel.unit, channel.source_unit, {}, channel.native_interval_s,
                     channel.interval_source};
        copy.values.assign(channel.values.begin() + static_cast<std::ptrdiff_t>(first),
                           channel.values.begin() + static_cast<std::ptrdiff_t>(last));
        out.channels.push_back(std::move(copy));
    }
    return out;
}

}  // namespace feedid
