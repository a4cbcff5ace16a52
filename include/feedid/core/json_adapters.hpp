#pragma once
// How the core values travel in the documents feedid writes and reads: std::optional as null or its value, an Estimate
// as {"value": v, "stderr": s} (with "systematic" and "uncertainty" where assessed), a Status as "ok", "partial" or
// "failed". Included only where a document is written or read; estimate.hpp and status.hpp know nothing of JSON.
// The build defines JSON_DISABLE_ENUM_SERIALIZATION, so that a file that writes a Status without this header fails to
// compile instead of writing the enum's number.

#include <optional>

#include <nlohmann/json.hpp>

#include "feedid/core/estimate.hpp"
#include "feedid/core/status.hpp"

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

// An unknown string reads as the first entry: failed, never a silent "ok".
NLOHMANN_JSON_SERIALIZE_ENUM(Status, {{Status::failed, "failed"}, {Status::ok, "ok"}, {Status::partial, "partial"}})

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
