#pragma once
// Trace: the in-memory model of one recording. Named channels, stored as contiguous double columns in SI units,
// each with a role; the source's metadata (file, format, original names and units, scalar constants).

#include <cstddef>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace feedid {

enum class Role {
    other,
    time,
    position,
    reference_position,
    velocity,
    velocity_command,
    current,
    force,
    external_force,  ///< a force acting on the mass from outside the drive (a load cell, a weight), in +x
    injection,       ///< a test signal added to the controller's output before the drive (in the drive signal)
    motor_position,  ///< the motor encoder's position in load units (m, rad), beside a direct scale in `position`
};

/// "position", "reference_position", ... (the names used on the command line and in JSON).
std::string_view role_name(Role role);
/// The inverse of role_name; nullopt for an unknown name.
std::optional<Role> parse_role(std::string_view name);

/// How a channel's native interval is known.
enum class IntervalSource {
    time_base,  ///< none other known: the trace's own sample time (the channel was sampled on the grid)
    format,     ///< stated by the file (a SINUMERIK dataSignal's interval, a TwinCAT Scope channel's sample time)
    detected,   ///< found in the data: the channel holds each value over k grid samples (sample-and-hold, k >= 2)
};

/// "time base", "format", "detected" (as in `feedid info`).
std::string_view interval_source_name(IntervalSource source);

struct Channel {
    std::string name;  ///< As in the source file.
    Role role{Role::other};
    std::string unit;         ///< SI unit of `values` ("m", "A", ...); empty when the source gave none.
    std::string source_unit;  ///< The unit the source file stated (empty when none).
    std::vector<double> values;
    /// The interval at which the source signal was sampled before it was put on the trace's time base [s]: a
    /// multiple of the sample time for a slower signal held (forward-filled) on a finer grid. Empty until import
    /// resolves it (resolve_native_intervals()); the time base's sample time when nothing else is known.
    std::optional<double> native_interval_s{};
    IntervalSource interval_source{IntervalSource::time_base};
    /// The zero removed from `values` at import (--tare), in the SI unit; none when the channel was not tared.
    std::optional<double> tare_removed{};
};

/// Statistics of the time base: the sample time and how regular it is.
struct TimeBase {
    double sample_time_s{0.0};    ///< Mean of the regular steps (within half the median step of it) [s].
    double max_deviation_s{0.0};  ///< Largest |dt - sample_time_s| over all steps, gaps included [s].
    double duration_s{0.0};       ///< Last minus first time stamp [s].
    bool jittery{false};          ///< max deviation above 1 % of the sample time.
};

class Trace {
public:
    std::string source_path;  ///< The file it came from ("" for a generated trace).
    std::string format;       ///< "csv", "mat", "sinumerik-trace", "twincat-scope", "halscope", "synthetic", ...
    std::vector<Channel> channels;
    std::map<std::string, double> constants;  ///< Scalars from the source (e.g. EMPS's gtau, kp, kv).
    std::vector<std::string> findings;        ///< What import noticed: guessed roles, assumed units, jitter, ...
    bool rotary{false};                       ///< Position in rad (a rotary axis), not m.
    /// The axes the source holds when it holds several (a SINUMERIK trace's axis indices, CNC name prefixes such as
    /// X1, Y1); empty for a single-axis source.
    std::vector<std::string> axes;

    /// Number of samples (length of the columns; 0 for an empty trace).
    [[nodiscard]] std::size_t samples() const;

    [[nodiscard]] const Channel* find(Role role) const;
    [[nodiscard]] Channel* find(Role role);
    [[nodiscard]] const Channel* find(std::string_view name) const;
    [[nodiscard]] Channel* find(std::string_view name);
    [[nodiscard]] bool has(Role role) const { return find(role) != nullptr; }

    /// The values of the channel with this role; throws InputError naming the role when there is none.
    [[nodiscard]] std::span<const double> column(Role role) const;

    /// Adds (or replaces) a channel; returns it.
    Channel& set(std::string name, Role role, std::string unit, std::vector<double> values);

    /// Time-base statistics from the time channel (requires one with >= 2 samples).
    [[nodiscard]] TimeBase time_base() const;

    /// Checks that the trace is usable: a time channel, equal column lengths, strictly increasing time, finite values
    /// in every role channel. Throws InputError with one sentence naming the file, channel and sample at the first
    /// violation. A jittery time base is not an error: it is added to `findings` with its figures.
    void validate();

    /// A copy holding samples [first, last).
    [[nodiscard]] Trace slice(std::size_t first, std::size_t last) const;
};

/// While alive, `trace.time_base()` returns the statistics its first call computed, without another pass over the
/// time column (each pass copies the steps for their median): identify asks for them in every stage of every run,
/// import once to validate and once for the native intervals. Making one computes nothing, so it may be made before
/// the time column is checked. The trace must not change meanwhile. Nestable, and visible from every thread.
class TimeBaseMemo {
public:
    explicit TimeBaseMemo(const Trace& trace);
    ~TimeBaseMemo();
    TimeBaseMemo(const TimeBaseMemo&) = delete;
    TimeBaseMemo& operator=(const TimeBaseMemo&) = delete;

private:
    const Trace* trace_{nullptr};
};

}  // namespace feedid
