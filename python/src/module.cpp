// feedid._feedid: the native layer of the Python module. This file: the module, its exceptions, Estimate, and the
// conversions the other files share (JSON <-> Python, options, numpy views).
#include <array>
#include <cmath>
#include <exception>

#include <fmt/core.h>

#include "binding.hpp"
#include "feedid/core/error.hpp"
#include "feedid/core/estimate.hpp"
#include "feedid/core/json_adapters.hpp"
#include "feedid/core/version.hpp"

namespace feedid::python {

// ---- JSON <-> Python

py::object to_python(const nlohmann::json& value) {
    switch (value.type()) {
        case nlohmann::json::value_t::null: return py::none();
        case nlohmann::json::value_t::boolean: return py::bool_(value.get<bool>());
        case nlohmann::json::value_t::number_integer: return py::int_(value.get<std::int64_t>());
        case nlohmann::json::value_t::number_unsigned: return py::int_(value.get<std::uint64_t>());
        case nlohmann::json::value_t::number_float: {
            const double number = value.get<double>();
            return std::isfinite(number) ? py::object(py::float_(number)) : py::object(py::none());
        }
        case nlohmann::json::value_t::string: return py::str(value.get_ref<const std::string&>());
        case nlohmann::json::value_t::array: {
            py::list list;
            for (const auto& element : value) list.append(to_python(element));
            return list;
        }
        case nlohmann::json::value_t::object: {
            py::dict dict;
            for (const auto& [key, element] : value.items()) dict[py::str(key)] = to_python(element);
            return dict;
        }
        default: return py::none();  // binary and discarded values: never in feedid's documents
    }
}

nlohmann::json to_json_value(py::handle value, const std::string& what) {
    if (value.is_none()) return nullptr;
    if (py::isinstance<py::bool_>(value)) return value.cast<bool>();
    if (py::isinstance<py::int_>(value)) return value.cast<long long>();
    if (py::isinstance<py::float_>(value)) return value.cast<double>();
    if (py::isinstance<py::str>(value)) return value.cast<std::string>();
    if (py::isinstance<py::dict>(value)) {
        nlohmann::json object = nlohmann::json::object();
        for (const auto& [key, element] : value.cast<py::dict>()) {
            if (!py::isinstance<py::str>(key))
                throw InputError(
                    fmt::format("{}: a key that is not a string ({})", what, py::repr(key).cast<std::string>()));
            const auto name = key.cast<std::string>();
            object[name] = to_json_value(element, what + "." + name);
        }
        return object;
    }
    if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
        nlohmann::json array = nlohmann::json::array();
        for (const auto& element : value) array.push_back(to_json_value(element, what));
        return array;
    }
    // numpy scalars and anything else with a float value
    if (py::hasattr(value, "__float__") && !py::isinstance<py::bytes>(value)) return value.cast<double>();
    throw InputError(fmt::format("{}: {} is not a JSON value", what, py::repr(value).cast<std::string>()));
}

// ---- options

std::optional<std::string> as_path(py::handle value) {
    if (py::isinstance<py::str>(value)) return value.cast<std::string>();
    const auto os = py::module_::import("os");
    if (py::isinstance(value, os.attr("PathLike"))) return os.attr("fspath")(value).cast<std::string>();
    return std::nullopt;
}

namespace {
std::string type_name(py::handle value) {
    return py::type::handle_of(value).attr("__name__").cast<std::string>();
}

[[noreturn]] void wrong_type(const char* name, py::handle value, const char* expected) {
    throw InputError(fmt::format("{}={}: expected {}, not {}", name, py::repr(value).cast<std::string>(), expected,
                                 type_name(value)));
}
}  // namespace

bool OptionReader::given(const char* name) const {
    return options_.contains(name) && !options_[name].is_none();
}

py::object OptionReader::object(const char* name) const {
    return options_.contains(name) ? py::object(options_[name]) : py::object(py::none());
}

std::optional<double> OptionReader::number(const char* name) const {
    if (!given(name)) return std::nullopt;
    const py::object value = options_[name];
    if (py::isinstance<py::bool_>(value) || py::isinstance<py::str>(value) || !py::hasattr(value, "__float__"))
        wrong_type(name, value, "a number");
    const double number = value.cast<double>();
    // no option takes nan or an infinity (the command line refuses them while parsing)
    if (!std::isfinite(number))
        throw InputError(fmt::format("{}={}: not a finite number", name, py::repr(value).cast<std::string>()));
    return number;
}

void check_range(const char* name, double value, const std::string& text, Range range) {
    if (!range.contains(value)) throw InputError(fmt::format("{}={}", name, range.refusal(text)));
}

std::optional<double> OptionReader::number(const char* name, Range range) const {
    const auto value = number(name);
    if (value) check_range(name, *value, py::repr(options_[name]).cast<std::string>(), range);
    return value;
}

std::optional<long long> OptionReader::integer(const char* name, Range range) const {
    const auto value = integer(name);
    if (value) check_range(name, static_cast<double>(*value), std::to_string(*value), range);
    return value;
}

std::optional<long long> OptionReader::integer(const char* name) const {
    if (!given(name)) return std::nullopt;
    const py::object value = options_[name];
    if (py::isinstance<py::bool_>(value) || !py::hasattr(value, "__index__")) wrong_type(name, value, "an integer");
    return value.cast<long long>();
}

std::optional<bool> OptionReader::flag(const char* name) const {
    if (!given(name)) return std::nullopt;
    const py::object value = options_[name];
    if (!py::isinstance<py::bool_>(value) && !py::hasattr(value, "__bool__")) wrong_type(name, value, "True or False");
    return value.cast<bool>();
}

std::optional<std::string> OptionReader::text(const char* name) const {
    if (!given(name)) return std::nullopt;
    const py::object value = options_[name];
    if (!py::isinstance<py::str>(value)) wrong_type(name, value, "a str");
    return value.cast<std::string>();
}

std::optional<std::string> OptionReader::path(const char* name) const {
    if (!given(name)) return std::nullopt;
    const py::object value = options_[name];
    auto text = as_path(value);
    if (!text) wrong_type(name, value, "a path (str or os.PathLike)");
    return text;
}

std::vector<std::string> OptionReader::texts(const char* name) const {
    std::vector<std::string> out;
    if (!given(name)) return out;
    const py::object value = options_[name];
    if (py::isinstance<py::str>(value)) return {value.cast<std::string>()};
    if (!py::isinstance<py::sequence>(value)) wrong_type(name, value, "a str or a sequence of str");
    for (const auto& element : value) {
        if (!py::isinstance<py::str>(element)) wrong_type(name, value, "a sequence of str");
        out.push_back(element.cast<std::string>());
    }
    return out;
}

std::vector<std::pair<std::string, std::string>> OptionReader::text_map(const char* name) const {
    std::vector<std::pair<std::string, std::string>> out;
    if (!given(name)) return out;
    const py::object value = options_[name];
    if (!py::isinstance<py::dict>(value) && !py::hasattr(value, "items")) wrong_type(name, value, "a dict of str");
    for (const auto& item : value.attr("items")()) {
        const auto pair = item.cast<py::tuple>();
        if (!py::isinstance<py::str>(pair[0]))
            throw InputError(
                fmt::format("{}: a key that is not a str ({})", name, py::repr(pair[0]).cast<std::string>()));
        const auto key = pair[0].cast<std::string>();
        if (!py::isinstance<py::str>(pair[1])) {
            throw InputError(fmt::format("{}['{}']={}: expected a str, not {}", name, key,
                                         py::repr(pair[1]).cast<std::string>(), type_name(pair[1])));
        }
        out.emplace_back(key, pair[1].cast<std::string>());
    }
    return out;
}

// ---- numpy

py::array_t<double> view(const std::vector<double>& values, py::handle owner) {
    if (values.empty()) return py::array_t<double>(0);
    py::array_t<double> array({values.size()}, {sizeof(double)}, values.data(), owner);
    py::detail::array_proxy(array.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    return array;
}

py::array_t<double> copy(const std::vector<double>& values) {
    py::array_t<double> array(static_cast<py::ssize_t>(values.size()));
    std::copy(values.begin(), values.end(), array.mutable_data());
    return array;
}

// ---- exceptions and Estimate

namespace {

// The Python exception classes (feedid._errors), held for the life of the interpreter.
PyObject* input_error_type = nullptr;
PyObject* identification_error_type = nullptr;

void raise(PyObject* type, const char* message) {
    const py::object instance = py::reinterpret_borrow<py::object>(type)(message);
    PyErr_SetObject(type, instance.ptr());
}

// The fields of feedid::Estimate, in one place: a field added to the C++ struct is one line here, and the Python
// Estimate takes it as a keyword and a positional argument, an attribute, in repr, equality and pickling.
// (to_dict() is the C++ struct's JSON, so a new field's key is there as soon as the struct writes it.)
struct EstimateField {
    const char* name;
    std::optional<double> Estimate::*member;
};
constexpr std::array estimate_fields{
    EstimateField{"value", &Estimate::value},
    EstimateField{"standard_error", &Estimate::standard_error},
    EstimateField{"systematic", &Estimate::systematic},
    EstimateField{"uncertainty", &Estimate::uncertainty},
};

std::optional<double> optional_number(py::handle value, const char* field) {
    if (value.is_none()) return std::nullopt;
    if (py::isinstance<py::bool_>(value) || py::isinstance<py::str>(value) || !py::hasattr(value, "__float__"))
        throw InputError(fmt::format("Estimate: {} must be a number or None, not {}", field, type_name(value)));
    return value.cast<double>();
}

Estimate make_estimate(const py::args& args, const py::kwargs& kwargs) {
    if (args.size() > estimate_fields.size())
        throw InputError(
            fmt::format("Estimate takes at most {} values, {} given", estimate_fields.size(), args.size()));
    Estimate estimate;
    for (std::size_t i = 0; i < args.size(); ++i)
        estimate.*(estimate_fields[i].member) = optional_number(args[i], estimate_fields[i].name);
    for (const auto& [key, value] : kwargs) {
        const auto name = key.cast<std::string>();
        const auto* field = std::find_if(estimate_fields.begin(), estimate_fields.end(),
                                         [&](const EstimateField& f) { return name == f.name; });
        if (field == estimate_fields.end()) throw InputError(fmt::format("Estimate has no field '{}'", name));
        estimate.*(field->member) = optional_number(value, field->name);
    }
    return estimate;
}

std::string format_optional(const std::optional<double>& value) {
    return value ? py::repr(py::float_(*value)).cast<std::string>() : std::string("None");
}

void bind_estimate(py::module_& m) {
    py::class_<Estimate> estimate(m, "Estimate", R"doc(A value with its standard error, in the SI unit its key names.

Both are None where the data cannot determine the parameter (the result's diagnostics say why). The fields are
those of the C++ ``feedid::Estimate``; ``Estimate._fields`` lists them and ``to_dict()`` gives the result document's
``{"stderr": ..., "value": ...}`` entry.

Example::

    >>> import feedid
    >>> m = feedid.Estimate(95.11, 0.12)
    >>> m.value, m.standard_error
    (95.11, 0.12)
    >>> m.to_dict()
    {'stderr': 0.12, 'value': 95.11}
)doc");
    estimate.def(py::init(&make_estimate),
                 "Estimate(value=None, standard_error=None): the fields in order, or by name");
    for (const auto& field : estimate_fields) estimate.def_readonly(field.name, field.member);
    py::tuple names(estimate_fields.size());
    for (std::size_t i = 0; i < estimate_fields.size(); ++i) names[i] = py::str(estimate_fields[i].name);
    estimate.attr("_fields") = names;
    estimate.def_property_readonly(
        "determined", [](const Estimate& e) { return e.determined(); }, "True when the value is known");
    estimate.def(
        "to_dict", [](const Estimate& e) { return to_python(nlohmann::json(e)); },
        "The result document's entry: {'value': ..., 'stderr': ...}");
    estimate.def("__repr__", [](const Estimate& e) {
        std::string text = "Estimate(";
        for (std::size_t i = 0; i < estimate_fields.size(); ++i)
            text += fmt::format("{}{}={}", i ? ", " : "", estimate_fields[i].name,
                                format_optional(e.*(estimate_fields[i].member)));
        return text + ")";
    });
    estimate.def("__eq__", [](const Estimate& a, py::object other) -> py::object {
        if (!py::isinstance<Estimate>(other)) return py::reinterpret_borrow<py::object>(Py_NotImplemented);
        const auto& b = other.cast<const Estimate&>();
        for (const auto& field : estimate_fields)
            if (a.*(field.member) != b.*(field.member)) return py::bool_(false);
        return py::bool_(true);
    });
    estimate.attr("__hash__") = py::none();
    estimate.def("__reduce__", [](py::object self) {
        const auto& e = self.cast<const Estimate&>();
        py::tuple values(estimate_fields.size());
        for (std::size_t i = 0; i < estimate_fields.size(); ++i) values[i] = py::cast(e.*(estimate_fields[i].member));
        return py::make_tuple(py::type::of(self), values);
    });
}

}  // namespace

void bind_common(py::module_& m) {
    const auto errors = py::module_::import("feedid._errors");
    input_error_type = py::object(errors.attr("InputError")).release().ptr();
    identification_error_type = py::object(errors.attr("IdentificationError")).release().ptr();
    py::register_exception_translator([](std::exception_ptr thrown) {
        try {
            if (thrown) std::rethrow_exception(thrown);
        } catch (const InputError& e) {
            raise(input_error_type, e.what());
        } catch (const AnalysisError& e) {
            raise(identification_error_type, e.what());
        }
    });
    m.attr("__version__") = py::str(version);
    bind_estimate(m);
}

}  // namespace feedid::python

PYBIND11_MODULE(_feedid, m) {
    m.doc() = "feedid's native layer (pybind11); use the feedid package, which wraps it";
    feedid::python::bind_common(m);
    feedid::python::bind_trace(m);
    feedid::python::bind_analysis(m);
    feedid::python::bind_rls(m);
    feedid::python::bind_history(m);
    feedid::python::bind_defaults(m);
}
