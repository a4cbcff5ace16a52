// feedid.History: the parameter history store (history/store.hpp), as `feedid identify --record` and `feedid history`
// use it.
#include <fmt/core.h>

#include "binding.hpp"
#include "feedid/core/error.hpp"
#include "feedid/history/record.hpp"
#include "feedid/history/store.hpp"
#include "feedid/history/trend.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/io/json_input.hpp"

namespace feedid::python {

namespace {

class PyHistory {
public:
    PyHistory(const py::object& path, bool read_only) {
        const auto text = as_path(path);
        if (!text)
            throw InputError(
                "History: expected the path of a history file or a postgresql:// location (str or os.PathLike)");
        path_ = *text;
        history::OpenOptions options;
        options.read_only = read_only;
        store_ = history::open_store(path_, options);
    }

    /// Records an identify result (a Result, its dict, or the path of its JSON document) as one run.
    py::tuple record(const py::object& result, const std::string& machine, const std::string& axis,
                     const py::object& trace, const std::string& location,
                     const std::optional<std::string>& recorded_at) {
        std::string source = "result";
        nlohmann::json document;
        if (py::isinstance<IdentifyResult>(result)) {
            document = nlohmann::json(result.cast<const IdentifyResult&>());
        } else if (py::isinstance<py::dict>(result)) {
            document = to_json_value(result, "result");
        } else if (const auto path = as_path(result)) {
            source = *path;
            document = read_json_file(*path);  // the command line's reader, with its limits
        } else {
            throw InputError("History.record: expected a feedid.Result, its dict or the path of its JSON document");
        }
        history::RecordContext context;
        context.machine = machine;
        context.axis = axis;
        context.location = location;
        if (recorded_at) context.recorded_at = *recorded_at;
        if (const auto problem = context.validate("History.record"); !problem.empty()) throw InputError(problem);
        if (trace.is_none()) {
            context.trace = history::trace_of_result(document, source);
        } else {
            const auto path = as_path(trace);
            if (!path) throw InputError("History.record: trace must be the path of the trace file");
            context.trace = *path;
        }
        if (document.contains("options") && document["options"].is_object()) context.options = document["options"];
        const auto run = history::prepare_run(document, source, context);
        const auto outcome = store().add_run(run);
        return py::make_tuple(outcome.id, outcome.inserted);
    }

    py::list runs(const std::string& machine, const std::string& axis, const std::string& location) const {
        py::list out;
        for (const auto& run : store().runs({machine, axis, location})) out.append(to_python(history::to_json(run)));
        return out;
    }

    py::list trends(const std::string& machine, const std::string& axis, const history::TrendOptions& options) const {
        py::list out;
        for (const auto& series : analyse(machine, axis, options)) out.append(to_python(history::to_json(series)));
        return out;
    }

    std::vector<std::string> check(const std::string& machine, const std::string& axis,
                                   const history::TrendOptions& options) const {
        std::vector<std::string> alarms;
        for (const auto& series : analyse(machine, axis, options))
            for (const auto& alarm : series.alarms) alarms.push_back(alarm.message());
        return alarms;
    }

    void pin(std::int64_t run_id) {
        const auto all = store().runs({});
        const auto found = std::find_if(all.begin(), all.end(), [&](const auto& run) { return run.id == run_id; });
        if (found == all.end())
            throw InputError(fmt::format("{}: there is no run #{}", history::shown_location(path_), run_id));
        store().pin_baseline(found->machine, found->axis, found->id);
    }

    [[nodiscard]] int schema_version() const { return store().schema_version(); }
    [[nodiscard]] const std::string& path() const { return path_; }
    void close() { store_.reset(); }
    [[nodiscard]] bool closed() const { return !store_; }

private:
    [[nodiscard]] history::HistoryStore& store() const {
        if (!store_) throw InputError(fmt::format("{}: the history is closed", history::shown_location(path_)));
        return *store_;
    }

    [[nodiscard]] std::vector<history::SeriesTrend> analyse(const std::string& machine, const std::string& axis,
                                                            const history::TrendOptions& options) const {
        if (const auto problem = options.validate(); !problem.empty()) throw InputError(problem);
        return history::analyse_trends(store().runs({machine, axis, ""}), store().pins(), options);
    }

    std::string path_;
    std::unique_ptr<history::HistoryStore> store_;
};

history::TrendOptions trend_options(int baseline_runs, double cusum_k, double cusum_h,
                                    std::optional<std::int64_t> baseline_from) {
    history::TrendOptions options;
    options.baseline_runs = baseline_runs;
    options.cusum_k = cusum_k;
    options.cusum_h = cusum_h;
    options.pinned_run = baseline_from;
    return options;
}

}  // namespace

void bind_history(py::module_& m) {
    const history::TrendOptions defaults;
    py::class_<PyHistory>(m, "History", R"doc(The parameter history of machines and axes: one SQLite file, or a
PostgreSQL database (``postgresql://user@host:port/db``, a plant's shared history), as ``feedid identify --record``
and ``feedid history`` use it. A run is recorded whole or not at all; the same trace
with the same options is recorded once; several processes may write at once. Parameters are stored in the SI unit
their keys name.

``check()`` gives the drift alarms ``feedid history --check`` prints (baseline: the first ``baseline_runs`` runs of an
axis, or from a pinned run; a two-sided CUSUM of each parameter's change in combined standard errors, allowance
``cusum_k``, decision interval ``cusum_h``); ``trends()`` the figures behind them.

Example::

    >>> result = feedid.identify(EMPS, channels={"position": "qm", "current": "vir"}, force_constant="gtau")
    >>> with feedid.History(DATABASE) as history:
    ...     run_id, added = history.record(result, machine="EMPS", axis="X", recorded_at="2019-01-01")
    ...     runs = history.runs(machine="EMPS")
    >>> added, runs[0]["parameters"]["mass_kg"]["value"] == result.parameters["mass_kg"].value
    (True, True)
)doc")
        .def(py::init<const py::object&, bool>(), py::arg("path"), py::kw_only(), py::arg("read_only") = false,
             "Opens (or creates) the history file or PostgreSQL database; InputError when it is not a feedid history")
        .def("record", &PyHistory::record, py::arg("result"), py::kw_only(), py::arg("machine"), py::arg("axis"),
             py::arg("trace") = py::none(), py::arg("location") = "", py::arg("recorded_at") = py::none(),
             "Records an identify result (a Result, its dict, or the path of its JSON) as a run of machine and axis; "
             "trace: the trace file (hashed; default: the result's trace path); recorded_at: ISO 8601 UTC (default: "
             "the trace file's modification time). Returns (run id, added): added is False when the same trace with "
             "the same options is recorded already")
        .def("runs", &PyHistory::runs, py::kw_only(), py::arg("machine") = "", py::arg("axis") = "",
             py::arg("location") = "",
             "The runs (as feedid history --json lists them), by recording time; empty filters match everything")
        .def(
            "trends",
            [](const PyHistory& h, const std::string& machine, const std::string& axis, int baseline_runs,
               double cusum_k, double cusum_h, std::optional<std::int64_t> baseline_from) {
                return h.trends(machine, axis, trend_options(baseline_runs, cusum_k, cusum_h, baseline_from));
            },
            py::kw_only(), py::arg("machine") = "", py::arg("axis") = "",
            py::arg("baseline_runs") = defaults.baseline_runs, py::arg("cusum_k") = defaults.cusum_k,
            py::arg("cusum_h") = defaults.cusum_h, py::arg("baseline_from") = py::none(),
            "Each axis's trend per parameter (as feedid history --json's 'trends'); cusum_k and cusum_h in combined "
            "standard errors")
        .def(
            "check",
            [](const PyHistory& h, const std::string& machine, const std::string& axis, int baseline_runs,
               double cusum_k, double cusum_h, std::optional<std::int64_t> baseline_from) {
                return h.check(machine, axis, trend_options(baseline_runs, cusum_k, cusum_h, baseline_from));
            },
            py::kw_only(), py::arg("machine") = "", py::arg("axis") = "",
            py::arg("baseline_runs") = defaults.baseline_runs, py::arg("cusum_k") = defaults.cusum_k,
            py::arg("cusum_h") = defaults.cusum_h, py::arg("baseline_from") = py::none(),
            "The drift alarms, one line each as feedid history --check prints them (empty: no alarm)")
        .def("pin", &PyHistory::pin, py::arg("run_id"),
             "After maintenance: the baseline of the run's machine and axis starts again at this run")
        .def_property_readonly("schema_version", &PyHistory::schema_version, "The store's schema version")
        .def_property_readonly("path", &PyHistory::path, "The history file")
        .def_property_readonly("closed", &PyHistory::closed, "Whether close() was called")
        .def("close", &PyHistory::close, "Closes the file (a with block does it)")
        .def("__enter__", [](py::object self) { return self; })
        .def("__exit__", [](PyHistory& h, const py::args&) { h.close(); })
        .def("__repr__", [](const PyHistory& h) {
            return fmt::format("<feedid.History '{}'{}>", h.path(), h.closed() ? " (closed)" : "");
        });
}

}  // namespace feedid::python
