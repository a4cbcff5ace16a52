#include "cli.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <iostream>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/io/config_file.hpp"
#include "feedid/io/json_input.hpp"
#include "feedid/io/output_file.hpp"
#include "feedid/core/terminal_text.hpp"

namespace feedid::cli {

std::optional<double> delay_seconds(const std::string& text) {
    const std::array<std::pair<const char*, double>, 3> units{{{"us", 1e-6}, {"ms", 1e-3}, {"s", 1.0}}};
    double scale = 1.0;
    std::string number = text;
    for (const auto& [suffix, factor] : units) {
        const std::string_view unit(suffix);
        if (number.size() > unit.size() && number.ends_with(unit)) {
            number.resize(number.size() - unit.size());
            scale = factor;
            break;
        }
    }
    double value = 0.0;
    const auto [end, error] = std::from_chars(number.data(), number.data() + number.size(), value);
    if (error != std::errc{} || end != number.data() + number.size() || !std::isfinite(value)) return std::nullopt;
    return value * scale;
}

std::string delay_problem(const std::string& text) {
    if (text == "auto" || text == "none") return {};
    const auto seconds = delay_seconds(text);
    if (!seconds) return fmt::format("'{}' is not auto, none or a time with its unit (0.5ms, 250us, 0.001s)", text);
    if (std::abs(*seconds) > 1.0) return fmt::format("'{}' is more than 1 s: two recorders' clocks? (--join)", text);
    return {};
}

double parse_delay(const std::string& text) {
    return *delay_seconds(text);
}

CLI::Validator allowed_range(double low, double high, const std::string& unit) {
    const std::string range = fmt::format("{:g} to {:g}{}", low, high, unit.empty() ? "" : " " + unit);
    auto check = [low, high, unit, range](std::string& text) -> std::string {
        char* end = nullptr;
        const double value = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size())
            return fmt::format("'{}' is not a number (allowed: {})", text, range);
        if (!std::isfinite(value)) return fmt::format("{} is not a finite number (allowed: {})", text, range);
        if (const ValueRange allowed{low, high, unit.c_str()}; !allowed.contains(value)) return allowed.refusal(text);
        return {};
    };
    return CLI::Validator(std::move(check), "in " + range);
}

CLI::Validator lead_range() {
    return allowed_range(allowed_lead_m.low * 1e3, allowed_lead_m.high * 1e3, "mm");
}

CLI::Validator gear_ratio_range() {
    return allowed_range(allowed_gear_ratio.low, allowed_gear_ratio.high, "motor turns per screw turn");
}

namespace {

// --force-constant: a number, which must be a force constant DriveConstants::validate() allows, or the name of a
// constant in the file (checked when the file is read).
CLI::Validator force_constant_check() {
    auto check = [](std::string& text) -> std::string {
        char* end = nullptr;
        const double value = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size()) return {};  // a name
        DriveConstants constants;
        constants.force_constant = value;
        const std::string problem = constants.validate();
        // "--force-constant 1e+308 is not allowed: ..." without the option's name, which CLI11 puts first
        return problem.empty() ? problem : text + problem.substr(problem.find(" is "));
    };
    return CLI::Validator(std::move(check), "number or the file's constant");
}

}  // namespace

void TraceArguments::add_to(CLI::App& app) {
    app.add_option("FILE", file,
                   "The trace: CSV, MATLAB .mat, SINUMERIK trace XML, TwinCAT Scope CSV, halscope text, MR "
                   "Configurator2 graph CSV or NI DAQ CSV")
        ->required();
    app.add_option("--channel", channel_assignments,
                   "Use a channel for a role: ROLE=NAME (roles: time, position, reference_position, velocity, "
                   "velocity_command, current, force, external_force, injection, motor_position); ROLE=none: no channel "
                   "for that role, none guessed (position=none: the motion from the logged velocity alone); "
                   "repeatable")
        ->take_all()
        ->allow_extra_args(false);
    app.add_option("--unit", unit_assignments, "The unit of a role's channel where the file gives none: ROLE=UNIT")
        ->take_all()
        ->allow_extra_args(false);
    app.add_option("--axis", axis,
                   "The axis: which one to read from a multi-axis trace (NC axis index or name; the X1 of X1_... "
                   "channel names in a CSV log) and its label in the history");
    app.add_option("--format", format, "Read as this format instead of detecting it")
        ->check(
            CLI::IsMember({"csv", "mat", "sinumerik-trace", "twincat-scope", "halscope", "mr-configurator", "ni-daq"}));
    app.add_option("--rated", rated,
                   "What 100 % means for channels given in percent, with its unit: 18A (rated current), 2.4Nm (rated "
                   "torque); a bare number is in A");
    app.add_option("--join", join,
                   "A second recording of the same move (e.g. a DAQ's load cell): FILE[@SHIFT], its channels "
                   "resampled onto this trace's time base after shifting its time stamps by SHIFT (@4ms, @-0.004s; "
                   "@auto or @auto:OURS=THEIRS: found by cross-correlation); --channel may name its channels");
    app.add_option("--join-max-shift", join_max_shift_s, "Largest shift @auto searches, either way [s] (default 0.1)")
        ->check(allowed_range(1e-6, 3600.0, "s"));
    app.add_option("--tare", tare,
                   "Zero a role's channel from the samples at rest before the move (e.g. a load cell's offset): "
                   "ROLE; repeatable")
        ->take_all()
        ->allow_extra_args(false);
    app.add_option("--invert", invert,
                   "Flip the sign of a role's channel: ROLE (e.g. current, when the drive counts positive current in "
                   "the direction the NC counts negative); repeatable")
        ->take_all()
        ->allow_extra_args(false);
    app.add_option("--sample-time", sample_time_s,
                   "Time between samples [s] for files without a time column (a CSV log, halsampler output)")
        ->check(allowed_range(1e-9, 3600.0, "s"));
    app.add_option("--skip-rows", skip_rows, "CSV: lines to skip at the top of the file before the header row")
        ->check(allowed_range(0.0, 1e9, "lines"));
    app.add_flag("--rotary", rotary,
                 "The axis is rotary: a SINUMERIK trace's posn signals are in deg and its velo signals in rpm; "
                 "channels without a unit are in rad, rad/s and N*m");
}

ImportOptions TraceArguments::import_options() const {
    ImportOptions options;
    for (const auto& text : channel_assignments) {
        auto [role, name] = parse_role_assignment(text, "--channel");
        options.channels[role] = name;
    }
    for (const auto& text : unit_assignments) {
        auto [role, unit] = parse_role_assignment(text, "--unit");
        options.units[role] = unit;
    }
    options.axis = axis;
    options.format = format;
    if (!join.empty()) {
        options.join = parse_join_spec(join);
        if (join_max_shift_s) {
            if (!(*join_max_shift_s > 0.0)) throw InputError("--join-max-shift must be a positive time [s]");
            options.join->options.max_shift_s = *join_max_shift_s;
        }
    } else if (join_max_shift_s) {
        throw InputError("--join-max-shift needs --join FILE@auto");
    }
    for (const auto& text : tare) {
        const auto role = parse_role(text);
        if (!role || *role == Role::other || *role == Role::time)
            throw InputError(fmt::format("--tare {}: not a role to zero (e.g. force, current, external_force)", text));
        options.tare.push_back(*role);
    }
    for (const auto& text : invert) {
        const auto role = parse_role(text);
        if (!role || *role == Role::other || *role == Role::time)
            throw InputError(fmt::format("--invert {}: not a role to invert (e.g. current, force, position)", text));
        options.invert.push_back(*role);
    }
    options.sample_time_s = sample_time_s;
    options.skip_rows = skip_rows;
    options.rotary = rotary;
    options.describe = describe;
    if (lead_mm) options.unit_context.lead_m = *lead_mm * 1e-3;
    options.unit_context.gear_ratio = gear_ratio;
    if (!rated.empty()) {
        const Rating rating = parse_rating(rated);
        options.unit_context.rated_value_si = rating.value_si;
        options.unit_context.rated_quantity = rating.quantity;
    }
    return options;
}

Trace TraceArguments::read(bool print_findings) const {
    Trace trace = read_trace(file, import_options());
    if (print_findings) {
        for (const auto& finding : trace.findings) fmt::print(stderr, "feedid: {}\n", terminal_message(finding));
    }
    return trace;
}

std::vector<GuardedFile> TraceArguments::inputs() const {
    std::vector<GuardedFile> files{{"the trace", file}};
    if (!join.empty()) files.push_back({"the --join trace", parse_join_spec(join).path});
    return files;
}

void DriveArguments::add_to(CLI::App& app) {
    app.add_option("--kt", kt, "Motor torque constant K_t [N*m/A]; with --lead gives F = K_t*i*2*pi/lead")
        ->check(allowed_range(allowed_torque_constant_Nm_per_A.low, allowed_torque_constant_Nm_per_A.high, "N*m/A"));
    app.add_option("--lead", lead_mm, "Ball-screw lead [mm per revolution]")->check(lead_range());
    app.add_option("--gear-ratio", gear_ratio, "Motor revolutions per screw revolution")
        ->capture_default_str()
        ->check(gear_ratio_range());
    app.add_option("--force-constant", force_constant,
                   "Force per unit of the drive signal [N per signal unit], a number or the name of a scalar in the "
                   "file (e.g. gtau)")
        ->check(force_constant_check());
}

DriveConstants DriveArguments::constants() const {
    DriveConstants constants;
    constants.torque_constant_Nm_per_A = kt;
    if (lead_mm) constants.lead_m = *lead_mm * 1e-3;
    constants.gear_ratio = gear_ratio;
    if (!force_constant.empty()) {
        double value = 0.0;
        const auto* begin = force_constant.data();
        const auto* end = begin + force_constant.size();
        const auto [ptr, error] = std::from_chars(begin, end, value);
        if (error == std::errc() && ptr == end)
            constants.force_constant = value;
        else
            constants.force_constant_name = force_constant;
    }
    if (const auto problem = constants.validate(); !problem.empty()) throw InputError(problem);
    for (const auto& warning : constants.warnings())
        fmt::print(stderr, "feedid: warning: {}\n", terminal_message(warning));
    return constants;
}

void write_json(const nlohmann::json& document, const std::string& path) {
    write_output(path, document.dump(2) + "\n");
}

nlohmann::json read_json(const std::string& path) {
    return read_json_file(path);
}

Trace read_trace_for_drive(const TraceArguments& trace, const DriveArguments& drive) {
    TraceArguments arguments = trace;
    if (!arguments.lead_mm) arguments.lead_mm = drive.lead_mm;
    if (!arguments.gear_ratio) arguments.gear_ratio = drive.gear_ratio;
    return arguments.read();
}

}  // namespace feedid::cli
