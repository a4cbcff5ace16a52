#include "feedid/stream/payload.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/core/terminal_text.hpp"
#include "feedid/core/units.hpp"
#include "feedid/io/unit_checks.hpp"

namespace feedid::watch {
namespace {

static_assert(std::endian::native == std::endian::little, "the binary payload is read with memcpy: little-endian only");

constexpr std::size_t header_bytes = 40;
enum ChannelRole : std::uint8_t { role_position = 1, role_current = 2, role_force = 3 };

/// value_SI = scale * value for a unit of the expected quantity; "" or the error.
std::string unit_scale(const std::string& unit, Quantity expected, std::string_view what, double& scale) {
    const auto conversion = parse_unit(unit);
    if (!conversion || conversion->quantity != expected || conversion->offset != 0.0)
        return fmt::format("units.{}: '{}' is not a {} unit", what, terminal_text(unit.substr(0, 32)),
                           si_symbol(expected));
    scale = conversion->scale;
    return "";
}

std::string read_column(const nlohmann::json& array, std::string_view name, double scale, std::size_t max_samples,
                        std::vector<double>& out) {
    if (!array.is_array()) return fmt::format("'{}' is not an array of numbers", name);
    if (array.size() > max_samples)
        return fmt::format("'{}' has {} samples, more than the limit of {}", name, array.size(), max_samples);
    out.resize(array.size());
    for (std::size_t k = 0; k < array.size(); ++k) {
        const auto& v = array[k];
        if (!v.is_number()) return fmt::format("{}[{}] is not a number", name, k);
        const double value = v.get<double>() * scale;
        if (!std::isfinite(value)) return fmt::format("{}[{}] is not a finite number", name, k);
        out[k] = value;
    }
    return "";
}

std::string check_times(const Batch& batch, const PayloadLimits& limits) {
    if (!std::isfinite(batch.t0)) return "t0 is not a finite number";
    if (!std::isfinite(batch.dt) || batch.dt < limits.min_dt_s || batch.dt > 10.0)
        return fmt::format("dt = {} s is not a sample time ({:g} s <= dt <= 10 s)", batch.dt, limits.min_dt_s);
    if (batch.force_constant && (!std::isfinite(*batch.force_constant) || *batch.force_constant == 0.0))
        return "force_constant is not a finite, non-zero number";
    if (batch.position.empty()) return "no samples";
    if (batch.position.size() != batch.drive.size())
        return fmt::format("position has {} samples, {} has {}", batch.position.size(),
                           batch.drive_is_force ? "force" : "current", batch.drive.size());
    return "";
}

/// "" when `name` is one a topic level can carry and a history stores, else what is wrong.
std::string check_name(std::string_view name, const char* key, std::size_t max_bytes) {
    if (auto problem = name_problem(name, max_bytes); !problem.empty())
        return fmt::format("'{}' is not a name of 1 to {} bytes of UTF-8 without control characters ({})", key,
                           max_bytes, problem);
    if (name.find_first_of("/+#") != std::string_view::npos)
        return fmt::format("'{}' is not a name of 1 to {} bytes without '/', '+', '#'", key, max_bytes);
    return "";
}

std::string read_name(const nlohmann::json& document, const char* key, std::size_t max_bytes, std::string& out) {
    out.clear();
    const auto it = document.find(key);
    if (it == document.end()) return "";
    if (!it->is_string()) return fmt::format("'{}' is not a string", key);
    const auto& text = it->get_ref<const std::string&>();
    if (auto e = check_name(text, key, max_bytes); !e.empty()) return e;
    out = text;
    return "";
}

std::string decode_json(std::span<const std::byte> payload, Batch& batch, const PayloadLimits& limits) {
    const auto* begin = reinterpret_cast<const char*>(payload.data());
    const auto document = nlohmann::json::parse(begin, begin + payload.size(), nullptr, false);
    if (document.is_discarded()) return "not JSON (nor a binary batch)";
    if (!document.is_object()) return "not a JSON object";
    static const char* const known[] = {"machine", "axis",          "t0", "dt", "position", "current", "force",
                                        "units",   "force_constant"};
    for (const auto& [key, value] : document.items()) {
        bool found = false;
        for (const char* k : known) found = found || key == k;
        if (!found) return fmt::format("unknown key '{}'", terminal_text(key.substr(0, 32)));
    }
    for (const char* key : {"t0", "dt", "position", "units"})
        if (!document.contains(key)) return fmt::format("missing key '{}'", key);
    const bool has_current = document.contains("current");
    const bool has_force = document.contains("force");
    if (has_current == has_force) return "give exactly one of 'current' and 'force'";
    const auto& units = document["units"];
    if (!units.is_object()) return "'units' is not an object";
    for (const auto& [key, value] : units.items()) {
        if (key != "position" && key != "time" && key != (has_current ? "current" : "force"))
            return fmt::format("units: unknown or unused key '{}'", terminal_text(key.substr(0, 32)));
        if (!value.is_string()) return fmt::format("units.{} is not a string", key);
    }
    const char* drive_name = has_current ? "current" : "force";
    if (!units.contains("position")) return "units.position is missing";
    if (!units.contains(drive_name)) return fmt::format("units.{} is missing", drive_name);
    double time_scale = 1.0, position_scale = 1.0, drive_scale = 1.0;
    if (units.contains("time")) {
        if (auto e = unit_scale(units["time"], Quantity::time, "time", time_scale); !e.empty()) return e;
    }
    if (auto e = unit_scale(units["position"], Quantity::length, "position", position_scale); !e.empty()) return e;
    if (auto e =
            unit_scale(units[drive_name], has_current ? Quantity::current : Quantity::force, drive_name, drive_scale);
        !e.empty())
        return e;
    for (const char* key : {"t0", "dt"})
        if (!document[key].is_number()) return fmt::format("'{}' is not a number", key);
    batch.t0 = document["t0"].get<double>() * time_scale;
    batch.dt = document["dt"].get<double>() * time_scale;
    batch.force_constant.reset();
    if (document.contains("force_constant")) {
        if (!document["force_constant"].is_number()) return "'force_constant' is not a number";
        batch.force_constant = document["force_constant"].get<double>();
    }
    if (auto e = read_name(document, "machine", limits.max_name_bytes, batch.machine); !e.empty()) return e;
    if (auto e = read_name(document, "axis", limits.max_name_bytes, batch.axis); !e.empty()) return e;
    batch.drive_is_force = has_force;
    if (auto e = read_column(document["position"], "position", position_scale, limits.max_samples, batch.position);
        !e.empty())
        return e;
    if (auto e = read_column(document[drive_name], drive_name, drive_scale, limits.max_samples, batch.drive);
        !e.empty())
        return e;
    return check_times(batch, limits);
}

template <typename T>
T load(const std::byte* at) {
    T value;
    std::memcpy(&value, at, sizeof(T));
    return value;
}

std::string decode_binary(std::span<const std::byte> payload, Batch& batch, const PayloadLimits& limits) {
    if (payload.size() < header_bytes)
        return fmt::format("binary batch of {} bytes: shorter than its header", payload.size());
    const std::byte* p = payload.data();
    const auto version = load<std::uint16_t>(p + 4);
    if (version != binary_version)
        return fmt::format("binary batch version {} (this feedid reads {})", version, binary_version);
    const auto channels = load<std::uint8_t>(p + 6);
    const auto flags = load<std::uint8_t>(p + 7);
    const auto samples = load<std::uint32_t>(p + 8);
    const auto machine_bytes = load<std::uint8_t>(p + 12);
    const auto axis_bytes = load<std::uint8_t>(p + 13);
    if (channels != 2) return fmt::format("binary batch with {} channels (position and current or force: 2)", channels);
    if (samples > limits.max_samples)
        return fmt::format("binary batch of {} samples, more than the limit of {}", samples, limits.max_samples);
    if (machine_bytes > limits.max_name_bytes || axis_bytes > limits.max_name_bytes)
        return fmt::format("binary batch: '{}' is not a name of 1 to {} bytes",
                           machine_bytes > limits.max_name_bytes ? "machine" : "axis", limits.max_name_bytes);
    const std::size_t names_at = header_bytes + 2u * channels;
    const std::size_t columns_at = names_at + machine_bytes + axis_bytes;
    const std::size_t expected = columns_at + std::size_t{channels} * samples * sizeof(double);
    if (payload.size() != expected)
        return fmt::format("binary batch of {} bytes; its header says {}", payload.size(), expected);
    batch.t0 = load<double>(p + 16);
    batch.dt = load<double>(p + 24);
    batch.force_constant.reset();
    if (flags & 1u) batch.force_constant = load<double>(p + 32);
    batch.machine.assign(reinterpret_cast<const char*>(p + names_at), machine_bytes);
    batch.axis.assign(reinterpret_cast<const char*>(p + names_at + machine_bytes), axis_bytes);
    for (const auto& [name, key] : {std::pair{&batch.machine, "machine"}, std::pair{&batch.axis, "axis"}})
        if (!name->empty())
            if (auto e = check_name(*name, key, limits.max_name_bytes); !e.empty()) return "binary batch: " + e;
    bool have_position = false, have_drive = false;
    for (std::size_t c = 0; c < channels; ++c) {
        const auto role = load<std::uint8_t>(p + header_bytes + 2 * c);
        const auto code = load<std::uint8_t>(p + header_bytes + 2 * c + 1);
        std::string_view unit;
        for (const auto& [k, u] : binary_unit_codes)
            if (k == code) unit = u;
        if (unit.empty()) return fmt::format("binary batch: unknown unit code {} of channel {}", code, c);
        const Quantity quantity = role == role_position  ? Quantity::length
                                  : role == role_current ? Quantity::current
                                  : role == role_force   ? Quantity::force
                                                         : Quantity::dimensionless;
        if (quantity == Quantity::dimensionless)
            return fmt::format("binary batch: unknown role {} of channel {}", role, c);
        const char* name = role == role_position ? "position" : role == role_current ? "current" : "force";
        double scale = 1.0;
        if (auto e = unit_scale(std::string(unit), quantity, name, scale); !e.empty()) return e;
        std::vector<double>& out = role == role_position ? batch.position : batch.drive;
        if ((role == role_position ? have_position : have_drive))
            return fmt::format("binary batch: two {} channels", name);
        (role == role_position ? have_position : have_drive) = true;
        if (role != role_position) batch.drive_is_force = role == role_force;
        out.resize(samples);
        const std::byte* column = p + columns_at + c * samples * sizeof(double);
        for (std::size_t k = 0; k < samples; ++k) {
            const double value = load<double>(column + k * sizeof(double)) * scale;
            if (!std::isfinite(value)) return fmt::format("{}[{}] is not a finite number", name, k);
            out[k] = value;
        }
    }
    if (!have_position || !have_drive) return "binary batch: needs a position and a current or force channel";
    return check_times(batch, limits);
}

template <typename T>
void store(std::string& out, T value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out.append(bytes, sizeof(T));
}

// A position unit mix-up (mm sent as m) makes the axis move at a speed no feed drive reaches, as identify and scan find
// in a file (unit_checks.hpp): more than 1 % of the batch's steps above it refuse the batch, naming the unit.
std::string implausible_speed(const Batch& batch) {
    const double limit = ConsistencyOptions{}.max_linear_speed;
    std::size_t fast = 0;
    double fastest = 0.0;
    for (std::size_t k = 1; k < batch.samples(); ++k) {
        const double speed = std::abs(batch.position[k] - batch.position[k - 1]) / batch.dt;
        fastest = std::max(fastest, speed);
        if (speed > limit) ++fast;
    }
    if (100 * fast <= batch.samples() - (batch.samples() > 0 ? 1 : 0)) return {};
    return fmt::format(
        "units.position: the position moves at up to {:.4g} m/s in {} of {} steps: no feed drive moves "
        "faster than {:g} m/s; is its unit right?",
        fastest, fast, batch.samples() - 1, limit);
}

}  // namespace

std::optional<std::uint8_t> binary_unit_code(std::string_view unit) {
    for (const auto& [code, name] : binary_unit_codes)
        if (name == unit) return code;
    return std::nullopt;
}

std::string decode_batch(std::span<const std::byte> payload, Batch& batch, const PayloadLimits& limits) {
    std::string error = payload.size() >= 4 && std::memcmp(payload.data(), binary_magic, 4) == 0
                            ? decode_binary(payload, batch, limits)
                            : decode_json(payload, batch, limits);
    return error.empty() ? implausible_speed(batch) : error;
}

std::string encode_json(const Batch& batch) {
    nlohmann::json document = {
        {"t0", batch.t0},
        {"dt", batch.dt},
        {"position", batch.position},
        {batch.drive_is_force ? "force" : "current", batch.drive},
        {"units", {{"position", "m"}, {batch.drive_is_force ? "force" : "current", batch.drive_is_force ? "N" : "A"}}}};
    if (!batch.machine.empty()) document["machine"] = batch.machine;
    if (!batch.axis.empty()) document["axis"] = batch.axis;
    if (batch.force_constant) document["force_constant"] = *batch.force_constant;
    return document.dump();
}

std::string encode_binary(const Batch& batch) {
    std::string out;
    out.reserve(header_bytes + 4 + batch.machine.size() + batch.axis.size() + 16 * batch.samples());
    out.append(binary_magic, 4);
    store<std::uint16_t>(out, binary_version);
    store<std::uint8_t>(out, 2);
    store<std::uint8_t>(out, batch.force_constant ? 1 : 0);
    store<std::uint32_t>(out, static_cast<std::uint32_t>(batch.samples()));
    store<std::uint8_t>(out, static_cast<std::uint8_t>(batch.machine.size()));
    store<std::uint8_t>(out, static_cast<std::uint8_t>(batch.axis.size()));
    store<std::uint16_t>(out, 0);
    store<double>(out, batch.t0);
    store<double>(out, batch.dt);
    store<double>(out, batch.force_constant.value_or(std::numeric_limits<double>::quiet_NaN()));
    store<std::uint8_t>(out, role_position);
    store<std::uint8_t>(out, *binary_unit_code("m"));
    store<std::uint8_t>(out, batch.drive_is_force ? role_force : role_current);
    store<std::uint8_t>(out, *binary_unit_code(batch.drive_is_force ? "N" : "A"));
    out += batch.machine;
    out += batch.axis;
    for (const double v : batch.position) store<double>(out, v);
    for (const double v : batch.drive) store<double>(out, v);
    return out;
}

std::optional<std::pair<std::string, std::string>> machine_axis_of_topic(std::string_view topic) {
    const auto first = topic.find('/');
    if (first == std::string_view::npos) return std::nullopt;
    const auto second = topic.find('/', first + 1);
    if (second == std::string_view::npos) return std::nullopt;
    const auto third = topic.find('/', second + 1);
    const std::string_view machine = topic.substr(first + 1, second - first - 1);
    const std::string_view axis =
        third == std::string_view::npos ? topic.substr(second + 1) : topic.substr(second + 1, third - second - 1);
    if (machine.empty() || axis.empty()) return std::nullopt;
    return std::pair{std::string(machine), std::string(axis)};
}

}  // namespace feedid::watch
