// What the MQTT commands check before any connection (parse_broker, BrokerOptions::validate, check_topic_filter), and
// the stand-ins of a build without libmosquitto.
#include <charconv>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/stream/service.hpp"

namespace feedid::watch {

std::string BrokerOptions::url() const {
    const bool ipv6 = host.find(':') != std::string::npos;
    return fmt::format("{}://{}{}{}:{}", tls ? "mqtts" : "mqtt", ipv6 ? "[" : "", host, ipv6 ? "]" : "", port);
}

std::string BrokerOptions::validate() const {
    if (!tls && (!cafile.empty() || !certfile.empty() || !keyfile.empty()))
        return fmt::format("--cafile, --cert and --key are for TLS: give the broker as mqtts://{}", host);
    if (certfile.empty() != keyfile.empty()) return "a client certificate needs both --cert and --key";
    if (!password_file.empty() && username.empty()) return "--password-file needs --username";
    if (!(connect_timeout_s > 0.0 && connect_timeout_s <= 3600.0)) return "the connect timeout must be 0 to 3600 s";
    return "";
}

namespace {

/// The URL with the password of its user part replaced by "***", for the message that refuses it.
std::string masked(const std::string& text, std::size_t authority, std::size_t at) {
    const std::size_t colon = text.find(':', authority);
    if (colon == std::string::npos || colon > at) return text;
    return text.substr(0, colon + 1) + "***" + text.substr(at);
}

}  // namespace

BrokerOptions parse_broker(const std::string& text) {
    std::string_view rest = text;
    BrokerOptions broker;
    std::size_t authority = 0;
    if (rest.starts_with("mqtts://")) {
        broker.tls = true;
        broker.port = 8883;
        authority = 8;
    } else if (rest.starts_with("mqtt://")) {
        authority = 7;
    } else if (rest.find("://") != std::string_view::npos) {
        const auto at = text.find('@');
        throw InputError(fmt::format("--broker '{}': give mqtt://HOST[:PORT] or mqtts://HOST[:PORT] (TLS)",
                                     at == std::string::npos ? text : masked(text, text.find("://") + 3, at)));
    }
    rest.remove_prefix(authority);
    if (const auto at = rest.rfind('@'); at != std::string_view::npos) {
        const std::string_view user = rest.substr(0, at);
        if (user.find(':') != std::string_view::npos)
            throw InputError(fmt::format(
                "--broker '{}': a password in the URL is refused (it would show in ps and in logs); give it in a "
                "file (--password-file) or in the environment variable {}",
                masked(text, authority, authority + at), broker_password_variable));
        broker.username = std::string(user);
        rest.remove_prefix(at + 1);
    }
    std::string_view port;
    if (rest.starts_with('[')) {  // [IPv6]:PORT
        const auto close = rest.find(']');
        if (close == std::string_view::npos) throw InputError(fmt::format("--broker '{}': an unclosed '['", text));
        broker.host = std::string(rest.substr(1, close - 1));
        if (close + 1 < rest.size()) {
            if (rest[close + 1] != ':') throw InputError(fmt::format("--broker '{}': give [HOST]:PORT", text));
            port = rest.substr(close + 2);
        }
    } else {
        const auto colon = rest.rfind(':');
        broker.host = std::string(rest.substr(0, colon));
        if (colon != std::string_view::npos) port = rest.substr(colon + 1);
    }
    if (!port.empty() || rest.ends_with(':')) {
        int value = 0;
        const auto [end, error] = std::from_chars(port.data(), port.data() + port.size(), value);
        if (error != std::errc{} || end != port.data() + port.size() || value < 1 || value > 65535)
            throw InputError(fmt::format("--broker '{}': the port is not a number from 1 to 65535", text));
        broker.port = value;
    }
    if (broker.host.empty() || broker.host.find_first_of("/ ?#@") != std::string::npos)
        throw InputError(fmt::format("--broker '{}': give mqtt://HOST[:PORT] or mqtts://HOST[:PORT] (TLS)", text));
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
