// JSON documents from users, parsed with limits (json_input.hpp): nlohmann's SAX parser drives a DOM builder that
// counts the nesting and keeps the path of keys for messages.
#include "feedid/io/json_input.hpp"

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <iterator>
#include <limits>
#include <system_error>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/core.h>

#include "feedid/core/error.hpp"

namespace feedid {
namespace {

using Json = nlohmann::json;

/// Builds the document as nlohmann's own DOM parser does, with the depth limit and the key path.
class LimitedDomBuilder {
public:
    LimitedDomBuilder(Json& root, const std::string& source, const JsonLimits& limits)
        : root_(root), source_(source), limits_(limits) {}

    bool null() { return value(nullptr); }
    bool boolean(bool v) { return value(v); }
    bool number_integer(Json::number_integer_t v) { return value(v); }
    bool number_unsigned(Json::number_unsigned_t v) { return value(v); }
    bool number_float(Json::number_float_t v, const Json::string_t& /*text*/) { return value(v); }
    bool string(Json::string_t& v) { return value(std::move(v)); }
    bool binary(Json::binary_t& v) { return value(std::move(v)); }
    bool start_object(std::size_t /*elements*/) { return open(Json::value_t::object); }
    bool start_array(std::size_t /*elements*/) { return open(Json::value_t::array); }
    bool end_object() { return close(); }
    bool end_array() { return close(); }
    bool key(Json::string_t& name) {
        frames_.back().key = name;
        element_ = &(*frames_.back().container)[name];
        return true;
    }

    bool parse_error(std::size_t position, const std::string& /*token*/, const nlohmann::detail::exception& error) {
        // 406: a number nlohmann cannot hold (1e400, an integer beyond the range of a double)
        if (error.id == 406)
            throw InputError(fmt::format("{}: the number at {} is out of range (byte {}; the largest is about 1.8e308)",
                                         source_, where_next(), position));
        throw JsonSyntaxError(fmt::format("{}: not a JSON document (byte {})", source_, position));
    }

private:
    struct Frame {
        Json* container{nullptr};
        std::string key;       // of the element being read, in an object
        std::size_t index{0};  // elements placed so far, in an array
    };

    /// The key path of the value about to be read: in each enclosing array the element that is open, in the
    /// innermost one the next.
    std::string where_next() const {
        std::vector<std::string> keys;
        for (std::size_t f = 0; f < frames_.size(); ++f) {
            const Frame& frame = frames_[f];
            const std::size_t index = f + 1 == frames_.size() ? frame.index : frame.index - 1;
            keys.push_back(frame.container->is_array() ? fmt::format("[{}]", index) : frame.key);
        }
        return keys.empty() ? std::string("the top level") : json_key_path(keys);
    }

    Json* place(Json&& v) {
        if (frames_.empty()) {
            root_ = std::move(v);
            return &root_;
        }
        Frame& frame = frames_.back();
        if (frame.container->is_array()) {
            frame.container->push_back(std::move(v));
            ++frame.index;
            return &frame.container->back();
        }
        *element_ = std::move(v);
        return element_;
    }

    bool value(Json&& v) {
        place(std::move(v));
        return true;
    }

    bool open(Json::value_t type) {
        if (frames_.size() + 1 > limits_.max_depth)
            throw InputError(
                fmt::format("{}: nested deeper than {} levels at {}", source_, limits_.max_depth, where_next()));
        Json* container = place(Json(type));
        frames_.push_back({container, {}, 0});
        return true;
    }

    bool close() {
        frames_.pop_back();
        return true;
    }

    Json& root_;
    const std::string& source_;
    const JsonLimits& limits_;
    std::vector<Frame> frames_;
    Json* element_{nullptr};
};

std::string too_large(const std::string& source, std::size_t limit) {
    return fmt::format("{}: larger than {} MiB, the limit for a JSON document", source, limit / (1024 * 1024));
}

}  // namespace

std::string json_key_path(const std::vector<std::string>& keys) {
    const auto join = [&](std::size_t begin, std::size_t end) {
        std::string text;
        for (std::size_t i = begin; i < end; ++i) {
            if (!text.empty() && !keys[i].starts_with("[")) text += '.';
            text += keys[i];
        }
        return text;
    };
    constexpr std::size_t head = 4;
    constexpr std::size_t tail = 2;
    if (keys.size() <= head + tail + 1) return join(0, keys.size());
    return fmt::format("{} … ({} levels) … {}", join(0, head), keys.size(), join(keys.size() - tail, keys.size()));
}

Json parse_json(std::string_view text, const std::string& source, const JsonLimits& limits) {
    if (text.size() > limits.max_bytes) throw InputError(too_large(source, limits.max_bytes));
    Json document;
    LimitedDomBuilder builder(document, source, limits);
    Json::sax_parse(text.begin(), text.end(), &builder);
    return document;
}

Json read_json_file(const std::string& path, const JsonLimits& limits) {
    std::string text;
    if (path == "-") {
        // standard input: read up to the limit and one byte more
        char buffer[65536];
        while (std::cin.read(buffer, sizeof buffer) || std::cin.gcount() > 0) {
            text.append(buffer, static_cast<std::size_t>(std::cin.gcount()));
            if (text.size() > limits.max_bytes) throw InputError(too_large("standard input", limits.max_bytes));
        }
        return parse_json(text, "standard input", limits);
    }
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        throw InputError(fmt::format("{}: cannot open the file: {}", path,
                                     std::error_code(errno, std::generic_category()).message()));
    struct stat status {};
    if (::fstat(fd, &status) == 0 && S_ISDIR(status.st_mode)) {
        ::close(fd);
        throw InputError(fmt::format("{}: is a folder, not a file", path));
    }
    if (S_ISREG(status.st_mode)) {
        if (static_cast<std::size_t>(status.st_size) > limits.max_bytes) {
            ::close(fd);
            throw InputError(too_large(path, limits.max_bytes));
        }
        text.reserve(static_cast<std::size_t>(status.st_size));
    }
    char buffer[65536];
    for (;;) {
        const ssize_t n = ::read(fd, buffer, sizeof buffer);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            const int error = errno;
            ::close(fd);
            throw InputError(fmt::format("{}: cannot read the file: {}", path,
                                         std::error_code(error, std::generic_category()).message()));
        }
        if (n == 0) break;
        text.append(buffer, static_cast<std::size_t>(n));
        if (text.size() > limits.max_bytes) {
            ::close(fd);
            throw InputError(too_large(path, limits.max_bytes));
        }
    }
    ::close(fd);
    return parse_json(text, path, limits);
}

// ---- JsonField

const char* json_type_name(const Json& value) {
    switch (value.type()) {
        case Json::value_t::null: return "null";
        case Json::value_t::object: return "an object";
        case Json::value_t::array: return "an array";
        case Json::value_t::string: return "a string";
        case Json::value_t::boolean: return "true or false";
        case Json::value_t::binary: return "binary data";
        case Json::value_t::discarded: return "nothing";
        default: return "a number";
    }
}

namespace {

std::string member_path(const std::string& parent, const std::string& key) {
    return parent.empty() ? key : parent + "." + key;
}

}  // namespace

void JsonField::wrong(const std::string& expected) const {
    throw InputError(
        fmt::format("{}: must be {}, not {}", path_.empty() ? "the document" : path_, expected, json_type_name(*value_)));
}

bool JsonField::has(const std::string& key) const {
    return value_->is_object() && value_->contains(key);
}

std::optional<JsonField> JsonField::find(const std::string& key) const {
    if (!object().has(key)) return std::nullopt;
    return JsonField(value_->at(key), member_path(path_, key));
}

JsonField JsonField::at(const std::string& key) const {
    if (auto member = find(key)) return *member;
    throw InputError(fmt::format("{}: is missing", member_path(path_, key)));
}

const JsonField& JsonField::object() const {
    if (!value_->is_object()) wrong("an object");
    return *this;
}

const JsonField& JsonField::array() const {
    if (!value_->is_array()) wrong("an array");
    return *this;
}

double JsonField::number() const {
    if (value_->is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!value_->is_number()) wrong("a number or null");
    return value_->get<double>();
}

std::optional<double> JsonField::optional_number() const {
    if (value_->is_null()) return std::nullopt;
    if (!value_->is_number()) wrong("a number or null");
    return value_->get<double>();
}

std::size_t JsonField::count() const {
    if (value_->is_number_unsigned()) return value_->get<std::size_t>();
    if (value_->is_number_integer() && value_->get<std::int64_t>() >= 0)
        return static_cast<std::size_t>(value_->get<std::int64_t>());
    if (value_->is_number_float()) {
        const double v = value_->get<double>();
        if (v >= 0.0 && v <= 9007199254740992.0 && v == std::floor(v)) return static_cast<std::size_t>(v);
    }
    wrong("a whole number >= 0");
}

int JsonField::integer() const {
    const bool whole = value_->is_number_integer() ||
                       (value_->is_number_float() && value_->get<double>() == std::floor(value_->get<double>()));
    if (whole) {
        const double v = value_->get<double>();
        if (v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max()) return static_cast<int>(v);
    }
    wrong("a whole number");
}

bool JsonField::boolean() const {
    if (!value_->is_boolean()) wrong("true or false");
    return value_->get<bool>();
}

std::string JsonField::text() const {
    if (!value_->is_string()) wrong("a string");
    return value_->get<std::string>();
}

std::vector<double> JsonField::numbers() const {
    std::vector<double> out;
    out.reserve(array().json().size());
    for (const auto& element : elements()) out.push_back(element.number());
    return out;
}

std::vector<std::string> JsonField::texts() const {
    std::vector<std::string> out;
    for (const auto& element : elements()) out.push_back(element.text());
    return out;
}

std::vector<std::pair<std::string, JsonField>> JsonField::members() const {
    std::vector<std::pair<std::string, JsonField>> out;
    for (const auto& [key, value] : object().json().items())
        out.emplace_back(key, JsonField(value, member_path(path_, key)));
    return out;
}

std::vector<JsonField> JsonField::elements() const {
    std::vector<JsonField> out;
    std::size_t index = 0;
    for (const auto& value : array().json()) out.emplace_back(value, fmt::format("{}[{}]", path_, index++));
    return out;
}

}  // namespace feedid
