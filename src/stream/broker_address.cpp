// What the MQTT commands check before any connection (parse_broker, check_topic_filter), and the stand-ins of a
// build without libmosquitto.
#include <charconv>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/stream/service.hpp"

namespace feedid::watch {

std::string BrokerAddress::url() const {
    return fmt::format("mqtt://{}:{}", host, port);
}

BrokerAddress parse_broker(const std::string& text) {
    std::string_view rest = text;
    if (rest.starts_with("mqtt://"))
        rest.remove_prefix(7);
    else if (rest.find("://") != std::string_view::npos)
        throw InputError(fmt::format("--broker '{}': only mqtt:// (plain TCP) is supported", text));
    BrokerAddress broker;
    const auto colon = rest.rfind(':');
    broker.host = std::string(rest.substr(0, colon));
    if (colon != std::string_view::npos) {
        const std::string_view port = rest.substr(colon + 1);
        int value = 0;
        const auto [end, error] = std::from_chars(port.data(), port.data() + port.size(), value);
        if (error != std::errc{} || end != port.data() + port.size() || value < 1 || value > 65535)
            throw InputError(fmt::format("--broker '{}': the port is not a number from 1 to 65535", text));
        broker.port = value;
    }
    if (broker.host.empty() || broker.host.find_first_of("/ ") != std::string::npos)
        throw InputError(fmt::format("--broker '{}': give mqtt://HOST[:PORT]", text));
    return broker;
}

std::string check_topic_filter(const std::string& filter) {
    if (filter.empty()) return "an empty topic filter";
    if (filter.size() > 65535) return "longer than MQTT allows (65535 bytes)";
    std::size_t begin = 0;
    while (true) {
        const auto end = filter.find('/', begin);
        const std::string_view level =
            std::string_view(filter).substr(begin, end == std::string::npos ? std::string::npos : end - begin);
        if (level.find('\0') != std::string_view::npos) return "a NUL character";
        if (level.find('#') != std::string_view::npos && (level != "#" || end != std::string::npos))
            return "'#' must be a whole level, and the last";
        if (level.find('+') != std::string_view::npos && level != "+") return "'+' must be a whole level";
        if (end == std::string::npos) break;
        begin = end + 1;
    }
    return "";
}

#ifndef FEEDID_HAVE_MQTT
namespace {
[[noreturn]] void missing() {
    throw InputError("this feedid was built without MQTT: install libmosquitto-dev (scripts/setup.sh) and rebuild");
}
}  // namespace
bool mqtt_available() {
    return false;
}
int run_watch(const ServiceOptions&) {
    missing();
}
int run_publish(const Batch&, const PublishOptions&) {
    missing();
}
#endif

}  // namespace feedid::watch
