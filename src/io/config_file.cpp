// Configuration files, JSON or TOML, through one reader (config_file.hpp).
#include "feedid/io/config_file.hpp"

#include <cmath>
#include <sstream>
#include <system_error>
#include <utility>

#include <fmt/core.h>
#include <toml++/toml.h>

#include "feedid/core/error.hpp"
#include "feedid/io/import.hpp"

namespace feedid {

std::string ValueRange::refusal(std::string_view value) const {
    const std::string shown_unit = *unit != '\0' ? std::string(" ") + unit : std::string();
    return fmt::format("{} is outside the allowed range {:g} to {:g}{}", value, low, high, shown_unit);
}

namespace {

// TOML values as JSON, counting the nesting as parse_json does (the document itself is level 1).
class TomlConverter {
public:
    TomlConverter(const std::string& source, const JsonLimits& limits) : source_(source), limits_(limits) {}

    nlohmann::json convert(const toml::node& node) {
        if (node.is_table() || node.is_array()) {
            if (keys_.size() + 1 > limits_.max_depth)
                throw InputError(fmt::format("{}: nested deeper than {} levels at {}", source_, limits_.max_depth,
                                             json_key_path(keys_)));
        }
        if (const auto* table = node.as_table()) {
            nlohmann::json object = nlohmann::json::object();
            for (const auto& [key, value] : *table) {
                keys_.emplace_back(key.str());
                object[std::string(key.str())] = convert(value);
                keys_.pop_back();
            }
            return object;
        }
        if (const auto* array = node.as_array()) {
            nlohmann::json list = nlohmann::json::array();
            for (std::size_t k = 0; k < array->size(); ++k) {
                keys_.push_back(fmt::format("[{}]", k));
                list.push_back(convert(*array->get(k)));
                keys_.pop_back();
            }
            return list;
        }
        if (const auto* integer = node.as_integer()) return integer->get();
        if (const auto* floating = node.as_floating_point()) return floating->get();
        if (const auto* boolean = node.as_boolean()) return boolean->get();
        if (const auto* text = node.as_string()) return text->get();
        // dates and times as their TOML text: no setting takes one, so a getter refuses it as a string
        std::ostringstream text;
        node.visit([&](const auto& value) { text << value; });
        return text.str();
    }

private:
    const std::string& source_;
    const JsonLimits& limits_;
    std::vector<std::string> keys_;
};

bool is_toml(const std::filesystem::path& path) {
    return path.extension() == ".toml";
}

}  // namespace

nlohmann::json parse_toml(std::string_view text, const std::string& source, const JsonLimits& limits) {
    if (text.size() > limits.max_bytes)
        throw InputError(
            fmt::format("{}: larger than {} MiB, the limit for a configuration file", source, limits.max_bytes >> 20));
    toml::table table;
    try {
        table = toml::parse(text, source);
    } catch (const toml::parse_error& e) {
        throw InputError(fmt::format("{}:{}: not valid TOML: {}", source, e.source().begin.line, e.description()));
    }
    return TomlConverter(source, limits).convert(table);
}

nlohmann::json read_config_file(const std::filesystem::path& path, const JsonLimits& limits) {
    std::error_code error;
    const auto size = std::filesystem::file_size(path, error);
    if (!error && size > limits.max_bytes)
        throw InputError(fmt::format("{}: larger than {} MiB, the limit for a configuration file", path.string(),
                                     limits.max_bytes >> 20));
    const std::string text = read_file_bytes(path);
    return is_toml(path) ? parse_toml(text, path.string(), limits) : parse_json(text, path.string(), limits);
}

// ---- ConfigSection

ConfigSection::ConfigSection(const nlohmann::json& object, std::string source, std::string path)
    : object_(&object), source_(std::move(source)), path_(std::move(path)) {
    if (!object.is_object())
        refuse("", fmt::format("must be an object (a TOML table), not {}", json_type_name(object)));
}

std::string ConfigSection::path(const std::string& key) const {
    if (key.empty()) return path_;
    return path_.empty() ? key : path_ + "." + key;
}

std::vector<std::string> ConfigSection::keys() const {
    std::vector<std::string> out;
    for (const auto& [key, value] : object_->items()) out.push_back(key);
    return out;
}

bool ConfigSection::has(const std::string& key) const {
    return object_->contains(key) && !(*object_)[key].is_null();
}

bool ConfigSection::is_null(const std::string& key) const {
    return object_->contains(key) && (*object_)[key].is_null();
}

void ConfigSection::refuse(const std::string& key, const std::string& what) const {
    const std::string where = path(key);
    throw InputError(where.empty() ? fmt::format("{}: {}", source_, what)
                                   : fmt::format("{}: {}: {}", source_, where, what));
}

const nlohmann::json* ConfigSection::member(const std::string& key) {
    known_.insert(key);
    return has(key) ? &(*object_)[key] : nullptr;
}

namespace {

std::optional<double> finite_number(const nlohmann::json& value) {
    if (!value.is_number()) return std::nullopt;
    const double number = value.get<double>();
    return std::isfinite(number) ? std::optional<double>(number) : std::nullopt;
}

std::string shown(const nlohmann::json& value) {
    return value.is_number() ? fmt::format("{}", value.get<double>()) : json_type_name(value);
}

}  // namespace

std::optional<double> ConfigSection::number(const std::string& key) {
    const auto* value = member(key);
    if (value == nullptr) return std::nullopt;
    const auto number = finite_number(*value);
    if (!number) refuse(key, fmt::format("must be a finite number, not {}", shown(*value)));
    return number;
}

std::optional<double> ConfigSection::number(const std::string& key, const ValueRange& range) {
    const auto value = number(key);
    if (value && !range.contains(*value)) refuse(key, range.refusal(fmt::format("{}", *value)));
    return value;
}

bool ConfigSection::read(const std::string& key, double& target, double scale) {
    const auto value = number(key);
    if (value) target = *value * scale;
    return value.has_value();
}

std::optional<bool> ConfigSection::boolean(const std::string& key) {
    const auto* value = member(key);
    if (value == nullptr) return std::nullopt;
    if (!value->is_boolean()) refuse(key, fmt::format("must be true or false, not {}", json_type_name(*value)));
    return value->get<bool>();
}

std::optional<std::string> ConfigSection::text(const std::string& key) {
    const auto* value = member(key);
    if (value == nullptr) return std::nullopt;
    if (!value->is_string()) refuse(key, fmt::format("must be a string, not {}", json_type_name(*value)));
    return value->get<std::string>();
}

std::optional<std::vector<double>> ConfigSection::numbers(const std::string& key) {
    const auto* value = member(key);
    if (value == nullptr) return std::nullopt;
    if (!value->is_array()) refuse(key, fmt::format("must be a list of numbers, not {}", json_type_name(*value)));
    std::vector<double> out;
    for (std::size_t k = 0; k < value->size(); ++k) {
        const auto number = finite_number((*value)[k]);
        if (!number)
            refuse(key, fmt::format("must be a list of finite numbers, not {} at [{}]", shown((*value)[k]), k));
        out.push_back(*number);
    }
    return out;
}

std::optional<ConfigSection> ConfigSection::section(const std::string& key) {
    const auto* value = member(key);
    if (value == nullptr) return std::nullopt;
    return ConfigSection(*value, source_, path(key));
}

std::vector<ConfigSection> ConfigSection::sections(const std::string& key) {
    std::vector<ConfigSection> out;
    const auto* value = member(key);
    if (value == nullptr) return out;
    if (!value->is_array()) refuse(key, fmt::format("must be a list of objects, not {}", json_type_name(*value)));
    for (std::size_t k = 0; k < value->size(); ++k)
        out.emplace_back((*value)[k], source_, path(key) + fmt::format("[{}]", k));
    return out;
}

void ConfigSection::accept(const std::string& key) {
    known_.insert(key);
}

void ConfigSection::reject_unknown() const {
    for (const auto& [key, value] : object_->items()) {
        if (!known_.contains(key)) throw InputError(fmt::format("{}: unknown key '{}'", source_, path(key)));
    }
}

}  // namespace feedid
