// identify and its Result (with the pipeline's typed stage records), gains, simulate: each as the command line runs
// it, so that a document made here equals the one `feedid ... --json` writes.
#include <fmt/core.h>

#include "binding.hpp"
#include "feedid/core/error.hpp"
#include "feedid/identify/brief_report.hpp"
#include "feedid/identify/fingerprint.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/identify/option_names.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/io/json_input.hpp"
#include "feedid/sim/simulate.hpp"
#include "feedid/sim/twin.hpp"

namespace feedid::python {

namespace {

// ---- options

/// `kt_Nm_per_A`, `lead_mm`, `gear_ratio`, `force_constant` (a number, or the name of a scalar in the file), and how
/// the command line records them.
DriveConstants drive_constants(const OptionReader& o, nlohmann::json& record) {
    DriveConstants drive;
    // the allowed ranges of drive.hpp, stated as the command line states them (cli.cpp)
    const Range kt_range{allowed_torque_constant_Nm_per_A.low, allowed_torque_constant_Nm_per_A.high, "N*m/A"};
    const Range lead_range{allowed_lead_m.low * 1e3, allowed_lead_m.high * 1e3, "mm"};
    const Range gear_range{allowed_gear_ratio.low, allowed_gear_ratio.high, "motor turns per screw turn"};
    drive.torque_constant_Nm_per_A = o.number("kt_Nm_per_A", kt_range);
    if (const auto lead = o.number("lead_mm", lead_range)) drive.lead_m = *lead * 1e-3;
    drive.gear_ratio = o.number("gear_ratio", gear_range).value_or(drive.gear_ratio);
    std::string force_constant;
    if (o.given("force_constant")) {
        const py::object value = o.object("force_constant");
        if (py::isinstance<py::str>(value)) {
            force_constant = value.cast<std::string>();
            drive.force_constant_name = force_constant;
        } else {
            drive.force_constant = o.number("force_constant");
            force_constant = fmt::format("{}", *drive.force_constant);
        }
    }
    if (const auto problem = drive.validate(); !problem.empty()) throw InputError(problem);
    const auto optional = [](const std::optional<double>& value) {
        return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
    };
    record = {{"kt_Nm_per_A", optional(o.number("kt_Nm_per_A"))},
              {"lead_mm", optional(o.number("lead_mm"))},
              {"gear_ratio", drive.gear_ratio},
              {"force_constant", force_constant}};
    return drive;
}

/// The value named by option `name` (the command line's names, option_names.hpp); `fallback` when not given.
template <class Enum, std::size_t N>
Enum choice(const OptionReader& o, const char* name, Enum fallback, const std::array<NamedChoice<Enum>, N>& choices) {
    const auto text = o.text(name);
    if (!text) return fallback;
    if (const auto value = value_named(choices, *text)) return *value;
    std::string names;
    for (const auto& key : names_of(choices)) names += fmt::format("{}'{}'", names.empty() ? "" : ", ", key);
    throw InputError(fmt::format("{}='{}': one of {}", name, *text, names));
}

void preprocess_options(const OptionReader& o, PreprocessOptions& p) {
    p.differentiation = choice(o, "differentiation", p.differentiation, differentiation_names);
    p.velocity_source = choice(o, "velocity_source", p.velocity_source, velocity_source_names);
    const auto integer = [&](const char* name, int fallback, Range range) {
        return static_cast<int>(o.integer(name, range).value_or(fallback));
    };
    // the allowed ranges are the command line's (cmd_identify.cpp)
    p.filter_order = integer("filter_order", p.filter_order, {1, 12, ""});
    p.cutoff_hz = o.number("cutoff_hz", {1e-3, 1e6, "Hz"});
    p.savitzky_golay_window = integer("savitzky_golay_window", p.savitzky_golay_window, {5, 1e6, "samples"});
    p.savitzky_golay_order = integer("savitzky_golay_order", p.savitzky_golay_order, {2, 6, ""});
    p.decimation = integer("decimation", p.decimation, {0, 1000, ""});
    if (const auto edge = o.integer("edge_samples", {0, 1e9, "samples"}))
        p.edge_samples = static_cast<std::size_t>(*edge);
    p.from_s = o.number("from_s", {-1e12, 1e12, "s"});
    p.to_s = o.number("to_s", {-1e12, 1e12, "s"});
}

/// The options of `feedid identify` from the keyword arguments of feedid.identify, and the command line's record of
/// the drive constants.
IdentifyOptions identify_options(const OptionReader& o, nlohmann::json& drive_record) {
    IdentifyOptions options;
    // as the command line: model "auto" and offset=None leave the model to the data; a model or an offset given
    // forces it
    const auto model = o.text("model");
    const auto offset = o.flag("offset");
    const bool automatic_model = !model || *model == automatic_model_name;
    if (!automatic_model) options.model = choice(o, "model", options.model, friction_model_names);
    options.offset = offset.value_or(options.offset);
    options.model_selection.automatic = automatic_model && !offset;
    if (o.given("delay") && py::isinstance<py::str>(o.object("delay"))) {
        const auto delay = o.text("delay");
        if (*delay == "auto")
            options.model_selection.delay = ModelSelectionOptions::Delay::estimate;
        else if (*delay == "none")
            options.model_selection.delay = ModelSelectionOptions::Delay::none;
        else
            throw InputError(fmt::format("delay='{}': 'auto', 'none' or a delay in seconds", *delay));
    } else if (const auto seconds = o.number("delay", {-1.0, 1.0, "s"})) {
        options.model_selection.known_delay_s = *seconds;
    }
    options.stribeck = o.flag("stribeck").value_or(options.stribeck);
    options.systematic = o.flag("systematic").value_or(options.systematic);
    if (const auto threads = o.integer("threads", {0, 1024, ""})) options.threads = static_cast<unsigned>(*threads);
    options.drive = drive_constants(o, drive_record);
    preprocess_options(o, options.preprocess);
    options.selection.split_velocity = o.number("split_velocity", {0.0, 1e4, "m/s or rad/s"});
    options.selection.moving_threshold = o.number("moving_threshold", {0.0, 1e4, "m/s or rad/s"});
    options.step1.rls.variant = choice(o, "rls", options.step1.rls.variant, rls_variant_names);
    if (const auto lambda = o.number("forgetting_factor", {1e-6, 1.0, ""}))
        options.step1.rls.forgetting_factor = *lambda;
    if (const auto p0 = o.number("initial_covariance", {1e-12, 1e12, ""})) options.step1.rls.initial_covariance = *p0;
    if (const auto problem = options.validate(); !problem.empty()) throw InputError(problem);
    return options;
}

IdentifyResult identify(py::handle trace_argument_object, const py::dict& kwargs) {
    const OptionReader o(kwargs);
    nlohmann::json drive_record;
    const IdentifyOptions options = identify_options(o, drive_record);
    std::optional<PyTrace> storage;
    const PyTrace& trace = trace_argument(trace_argument_object, o, storage);
    IdentifyResult result;
    {
        py::gil_scoped_release release;
        result = feedid::identify(trace.trace, options);
    }
    // As `feedid identify` records them: what shaped the result, with the reading options under their own keys.
    nlohmann::json command_line = trace.read_options;
    command_line["drive"] = drive_record;
    result.options = identify_options_document(options, command_line);
    return result;
}

// ---- the Result and its records

template <class Record, class Member>
py::object optional_record(py::object self, const std::optional<Member> Record::*member) {
    const auto& record = self.cast<const Record&>();
    const auto& value = record.*member;
    if (!value) return py::none();
    return py::cast(&*value, py::return_value_policy::reference_internal, self);
}

py::dict keyed_numbers(const std::vector<std::string>& keys, const std::vector<double>& values) {
    py::dict out;
    for (std::size_t c = 0; c < keys.size() && c < values.size(); ++c) out[py::str(keys[c])] = values[c];
    return out;
}

std::string result_failure(const IdentifyResult& r) {
    std::string lines;
    for (const auto& d : r.diagnostics) lines += (lines.empty() ? "" : "\n") + d;
    return lines;
}

// The records of what the pipeline read and which samples it kept.
void bind_input_records(py::module_& m) {
    py::class_<TraceSummary>(m, "TraceSummary",
                             "The trace a result came from: path, format, samples, sample_time_s [s], duration_s [s]")
        .def_readonly("path", &TraceSummary::path)
        .def_readonly("format", &TraceSummary::format)
        .def_readonly("samples", &TraceSummary::samples)
        .def_readonly("sample_time_s", &TraceSummary::sample_time_s)
        .def_readonly("duration_s", &TraceSummary::duration_s);
    py::class_<PreprocessReport>(
        m, "PreprocessReport",
        "What preprocessing used (defaults resolved): differentiation, filter_order, cutoff_hz [Hz], decimation, "
        "edge_samples [samples], velocity_source ('position' or 'velocity')")
        .def_readonly("differentiation", &PreprocessReport::differentiation)
        .def_readonly("filter_order", &PreprocessReport::filter_order)
        .def_readonly("cutoff_hz", &PreprocessReport::cutoff_hz)
        .def_readonly("decimation", &PreprocessReport::decimation)
        .def_readonly("savitzky_golay_window", &PreprocessReport::savitzky_golay_window)
        .def_readonly("savitzky_golay_order", &PreprocessReport::savitzky_golay_order)
        .def_readonly("edge_samples", &PreprocessReport::edge_samples)
        .def_readonly("velocity_source", &PreprocessReport::velocity_source);
    py::class_<SelectionReport>(
        m, "SelectionReport",
        "The samples each step used [counts: total, window, moving, step1, step2], moving_threshold and split_velocity "
        "[m/s or rad/s], and notes saying why samples were dropped")
        .def_readonly("total", &SelectionReport::total)
        .def_readonly("window", &SelectionReport::window)
        .def_readonly("moving", &SelectionReport::moving)
        .def_readonly("step1", &SelectionReport::step1)
        .def_readonly("step2", &SelectionReport::step2)
        .def_readonly("passes", &SelectionReport::passes)
        .def_readonly("stick_slip_passes", &SelectionReport::stick_slip_passes)
        .def_readonly("stick_slip_samples", &SelectionReport::stick_slip_samples)
        .def_readonly("clipped", &SelectionReport::clipped)
        .def_readonly("near_rest", &SelectionReport::near_rest)
        .def_readonly("initial_split_velocity", &SelectionReport::initial_split)
        .def_readonly("moving_threshold", &SelectionReport::moving_threshold)
        .def_readonly("split_velocity", &SelectionReport::split_velocity)
        .def_readonly("notes", &SelectionReport::notes);
}

// The records of step 1: the batch fit and the RLS.
void bind_step1_records(py::module_& m) {
    py::class_<Step1Report>(m, "Step1Report",
                            "Step 1's batch QR fit: batch (key -> Estimate [SI]), relative_error_pct [%], "
                            "condition_number, samples_used, residual_std [N or N*m], r_diagonal (|diag R|)")
        .def_property_readonly("batch",
                               [](const Step1Report& s) {
                                   py::dict out;
                                   for (std::size_t c = 0; c < s.keys.size(); ++c) out[py::str(s.keys[c])] = s.batch[c];
                                   return out;
                               })
        .def_readonly("relative_error_pct", &Step1Report::relative_error_pct)
        .def_readonly("condition_number", &Step1Report::condition_number)
        .def_readonly("samples_used", &Step1Report::samples_used)
        .def_readonly("residual_std", &Step1Report::residual_std)
        .def_property_readonly("r_diagonal", [](const Step1Report& s) { return copy(s.r_diagonal); })
        .def_property_readonly(
            "white_noise_standard_error",
            [](const Step1Report& s) { return keyed_numbers(s.keys, s.white_noise_standard_error); },
            "key -> the textbook standard error sigma*sqrt(diag((Phi'Phi)^-1)) [SI], for published comparisons")
        .def_property_readonly(
            "correlation",
            [](const Step1Report& s) {
                const auto n = static_cast<py::ssize_t>(s.correlation.size());
                py::array_t<double> out({n, n});
                for (py::ssize_t i = 0; i < n; ++i)
                    for (py::ssize_t j = 0; j < n; ++j)
                        out.mutable_at(i, j) = s.correlation[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)];
                return out;
            },
            "The estimates' correlations, in the order of keys (0 x 0 when not estimated)")
        .def_readonly("keys", &Step1Report::keys, "The columns' parameter keys");
    py::class_<RlsReport>(
        m, "RlsReport",
        "Step 1's RLS: variant, forgetting_factor, initial_covariance; final and averaged estimates (key -> value "
        "[SI]); settled, transient_end_s [s]; history_time_s [s] and history (key -> array [SI]) for plots")
        .def_property_readonly("variant",
                               [](const RlsReport& r) {
                                   return r.options.variant == RlsVariant::exponential ? "exponential" : "directional";
                               })
        .def_property_readonly("forgetting_factor", [](const RlsReport& r) { return r.options.forgetting_factor; })
        .def_property_readonly("initial_covariance", [](const RlsReport& r) { return r.options.initial_covariance; })
        .def_property_readonly("final", [](const RlsReport& r) { return keyed_numbers(r.keys, r.final_estimate); })
        .def_property_readonly("averaged", [](const RlsReport& r) { return keyed_numbers(r.keys, r.averaged); })
        .def_readonly("settled", &RlsReport::settled)
        .def_readonly("transient_end_s", &RlsReport::transient_end_s)
        .def_property_readonly("history_time_s",
                               [](py::object self) { return view(self.cast<const RlsReport&>().history_time, self); })
        .def_property_readonly("history", [](py::object self) {
            const auto& r = self.cast<const RlsReport&>();
            py::dict out;
            for (std::size_t c = 0; c < r.keys.size() && c < r.history.size(); ++c)
                out[py::str(r.keys[c])] = view(r.history[c], self);
            return out;
        });
}

// The records of step 2: the log-linear Stribeck RLS per direction and the nonlinear curve fit.
void bind_step2_records(py::module_& m) {
    py::class_<LogLinearStribeck>(m, "LogLinearStribeck",
                                  "Step 2's log-linear RLS of one direction (eq. 12-14): breakaway [N or N*m], "
                                  "stribeck_velocity [m/s or rad/s], samples used and excluded")
        .def_readonly("breakaway", &LogLinearStribeck::breakaway)
        .def_readonly("stribeck_velocity", &LogLinearStribeck::stribeck_velocity)
        .def_readonly("samples_used", &LogLinearStribeck::used)
        .def_readonly("excluded_wrong_sign", &LogLinearStribeck::wrong_sign)
        .def_readonly("excluded_below_noise", &LogLinearStribeck::below_noise);
    py::class_<NonlinearFitReport>(
        m, "NonlinearFitReport",
        "Step 2's Levenberg-Marquardt fit of the friction curve: method, converged, relative_error_pct [%], "
        "residual_std [N or N*m], samples_used, function_evaluations")
        .def_readonly("method", &NonlinearFitReport::method)
        .def_readonly("converged", &NonlinearFitReport::converged)
        .def_readonly("relative_error_pct", &NonlinearFitReport::relative_error_pct)
        .def_readonly("residual_std", &NonlinearFitReport::residual_std)
        .def_readonly("samples_used", &NonlinearFitReport::samples_used)
        .def_readonly("function_evaluations", &NonlinearFitReport::function_evaluations);
    py::class_<StribeckReport>(m, "StribeckReport",
                               "Step 2: forward and reverse (LogLinearStribeck: F_B [N], v_s [m/s]; or None), "
                               "nonlinear (NonlinearFitReport or None)")
        .def_property_readonly("forward",
                               [](py::object self) {
                                   const auto& s = self.cast<const StribeckReport&>();
                                   return s.log_linear[0] ? py::cast(&*s.log_linear[0],
                                                                     py::return_value_policy::reference_internal, self)
                                                          : py::none();
                               })
        .def_property_readonly("reverse",
                               [](py::object self) {
                                   const auto& s = self.cast<const StribeckReport&>();
                                   return s.log_linear[1] ? py::cast(&*s.log_linear[1],
                                                                     py::return_value_policy::reference_internal, self)
                                                          : py::none();
                               })
        .def_property_readonly("nonlinear",
                               [](py::object self) { return optional_record(self, &StribeckReport::nonlinear); });
}

// The records around the estimates: the friction curve, the preprocessing family, the friction-only fallback.
void bind_friction_records(py::module_& m) {
    py::class_<FrictionCurvePoints>(m, "FrictionCurvePoints",
                                    "Quasi-static friction binned by speed: speed [m/s or rad/s], force (friction "
                                    "magnitude) [N or N*m], fitted (the identified curve at speed)")
        .def_property_readonly(
            "speed", [](py::object self) { return view(self.cast<const FrictionCurvePoints&>().speed, self); })
        .def_property_readonly(
            "force", [](py::object self) { return view(self.cast<const FrictionCurvePoints&>().force, self); })
        .def_property_readonly(
            "fitted", [](py::object self) { return view(self.cast<const FrictionCurvePoints&>().fitted, self); });
    py::class_<FrictionCurveReport>(
        m, "FrictionCurveReport",
        "The friction curve per direction: forward, reverse (FrictionCurvePoints: speed [m/s], force [N]; or None)")
        .def_property_readonly("forward",
                               [](py::object self) { return optional_record(self, &FrictionCurveReport::forward); })
        .def_property_readonly("reverse",
                               [](py::object self) { return optional_record(self, &FrictionCurveReport::reverse); });
    py::class_<SystematicVariant>(m, "SystematicVariant",
                                  "One preprocessing of the family: label, status, and each parameter's estimate "
                                  "(key -> value [SI], None where undetermined)")
        .def_readonly("label", &SystematicVariant::label)
        .def_property_readonly("status", [](const SystematicVariant& v) { return to_string(v.status); })
        .def_property_readonly("parameters", [](const SystematicVariant& v) {
            py::dict out;
            for (std::size_t c = 0; c < v.keys.size() && c < v.values.size(); ++c)
                out[py::str(v.keys[c])] = v.values[c];
            return out;
        });
    py::class_<SystematicReport>(m, "SystematicReport",
                                 "The preprocessing family that gives each parameter's systematic uncertainty [SI of "
                                 "each key]: variants (SystematicVariant)")
        .def_readonly("variants", &SystematicReport::variants);
    py::class_<FrictionOnlyReport>(m, "FrictionOnlyReport",
                                   "Why the mass could not be identified (reason, in figures) and the steady-speed "
                                   "friction fit: samples_used, relative_error_pct [%], residual_std [N or N*m], "
                                   "rejected_samples (by the robust weights)")
        .def_readonly("reason", &FrictionOnlyReport::reason)
        .def_readonly("samples_used", &FrictionOnlyReport::samples_used)
        .def_readonly("relative_error_pct", &FrictionOnlyReport::relative_error_pct)
        .def_readonly("residual_std", &FrictionOnlyReport::residual_std)
        .def_readonly("rejected_samples", &FrictionOnlyReport::rejected_samples);
}

void bind_records(py::module_& m) {
    bind_input_records(m);
    bind_step1_records(m);
    bind_step2_records(m);
    bind_friction_records(m);
}

// Result: what it is (status, model, parameters with their units and symbols) and where it came from.
void add_result_summary(py::class_<IdentifyResult>& cls) {
    cls.def_property_readonly(
        "status", [](const IdentifyResult& r) { return to_string(r.status); },
        "'ok'; 'partial' when some parameters are None (each with a diagnostic); 'failed'");
    cls.def_property_readonly("model", &IdentifyResult::model_name, "'symmetric' or 'asymmetric'");
    cls.def_readonly("offset", &IdentifyResult::offset, "Whether a force offset F_0 was estimated");
    cls.def_readonly("rotary", &IdentifyResult::rotary, "A rotary axis (inertia, torques)");
    cls.def_readonly("feedid_version", &IdentifyResult::feedid_version, "The version that identified it");
    cls.def_readonly("diagnostics", &IdentifyResult::diagnostics, "What the data could not tell, and why");
    cls.def_property_readonly(
        "trace",
        [](py::object self) {
            return py::cast(&self.cast<const IdentifyResult&>().trace, py::return_value_policy::reference_internal,
                            self);
        },
        "The trace it came from: path, format, samples, sample_time_s [s], duration_s [s]");
    cls.def_property_readonly(
        "parameters",
        [](const IdentifyResult& r) {
            py::dict out;
            for (const auto& p : r.parameters) out[py::str(p.key)] = p.estimate;
            return out;
        },
        "Key -> Estimate, in the model's order (M; B, F_C per direction; F_0; F_B, v_s per direction)");
    cls.def_property_readonly(
        "units",
        [](const IdentifyResult& r) {
            py::dict out;
            for (const auto& p : r.parameters) out[py::str(p.key)] = p.unit;
            return out;
        },
        "Key -> unit ('kg', 'N*s/m', ...)");
    cls.def_property_readonly(
        "symbols",
        [](const IdentifyResult& r) {
            py::dict out;
            for (const auto& p : r.parameters) out[py::str(p.key)] = p.symbol;
            return out;
        },
        "Key -> symbol ('M', 'B', 'F_C+', ...)");
}

// Result: the pipeline's stage records, None where it did not get there.
void add_result_stages(py::class_<IdentifyResult>& cls) {
    cls.def_property_readonly(
        "preprocessing", [](py::object self) { return optional_record(self, &IdentifyResult::preprocessing); },
        "PreprocessReport: the differentiation, cut-off [Hz], decimation and edge trim used");
    cls.def_property_readonly(
        "selection", [](py::object self) { return optional_record(self, &IdentifyResult::selection); },
        "SelectionReport: the samples each step used [counts], thresholds [m/s], notes");
    cls.def_property_readonly(
        "step1", [](py::object self) { return optional_record(self, &IdentifyResult::step1); },
        "Step1Report: the batch QR fit (estimates, relative error [%], condition number)");
    cls.def_property_readonly(
        "rls", [](py::object self) { return optional_record(self, &IdentifyResult::rls); },
        "RlsReport: the RLS run (final and averaged estimates, transient, history over time)");
    cls.def_property_readonly(
        "stribeck", [](py::object self) { return optional_record(self, &IdentifyResult::stribeck); },
        "StribeckReport: step 2 (log-linear RLS per direction, the nonlinear curve fit)");
    cls.def_property_readonly(
        "friction_curve", [](py::object self) { return optional_record(self, &IdentifyResult::friction_curve); },
        "FrictionCurveReport: quasi-static friction per direction, binned by speed, with the fitted curve");
    cls.def_property_readonly(
        "friction_only", [](py::object self) { return optional_record(self, &IdentifyResult::friction_only); },
        "FrictionOnlyReport: why the mass could not be identified (None when it could)");
    cls.def_property_readonly(
        "systematic", [](py::object self) { return optional_record(self, &IdentifyResult::systematic); },
        "SystematicReport: the preprocessing family's estimates (None with systematic=False)");
}

// Result: the options, the failure text, the document both ways and the repr.
void add_result_documents(py::class_<IdentifyResult>& cls) {
    cls.def_property_readonly(
        "options", [](const IdentifyResult& r) { return to_python(r.options); },
        "The options that shaped the result, as the command line records them");
    cls.def_property_readonly(
        "failure",
        [](const IdentifyResult& r) -> py::object {
            if (r.status != Status::failed) return py::none();
            return py::str(result_failure(r));
        },
        "For a failed result, what the command line prints (its diagnostics, one per line); None otherwise");
    cls.def(
        "to_dict", [](const IdentifyResult& r) { return to_python(nlohmann::json(r)); },
        "The result document of feedid identify --json (plain dicts, lists, floats; None for null)");
    cls.def(
        "to_json", [](const IdentifyResult& r, int indent) { return nlohmann::json(r).dump(indent) + "\n"; },
        py::arg("indent") = 2, "The result document as feedid identify --json writes it");
    cls.def_static(
        "from_dict",
        [](py::handle document) {
            IdentifyResult r;
            from_json(to_json_value(document, "result"), r);
            return r;
        },
        py::arg("document"), "A result read back from its document (what feedid identify --json wrote)");
    // the lines feedid identify prints first: the trace, model and status, and the parameter table
    cls.def("__repr__", [](const IdentifyResult& r) {
        std::string text = brief_report(r);
        while (!text.empty() && text.back() == '\n') text.pop_back();
        return text;
    });
}

void bind_result(py::module_& m) {
    py::class_<IdentifyResult> cls(m, "Result",
                                   R"doc(An identification (:func:`feedid.identify`): the parameters, each an
:class:`Estimate` in the SI unit its key names (``mass_kg`` [kg], ``viscous_Ns_per_m`` [N*s/m], ``coulomb_N`` [N],
``breakaway_N`` [N], ``stribeck_velocity_m_per_s`` [m/s], ``offset_N`` [N]; per direction ``coulomb_forward_N``, ...;
rotary ``inertia_kgm2``, ``coulomb_Nm``, ...), the pipeline's stage records (``preprocessing``, ``selection``,
``step1``, ``rls``, ``stribeck``, ``friction_curve``, ``friction_only``; None where the pipeline did not get there)
and the diagnostics. ``to_dict()`` is the document ``feedid identify --json`` writes, key for key.

Example::

    >>> result = feedid.identify(EMPS, channels={"position": "qm", "current": "vir"}, force_constant="gtau",
    ...                          offset=True)
    >>> result.status, result.symbols["viscous_Ns_per_m"], result.units["viscous_Ns_per_m"]
    ('partial', 'B', 'N*s/m')
    >>> result.parameters["breakaway_N"].value is None      # EMPS has no slow passes; a diagnostic says so
    True
    >>> round(result.step1.condition_number, 1), round(result.preprocessing.cutoff_hz, 6)
    (26.1, 100.0)
    >>> sorted(result.to_dict()["parameters"]) == sorted(result.parameters)
    True
)doc");
    add_result_summary(cls);
    add_result_stages(cls);
    add_result_documents(cls);
}

// ---- gains and simulate

// The gain options as given; the allowed ranges are the command line's (gain_arguments.hpp).
GainOptions given_gain_options(const OptionReader& o) {
    GainOptions options;
    options.velocity_loop = choice(o, "velocity_loop", options.velocity_loop, velocity_loop_names);
    options.feedforward = o.flag("feedforward").value_or(options.feedforward);
    if (const auto n = o.integer("velocity_difference", {1, 8, "samples"}))
        options.velocity_difference_samples = static_cast<int>(*n);
    if (const auto lag = o.number("current_lag_ms", {0.0, 1000.0, "ms"})) options.current_lag_s = *lag * 1e-3;
    options.rls.forgetting_factor = o.number("forgetting", {1e-6, 1.0, ""}).value_or(options.rls.forgetting_factor);
    return options;
}

std::optional<double> saturation_option(const OptionReader& o) {
    return o.number("saturation", {1e-9, 1e12, "drive signal units"});
}

GainOptions gain_options(const OptionReader& o, const Trace& trace, const DriveConstants& drive) {
    GainOptions options = given_gain_options(o);
    set_drive_signal(options, trace, drive, saturation_option(o));
    if (const auto problem = options.validate(); !problem.empty()) throw InputError(problem);
    return options;
}

struct PyGains {
    GainResult result;
    nlohmann::json document;
};

PyGains gains(py::handle trace_argument_object, const py::dict& kwargs) {
    const OptionReader o(kwargs);
    nlohmann::json drive_record;
    const DriveConstants drive = drive_constants(o, drive_record);
    std::optional<PyTrace> storage;
    const Trace& trace = trace_argument(trace_argument_object, o, storage).trace;
    const GainOptions options = gain_options(o, trace, drive);
    PyGains out;
    {
        py::gil_scoped_release release;
        const std::vector<double> force = drive_force(trace, drive);
        const std::vector<double> injection = injection_force(trace, drive);
        out.result = identify_gains(trace, force, options, injection);
    }
    for (auto& warning : drive.warnings()) out.result.diagnostics.push_back(std::move(warning));
    out.document = gains_document(out.result, options, trace);
    return out;
}

void bind_gains(py::module_& m) {
    py::class_<PyGains> cls(m, "Gains",
                            R"doc(The controller's gains (:func:`feedid.gains`): position loop K_v [1/s], velocity loop
K_p [N*s/m; N*m*s/rad on a rotary axis] and K_i [N/m; N*m/rad], each an :class:`Estimate`, with the loop structure
found. ``to_dict()`` is the document ``feedid gains --json`` writes (with the gains per drive-signal unit).

Example::

    >>> g = feedid.gains(feedid.synth(seed=1, slow_passes=False), force_constant="force_constant_N_per_A")
    >>> round(g.position_gain_per_s.value, 2), g.status                    # the demo drive: 2 (m/min)/mm
    (33.33, 'ok')
)doc");
    cls.def_property_readonly("status", [](const PyGains& g) { return to_string(g.result.status); });
    cls.def_property_readonly("position_gain_per_s", [](const PyGains& g) { return g.result.position_gain_per_s; });
    cls.def_property_readonly("velocity_gain", [](const PyGains& g) { return g.result.velocity_gain_N_s_per_m; });
    cls.def_property_readonly("velocity_integral_gain",
                              [](const PyGains& g) { return g.result.velocity_integral_gain_N_per_m; });
    cls.def_property_readonly("velocity_feedforward", [](const PyGains& g) { return g.result.velocity_feedforward; });
    cls.def_property_readonly("reset_time_s", [](const PyGains& g) { return g.result.reset_time_s; });
    cls.def_property_readonly("method", [](const PyGains& g) { return g.result.method; });
    cls.def_property_readonly("velocity_difference_samples",
                              [](const PyGains& g) { return g.result.velocity_difference_samples; });
    cls.def_property_readonly("reference_delay_samples",
                              [](const PyGains& g) { return g.result.reference_delay_samples; });
    cls.def_property_readonly("drive_delay_samples", [](const PyGains& g) { return g.result.drive_delay_samples; });
    cls.def_property_readonly("current_lag_s", [](const PyGains& g) { return g.result.current_lag_s; });
    cls.def_property_readonly("setpoint_delay_s", [](const PyGains& g) { return g.result.setpoint_delay_s; });
    cls.def_property_readonly("relative_error_pct", [](const PyGains& g) { return g.result.relative_error_pct; });
    cls.def_property_readonly("systematic_error_pct", [](const PyGains& g) { return g.result.systematic_error_pct; });
    cls.def_property_readonly("samples_used", [](const PyGains& g) { return g.result.samples_used; });
    cls.def_property_readonly("injection_subtracted", [](const PyGains& g) { return g.result.injection_subtracted; });
    cls.def_property_readonly("diagnostics", [](const PyGains& g) { return g.result.diagnostics; });
    cls.def_property_readonly("failure", [](const PyGains& g) -> py::object {
        if (g.result.status != Status::failed || g.result.diagnostics.empty()) return py::none();
        return py::str(g.result.diagnostics.front());
    });
    cls.def("to_dict", [](const PyGains& g) { return to_python(g.document); });
    cls.def("__repr__", [](const PyGains& g) {
        return fmt::format("<feedid.Gains {} K_v {} 1/s, K_p {}>", to_string(g.result.status),
                           g.result.position_gain_per_s.value.value_or(NAN),
                           g.result.velocity_gain_N_s_per_m.value.value_or(NAN));
    });
}

/// A JSON document given as a dict, a path of a JSON file, or an object with to_dict() (a Result, Gains).
nlohmann::json document_argument(py::handle value, const char* name, std::string& source) {
    if (const auto path = as_path(value)) {
        source = *path;
        return read_json_file(*path);  // the command line's reader, with its limits
    }
    source = name;
    if (py::isinstance<IdentifyResult>(value)) return nlohmann::json(value.cast<const IdentifyResult&>());
    if (py::isinstance<PyGains>(value)) return value.cast<const PyGains&>().document;
    if (py::isinstance<py::dict>(value)) return to_json_value(value, name);
    throw InputError(fmt::format("{}: expected a feedid result, a dict or the path of a JSON document", name));
}

struct PySimulation {
    Twin twin;
    nlohmann::json document;
};

PySimulation simulate(py::handle trace_argument_object, py::handle result, py::handle gains_argument,
                      const py::dict& kwargs) {
    const OptionReader o(kwargs);
    std::string result_source, gains_source;
    const nlohmann::json result_document = document_argument(result, "result", result_source);
    std::optional<nlohmann::json> gains_document;
    if (!gains_argument.is_none()) gains_document = document_argument(gains_argument, "gains", gains_source);
    nlohmann::json drive_record;
    TwinOptions options;
    options.drive = drive_constants(o, drive_record);
    std::optional<PyTrace> storage;
    const Trace& trace = trace_argument(trace_argument_object, o, storage).trace;
    options.gains = given_gain_options(o);
    options.saturation = saturation_option(o);
    if (const auto substeps = o.integer("substeps", {1, 1000, "steps"}))
        options.simulation.substeps = static_cast<int>(*substeps);
    PySimulation out;
    {
        py::gil_scoped_release release;
        out.twin = run_twin(
            trace, {result_document, result_source},
            gains_document ? std::optional<TwinDocument>({*gains_document, gains_source}) : std::nullopt, options);
    }
    out.document = twin_document(trace, out.twin);
    return out;
}

void bind_simulation(py::module_& m) {
    py::class_<ValidationMetrics>(m, "ValidationMetrics",
                                  "How the simulated axis compares with the machine: relative errors [%] of position, "
                                  "velocity, acceleration and force; tracking and modelling errors [m, or rad on a "
                                  "rotary axis], mean absolute and largest")
        .def_readonly("position_relative_error_pct", &ValidationMetrics::position_relative_error_pct)
        .def_readonly("velocity_relative_error_pct", &ValidationMetrics::velocity_relative_error_pct)
        .def_readonly("acceleration_relative_error_pct", &ValidationMetrics::acceleration_relative_error_pct)
        .def_readonly("force_relative_error_pct", &ValidationMetrics::force_relative_error_pct)
        .def_readonly("tracking_error_mae_model", &ValidationMetrics::tracking_error_mae_model_m)
        .def_readonly("tracking_error_mae_machine", &ValidationMetrics::tracking_error_mae_machine_m)
        .def_readonly("modelling_error_mae", &ValidationMetrics::modelling_error_mae_m)
        .def_readonly("tracking_error_max_model", &ValidationMetrics::tracking_error_max_model_m)
        .def_readonly("tracking_error_max_machine", &ValidationMetrics::tracking_error_max_machine_m)
        .def_readonly("modelling_error_max", &ValidationMetrics::modelling_error_max_m);
    py::class_<PySimulation> cls(m, "Simulation", R"doc(The identified axis simulated in closed loop on the trace's
reference (:func:`feedid.simulate`): ``metrics`` (ValidationMetrics), ``signals`` (numpy arrays [SI] at the sample
instants), ``to_pandas()``, and ``to_dict()``, the document ``feedid simulate --json`` writes.

Example::

    >>> trace = feedid.synth(seed=1, slow_passes=False)
    >>> result = feedid.identify(trace, force_constant="force_constant_N_per_A")
    >>> sim = feedid.simulate(trace, result, force_constant="force_constant_N_per_A")
    >>> sim.metrics.position_relative_error_pct < 0.1, sorted(sim.signals)[:3]
    (True, ['acceleration', 'force', 'force_command'])
)doc");
    cls.def_property_readonly("status", [](const PySimulation& s) { return to_string(s.twin.status); });
    cls.def_property_readonly("metrics", [](py::object self) {
        return py::cast(&self.cast<const PySimulation&>().twin.simulation.metrics,
                        py::return_value_policy::reference_internal, self);
    });
    cls.def_property_readonly("injected", [](const PySimulation& s) { return s.twin.simulation.injected; });
    cls.def_property_readonly("diagnostics", [](const PySimulation& s) { return s.twin.diagnostics(); });
    cls.def_property_readonly("failure", [](const PySimulation& s) -> py::object {
        if (s.twin.status != Status::failed) return py::none();
        return py::str(s.twin.failure);
    });
    cls.def_property_readonly("signals", [](py::object self) {
        const auto& out = self.cast<const PySimulation&>().twin.simulation.output;
        py::dict signals;
        const std::pair<const char*, const std::vector<double>*> columns[] = {
            {"time", &out.time},
            {"reference", &out.reference},
            {"position", &out.position},
            {"measured_position", &out.measured_position},
            {"velocity", &out.velocity},
            {"acceleration", &out.acceleration},
            {"velocity_command", &out.velocity_command},
            {"force_command", &out.force_command},
            {"force", &out.force},
            {"tracking_error", &out.tracking_error}};
        for (const auto& [name, values] : columns) signals[name] = view(*values, self);
        return signals;
    });
    cls.def("to_dict", [](const PySimulation& s) { return to_python(s.document); });
    cls.def("__repr__", [](const PySimulation& s) {
        return fmt::format("<feedid.Simulation position {:.4g} %, force {:.4g} %>",
                           s.twin.simulation.metrics.position_relative_error_pct,
                           s.twin.simulation.metrics.force_relative_error_pct);
    });
}

// feedid.fingerprint: the document `feedid fingerprint --json` writes, as a dict.
py::object fingerprint_of(py::handle trace_argument_object, const py::dict& kwargs) {
    const OptionReader o(kwargs);
    nlohmann::json drive_record;
    FingerprintOptions options;
    options.drive = drive_constants(o, drive_record);
    if (const auto settle = o.number("settle_s", {0.0, 10.0, "s"})) options.settle_s = *settle;
    std::optional<PyTrace> storage;
    const Trace& trace = trace_argument(trace_argument_object, o, storage).trace;
    FingerprintResult result;
    {
        py::gil_scoped_release release;
        result = fingerprint(trace, options);
    }
    return to_python(fingerprint_document(result));
}

}  // namespace

void bind_analysis(py::module_& m) {
    bind_records(m);
    bind_result(m);
    bind_gains(m);
    bind_simulation(m);
    m.def("identify", &identify, py::arg("trace"), py::arg("options"));
    m.def("gains", &gains, py::arg("trace"), py::arg("options"));
    m.def("simulate", &simulate, py::arg("trace"), py::arg("result"), py::arg("gains"), py::arg("options"));
    m.def("fingerprint", &fingerprint_of, py::arg("trace"), py::arg("options"));
}

}  // namespace feedid::python
