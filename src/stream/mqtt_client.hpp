#pragma once
// One MQTT connection over libmosquitto, the transport that feedid watch (a source: it subscribes) and feedid publish
// (a sink) share: the broker's address and login (TLS with a CA and an optional client certificate, a username and
// a password read from a file or the environment, never from the command line), the first connection made or refused
// within a bounded time (the reason said: unreachable, TLS, login refused), then libmosquitto's network thread, which
// reconnects with backoff; the subscription renewed on every connection the broker does not resume as a session; and
// the account of the messages handed to the library until the broker acknowledges them.

#include <atomic>
#include <cstddef>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <string_view>

#include <mosquitto.h>

#include "feedid/stream/service.hpp"

namespace feedid::watch {

/// mosquitto_lib_init / cleanup around one command.
struct MqttLibrary {
    MqttLibrary() { mosquitto_lib_init(); }
    ~MqttLibrary() { mosquitto_lib_cleanup(); }
    MqttLibrary(const MqttLibrary&) = delete;
    MqttLibrary& operator=(const MqttLibrary&) = delete;
};

/// What a client is for: its session, what it says when it comes and goes, what it subscribes to.
struct ClientRole {
    std::string client_id;
    bool clean_session{true};  ///< false: a persistent session under client_id (the broker may keep it)
    int reconnect_min_s{1};    ///< backoff after a lost connection [s] ...
    int reconnect_max_s{32};   ///< ... doubling up to this [s]
    std::string status_topic;  ///< "online" (retained, QoS 1) on every connection, "offline" as the last will; "" none
    std::string subscription;  ///< topic filter subscribed at QoS 1 on every connection not resumed; "" none (a sink)
    std::string program{"feedid"};  ///< for the messages on stderr ("feedid watch")
};

class MqttClient {
public:
    using MessageHandler = std::function<void(const mosquitto_message&)>;

    /// Sets the client up (login, TLS, last will); connects nothing yet. InputError when a file it needs (the
    /// password file, the CA, the client certificate or key) cannot be read.
    MqttClient(const BrokerOptions& broker, ClientRole role, MessageHandler handler = {});
    ~MqttClient();
    MqttClient(const MqttClient&) = delete;
    MqttClient& operator=(const MqttClient&) = delete;

    /// The first connection, on the calling thread: made and accepted by the broker within the broker's
    /// connect_timeout_s, else InputError naming the broker and the reason (unreachable, TLS, the login refused, no
    /// answer). Then libmosquitto's network thread takes over and reconnects with backoff whenever the connection is
    /// lost.
    void start();
    /// Hands a message to the library: true when it took it (written, or with QoS > 0 queued until the connection is
    /// back; the broker's acknowledgement is counted in pending()).
    bool publish(const std::string& topic, std::string_view payload, int qos, bool retain);
    /// Disconnects (after what the library holds has left, as far as it can) and stops the network thread.
    void stop();

    [[nodiscard]] bool connected() const { return connected_; }
    /// Connections accepted by the broker (a reconnect counts).
    [[nodiscard]] std::size_t connects() const { return connects_; }
    /// Connections on which the subscription was made again (the broker had no session to resume).
    [[nodiscard]] std::size_t subscriptions() const { return subscriptions_; }
    /// Messages handed to the library and not yet acknowledged (QoS 1, 2) or written (QoS 0).
    [[nodiscard]] std::size_t pending() const;
    /// QoS 0 messages the library dropped unwritten when a connection was lost.
    [[nodiscard]] std::size_t dropped_unwritten() const;
    [[nodiscard]] const std::string& url() const { return url_; }

private:
    static void on_connect(mosquitto* client, void* self, int code, int flags);
    static void on_disconnect(mosquitto* client, void* self, int code);
    static void on_publish(mosquitto* client, void* self, int mid);
    static void on_message(mosquitto* client, void* self, const mosquitto_message* message);
    static void on_log(mosquitto* client, void* self, int level, const char* text);
    void handed(int mid, int qos);
    [[nodiscard]] std::string refusal(int code) const;
    [[nodiscard]] std::string failure(int code, int error_number) const;

    mosquitto* client_{nullptr};
    ClientRole role_;
    MessageHandler on_message_;
    std::string url_;
    std::string host_;
    int port_{1883};
    std::string username_;
    double connect_timeout_s_{10.0};
    bool tls_{false};
    bool started_{false}, stopped_{false};
    std::atomic<bool> connected_{false};
    std::atomic<std::size_t> connects_{0}, subscriptions_{0};
    std::atomic<int> first_answer_{-1};  ///< the broker's answer to the first CONNECT (-1: none yet)
    mutable std::mutex mutex_;
    std::map<int, int> unacknowledged_;  ///< mid -> QoS of what the library holds
    std::map<int, int> early_;           ///< acknowledged before mosquitto_publish returned its mid
    std::size_t dropped_unwritten_{0};
    std::string last_error_;  ///< the library's last error log line (OpenSSL's reason of a TLS failure)
};

/// The password for a broker: the first line of its password_file, else the environment variable
/// FEEDID_MQTT_PASSWORD, else none. InputError naming the file when it cannot be read or its first line is empty.
std::string broker_password(const BrokerOptions& broker);

}  // namespace feedid::watch
