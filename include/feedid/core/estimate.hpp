#pragma once
// A value with its standard error, and how it travels as JSON: {"value": v, "stderr": s}, null where the data cannot
// tell. The one place where an optional number is read from or written to a document.

#include <cmath>
#include <optional>

#include <nlohmann/json.hpp>

// std::optional<T> <-> JSON null or T, the serializer nlohmann's documentation prescribes for third-party types
// (its own support arrived after the 3.11 that Debian 12 ships).
namespace nlohmann {
template <class T>
struct adl_serializer<std::optional<T>> {
    static void to_json(json& j, const std::optional<T>& value) {
        if (value)
            j = *value;
        else
            j = nullptr;
    }
    static void from_json(const json& j, std::optional<T>& value) {
        if (j.is_null())
            value.reset();
        else
            value = j.get<T>();
    }
};
}  // namespace nlohmann

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

/// {"value": v, "stderr": s} and, where assessed, "systematic" and "uncertainty".
inline void to_json(nlohmann::json& j, const Estimate& estimate) {
    j = nlohmann::json{{"value", estimate.value}, {"stderr", estimate.standard_error}};
    if (estimate.systematic) j["systematic"] = *estimate.systematic;
    if (estimate.uncertainty) j["uncertainty"] = *estimate.uncertainty;
}

/// Reads {"value": v|null, "stderr": s|null, "systematic": .., "uncertainty": ..}; a missing key is null. Throws
/// nlohmann::json::exception on a value that is neither a number nor null.
inline void from_json(const nlohmann::json& j, Estimate& estimate) {
    const auto optional = [&](const char* key) {
        return j.contains(key) ? j.at(key).get<std::optional<double>>() : std::optional<double>{};
    };
    estimate.value = j.at("value").get<std::optional<double>>();
    estimate.standard_error = optional("stderr");
    estimate.systematic = optional("systematic");
    estimate.uncertainty = optional("uncertainty");
}

}  // namespace feedid
