#pragma once
// The Python module feedid._feedid (pybind11): what its translation units share. The public Python API (signatures,
// defaults, docstrings) is python/feedid/__init__.py; these functions are the native layer under it. Each takes the
// options as the Python wrapper passes them (a dict of keyword arguments) and reads them with OptionReader, which
// names an option of the wrong type in an InputError, as the command line names a bad option.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/io/config_file.hpp"
#include "feedid/io/import.hpp"
#include "feedid/core/trace.hpp"

namespace feedid::python {

namespace py = pybind11;

/// A JSON value as plain Python objects (dict, list, str, int, float, bool, None). A number that is not finite becomes
/// None, as nlohmann's dump writes it: the dict equals the document the command line prints.
py::object to_python(const nlohmann::json& value);
/// A Python value (dict, list, str, int, float, bool, None) as JSON; InputError naming `what` for anything else.
nlohmann::json to_json_value(py::handle value, const std::string& what);

/// The values an option allows, as the command line states them (apps/feedid: allowed_range) [the option's unit].
using Range = ValueRange;

/// The keyword arguments of one call, read by name with a type check: a wrong type is an InputError naming the
/// option; None reads as "not given". No number may be nan or infinite; one with a Range must lie in it.
class OptionReader {
public:
    explicit OptionReader(py::dict options) : options_(std::move(options)) {}

    [[nodiscard]] bool given(const char* name) const;
    [[nodiscard]] std::optional<double> number(const char* name) const;
    [[nodiscard]] std::optional<double> number(const char* name, Range range) const;
    [[nodiscard]] std::optional<long long> integer(const char* name) const;
    [[nodiscard]] std::optional<long long> integer(const char* name, Range range) const;
    [[nodiscard]] std::optional<bool> flag(const char* name) const;
    [[nodiscard]] std::optional<std::string> text(const char* name) const;
    /// A str or os.PathLike.
    [[nodiscard]] std::optional<std::string> path(const char* name) const;
    [[nodiscard]] std::vector<std::string> texts(const char* name) const;
    /// A mapping of str to str, in its iteration order.
    [[nodiscard]] std::vector<std::pair<std::string, std::string>> text_map(const char* name) const;
    [[nodiscard]] py::object object(const char* name) const;

private:
    py::dict options_;
};

/// InputError "NAME=VALUE is outside the allowed range LOW to HIGH UNIT" when `value` lies outside `range`.
void check_range(const char* name, double value, const std::string& text, Range range);

/// A str or os.PathLike as a path string; nullopt for anything else.
std::optional<std::string> as_path(py::handle value);

/// feedid.Trace: a trace in SI units, and how it was read (what the identify result document records of it).
struct PyTrace {
    Trace trace;
    /// The reading options as the command line records them in identify's "options": channels, units, axis, format,
    /// rated (and join, tare when used).
    nlohmann::json read_options = nlohmann::json::object();
};

/// The trace to analyse: a Trace as it is (no reading options may be given then), or a path read with the reading
/// options in `options` (channels, units, axis, format, sample_time_s, skip_rows, rated, join, join_max_shift_s, tare,
/// and the drive's lead_mm and gear_ratio for revolution speeds).
const PyTrace& trace_argument(py::handle trace, const OptionReader& options, std::optional<PyTrace>& storage);

/// A read-only numpy view of `values` that keeps `owner` alive.
py::array_t<double> view(const std::vector<double>& values, py::handle owner);
/// A numpy array holding a copy of `values`.
py::array_t<double> copy(const std::vector<double>& values);

void bind_common(py::module_& module);    // module.cpp: exceptions, Estimate
void bind_trace(py::module_& module);     // trace.cpp: Trace, read_trace, synth, plan
void bind_analysis(py::module_& module);  // analysis.cpp: identify and its Result, gains, simulate
void bind_rls(py::module_& module);       // rls.cpp: Rls
void bind_history(py::module_& module);   // history.cpp: History
void bind_defaults(py::module_& module);  // defaults.cpp: defaults(), the keyword defaults of the functions

}  // namespace feedid::python
