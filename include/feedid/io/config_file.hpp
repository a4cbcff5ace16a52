#pragma once
// Configuration files (drive files of `feedid synth`, machine files, watch.toml), JSON or TOML, read by one reader:
// TOML is converted to the JSON tree the same content written as JSON would give, and ConfigSection reads that tree
// with typed getters that check each value's type and range and remember the key, so that reject_unknown() refuses a
// key nobody read (a typo must not pass silently). Every message names the file and the key path:
//   "drive.toml: controller.tn_ms: must be a number, not a string"
//   "watch.toml: online.window_s: 1000 is outside the allowed range 0.1 to 600 s"
//   "machine.json: unknown key 'limits.X.jerk_m_per_s'"

#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/io/json_input.hpp"

namespace feedid {

/// The values a setting allows, in its unit, as every front-end states them.
struct ValueRange {
    double low{0.0};
    double high{0.0};
    const char* unit{""};  ///< "s", "Hz", "mm/min"; "" for a count

    [[nodiscard]] bool contains(double value) const { return value >= low && value <= high; }
    /// "VALUE is outside the allowed range LOW to HIGH UNIT" (numbers as %g), with the value as the user wrote it.
    [[nodiscard]] std::string refusal(std::string_view value) const;
};

/// TOML text as JSON: tables as objects, arrays as arrays, integers, floats, booleans and strings as themselves;
/// dates and times as their text (no setting takes one: a getter refuses them as a string). InputError "SOURCE:LINE:
/// not valid TOML: WHAT" on a syntax error, and as parse_json() for nesting beyond `limits` or a text beyond its size.
nlohmann::json parse_toml(std::string_view text, const std::string& source, const JsonLimits& limits = {});

/// A configuration file as JSON: TOML when its name ends in .toml, JSON (parse_json) otherwise.
nlohmann::json read_config_file(const std::filesystem::path& path, const JsonLimits& limits = {});

/// An object of a configuration file and its key path ("" at the top, "controller", "axes.X.test"). Each getter
/// takes its key as known; a key that is absent, or null in JSON, reads as not given. Every refusal is an InputError
/// "SOURCE: PATH.KEY: ...". The section refers to `object`, which must outlive it.
class ConfigSection {
public:
    /// InputError "SOURCE: PATH: must be an object (a TOML table), not TYPE" when `object` is not one.
    ConfigSection(const nlohmann::json& object, std::string source, std::string path = {});

    [[nodiscard]] const std::string& source() const { return source_; }
    [[nodiscard]] const std::string& path() const { return path_; }
    /// The key path of a member: "controller.tn_ms", at the top "seed".
    [[nodiscard]] std::string path(const std::string& key) const;
    [[nodiscard]] const nlohmann::json& json() const { return *object_; }
    /// The keys present, in the document's order.
    [[nodiscard]] std::vector<std::string> keys() const;

    /// Present and not null.
    [[nodiscard]] bool has(const std::string& key) const;
    /// Present as null (JSON only): "remove this", where a setting allows it.
    [[nodiscard]] bool is_null(const std::string& key) const;

    /// A finite number.
    std::optional<double> number(const std::string& key);
    /// A finite number within `range`.
    std::optional<double> number(const std::string& key, const ValueRange& range);
    /// Sets `target` to the number times `scale` (the unit's SI value: 1e-3 for "_ms") when given; true when it was.
    bool read(const std::string& key, double& target, double scale = 1.0);
    std::optional<bool> boolean(const std::string& key);
    std::optional<std::string> text(const std::string& key);
    /// A list of finite numbers.
    std::optional<std::vector<double>> numbers(const std::string& key);
    /// A nested object.
    std::optional<ConfigSection> section(const std::string& key);
    /// A list of objects (elements' paths KEY[0], KEY[1], ...); empty when not given.
    std::vector<ConfigSection> sections(const std::string& key);

    /// Takes a key as known without reading it (it is read elsewhere, or ignored: "$schema", "description").
    void accept(const std::string& key);
    /// InputError "SOURCE: unknown key 'PATH.KEY'" for the first key no getter took.
    void reject_unknown() const;
    /// InputError "SOURCE: PATH.KEY: WHAT" (`key` empty: "SOURCE: PATH: WHAT").
    [[noreturn]] void refuse(const std::string& key, const std::string& what) const;

private:
    const nlohmann::json* member(const std::string& key);

    const nlohmann::json* object_;
    std::string source_;
    std::string path_;
    std::set<std::string> known_;
};

}  // namespace feedid
