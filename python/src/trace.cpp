// feedid.Trace and what makes traces: read_trace, Trace from arrays, synth; and plan, whose reference is a trace.
#include <cmath>
#include <fstream>

#include <fmt/core.h>

#include "binding.hpp"
#include "feedid/model/drive.hpp"
#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/plan/gcode_writer.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/join.hpp"
#include "feedid/io/tare.hpp"
#include "feedid/sim/synth.hpp"
#include "feedid/plan/test_plan.hpp"
#include "feedid/core/units.hpp"

namespace feedid::python {

namespace {

constexpr double mm = 1e-3;
constexpr double mm_per_min = 1e-3 / 60.0;

// ---- the reading options (as `feedid identify FILE --channel ... --unit ...` takes them)

void add_roles(const OptionReader& o, ImportOptions& options, nlohmann::json& record) {
    std::vector<std::string> channels;
    for (const auto& [role, name] : o.text_map("channels")) {
        const std::string assignment = role + "=" + name;
        auto [parsed, channel] = parse_role_assignment(assignment, "channels");
        options.channels[parsed] = channel;
        channels.push_back(assignment);
    }
    std::vector<std::string> units;
    for (const auto& [role, unit] : o.text_map("units")) {
        const std::string assignment = role + "=" + unit;
        auto [parsed, text] = parse_role_assignment(assignment, "units");
        options.units[parsed] = text;
        units.push_back(assignment);
    }
    record["channels"] = channels;
    record["units"] = units;
}

void add_join_and_tare(const OptionReader& o, ImportOptions& options, nlohmann::json& record) {
    const auto shift = o.number("join_max_shift_s", {1e-6, 3600.0, "s"});
    if (const auto join = o.text("join")) {
        options.join = parse_join_spec(*join);
        if (shift) {
            if (!(*shift > 0.0)) throw InputError("join_max_shift_s must be a positive time [s]");
            options.join->options.max_shift_s = *shift;
        }
        record["join"] = *join;
    } else if (shift) {
        throw InputError("join_max_shift_s needs join='FILE@auto'");
    }
    const auto tare_roles = o.texts("tare");
    for (const auto& text : tare_roles) {
        const auto role = parse_role(text);
        if (!role || *role == Role::other || *role == Role::time)
            throw InputError(fmt::format("tare {}: not a role to zero (e.g. force, current, external_force)", text));
        options.tare.push_back(*role);
    }
    if (!tare_roles.empty()) record["tare"] = tare_roles;
    const auto invert_roles = o.texts("invert");
    for (const auto& text : invert_roles) {
        const auto role = parse_role(text);
        if (!role || *role == Role::other || *role == Role::time)
            throw InputError(fmt::format("invert {}: not a role to invert (e.g. current, force, position)", text));
        options.invert.push_back(*role);
    }
    if (!invert_roles.empty()) record["invert"] = invert_roles;
}

/// The import options of a call, and the record of them that identify's "options" keeps.
ImportOptions import_options(const OptionReader& o, nlohmann::json& record) {
    ImportOptions options;
    add_roles(o, options, record);
    options.axis = o.text("axis").value_or(options.axis);
    options.format = o.text("format").value_or(options.format);
    record["axis"] = options.axis;
    record["format"] = options.format;
    add_join_and_tare(o, options, record);
    // the allowed ranges are the command line's (cli.cpp)
    options.sample_time_s = o.number("sample_time_s", {1e-9, 3600.0, "s"});
    if (const auto skip = o.integer("skip_rows", {0, 1e9, "lines"}))
        options.skip_rows = static_cast<std::size_t>(*skip);
    if (const auto lead = o.number("lead_mm", {allowed_lead_m.low * 1e3, allowed_lead_m.high * 1e3, "mm"}))
        options.unit_context.lead_m = *lead * 1e-3;
    // the drive's gear ratio, as the command line's reading takes it (cli.cpp, read_trace_for_drive)
    options.unit_context.gear_ratio =
        o.number("gear_ratio", {allowed_gear_ratio.low, allowed_gear_ratio.high, "motor turns per screw turn"})
            .value_or(DriveConstants{}.gear_ratio);
    record["rated"] = nullptr;
    if (const auto rated = o.text("rated")) {
        const Rating rating = parse_rating(*rated);
        options.unit_context.rated_value_si = rating.value_si;
        options.unit_context.rated_quantity = rating.quantity;
        record["rated"] = *rated;
    }
    return options;
}

PyTrace read(const std::string& path, const OptionReader& o) {
    PyTrace out;
    const ImportOptions options = import_options(o, out.read_options);
    py::gil_scoped_release release;
    out.trace = read_trace(path, options);
    return out;
}

// ---- a trace from arrays

/// The values of one column as float64: converted (with a note) when the array is of another real type or not
/// contiguous; InputError naming the channel for anything that is not a 1-D array of real numbers.
std::vector<double> column_values(const std::string& name, py::handle object, std::vector<std::string>& notes) {
    py::array array;
    try {
        array = py::array::ensure(object);
    } catch (const py::error_already_set&) {}
    if (!array) throw InputError(fmt::format("channel '{}': not an array of numbers", name));
    const char kind = array.dtype().kind();
    const std::string dtype = py::str(array.dtype()).cast<std::string>();
    if (kind != 'f' && kind != 'i' && kind != 'u')
        throw InputError(fmt::format("channel '{}': values of type {} are not real numbers", name, dtype));
    if (array.ndim() != 1) {
        throw InputError(fmt::format("channel '{}': a 1-D array is needed, not one of shape {}", name,
                                     py::str(array.attr("shape")).cast<std::string>()));
    }
    if (kind != 'f' || array.itemsize() != 8)
        notes.push_back(fmt::format("channel '{}': {} values converted to float64", name, dtype));
    if (!(array.flags() & py::array::c_style) && array.size() > 1)
        notes.push_back(fmt::format("channel '{}': a strided array, gathered into the trace's own copy", name));
    const auto converted = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
    return {converted.data(), converted.data() + converted.size()};
}

PyTrace from_columns(const py::list& columns, const py::dict& kwargs) {
    const OptionReader o(kwargs);
    PyTrace out;
    Trace& trace = out.trace;
    trace.source_path = o.text("path").value_or("");
    trace.format = o.text("source_format").value_or("arrays");
    std::vector<std::string> notes;
    for (const auto& column : columns) {
        const auto pair = column.cast<py::tuple>();
        auto [name, unit] = split_name_unit(pair[0].cast<std::string>());
        if (trace.find(name) != nullptr) throw InputError(fmt::format("channel '{}' given twice", name));
        Channel channel{name, Role::other, "", unit, column_values(name, pair[1], notes)};
        trace.channels.push_back(std::move(channel));
    }
    if (const auto constants = o.object("constants"); !constants.is_none()) {
        for (const auto& [key, value] : constants.cast<py::dict>()) {
            const auto name = key.cast<std::string>();
            if (py::isinstance<py::bool_>(value) || !py::hasattr(value, "__float__"))
                throw InputError(fmt::format("constants['{}']: not a number", name));
            trace.constants[name] = value.cast<double>();
        }
    }
    trace.findings = o.texts("findings");
    trace.findings.insert(trace.findings.end(), notes.begin(), notes.end());
    const ImportOptions options = import_options(o, out.read_options);
    prepare_trace(trace, options);
    for (const Role role : options.tare) tare(trace, role);
    return out;
}

// ---- the Trace class

py::dict constants_of(const Trace& trace) {
    py::dict out;
    for (const auto& [name, value] : trace.constants) out[py::str(name)] = value;
    return out;
}

const Channel& channel_named(const Trace& trace, const std::string& name) {
    const Channel* channel = trace.find(std::string_view(name));
    if (channel == nullptr) {
        std::string names;
        for (const auto& c : trace.channels) names += (names.empty() ? "'" : ", '") + c.name + "'";
        throw py::key_error(fmt::format("no channel '{}' (channels: {})", name, names));
    }
    return *channel;
}

Role role_named(const std::string& name) {
    const auto role = parse_role(name);
    if (!role || *role == Role::other) {
        throw InputError(
            fmt::format("unknown role '{}' (roles: time, position, reference_position, velocity, "
                        "velocity_command, current, force, external_force, injection, motor_position)",
                        name));
    }
    return *role;
}

std::string trace_repr(const Trace& trace) {
    std::string channels;
    for (const auto& c : trace.channels) {
        channels += fmt::format("{}{} ({}{}{})", channels.empty() ? "" : ", ", c.name,
                                c.role == Role::other ? "" : role_name(c.role), c.role == Role::other ? "" : ", ",
                                c.unit.empty() ? "no unit" : c.unit);
    }
    const double dt = trace.samples() >= 2 ? trace.time_base().sample_time_s : 0.0;
    return fmt::format("<feedid.Trace '{}' ({}), {} samples at {:.6g} s: {}>",
                       trace.source_path.empty() ? "trace" : trace.source_path, trace.format, trace.samples(), dt,
                       channels);
}

// Trace: where it came from, how long, what the import noticed.
void add_trace_summary(py::class_<PyTrace>& cls) {
    cls.def_property_readonly(
        "path", [](const PyTrace& t) { return t.trace.source_path; }, "The file it came from ('' when made in memory)");
    cls.def_property_readonly(
        "format", [](const PyTrace& t) { return t.trace.format; },
        "'csv', 'mat', 'sinumerik-trace', ..., 'synthetic', 'arrays', 'pandas'");
    cls.def_property_readonly(
        "samples", [](const PyTrace& t) { return t.trace.samples(); }, "Number of samples");
    cls.def("__len__", [](const PyTrace& t) { return t.trace.samples(); });
    cls.def_property_readonly(
        "rotary", [](const PyTrace& t) { return t.trace.rotary; }, "A rotary axis (positions in rad)");
    cls.def_property_readonly(
        "findings", [](const PyTrace& t) { return t.trace.findings; },
        "What the import noticed: guessed roles, assumed units, conversions, jitter");
    cls.def_property_readonly(
        "constants", [](const PyTrace& t) { return constants_of(t.trace); },
        "Scalars of the source (EMPS's gtau; synth's force_constant_N_per_A and true values)");
    cls.def_property_readonly("sample_time_s", [](const PyTrace& t) {
        return t.trace.samples() >= 2 ? t.trace.time_base().sample_time_s : 0.0;
    });
    cls.def_property_readonly(
        "duration_s", [](const PyTrace& t) { return t.trace.samples() >= 2 ? t.trace.time_base().duration_s : 0.0; });
}

// Trace: its channels' names, roles, units and sampling intervals.
void add_trace_channels(py::class_<PyTrace>& cls) {
    cls.def_property_readonly(
        "channel_names",
        [](const PyTrace& t) {
            std::vector<std::string> names;
            for (const auto& c : t.trace.channels) names.push_back(c.name);
            return names;
        },
        "The channels' names, in the source's order");
    cls.def_property_readonly(
        "roles",
        [](const PyTrace& t) {
            py::dict roles;
            for (const auto& c : t.trace.channels)
                if (c.role != Role::other) roles[py::str(std::string(role_name(c.role)))] = c.name;
            return roles;
        },
        "Role -> channel name, for the channels that have a role");
    cls.def_property_readonly(
        "units",
        [](const PyTrace& t) {
            py::dict units;
            for (const auto& c : t.trace.channels) units[py::str(c.name)] = c.unit;
            return units;
        },
        "Channel name -> SI unit of its values ('' where the source gave none for a channel without a role)");
    cls.def_property_readonly(
        "source_units",
        [](const PyTrace& t) {
            py::dict units;
            for (const auto& c : t.trace.channels) units[py::str(c.name)] = c.source_unit;
            return units;
        },
        "Channel name -> the unit the source stated");
    cls.def_property_readonly(
        "native_intervals_s",
        [](const PyTrace& t) {
            py::dict intervals;
            for (const auto& c : t.trace.channels) intervals[py::str(c.name)] = c.native_interval_s;
            return intervals;
        },
        "Channel name -> the interval its signal was sampled at [s] (a held, slower signal: a multiple of the "
        "sample time)");
}

// Trace: the channels as numpy views (by name or role), the pandas frame, the repr.
void add_trace_access(py::class_<PyTrace>& cls) {
    cls.def(
        "__getitem__",
        [](py::object self, const std::string& name) {
            return view(channel_named(self.cast<const PyTrace&>().trace, name).values, self);
        },
        py::arg("name"), "The channel of that name: a read-only float64 view [SI]; KeyError when there is none");
    cls.def(
        "__contains__",
        [](const PyTrace& t, const std::string& name) { return t.trace.find(std::string_view(name)) != nullptr; },
        py::arg("name"));
    cls.def(
        "role",
        [](py::object self, const std::string& name) {
            const Trace& trace = self.cast<const PyTrace&>().trace;
            const Role role = role_named(name);
            const Channel* channel = trace.find(role);
            if (channel == nullptr) (void)trace.column(role);  // the library's InputError naming the role
            return view(channel->values, self);
        },
        py::arg("role"),
        "The channel with that role ('time', 'position', 'current', ...): a read-only float64 view [SI]; InputError "
        "when the trace has none");
    cls.def(
        "to_csv",
        [](const PyTrace& t, py::object path) {
            const auto target = as_path(path);
            if (!target) throw InputError("to_csv: expected a path (str or os.PathLike)");
            std::ofstream out(*target, std::ios::binary);
            out << write_csv(t.trace);
            if (!out) throw InputError(fmt::format("{}: cannot write the file", *target));
        },
        py::arg("path"),
        "Writes the trace as CSV as feedid writes traces: '# name = value' constants, 'name [unit]' headers (SI), "
        "values that read back exactly");
    cls.def_property_readonly("_read_options", [](const PyTrace& t) { return to_python(t.read_options); });
    cls.def("__repr__", [](const PyTrace& t) { return trace_repr(t.trace); });
}

void bind_trace_class(py::module_& m) {
    py::class_<PyTrace> cls(m, "Trace", R"doc(A recording in SI units: named channels with roles, constants, findings.

Made by :func:`feedid.read_trace`, :meth:`Trace.from_arrays`, :meth:`Trace.from_pandas`, :func:`feedid.synth`.
Values are SI (m, s, m/s, A, N; rad, rad/s, N*m on a rotary axis); ``units`` names each channel's SI unit,
``source_units`` what the source stated. ``trace[name]`` and ``trace.role(role)`` are read-only float64 numpy views
of the trace's own columns (no copy; a view keeps the trace alive). The trace itself cannot be changed: copy a column
(``numpy.array(trace["x"])``) to work on it.

Example::

    >>> trace = feedid.read_trace(EMPS, channels={"position": "qm", "current": "vir"})
    >>> trace.roles["current"], trace.units["vir"], round(trace.constants["gtau"], 4)
    ('vir', 'A', 35.1507)
    >>> x = trace.role("position")
    >>> x.flags.writeable, x.dtype, len(x) == trace.samples
    (False, dtype('float64'), True)
)doc");
    add_trace_summary(cls);
    add_trace_channels(cls);
    add_trace_access(cls);
}

// ---- synth and plan

SynthSpec synth_spec(const OptionReader& o) {
    const bool rotary = o.flag("rotary").value_or(false);
    SynthSpec spec = rotary ? rotary_demo_spec() : demo_spec();
    std::string source = "drive";
    if (o.given("drive")) {
        const py::object drive = o.object("drive");
        if (const auto path = as_path(drive)) {
            spec = read_spec(*path);
            source = *path;
        } else if (py::isinstance<py::dict>(drive)) {
            spec = spec_from_json(to_json_value(drive, "drive"), "drive");
        } else {
            throw InputError("drive: expected a dict of the drive file's keys or the path of a drive file");
        }
    }
    if (rotary && !spec.axis.rotary) {
        throw InputError(
            fmt::format("synth(rotary=True): the drive {} describes a linear axis (give "
                        "axis.{}, or leave out rotary=True)",
                        source, ParameterNaming{true}.key(Term::mass)));
    }
    if (const auto preset = o.text("preset")) {
        if (*preset != "sinumerik") throw InputError(fmt::format("preset='{}': the presets are 'sinumerik'", *preset));
        apply_sinumerik_recording(spec);
    }
    if (const auto seed = o.integer("seed")) {
        if (*seed < 0) throw InputError(fmt::format("seed={}: must be 0 or more", *seed));
        spec.seed = static_cast<std::uint64_t>(*seed);
    }
    if (!o.flag("slow_passes").value_or(true)) spec.test.slow_passes = false;
    if (o.given("injection")) {
        const py::object injection = o.object("injection");
        const std::string expected = "injection: expected (amplitude_N, frequency_Hz), e.g. (300.0, 1.0)";
        if (!py::isinstance<py::sequence>(injection) || py::isinstance<py::str>(injection) || py::len(injection) != 2)
            throw InputError(expected);
        const py::object amplitude = injection[py::int_(0)], frequency = injection[py::int_(1)];
        for (const auto& value : {amplitude, frequency}) {
            if (py::isinstance<py::bool_>(value) || !py::hasattr(value, "__float__") ||
                !std::isfinite(value.cast<double>()))
                throw InputError(expected);
        }
        spec.injection = SquareWaveInjection{amplitude.cast<double>(), frequency.cast<double>()};
    }
    if (const auto problem = spec.validate(); !problem.empty())
        throw InputError(o.given("injection") ? "injection: " + problem : problem);
    return spec;
}

PyTrace synth(const py::dict& kwargs) {
    const OptionReader o(kwargs);
    const SynthSpec spec = synth_spec(o);
    std::optional<std::vector<double>> reference;
    if (o.given("reference")) {
        std::vector<std::string> notes;
        reference = column_values("reference", o.object("reference"), notes);
        for (const double x : *reference)
            if (!std::isfinite(x)) throw InputError("reference: a value that is not finite");
        if (reference->size() < 2) throw InputError("reference: at least 2 samples are needed");
    }
    PyTrace out;
    {
        py::gil_scoped_release release;
        out.trace = synthesize(spec, reference);
    }
    if (const auto path = o.path("out")) {
        std::ofstream file(*path, std::ios::binary);
        file << write_csv(in_recording_units(out.trace, spec.recording));
        if (!file) throw InputError(fmt::format("{}: cannot write the file", *path));
    }
    return out;
}

/// The plan as `feedid plan` makes it: its options (mm, mm/min), its prediction from a nominal drive.
struct PyPlan {
    TestPlan plan;
    IdentifiabilityPrediction prediction;
    nlohmann::json document;
};

/// A sequence of numbers, each in `range` [the option's unit], times `scale` (to SI).
std::vector<double> numbers_times(const py::object& values, const char* name, double scale, Range range) {
    std::vector<double> out;
    if (!py::isinstance<py::sequence>(values) || py::isinstance<py::str>(values))
        throw InputError(fmt::format("{}: expected a sequence of numbers", name));
    for (const auto& value : values) {
        const std::string text = py::repr(value).cast<std::string>();
        if (py::isinstance<py::bool_>(value) || !py::hasattr(value, "__float__"))
            throw InputError(fmt::format("{}: {} is not a number", name, text));
        const double number = value.cast<double>();
        if (!std::isfinite(number)) throw InputError(fmt::format("{}: {} is not a finite number", name, text));
        check_range(name, number, text, range);
        out.push_back(number * scale);
    }
    return out;
}

std::vector<std::string> comma_entries(const std::string& text) {
    std::vector<std::string> entries;
    std::size_t start = 0;
    while (true) {
        const auto comma = text.find(',', start);
        entries.push_back(text.substr(start, comma - start));
        if (comma == std::string::npos) return entries;
        start = comma + 1;
    }
}

// The allowed ranges are the command line's (cmd_plan.cpp) [mm, mm/min, s, m/s^2, ...].
constexpr Range feed_range{1e-3, 1e6, "mm/min"};
constexpr Range position_range{-1e6, 1e6, "mm"};

void plan_feeds(const OptionReader& o, TestPlanOptions& options) {
    if (o.given("feeds_mm_per_min")) {
        const py::object feeds = o.object("feeds_mm_per_min");
        options.feeds = py::isinstance<py::str>(feeds)
                            ? parse_feeds(comma_entries(feeds.cast<std::string>()))
                            : numbers_times(feeds, "feeds_mm_per_min", mm_per_min, feed_range);
    }
    const py::object slow = o.object("slow_feeds_mm_per_min");
    if (slow.is_none()) {
        options.slow_feeds.clear();
    } else {
        options.slow_feeds = py::isinstance<py::str>(slow)
                                 ? parse_slow_feeds(comma_entries(slow.cast<std::string>()))
                                 : numbers_times(slow, "slow_feeds_mm_per_min", mm_per_min, feed_range);
        if (options.slow_feeds.size() > 100)
            throw InputError(fmt::format("slow_feeds_mm_per_min: {} feeds; at most 100", options.slow_feeds.size()));
    }
}

// An option not given keeps the library's default (default_plan_options, default_prediction_options).
TestPlanOptions plan_options(const OptionReader& o) {
    TestPlanOptions options;
    options.axis = o.text("axis").value_or(options.axis);
    // The keywords name mm and mm/min; a rotary axis's test is planned in degrees by the command line.
    if (is_rotary_axis(options.axis))
        throw InputError(
            fmt::format("axis '{}' is a rotary axis: feedid.plan takes mm and mm/min (travel_mm, ...); "
                        "plan it with `feedid plan --axis {}` (degrees, deg/min)",
                        options.axis, options.axis));
    options = default_plan_options(options.axis);
    const py::object travel = o.object("travel_mm");
    if (py::isinstance<py::str>(travel)) {
        std::tie(options.travel_min, options.travel_max) = parse_travel(travel.cast<std::string>());
    } else {
        const auto limits = numbers_times(travel, "travel_mm", mm, position_range);
        if (limits.size() != 2) throw InputError("travel_mm: expected (min, max) [mm]");
        options.travel_min = limits[0];
        options.travel_max = limits[1];
    }
    options.centers = numbers_times(o.object("centers_mm"), "centers_mm", mm, position_range);
    if (const auto stroke = o.number("stroke_mm", {0.01, 1e5, "mm"})) options.stroke = *stroke * mm;
    plan_feeds(o, options);
    options.max_pass_time = o.number("max_pass_time_s", {0.01, 3600.0, "s"}).value_or(options.max_pass_time);
    if (const auto cycles = o.integer("cycles", {1, 100, "cycles"})) options.cycles = static_cast<int>(*cycles);
    options.acceleration = o.number("acceleration_m_per_s2", {1e-3, 1e6, "m/s^2"}).value_or(options.acceleration);
    options.jerk = o.number("jerk_m_per_s3", {1e-3, 1e9, "m/s^3"});
    options.dwell = o.number("dwell_s", {0.0, 60.0, "s"}).value_or(options.dwell);
    options.sample_time = o.number("sample_time_s", {1e-6, 1.0, "s"}).value_or(options.sample_time);
    if (const auto feed = o.number("max_feed_mm_per_min", feed_range)) options.max_feed = *feed * mm_per_min;
    if (const auto feed = o.number("positioning_feed_mm_per_min", feed_range))
        options.positioning_feed = *feed * mm_per_min;
    if (const auto start = o.number("start_mm", position_range)) options.start_position = *start * mm;
    return options;
}

PredictionOptions prediction_options(const OptionReader& o) {
    PredictionOptions nominal = default_prediction_options(false);
    FrictionBranch branch = nominal.drive.friction.forward;
    branch.viscous = o.number("viscous_Ns_per_m", {0.0, 1e7, "N*s/m"}).value_or(branch.viscous);
    branch.coulomb = o.number("coulomb_N", {0.0, 1e7, "N"}).value_or(branch.coulomb);
    if (const auto breakaway = o.number("breakaway_N", {0.0, 1e7, "N"})) branch.breakaway = *breakaway;
    if (const auto speed = o.number("stribeck_velocity_mm_per_s", {1e-6, 1e4, "mm/s"}))
        branch.stribeck_velocity = *speed * mm;
    nominal.drive.mass = o.number("mass_kg", {1e-6, 1e6, "kg"}).value_or(nominal.drive.mass);
    nominal.drive.friction = Friction::symmetric(branch);
    nominal.force_noise = o.number("force_noise_N", {1e-9, 1e9, "N"}).value_or(nominal.force_noise);
    nominal.level_error = o.number("level_error_N", {1e-9, 1e9, "N"}).value_or(nominal.level_error);
    if (const auto resolution = o.number("position_resolution_um", {1e-6, 1e4, "um"}))
        nominal.position_resolution = *resolution * 1e-6;
    return nominal;
}

PyPlan plan(const py::dict& kwargs) {
    const OptionReader o(kwargs);
    PyPlan out;
    out.plan = make_test_plan(plan_options(o));
    out.prediction = predict_identifiability(out.plan, prediction_options(o));
    out.document = plan_document(out.plan, out.prediction);
    return out;
}

void bind_plan_class(py::module_& m) {
    py::class_<PyPlan> cls(m, "Plan", R"doc(A designed axis test and what its data will identify (:func:`feedid.plan`).

Example::

    >>> p = feedid.plan(travel_mm=(-400, 400), centers_mm=[0], slow_feeds_mm_per_min=None)
    >>> p.blocks > 0, p.prediction["parameters"]["breakaway_N"]["identifiable"]
    (True, False)
    >>> reference = p.reference()                 # the commanded position, 1 ms samples [m]
    >>> reference.roles["reference_position"]
    'x_ref'
)doc");
    cls.def_property_readonly(
        "duration_s", [](const PyPlan& p) { return p.plan.duration; }, "Predicted duration of the test [s]");
    cls.def_property_readonly(
        "blocks", [](const PyPlan& p) { return p.plan.moves.size(); }, "Blocks of the part program");
    cls.def_property_readonly(
        "notes", [](const PyPlan& p) { return p.plan.notes; }, "What the design changed or warns about");
    cls.def_property_readonly(
        "passes", [](const PyPlan& p) { return to_python(p.document.at("passes")); },
        "Every pass: centre, feed [m/s and mm/min], stroke [m], durations [s]");
    cls.def_property_readonly(
        "prediction", [](const PyPlan& p) { return to_python(p.document.at("prediction")); },
        "Each parameter's nominal value, predicted standard error and identifiability");
    cls.def(
        "part_program",
        [](const PyPlan& p, const std::string& dialect) {
            const auto parsed = parse_dialect(dialect);
            if (!parsed)
                throw InputError(fmt::format("dialect='{}': the dialects are 'iso', 'sinumerik', 'linuxcnc'", dialect));
            return emit_part_program(p.plan, *parsed);
        },
        py::arg("dialect") = "iso", "The part program: dialect 'iso', 'sinumerik' or 'linuxcnc'");
    cls.def(
        "reference",
        [](const PyPlan& p) {
            return PyTrace{reference_trajectory(p.plan), nlohmann::json::object()};
        },
        "What an ideal NC commands: a Trace of t [s] and x_ref [m] at the plan's sample time");
    cls.def(
        "to_dict", [](const PyPlan& p) { return to_python(p.document); }, "The document of feedid plan --json");
    cls.def("__repr__", [](const PyPlan& p) {
        return fmt::format("<feedid.Plan axis {}, {} passes, {} blocks, {:.1f} s>", p.plan.options.axis,
                           p.plan.passes.size(), p.plan.moves.size(), p.plan.duration);
    });
}

}  // namespace

const PyTrace& trace_argument(py::handle trace, const OptionReader& options, std::optional<PyTrace>& storage) {
    if (py::isinstance<PyTrace>(trace)) {
        for (const char* name : {"channels", "units", "axis", "format", "sample_time_s", "skip_rows", "rated", "join",
                                 "join_max_shift_s", "tare", "invert"}) {
            if (options.given(name))
                throw InputError(fmt::format("{}: a reading option, for a path; this trace is read already", name));
        }
        return trace.cast<const PyTrace&>();
    }
    const auto path = as_path(trace);
    if (!path) {
        throw InputError(fmt::format("expected a feedid.Trace or the path of a trace file, not {}",
                                     py::type::handle_of(trace).attr("__name__").cast<std::string>()));
    }
    storage = read(*path, options);
    return *storage;
}

void bind_trace(py::module_& m) {
    bind_trace_class(m);
    bind_plan_class(m);
    m.def(
        "read_trace",
        [](py::object path, const py::dict& options) {
            const auto text = as_path(path);
            if (!text) throw InputError("read_trace: expected a path (str or os.PathLike)");
            return read(*text, OptionReader(options));
        },
        py::arg("path"), py::arg("options"));
    m.def("trace_from_columns", &from_columns, py::arg("columns"), py::arg("options"));
    m.def("synth", &synth, py::arg("options"));
    m.def(
        "demo_drive", [](bool rotary) { return to_python(spec_to_json(rotary ? rotary_demo_spec() : demo_spec())); },
        py::arg("rotary") = false);
    m.def("plan", &plan, py::arg("options"));
}

}  // namespace feedid::python
