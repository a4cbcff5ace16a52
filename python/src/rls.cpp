// feedid.Rls: the fixed-size RLS of rls.hpp for 1 to 8 parameters, one sample at a time or a whole array at once
// (the loop in C++, without the GIL). Each Rls has a lock of its own: update_many runs without the GIL, so two Python
// threads could otherwise update one estimator at once and interleave their samples; with the lock, each call is
// whole, and two threads give the result of one order or the other.
#include <mutex>
#include <variant>

#include <fmt/core.h>

#include "binding.hpp"
#include "feedid/core/error.hpp"
#include "feedid/numeric/rls.hpp"

namespace feedid::python {

namespace {

constexpr int max_parameters = 8;

template <int... N>
std::variant<Rls<N>...> rls_variant(std::integer_sequence<int, N...>);
using AnyRls = decltype(rls_variant(std::integer_sequence<int, 1, 2, 3, 4, 5, 6, 7, 8>{}));

template <int N>
AnyRls make_rls(int n, const RlsOptions& options, const double* initial) {
    if (n != N) {
        if constexpr (N < max_parameters) return make_rls<N + 1>(n, options, initial);
    }
    typename Rls<N>::Vector start = Rls<N>::Vector::Zero();
    if (initial != nullptr)
        for (int i = 0; i < N; ++i) start(i) = initial[i];
    return Rls<N>(options, start);
}

const char* update_name(RlsUpdate update) {
    switch (update) {
        case RlsUpdate::updated: return "updated";
        case RlsUpdate::no_excitation: return "no_excitation";
        case RlsUpdate::non_finite: return "non_finite";
    }
    return "non_finite";
}

/// Samples skipped by update_many, counted per reason.
struct UpdateCounts {
    std::size_t updated{0};
    std::size_t no_excitation{0};
    std::size_t non_finite{0};
};

class PyRls {
public:
    PyRls(int n, double forgetting_factor, double initial_covariance, const std::string& variant,
          const py::object& initial_estimate) {
        if (n < 1 || n > max_parameters)
            throw InputError(fmt::format("Rls: n={} parameters; 1 to {} are supported", n, max_parameters));
        RlsOptions options;
        options.forgetting_factor = forgetting_factor;
        options.initial_covariance = initial_covariance;
        if (variant == "directional")
            options.variant = RlsVariant::directional;
        else if (variant == "exponential" || variant == "paper")
            options.variant = RlsVariant::exponential;
        else
            throw InputError(fmt::format("Rls: variant='{}': 'directional' or 'exponential'", variant));
        if (!(forgetting_factor > 0.0 && forgetting_factor <= 1.0))
            throw InputError(fmt::format("Rls: forgetting_factor={}: must be in (0, 1]", forgetting_factor));
        if (!(initial_covariance > 0.0 && std::isfinite(initial_covariance)))
            throw InputError(
                fmt::format("Rls: initial_covariance={}: must be positive and finite", initial_covariance));
        std::vector<double> start;
        if (!initial_estimate.is_none()) start = finite_vector_of(initial_estimate, "initial_estimate", n);
        n_ = n;
        rls_ = make_rls<1>(n, options, start.empty() ? nullptr : start.data());
    }

    [[nodiscard]] int n() const { return n_; }

    std::string update(const py::object& phi, double y) {
        const auto values = vector_of(phi, "phi", n_);
        const auto lock = acquire();
        return std::visit(
            [&](auto& rls) {
                using Vector = typename std::decay_t<decltype(rls)>::Vector;
                return update_name(rls.update(Eigen::Map<const Vector>(values.data()), y));
            },
            rls_);
    }

    /// Phi (m x n) and Y (m): every row in order. Returns the estimate after each row when `history`.
    py::object update_many(const py::object& phi_object, const py::object& y_object, bool history) {
        using Rows = py::array_t<double, py::array::c_style | py::array::forcecast>;
        const Rows phi = Rows::ensure(phi_object);
        const Rows y = Rows::ensure(y_object);
        if (!phi || !y) throw InputError("Rls.update_many: Phi and Y must be arrays of numbers");
        if (phi.ndim() != 2 || phi.shape(1) != n_) {
            throw InputError(fmt::format("Rls.update_many: Phi must have shape (m, {}), not {}", n_,
                                         py::str(phi.attr("shape")).cast<std::string>()));
        }
        if (y.ndim() != 1 || y.shape(0) != phi.shape(0)) {
            throw InputError(fmt::format("Rls.update_many: Y must have shape ({},), not {}", phi.shape(0),
                                         py::str(y.attr("shape")).cast<std::string>()));
        }
        const auto rows = static_cast<std::size_t>(phi.shape(0));
        py::array_t<double> estimates;
        double* out = nullptr;
        if (history) {
            estimates = py::array_t<double>({phi.shape(0), static_cast<py::ssize_t>(n_)});
            out = estimates.mutable_data();
        }
        UpdateCounts counts;
        {
            // the lock is taken and released without the GIL: a thread waiting for it never blocks the others
            py::gil_scoped_release release;
            const std::lock_guard lock(mutex_);
            std::visit([&](auto& rls) { counts = run(rls, phi.data(), y.data(), rows, out); }, rls_);
            last_counts_ = counts;
        }
        if (history) return estimates;
        return py::none();
    }

    [[nodiscard]] py::array_t<double> estimate() const {
        const auto lock = acquire();
        return std::visit(
            [&](const auto& rls) {
                py::array_t<double> out(n_);
                for (int i = 0; i < n_; ++i) out.mutable_at(i) = rls.estimate()(i);
                return out;
            },
            rls_);
    }

    [[nodiscard]] py::array_t<double> covariance() const {
        const auto lock = acquire();
        return std::visit(
            [&](const auto& rls) {
                py::array_t<double> out({n_, n_});
                for (int i = 0; i < n_; ++i)
                    for (int j = 0; j < n_; ++j) out.mutable_at(i, j) = rls.covariance()(i, j);
                return out;
            },
            rls_);
    }

    [[nodiscard]] std::size_t updates() const {
        const auto lock = acquire();
        return std::visit([](const auto& rls) { return rls.updates(); }, rls_);
    }
    [[nodiscard]] bool wound_up() const {
        const auto lock = acquire();
        return std::visit([](const auto& rls) { return rls.wound_up(); }, rls_);
    }
    [[nodiscard]] RlsOptions options() const {
        return std::visit([](const auto& rls) { return rls.options(); }, rls_);
    }
    void reset(const py::object& initial_estimate) {
        std::vector<double> start(static_cast<std::size_t>(n_), 0.0);
        if (!initial_estimate.is_none()) start = finite_vector_of(initial_estimate, "initial_estimate", n_);
        const auto lock = acquire();
        std::visit(
            [&](auto& rls) {
                using Vector = typename std::decay_t<decltype(rls)>::Vector;
                rls.reset(Eigen::Map<const Vector>(start.data()));
            },
            rls_);
    }
    [[nodiscard]] py::dict last_counts() const {
        UpdateCounts counts;
        {
            const auto lock = acquire();
            counts = last_counts_;
        }
        py::dict out;
        out["updated"] = counts.updated;
        out["no_excitation"] = counts.no_excitation;
        out["non_finite"] = counts.non_finite;
        return out;
    }

private:
    /// This estimator's lock, taken with the GIL released (so that a thread waiting for it lets the others run,
    /// among them the one that holds it and needs the GIL to return).
    [[nodiscard]] std::unique_lock<std::mutex> acquire() const {
        std::unique_lock lock(mutex_, std::defer_lock);
        if (!lock.try_lock()) {
            py::gil_scoped_release release;
            lock.lock();
        }
        return lock;
    }

    static std::vector<double> finite_vector_of(const py::object& object, const char* name, int n) {
        auto values = vector_of(object, name, n);
        for (const double value : values)
            if (!std::isfinite(value)) throw InputError(fmt::format("Rls: {} holds a value that is not finite", name));
        return values;
    }

    static std::vector<double> vector_of(const py::object& object, const char* name, int n) {
        using Values = py::array_t<double, py::array::c_style | py::array::forcecast>;
        const Values values = Values::ensure(object);
        if (!values || values.ndim() != 1 || values.shape(0) != n) {
            throw InputError(fmt::format("Rls: {} must be {} numbers (shape ({},))", name, n, n));
        }
        return {values.data(), values.data() + n};
    }

    template <class Estimator>
    static UpdateCounts run(Estimator& rls, const double* phi, const double* y, std::size_t rows, double* out) {
        using Vector = typename Estimator::Vector;
        constexpr int N = Vector::RowsAtCompileTime;
        UpdateCounts counts;
        for (std::size_t k = 0; k < rows; ++k) {
            switch (rls.update(Eigen::Map<const Vector>(phi + k * N), y[k])) {
                case RlsUpdate::updated: ++counts.updated; break;
                case RlsUpdate::no_excitation: ++counts.no_excitation; break;
                case RlsUpdate::non_finite: ++counts.non_finite; break;
            }
            if (out != nullptr)
                for (int i = 0; i < N; ++i) out[k * N + static_cast<std::size_t>(i)] = rls.estimate()(i);
        }
        return counts;
    }

    int n_{1};
    AnyRls rls_;
    UpdateCounts last_counts_;
    mutable std::mutex mutex_;
};

}  // namespace

void bind_rls(py::module_& m) {
    py::class_<PyRls>(m, "Rls",
                      R"doc(Recursive least squares for 1 to 8 parameters, y = phi' * theta + noise: the fixed-size,
allocation-free estimator of feedid's step 1 (rls.hpp).

``variant="exponential"`` (or ``"paper"``) is the paper's eq. (7)-(9): L = P*phi/(lambda + phi'*P*phi),
theta += L*(y - phi'*theta), P = (I - L*phi')*P/lambda; with lambda < 1 and data that do not excite every direction
its covariance winds up (``wound_up``); and its update of P, as written, amplifies P's round-off by 1/lambda per
sample: over 10^5 samples and more with lambda < 1 the estimate drifts away (measured: 200,000 samples of 3
parameters at lambda 0.9999). ``"directional"`` (the default) forgets only along the regressor (Kulhavy 1987), keeps P
exactly symmetric and stays bounded: use it for long streams. Units are those of phi and y (theta in y per phi).

``update(phi, y)`` takes one sample; ``update_many(Phi, Y)`` takes m samples at once (Phi: m x n, Y: m) and runs the
loop in C++ without the GIL (other Python threads run meanwhile); Phi and Y are converted to C-ordered float64 first
when they are not. Each Rls has a lock: calls from several threads on one Rls each run whole, one after the other (two
update_many calls give the result of one order or the other, never a mix). A sample with a value that is not finite is skipped (``"non_finite"``); one with no excitation
changes nothing (``"no_excitation"``); ``last_counts`` counts them for the last ``update_many``.

Example::

    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> Phi = np.column_stack([rng.normal(size=10000), np.sign(rng.normal(size=10000))])    # a [m/s^2], sgn v
    >>> Y = Phi @ [69.1, 742.8] + rng.normal(scale=5.0, size=10000)                      # force [N]
    >>> rls = feedid.Rls(2, forgetting_factor=1.0)
    >>> rls.update_many(Phi, Y)
    >>> np.round(rls.estimate, 1)                                                        # M [kg], F_C [N]
    array([ 69.1, 742.8])
)doc")
        .def(py::init<int, double, double, const std::string&, const py::object&>(), py::arg("n"),
             py::arg("forgetting_factor") = RlsOptions{}.forgetting_factor,
             py::arg("initial_covariance") = RlsOptions{}.initial_covariance, py::arg("variant") = "directional",
             py::arg("initial_estimate") = py::none(),
             "n parameters (1 to 8); lambda in (0, 1]; P(0) = initial_covariance * I; theta(0) = initial_estimate "
             "(zeros)")
        .def_property_readonly("n", &PyRls::n, "Number of parameters")
        .def("update", &PyRls::update, py::arg("phi"), py::arg("y"),
             "One sample (phi: n numbers, y: a number); returns 'updated', 'no_excitation' or 'non_finite'")
        .def("update_many", &PyRls::update_many, py::arg("Phi"), py::arg("Y"), py::kw_only(),
             py::arg("history") = false,
             "m samples in order (Phi: m x n, Y: m), the loop in C++ without the GIL; with history=True returns the "
             "estimate after each sample (m x n), else None")
        .def_property_readonly("estimate", &PyRls::estimate, "theta (a copy, n numbers)")
        .def_property_readonly("covariance", &PyRls::covariance, "P (a copy, n x n)")
        .def_property_readonly("updates", &PyRls::updates, "Samples that updated the estimate since the start or reset")
        .def_property_readonly("wound_up", &PyRls::wound_up,
                               "The exponential variant's covariance grew past 1e150 or overflowed")
        .def_property_readonly(
            "forgetting_factor", [](const PyRls& r) { return r.options().forgetting_factor; }, "lambda")
        .def_property_readonly(
            "initial_covariance", [](const PyRls& r) { return r.options().initial_covariance; }, "P(0) / I")
        .def_property_readonly(
            "variant",
            [](const PyRls& r) {
                return r.options().variant == RlsVariant::exponential ? "exponential" : "directional";
            },
            "'directional' or 'exponential'")
        .def_property_readonly("last_counts", &PyRls::last_counts,
                               "The last update_many's samples: {'updated', 'no_excitation', 'non_finite'}")
        .def("reset", &PyRls::reset, py::arg("initial_estimate") = py::none(),
             "Starts again: theta = initial_estimate (zeros; finite numbers), P = P(0)")
        .def("__repr__", [](const PyRls& r) {
            return fmt::format("<feedid.Rls n={}, {} forgetting {}, {} updates>", r.n(),
                               r.options().variant == RlsVariant::exponential ? "exponential" : "directional",
                               r.options().forgetting_factor, r.updates());
        });
}

}  // namespace feedid::python
