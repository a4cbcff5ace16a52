#include "feedid/io/import.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <fstream>
#include <vector>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/halscope.hpp"
#include "feedid/io/mat.hpp"
#include "feedid/io/mr_configurator.hpp"
#include "feedid/io/ni_daq.hpp"
#include "feedid/io/sinumerik_trace.hpp"
#include "feedid/io/tare.hpp"
#include "feedid/io/twincat_scope.hpp"
#include "feedid/numeric/native_interval.hpp"
#include "channel_hint.hpp"

namespace feedid {

namespace {

std::string lower_alnum(std::string_view name) {
    std::string out;
    for (const char c : name) {
        if (std::isalnum(static_cast<unsigned char>(c)))
            out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    }
    return out;
}

// Common channel names, compared lower-case with punctuation removed ("x_ref" == "xref").
struct RoleNames {
    Role role;
    std::array<std::string_view, 16> names;
};
// Drive and CNC logs add their own: `X1_ActualPosition`, `X1_CommandVelocity`, `X1_CurrentFeedback` (guessed without
// the axis prefix), MR Configurator2's `Servo motor speed` and `Torque` (the drive signal: the current role takes
// torque and % units).
constexpr std::array<RoleNames, 8> common_names{{
    {Role::time, {"t", "time", "times", "zeit", "timestamp", "tsec", "ts"}},
    {Role::position,
     {"x", "pos", "position", "qm", "q", "xact", "posact", "actpos", "actualposition", "xmeas", "measpos", "y", "z",
      "phi", "angle"}},
    {Role::reference_position,
     {"xref", "xset", "xcmd", "qg", "qr", "qref", "posref", "posset", "poscmd", "cmdpos", "setpos", "possetpoint",
      "reference", "ref", "xr", "commandposition"}},
    {Role::velocity,
     {"v", "vel", "velocity", "dq", "qd", "vact", "velact", "actvel", "speed", "actualvelocity", "servomotorspeed",
      "motorspeed"}},
    {Role::velocity_command,
     {"vset", "vcmd", "vref", "velset", "velcmd", "velref", "cmdvel", "velocitycommand", "velocitysetpoint", "nset",
      "speedsetpoint", "commandvelocity"}},
    {Role::current,
     {"i", "iq", "current", "cur", "iact", "iqact", "actcurr", "actcurrent", "id", "idrive", "currentfeedback",
      "torque"}},
    {Role::force, {"f", "force", "fd", "fdrive", "driveforce", "tau"}},
    {Role::motor_position, {"xmotor", "motorposition", "motorpos", "posmotor", "qmotor", "xenc", "encoderposition"}},
}};

bool is_common_name(std::string_view key) {
    return std::any_of(common_names.begin(), common_names.end(), [key](const RoleNames& entry) {
        return std::find(entry.names.begin(), entry.names.end(), key) != entry.names.end();
    });
}

// The CNC axis prefix of a channel name, as drive and NC logs write it: letters then digits, then '_'
// ("X1_ActualPosition" -> "X1"), or one capital axis letter then '_' ("X_x_ref", as feedid synth --program writes;
// lower-case "x_ref" stays a name of its own); "" when there is none.
std::string_view axis_prefix(std::string_view name) {
    if (name.size() > 2 && name[1] == '_' && std::string_view("XYZABCUVW").find(name[0]) != std::string_view::npos)
        return name.substr(0, 1);
    std::size_t k = 0;
    while (k < name.size() && std::isalpha(static_cast<unsigned char>(name[k]))) ++k;
    const std::size_t letters = k;
    while (k < name.size() && std::isdigit(static_cast<unsigned char>(name[k]))) ++k;
    if (letters == 0 || k == letters || k >= name.size() || name[k] != '_') return {};
    return name.substr(0, k);
}

std::string upper(std::string_view text) {
    std::string out(text);
    for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return out;
}

// The axes a trace's channel names carry: prefixes of at least one name whose rest is a common role name.
std::vector<std::string> axes_in_names(const Trace& trace) {
    std::vector<std::string> axes;
    for (const auto& channel : trace.channels) {
        const auto prefix = axis_prefix(channel.name);
        if (prefix.empty() || !is_common_name(lower_alnum(std::string_view(channel.name).substr(prefix.size() + 1))))
            continue;
        if (std::find(axes.begin(), axes.end(), upper(prefix)) == axes.end()) axes.push_back(upper(prefix));
    }
    return axes;
}

std::string joined(const std::vector<std::string>& items) {
    std::string out;
    for (const auto& item : items) out += (out.empty() ? "" : ", ") + item;
    return out;
}

std::string where(const Trace& trace) {
    return trace.source_path.empty() ? std::string("trace") : trace.source_path;
}

bool compatible(Role role, Quantity quantity) {
    switch (role) {
        case Role::time: return quantity == Quantity::time;
        case Role::position:
        case Role::motor_position:
        case Role::reference_position: return quantity == Quantity::length || quantity == Quantity::angle;
        case Role::velocity:
        case Role::velocity_command: return quantity == Quantity::velocity || quantity == Quantity::angular_velocity;
        case Role::current:
        case Role::injection:  // in the drive signal's units, or already a force (torque)
            return quantity == Quantity::current || quantity == Quantity::voltage || quantity == Quantity::torque ||
                   quantity == Quantity::force || quantity == Quantity::dimensionless;
        case Role::force:
        case Role::external_force: return quantity == Quantity::force || quantity == Quantity::torque;
        case Role::other: return true;
    }
    return true;
}

std::string_view default_si_unit(Role role, bool rotary) {
    switch (role) {
        case Role::time: return "s";
        case Role::position:
        case Role::motor_position:
        case Role::reference_position: return rotary ? "rad" : "m";
        case Role::velocity:
        case Role::velocity_command: return rotary ? "rad/s" : "m/s";
        case Role::current:
        case Role::injection: return "A";
        case Role::force:
        case Role::external_force: return rotary ? "N*m" : "N";
        case Role::other: return "";
    }
    return "";
}

// The channel name that takes a role away (--channel position=none) where no channel bears that name.
constexpr std::string_view removed_role = "none";

void assign_explicit_roles(Trace& trace, const ImportOptions& options) {
    // Explicit assignments first; they take a role away from any channel that had it.
    for (const auto& [role, name] : options.channels) {
        auto* channel = trace.find(name);
        if (channel == nullptr && name == removed_role) {
            // --channel ROLE=none: no channel has the role, none is guessed for it (a position that jumps, when the
            // logged velocity is the measure of the motion)
            for (auto& other : trace.channels)
                if (other.role == role) other.role = Role::other;
            trace.findings.push_back(fmt::format("--channel {}=none: no channel taken as {}", role_name(role),
                                                 role_name(role)));
            continue;
        }
        if (channel == nullptr) {
            std::string available;
            for (const auto& c : trace.channels) available += (available.empty() ? "" : ", ") + c.name;
            throw InputError(fmt::format("{}: --channel {}={}: no channel named '{}' (the file has: {})", where(trace),
                                         role_name(role), name, name, available));
        }
        for (auto& other : trace.channels) {
            if (other.role == role) other.role = Role::other;
        }
        channel->role = role;
        // a reader's guess (SINUMERIK's, made as it reads) that this assignment overrules is no longer what happened
        const std::string guessed_role = fmt::format(" taken as {} (guessed", role_name(role));
        const std::string this_channel = fmt::format("channel '{}'", channel->name);
        std::erase_if(trace.findings, [&](const std::string& finding) {
            const bool a_guess = finding.starts_with("channel '") && finding.find(" (guessed ") != std::string::npos;
            return a_guess && (finding.find(guessed_role) != std::string::npos || finding.starts_with(this_channel));
        });
    }
}

// Which axis prefix names are guessed from ("" = names without one only), after leaving out the channels of the other
// axes when --axis chose one. Several axes and no choice is an error, unless the roles were given with --channel.
std::string select_axis(Trace& trace, const ImportOptions& options) {
    if (trace.format == "sinumerik-trace") return {};  // its reader has already read the chosen axis alone
    const auto axes = axes_in_names(trace);
    if (axes.empty()) return {};
    if (axes.size() > 1) trace.axes = axes;
    if (options.axis.empty()) {
        if (axes.size() == 1) return axes.front();
        if (options.describe && options.channels.empty()) {
            trace.findings.push_back(fmt::format("channels of several axes ({}): no role guessed; read one with "
                                                 "--axis {}",
                                                 joined(axes), axes.front()));
            return "-";
        }
        if (options.channels.empty()) {
            throw InputError(
                fmt::format("{}: channels of several axes ({}): choose one with --axis NAME, or give the "
                            "roles with --channel ROLE=NAME",
                            where(trace), joined(axes)));
        }
        trace.findings.push_back(
            fmt::format("channels of several axes ({}): no role guessed from their names (choose "
                        "one with --axis NAME)",
                        joined(axes)));
        return "-";
    }
    const std::string chosen = upper(options.axis);
    if (std::find(axes.begin(), axes.end(), chosen) == axes.end()) {
        if (axes.size() == 1) return axes.front();  // --axis is then the axis's label in the history only
        throw InputError(fmt::format("{}: --axis {}: no channels named {}_...; the file holds the axes {}",
                                     where(trace), options.axis, options.axis, joined(axes)));
    }
    std::vector<std::string> left_out;
    std::erase_if(trace.channels, [&](const Channel& channel) {
        const std::string prefix = upper(axis_prefix(channel.name));
        const bool other_axis = !prefix.empty() && prefix != chosen &&
                                std::find(axes.begin(), axes.end(), prefix) != axes.end() &&
                                channel.role == Role::other;
        if (other_axis && std::find(left_out.begin(), left_out.end(), prefix) == left_out.end())
            left_out.push_back(prefix);
        return other_axis;
    });
    if (!left_out.empty()) {
        trace.findings.push_back(
            fmt::format("--axis {}: the channels of the other axes ({}) left out", options.axis, joined(left_out)));
    }
    return chosen;
}

// Guesses for the roles still open, from common names (without the chosen axis prefix); each guess is said. Returns
// the names of the channels given a role by guess.
std::vector<std::string> guess_roles(Trace& trace, const std::string& axis,
                                     const std::vector<Role>& assigned_elsewhere) {
    std::vector<std::string> guessed;
    for (const auto& [role, names] : common_names) {
        if (trace.has(role) ||
            std::find(assigned_elsewhere.begin(), assigned_elsewhere.end(), role) != assigned_elsewhere.end())
            continue;
        for (auto& channel : trace.channels) {
            if (channel.role != Role::other) continue;
            std::string_view name = channel.name;
            if (const auto prefix = axis_prefix(name); !prefix.empty() && !axis.empty()) {
                if (axis == "-" || upper(prefix) != axis) continue;
                name.remove_prefix(prefix.size() + 1);
            }
            const std::string key = lower_alnum(name);
            if (std::find(names.begin(), names.end(), key) != names.end() && !key.empty()) {
                channel.role = role;
                guessed.push_back(channel.name);
                trace.findings.push_back(
                    fmt::format("channel '{}' taken as {} (guessed from its name; set it with {})", channel.name,
                                role_name(role), io_detail::channel_option(role_name(role), channel.name)));
                break;
            }
        }
    }
    return guessed;
}

// A guessed role channel whose unit does not fit the role (a load cell logged in V guessed as force by its name), or
// needs a rating that was not given (% without --rated), is left without a role, with a finding that says why; given
// with --channel, either stays an error. A guess with an unknown unit stays an error naming it.
void drop_unusable_guesses(Trace& trace, const ImportOptions& options, const std::vector<std::string>& guessed) {
    const UnitContext with_rating{
        .lead_m = std::nullopt, .gear_ratio = std::nullopt, .rated_value_si = 1.0, .rated_quantity = Quantity::current};
    for (auto& channel : trace.channels) {
        if (channel.role == Role::other || channel.source_unit.empty() || options.units.contains(channel.role) ||
            std::find(guessed.begin(), guessed.end(), channel.name) == guessed.end()) {
            continue;
        }
        std::string reason;
        if (const auto conversion = parse_unit(channel.source_unit, options.unit_context)) {
            if (compatible(channel.role, conversion->quantity)) continue;
            reason = fmt::format("channel '{}': unit '{}' is not one for {}", channel.name, channel.source_unit,
                                 role_name(channel.role));
        } else if (!options.unit_context.rated_value_si && parse_unit(channel.source_unit, with_rating)) {
            try {
                (void)parse_unit_or_throw(channel.source_unit, channel.name, options.unit_context);
            } catch (const InputError& e) {
                reason = e.what();
            }
        } else {
            continue;
        }
        const auto guess = fmt::format("channel '{}' taken as {} (guessed", channel.name, role_name(channel.role));
        std::erase_if(trace.findings, [&guess](const std::string& finding) { return finding.starts_with(guess); });
        trace.findings.push_back(fmt::format("{}: not taken as {}", reason, role_name(channel.role)));
        channel.role = Role::other;
    }
}

// The axis kind, decided once for the whole trace, and what decided it (for messages).
struct AxisDecision {
    AxisKind kind{AxisKind::linear};
    std::string reason;
};

// From the position channel's unit; without one, the reference position's; without either (a velocity-only trace or
// positions without a unit), the velocity channel's: a revolution speed is angular unless a lead makes it a table
// velocity. With none of these the axis is linear, as feedid always took it.
AxisDecision decide_axis_kind(const Trace& trace, const ImportOptions& options) {
    const UnitContext& context = options.unit_context;
    if (options.rotary) return {AxisKind::rotary, "--rotary"};
    for (const Role role :
         {Role::position, Role::reference_position, Role::motor_position, Role::velocity, Role::velocity_command}) {
        const auto* channel = trace.find(role);
        if (channel == nullptr) continue;
        const std::string& unit = channel->unit.empty() ? channel->source_unit : channel->unit;
        if (unit.empty()) continue;
        const auto conversion = parse_unit(unit, context);
        if (!conversion) continue;
        if (const auto kind = axis_kind_of(conversion->quantity)) {
            std::string reason = fmt::format("{} channel '{}' in {}", role_name(role), channel->name, unit);
            if (is_revolution_speed(unit)) reason += context.lead_m ? " with --lead" : " without --lead";
            return {*kind, std::move(reason)};
        }
    }
    return {AxisKind::linear, "no channel states a length or an angle"};
}

// A role channel whose unit belongs to the other axis kind is refused, naming channel, unit and axis kind. The one
// crossing allowed: a motor torque on a linear axis when the lead is known (the drive turns it into force).
void check_axis_kind(const Trace& trace, const Channel& channel, Quantity quantity, const AxisDecision& axis,
                     const UnitContext& context) {
    const auto kind = axis_kind_of(quantity);
    if (channel.role == Role::other || !kind || *kind == axis.kind) return;
    if (quantity == Quantity::torque && axis.kind == AxisKind::linear && context.lead_m) return;
    std::string hint;
    if (axis.kind == AxisKind::rotary) {
        hint = "a rotary axis takes deg, rad or rev, rpm, deg/s or rad/s, and N*m (state it with --unit " +
               std::string(role_name(channel.role)) + "=UNIT)";
    } else if (quantity == Quantity::torque) {
        hint = "give the ball-screw lead (--lead MM, and --gear-ratio) to turn the motor torque into force";
    } else if (is_revolution_speed(channel.source_unit)) {
        hint = "give the ball-screw lead (--lead MM per revolution, and --gear-ratio) to make it a table velocity";
    } else {
        hint = "if the axis is rotary, state the position in an angle (--unit position=deg)";
    }
    throw InputError(fmt::format("{}: channel '{}' ({}) has unit '{}', a {} unit, but the axis is {} ({}): {}",
                                 where(trace), channel.name, role_name(channel.role), channel.source_unit,
                                 axis_kind_name(*kind), axis_kind_name(axis.kind), axis.reason, hint));
}

// An injected signal is added to the controller's output, so it is logged in the drive signal's units: an injection
// channel without a unit of its own takes the drive signal's (the current channel's, else the force channel's), and
// is converted with it. Said in the findings.
void adopt_drive_signal_unit(Trace& trace) {
    Channel* injection = trace.find(Role::injection);
    if (injection == nullptr || !injection->source_unit.empty() || !injection->unit.empty()) return;
    const Channel* drive = trace.find(Role::current);
    if (drive == nullptr) drive = trace.find(Role::force);
    if (drive == nullptr) return;
    if (!drive->source_unit.empty()) {
        injection->source_unit = drive->source_unit;  // converted below as the drive signal is
    } else if (!drive->unit.empty()) {
        injection->unit = drive->unit;  // a reader converted the drive signal itself
    } else if (drive->role == Role::force) {
        injection->unit = std::string(default_si_unit(Role::force, trace.rotary));
    } else {
        return;  // neither carries a unit: both take the current's default, and each default is said
    }
    const std::string& unit = injection->source_unit.empty() ? injection->unit : injection->source_unit;
    trace.findings.push_back(
        fmt::format("channel '{}' (injection) carries no unit: taken in the unit of the drive signal '{}', {} (state "
                    "it with --unit injection=UNIT)",
                    injection->name, drive->name, unit));
}

// The unit overrides (--unit ROLE=UNIT) replace what the source said.
void apply_unit_overrides(Trace& trace, const ImportOptions& options) {
    for (auto& channel : trace.channels) {
        const auto override_unit = options.units.find(channel.role);
        if (channel.role != Role::other && override_unit != options.units.end())
            channel.source_unit = override_unit->second;
    }
}

// The conversion of one channel with a source unit; nullopt (and a finding) for a channel no analysis uses whose unit
// is not understood.
std::optional<UnitConversion> channel_conversion(Trace& trace, const Channel& channel, const AxisDecision& axis,
                                                 const UnitContext& context) {
    if (channel.role == Role::other) {
        auto conversion = parse_unit(channel.source_unit, context);
        if (!conversion) {
            // Not an error for a channel no analysis uses: say why it stays in its source unit.
            try {
                (void)parse_unit_or_throw(channel.source_unit, channel.name, context);
            } catch (const InputError& e) {
                // once: a guess dropped for this unit has said it already (drop_unusable_guesses)
                const std::string reason = e.what();
                if (std::none_of(trace.findings.begin(), trace.findings.end(),
                                 [&reason](const std::string& finding) { return finding.starts_with(reason); }))
                    trace.findings.push_back(fmt::format("{}; values left as they are", reason));
            }
        }
        return conversion;
    }
    UnitConversion conversion;
    try {
        conversion = parse_unit_or_throw(channel.source_unit, channel.name, context);
    } catch (const InputError& e) {
        throw InputError(fmt::format("{}: {}", where(trace), e.what()));
    }
    if (!compatible(channel.role, conversion.quantity)) {
        throw InputError(fmt::format("{}: channel '{}' is used as {} but its unit '{}' is not one for that role",
                                     where(trace), channel.name, role_name(channel.role), channel.source_unit));
    }
    check_axis_kind(trace, channel, conversion.quantity, axis, context);
    return conversion;
}

// A SINUMERIK trace states posn and velo signals in the NC's basic length system without saying the axis kind (the
// reader takes mm and mm/min). One statement that the axis is rotary (--rotary, or an angle for a position role)
// holds for every such signal: posn in deg and velo in rpm, as the NC writes them for a rotary axis, except where a
// role's unit was stated on its own.
void carry_rotary_to_sinumerik_units(Trace& trace, const ImportOptions& options) {
    if (trace.format != "sinumerik-trace") return;
    bool rotary = options.rotary;
    for (const Role role : {Role::position, Role::reference_position, Role::motor_position}) {
        const auto stated = options.units.find(role);
        if (stated == options.units.end()) continue;
        const auto conversion = parse_unit(stated->second, options.unit_context);
        if (conversion && conversion->quantity == Quantity::angle) rotary = true;
    }
    if (!rotary) return;
    for (auto& channel : trace.channels) {
        if (channel.role != Role::other && options.units.contains(channel.role)) continue;
        if (channel.source_unit == "mm") channel.source_unit = "deg";
        if (channel.source_unit == "mm/min") channel.source_unit = "rpm";
    }
}

void convert_units(Trace& trace, const ImportOptions& options) {
    apply_unit_overrides(trace, options);
    carry_rotary_to_sinumerik_units(trace, options);
    adopt_drive_signal_unit(trace);
    const AxisDecision axis = decide_axis_kind(trace, options);
    trace.rotary = axis.kind == AxisKind::rotary;
    UnitContext context = options.unit_context;
    if (trace.rotary) {
        // The reader's assumption of a linear axis no longer holds: the units were stated.
        std::erase_if(trace.findings,
                      [](const std::string& finding) { return finding.starts_with(sinumerik_linear_units_finding); });
    }
    if (trace.rotary && context.lead_m) {
        // A lead turns motor revolutions into table travel; a rotary axis has no table travel.
        trace.findings.push_back(
            fmt::format("--lead {:g} mm is not used for units: the axis is rotary ({}), so "
                        "revolution speeds stay angular (rad/s)",
                        *context.lead_m * 1e3, axis.reason));
        context.lead_m.reset();
        context.gear_ratio.reset();
    }
    for (auto& channel : trace.channels) {
        if (!channel.unit.empty()) continue;  // already SI (a reader that converted itself)
        if (channel.source_unit.empty()) {
            if (channel.role != Role::other) {
                channel.unit = std::string(default_si_unit(channel.role, trace.rotary));
                trace.findings.push_back(
                    fmt::format("channel '{}' ({}) carries no unit: taken as {} (state it with "
                                "--unit {}=UNIT)",
                                channel.name, role_name(channel.role), channel.unit, role_name(channel.role)));
            }
            continue;
        }
        const auto conversion = channel_conversion(trace, channel, axis, context);
        if (!conversion) continue;
        if (conversion->scale != 1.0 || conversion->offset != 0.0) {
            for (double& value : channel.values) value = conversion->scale * value + conversion->offset;
        }
        channel.unit = conversion->si_unit;
    }
}

// A trace without a time channel gets one from the stated sample time (a finding says so); without one it is an
// error that says what to give.
void add_time_from_sample_time(Trace& trace, const ImportOptions& options) {
    if (trace.has(Role::time) || trace.channels.empty()) return;
    if (!options.sample_time_s && options.describe) {
        trace.findings.push_back("no time column (none is named like 't' or 'time'): the sample time is unknown; give "
                                 "it with --sample-time SECONDS");
        return;
    }
    if (!options.sample_time_s) {
        throw InputError(
            fmt::format("{}: no time column (none is named like 't' or 'time'); give the sample time "
                        "with --sample-time SECONDS, or name the column with --channel time=NAME",
                        where(trace)));
    }
    const double dt = *options.sample_time_s;
    if (!(dt > 0.0) || !std::isfinite(dt)) {
        throw InputError(fmt::format("--sample-time {}: must be a positive number of seconds", dt));
    }
    std::string name = "time";
    while (trace.find(name) != nullptr) name += "#2";
    std::vector<double> time(trace.channels.front().values.size());
    for (std::size_t k = 0; k < time.size(); ++k) time[k] = static_cast<double>(k) * dt;
    auto& channel = trace.set(name, Role::time, "s", std::move(time));
    channel.source_unit = "s";
    trace.findings.push_back(fmt::format("no time column: channel '{}' made from --sample-time {} s", name, dt));
}

}  // namespace

std::pair<Role, std::string> parse_role_assignment(std::string_view text, std::string_view option) {
    const auto equals = text.find('=');
    if (equals == std::string_view::npos || equals == 0 || equals + 1 == text.size()) {
        throw InputError(fmt::format("{} {}: expected ROLE=VALUE", option, text));
    }
    const auto role = parse_role(text.substr(0, equals));
    if (!role || *role == Role::other) {
        throw InputError(
            fmt::format("{} {}: unknown role '{}' (roles: time, position, reference_position, velocity, "
                        "velocity_command, current, force, external_force, injection, motor_position)",
                        option, text, text.substr(0, equals)));
    }
    return {*role, std::string(text.substr(equals + 1))};
}

void prepare_trace(Trace& trace, const ImportOptions& options) {
    assign_explicit_roles(trace, options);
    std::vector<Role> not_guessed = options.assigned_elsewhere;
    for (const auto& [role, name] : options.channels)
        if (name == removed_role && trace.find(name) == nullptr) not_guessed.push_back(role);
    const auto guessed = guess_roles(trace, select_axis(trace, options), not_guessed);
    drop_unusable_guesses(trace, options, guessed);
    add_time_from_sample_time(trace, options);
    convert_units(trace, options);
    if (options.describe && !trace.has(Role::time)) return;  // described without a time base (a finding says so)
    const TimeBaseMemo time_base(trace);                     // validate and the native intervals: one pass
    trace.validate();
    resolve_native_intervals(trace);
}

std::string read_file_bytes(const std::filesystem::path& path) {
    std::error_code error;
    if (std::filesystem::is_directory(path, error))
        throw InputError(fmt::format("{}: is a directory, not a file", path.string()));
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(fmt::format("{}: cannot open the file", path.string()));
    in.seekg(0, std::ios::end);
    const auto size = in.tellg();
    if (size < 0) throw InputError(fmt::format("{}: cannot read the file", path.string()));
    in.seekg(0, std::ios::beg);
    std::string bytes(static_cast<std::size_t>(size), '\0');
    in.read(bytes.data(), size);
    if (!in) throw InputError(fmt::format("{}: cannot read the file", path.string()));
    return bytes;
}

namespace {
std::string format_from_content(std::string_view head, const std::filesystem::path& path) {
    if (head.substr(0, 6) == "MATLAB" || head.substr(0, 4) == "\x89HDF") return "mat";
    if (head.find("<traceSession") != std::string_view::npos) return "sinumerik-trace";
    if (looks_like_mr_configurator(head)) return "mr-configurator";
    if (looks_like_ni_daq(head)) return "ni-daq";
    // TwinCAT Scope: "Name<separator>scope name", then "File<separator>..." and "Starttime of export".
    if (head.size() > 5 && head.starts_with("Name") &&
        std::string_view("\t ;:,").find(head[4]) != std::string_view::npos &&
        (head.find("Starttime of export") != std::string_view::npos || head.find("\nFile") != std::string_view::npos)) {
        return "twincat-scope";
    }
    // halscope: the first non-blank line states the sampling period ("# Sampling period is N ns" from 2.9 on).
    if (const auto first = head.find_first_not_of(" \t\r\n"); first != std::string_view::npos) {
        auto line = head.substr(first, head.find('\n', first) - first);
        while (!line.empty() && (line.front() == '#' || line.front() == ' ')) line.remove_prefix(1);
        if (line.starts_with("Sampling period is")) return "halscope";
    }
    if (looks_like_halsampler(head)) return "halscope";
    auto extension = path.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (extension == ".mat") return "mat";
    if (extension == ".xml") return "sinumerik-trace";
    return "csv";
}
}  // namespace

std::string detect_format(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(fmt::format("{}: cannot open the file", path.string()));
    std::string head(4096, '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<std::size_t>(in.gcount()));
    return format_from_content(head, path);
}

Trace read_source(const std::filesystem::path& path, const ImportOptions& options) {
    std::error_code error;
    if (!std::filesystem::exists(path, error)) throw InputError(fmt::format("{}: no such file", path.string()));
    const std::string format = options.format.empty() ? detect_format(path) : options.format;
    if (options.skip_rows > 0 && format != "csv") {
        throw InputError(
            fmt::format("{}: --skip-rows applies to plain CSV files; this file reads as {} (add "
                        "--format csv to read it as plain CSV)",
                        path.string(), format));
    }
    Trace trace;
    if (format == "mat") {
        trace = read_mat(path);
    } else if (format == "csv") {
        CsvOptions csv;
        csv.skip_rows = options.skip_rows;
        for (const auto& [role, name] : options.channels) csv.numeric_columns.push_back(name);
        trace = read_csv(path, csv);
    } else {
        const std::string bytes = read_file_bytes(path);
        if (bytes.empty()) throw InputError(fmt::format("{}: empty file", path.string()));
        if (format == "sinumerik-trace")
            trace = parse_sinumerik_trace(bytes, path.string(), options.axis);
        else if (format == "twincat-scope")
            trace = parse_twincat_scope(bytes, path.string());
        else if (format == "halscope")
            trace = parse_halscope(bytes, path.string(), options.sample_time_s);
        else if (format == "mr-configurator")
            trace = parse_mr_configurator(bytes, path.string());
        else if (format == "ni-daq")
            trace = parse_ni_daq(bytes, path.string());
        else
            throw InputError(
                fmt::format("--format {}: unknown format (csv, mat, sinumerik-trace, twincat-scope, halscope, "
                            "mr-configurator, ni-daq)",
                            format));
    }
    trace.source_path = path.string();
    if (trace.format.empty()) trace.format = format;
    return trace;
}

namespace {

/// The options for one of two joined files: the channel assignments that name one of its channels.
ImportOptions options_for(const Trace& raw, const ImportOptions& options) {
    ImportOptions own = options;
    own.join.reset();
    own.channels.clear();
    for (const auto& [role, name] : options.channels) {
        if (raw.find(name) != nullptr)
            own.channels[role] = name;
        else
            own.assigned_elsewhere.push_back(role);
    }
    return own;
}

/// After a join each role belongs to one channel: the one named by --channel, else the first file's.
void settle_roles(Trace& joined, const ImportOptions& options) {
    for (std::size_t a = 0; a < joined.channels.size(); ++a) {
        auto& channel = joined.channels[a];
        if (channel.role == Role::other) continue;
        const auto named = options.channels.find(channel.role);
        for (std::size_t b = a + 1; b < joined.channels.size(); ++b) {
            auto& later = joined.channels[b];
            if (later.role != channel.role) continue;
            const bool later_named = named != options.channels.end() && named->second == later.name;
            auto& loser = later_named ? channel : later;
            joined.findings.push_back(fmt::format("channel '{}' is not used as {} ('{}' is)", loser.name,
                                                  role_name(loser.role), (later_named ? later : channel).name));
            loser.role = Role::other;
            if (later_named) break;
        }
    }
}

Trace read_joined(const std::filesystem::path& path, const ImportOptions& options) {
    Trace first = read_source(path, options);
    ImportOptions second_read;
    second_read.sample_time_s = options.sample_time_s;
    Trace second = read_source(options.join->path, second_read);
    for (const auto& [role, name] : options.channels) {
        if (first.find(name) == nullptr && second.find(name) == nullptr) {
            throw InputError(fmt::format("--channel {}={}: neither {} nor {} has a channel named '{}'", role_name(role),
                                         name, first.source_path, second.source_path, name));
        }
    }
    prepare_trace(first, options_for(first, options));
    prepare_trace(second, options_for(second, options));
    Trace joined = join_traces(first, second, options.join->options);
    settle_roles(joined, options);
    if (!first.has(Role::position)) joined.rotary = second.rotary;
    joined.validate();
    return joined;
}

}  // namespace

Trace read_trace(const std::filesystem::path& path, const ImportOptions& options) {
    Trace trace;
    if (options.join) {
        trace = read_joined(path, options);
    } else {
        trace = read_source(path, options);
        prepare_trace(trace, options);
    }
    for (const Role role : options.invert) {
        Channel* channel = trace.find(role);
        if (channel == nullptr) {
            throw InputError(fmt::format("{}: --invert {}: the trace has no {} channel", path.string(), role_name(role),
                                         role_name(role)));
        }
        for (double& value : channel->values) value = -value;
        trace.findings.push_back(fmt::format("channel '{}' ({}) inverted (--invert)", channel->name, role_name(role)));
    }
    for (const Role role : options.tare) tare(trace, role);
    return trace;
}

}  // namespace feedid
