#pragma once
// Reading JSON documents given by users (results, gains, simulations, drive files) with limits, so that no document
// can crash feedid or exhaust its memory: at most `max_depth` levels of nesting, at most `max_bytes` bytes, and every
// number within the range of a double. A document beyond a limit is refused with an InputError naming the source,
// the key (as a path: options.rls.forgetting_factor, series.time_s[12]) and the limit.

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"

namespace feedid {

/// The text is not JSON at all (as opposed to a JSON document beyond a limit or of the wrong shape).
class JsonSyntaxError : public InputError {
public:
    using InputError::InputError;
};

struct JsonLimits {
    std::size_t max_depth{64};                 ///< objects and arrays nested in each other, the outermost counting 1
    std::size_t max_bytes{64u * 1024 * 1024};  ///< the document's size [bytes]
};

/// Parses `text` as one JSON document. JsonSyntaxError "SOURCE: not a JSON document (byte N)" on a syntax error, and
/// naming the key on a document nested too deep, too large, or with a number outside the range of a double (1e400,
/// an integer of 5,000 digits).
nlohmann::json parse_json(std::string_view text, const std::string& source, const JsonLimits& limits = {});

/// Reads and parses a file ("-": standard input) with parse_json(); a file larger than the limit is refused before
/// it is read.
nlohmann::json read_json_file(const std::string& path, const JsonLimits& limits = {});

/// The path of a key for messages: "parameters.mass_kg.value", "series.time_s[3]"; long paths keep their first
/// and last keys ("options.a.b.c. … .y.z").
std::string json_key_path(const std::vector<std::string>& keys);

/// What a value is, for messages: "null", "an object", "an array", "a string", "true or false", "a number".
const char* json_type_name(const nlohmann::json& value);

/// A value inside a document with its key path, for readers that check every type against the schema they read:
/// each accessor throws InputError "PATH: must be EXPECTED, not TYPE" ("rotary: must be true or false, not a
/// string", "parameters.mass_kg.value: must be a number or null, not a string"). Callers put the source in front.
class JsonField {
public:
    JsonField(const nlohmann::json& value, std::string path) : value_(&value), path_(std::move(path)) {}

    [[nodiscard]] const nlohmann::json& json() const { return *value_; }
    [[nodiscard]] const std::string& path() const { return path_; }
    /// True when this is an object holding `key`.
    [[nodiscard]] bool has(const std::string& key) const;
    /// The member `key` of an object; "PATH.KEY: is missing" when absent.
    [[nodiscard]] JsonField at(const std::string& key) const;
    /// The member `key`, or nothing when this object lacks it.
    [[nodiscard]] std::optional<JsonField> find(const std::string& key) const;
    /// This value, checked to be an object / an array.
    const JsonField& object() const;
    const JsonField& array() const;

    [[nodiscard]] double number() const;                          ///< a number; null reads as NaN
    [[nodiscard]] std::optional<double> optional_number() const;  ///< a number or null
    [[nodiscard]] std::size_t count() const;                      ///< a whole number >= 0
    [[nodiscard]] int integer() const;                            ///< a whole number within the range of int
    [[nodiscard]] bool boolean() const;
    [[nodiscard]] std::string text() const;
    [[nodiscard]] std::vector<double> numbers() const;  ///< an array of numbers (null reads as NaN)
    [[nodiscard]] std::vector<std::string> texts() const;
    [[nodiscard]] std::vector<std::pair<std::string, JsonField>> members() const;  ///< of an object, in order
    [[nodiscard]] std::vector<JsonField> elements() const;                         ///< of an array

    /// InputError "PATH: must be EXPECTED, not TYPE".
    [[noreturn]] void wrong(const std::string& expected) const;

private:
    const nlohmann::json* value_;
    std::string path_;
};

}  // namespace feedid
