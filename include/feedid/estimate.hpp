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

/// A value with its standard error; both null when the data cannot determine them.
struct Estimate {
    std::optional<double> value;
    std::optional<double> standard_error;

    /// The estimate of a computation: a non-finite value or standard error becomes null.
    static Estimate of(double value, double standard_error) {
        Estimate e;
        if (std::isfinite(value)) e.value = value;
        if (std::isfinite(standard_error)) e.standard_error = standard_error;
        return e;
    }
    [[nodiscard]] bool determined() const { return value.has_value(); }
};

inline void to_json(nlohmann::json& j, const Estimate& estimate) {
    j = nlohmann::json{{"value", estimate.value}, {"stderr", estimate.standard_error}};
}

/// Reads {"value": v|null, "stderr": s|null}; a missing "stderr" is null. Throws nlohmann::json::exception on a
/// value that is neither a number nor null.
inline void from_json(const nlohmann::json& j, Estimate& estimate) {
    estimate.value = j.at("value").get<std::optional<double>>();
    estimate.standard_error =
        j.contains("stderr") ? j.at("stderr").get<std::optional<double>>() : std::optional<double>{};
}

}  // namespace feedid
