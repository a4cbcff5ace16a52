#pragma once
// A value with its standard error, null where the data cannot tell. How it travels as JSON ({"value": v, "stderr": s})
// is json_adapters.hpp's.

#include <cmath>
#include <optional>

namespace feedid {

/// A value with its standard error; both null when the data cannot determine them. An identified parameter also
/// carries the systematic part of its uncertainty (how far the estimate moves over a documented family of reasonable
/// preprocessing choices) and the combined uncertainty sqrt(standard_error^2 + systematic^2).
struct Estimate {
    std::optional<double> value;
    std::optional<double> standard_error;  ///< statistical (from the fit's residuals)
    std::optional<double> systematic{};    ///< spread over the preprocessing family; null where not assessed
    std::optional<double> uncertainty{};   ///< combined; null where not assessed

    /// The estimate of a computation: a non-finite value or standard error becomes null.
    static Estimate of(double value, double standard_error) {
        Estimate e;
        if (std::isfinite(value)) e.value = value;
        if (std::isfinite(standard_error)) e.standard_error = standard_error;
        return e;
    }
    [[nodiscard]] bool determined() const { return value.has_value(); }
    /// The uncertainty to judge the value by: the combined one where assessed, else the standard error.
    [[nodiscard]] std::optional<double> total_uncertainty() const { return uncertainty ? uncertainty : standard_error; }
    /// Sets the systematic part and the combined uncertainty sqrt(standard_error^2 + systematic^2) (a non-finite
    /// systematic part leaves both null).
    void set_systematic(double spread) {
        if (!value || !std::isfinite(spread)) return;
        systematic = spread;
        const double statistical = standard_error.value_or(0.0);
        uncertainty = std::hypot(statistical, spread);
    }
};

}  // namespace feedid
