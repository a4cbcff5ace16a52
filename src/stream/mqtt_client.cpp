// The MQTT transport of watch and publish (mqtt_client.hpp), over libmosquitto.
#include "mqtt_client.hpp"

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/terminal_text.hpp"

namespace feedid::watch {
namespace {

using Clock = std::chrono::steady_clock;

/// An encrypted client key is refused rather than asked for on a terminal that a service does not have.
int no_key_password(char*, int, int, void*) {
    return 0;
}

void require_readable(const std::string& path, const char* what) {
    std::ifstream file(path);
    if (!file) throw InputError(fmt::format("{} '{}': cannot be read ({})", what, path, std::strerror(errno)));
}

}  // namespace

std::string broker_password(const BrokerOptions& broker) {
    if (!broker.password_file.empty()) {
        std::ifstream file(broker.password_file);
        if (!file)
            throw InputError(
                fmt::format("--password-file '{}': cannot be read ({})", broker.password_file, std::strerror(errno)));
        std::string line;
        std::getline(file, line);
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.empty())
            throw InputError(
                fmt::format("--password-file '{}': its first line (the password) is empty", broker.password_file));
        return line;
    }
    const char* variable = std::getenv(broker_password_variable);
    return variable ? std::string(variable) : std::string();
}

MqttClient::MqttClient(const BrokerOptions& broker, ClientRole role, MessageHandler handler)
    : role_(std::move(role)),
      on_message_(std::move(handler)),
      url_(broker.url()),
      host_(broker.host),
      port_(broker.port),
      username_(broker.username),
      connect_timeout_s_(broker.connect_timeout_s),
      tls_(broker.tls) {
    if (auto problem = broker.validate(); !problem.empty()) throw InputError(fmt::format("{}: {}", url_, problem));
    client_ = mosquitto_new(role_.client_id.c_str(), role_.clean_session, this);
    if (!client_) throw InputError("cannot create an MQTT client (out of memory)");
    if (!broker.username.empty()) {
        std::string password = broker_password(broker);
        const int code =
            mosquitto_username_pw_set(client_, broker.username.c_str(), password.empty() ? nullptr : password.c_str());
        std::fill(password.begin(), password.end(), '\0');  // libmosquitto keeps its own copy
        if (code != MOSQ_ERR_SUCCESS)
            throw InputError(fmt::format("{}: the username is not one ({})", url_, mosquitto_strerror(code)));
    } else if (!broker.password_file.empty()) {
        throw InputError("--password-file needs --username");
    }
    if (broker.tls) {
        for (const auto& [path, what] : {std::pair{&broker.cafile, "--cafile"}, std::pair{&broker.certfile, "--cert"},
                                         std::pair{&broker.keyfile, "--key"}})
            if (!path->empty()) require_readable(*path, what);
        // without a CA file, the system's certificates (Debian: /etc/ssl/certs)
        const int code = mosquitto_tls_set(client_, broker.cafile.empty() ? nullptr : broker.cafile.c_str(),
                                           broker.cafile.empty() ? "/etc/ssl/certs" : nullptr,
                                           broker.certfile.empty() ? nullptr : broker.certfile.c_str(),
                                           broker.keyfile.empty() ? nullptr : broker.keyfile.c_str(), no_key_password);
        if (code != MOSQ_ERR_SUCCESS)
            throw InputError(fmt::format("{}: cannot set up TLS ({})", url_, mosquitto_strerror(code)));
        mosquitto_tls_opts_set(client_, 1, nullptr, nullptr);  // SSL_VERIFY_PEER: the broker proves who it is
        mosquitto_tls_insecure_set(client_, false);            // ... and its certificate names the host
    }
    if (!role_.status_topic.empty()) mosquitto_will_set(client_, role_.status_topic.c_str(), 7, "offline", 1, true);
    mosquitto_reconnect_delay_set(client_, static_cast<unsigned>(role_.reconnect_min_s),
                                  static_cast<unsigned>(role_.reconnect_max_s),
                                  role_.reconnect_max_s > role_.reconnect_min_s);
    mosquitto_connect_with_flags_callback_set(client_, on_connect);
    mosquitto_disconnect_callback_set(client_, on_disconnect);
    mosquitto_publish_callback_set(client_, on_publish);
    mosquitto_message_callback_set(client_, on_message);
    mosquitto_log_callback_set(client_, on_log);
}

MqttClient::~MqttClient() {
    stop();
    mosquitto_destroy(client_);
}

void MqttClient::on_connect(mosquitto* client, void* self_pointer, int code, int flags) {
    auto* self = static_cast<MqttClient*>(self_pointer);
    if (self->first_answer_ < 0) self->first_answer_ = code;
    if (code != 0) {
        if (self->started_)  // later: the network thread tries again, with backoff
            fmt::print(stderr, "{}: {} refused the connection: {}\n", self->role_.program, self->url_,
                       self->refusal(code));
        return;
    }
    // A session the broker resumed keeps its subscription (subscribing again would resend every retained message);
    // a broker without persistence, or one that expired the session, has none: subscribe again, on every connection
    // (flags bit 0: the CONNACK's session-present).
    const bool resumed = (flags & 1) != 0 && !self->role_.clean_session;
    if (!self->role_.subscription.empty() && !resumed) {
        mosquitto_subscribe(client, nullptr, self->role_.subscription.c_str(), 1);
        ++self->subscriptions_;
    }
    if (!self->role_.status_topic.empty()) {
        int mid = 0;
        if (mosquitto_publish(client, &mid, self->role_.status_topic.c_str(), 6, "online", 1, true) == MOSQ_ERR_SUCCESS)
            self->handed(mid, 1);
    }
    if (++self->connects_ > 1)
        fmt::print(stderr, "{}: connected again to {} ({})\n", self->role_.program, self->url_,
                   self->role_.subscription.empty() ? "publishing"
                   : resumed                        ? "the broker resumed the session and its subscription"
                                                    : "subscribed again: the broker had no session");
    self->connected_ = true;
}

void MqttClient::on_disconnect(mosquitto*, void* self_pointer, int) {
    auto* self = static_cast<MqttClient*>(self_pointer);
    self->connected_ = false;
    // QoS 1 and 2: the library keeps them and sends them again; QoS 0 not yet written is gone
    std::lock_guard lock(self->mutex_);
    for (auto it = self->unacknowledged_.begin(); it != self->unacknowledged_.end();) {
        if (it->second == 0) {
            ++self->dropped_unwritten_;
            it = self->unacknowledged_.erase(it);
        } else {
            ++it;
        }
    }
}

void MqttClient::on_publish(mosquitto*, void* self_pointer, int mid) {
    auto* self = static_cast<MqttClient*>(self_pointer);
    std::lock_guard lock(self->mutex_);
    if (const auto it = self->unacknowledged_.find(mid); it != self->unacknowledged_.end())
        self->unacknowledged_.erase(it);
    else
        ++self->early_[mid];
}

void MqttClient::on_message(mosquitto*, void* self_pointer, const mosquitto_message* message) {
    auto* self = static_cast<MqttClient*>(self_pointer);
    if (self->on_message_) self->on_message_(*message);
}

void MqttClient::on_log(mosquitto*, void* self_pointer, int level, const char* text) {
    if (level != MOSQ_LOG_ERR || text == nullptr) return;
    auto* self = static_cast<MqttClient*>(self_pointer);
    std::lock_guard lock(self->mutex_);
    self->last_error_ = text;
}

void MqttClient::handed(int mid, int qos) {
    std::lock_guard lock(mutex_);
    if (const auto it = early_.find(mid); it != early_.end()) {
        if (--it->second == 0) early_.erase(it);
        return;
    }
    unacknowledged_[mid] = qos;
}

std::string MqttClient::refusal(int code) const {
    // MQTT 3.1.1's CONNACK return codes
    if (code == 4 || code == 5)
        return fmt::format(
            "the broker refused the login{} ({}): check --username and the password (--password-file or {})",
            username_.empty() ? " of an anonymous client" : fmt::format(" of user '{}'", terminal_text(username_)),
            mosquitto_connack_string(code), broker_password_variable);
    if (code == 2) return fmt::format("the broker refused the client id '{}'", terminal_text(role_.client_id));
    return fmt::format("the broker refused the connection ({})", mosquitto_connack_string(code));
}

std::string MqttClient::failure(int code, int error_number) const {
    std::string library_error;
    {
        std::lock_guard lock(mutex_);
        library_error = last_error_;
    }
    if (code == MOSQ_ERR_TLS || (tls_ && library_error.find("OpenSSL") != std::string::npos))
        return fmt::format(
            "TLS failed ({}); check --cafile (the CA that signed the broker's certificate) and that "
            "the certificate names the host",
            library_error.empty() ? mosquitto_strerror(code) : terminal_text(library_error));
    if (code == MOSQ_ERR_ERRNO || code == MOSQ_ERR_CONN_REFUSED || code == MOSQ_ERR_NO_CONN)
        return error_number != 0 ? std::strerror(error_number) : "the connection was closed";
    if (code == MOSQ_ERR_EAI) return "the host name does not resolve";
    if (code == MOSQ_ERR_PROTOCOL || code == MOSQ_ERR_CONN_LOST)
        return fmt::format("the broker closed the connection before answering ({}{})",
                           tls_ ? "is it a TLS port?" : "a TLS port? then give mqtts://",
                           library_error.empty() ? "" : "; " + terminal_text(library_error));
    return mosquitto_strerror(code);
}

void MqttClient::start() {
    // The first connection is driven here, so that a broker that refuses us or never answers is an error now, with
    // its reason, instead of a service that runs and hears nothing; libmosquitto's thread reconnects only after it.
    const auto unreachable = [&](const std::string& reason) {
        return InputError(fmt::format("cannot reach the MQTT broker at {}: {}", url_, reason));
    };
    errno = 0;
    int code = mosquitto_connect_async(client_, host_.c_str(), port_, 30);
    if (code != MOSQ_ERR_SUCCESS) throw unreachable(failure(code, errno));
    const auto deadline =
        Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(connect_timeout_s_));
    while (first_answer_ < 0) {
        errno = 0;
        code = mosquitto_loop(client_, 100, 1);
        if (first_answer_ >= 0) break;
        if (code != MOSQ_ERR_SUCCESS) throw unreachable(failure(code, errno));
        if (Clock::now() > deadline)
            throw unreachable(fmt::format("no answer within {:g} s{}", connect_timeout_s_,
                                          tls_ ? "" : " (a TLS port? then give mqtts://)"));
    }
    if (first_answer_ != 0) throw InputError(fmt::format("the MQTT broker at {}: {}", url_, refusal(first_answer_)));
    started_ = true;
    mosquitto_loop_start(client_);
}

bool MqttClient::publish(const std::string& topic, std::string_view payload, int qos, bool retain) {
    int mid = 0;
    const int code =
        mosquitto_publish(client_, &mid, topic.c_str(), static_cast<int>(payload.size()), payload.data(), qos, retain);
    // QoS > 0: the library queues the message before it tries to send it, and keeps it while the connection is down
    const bool taken = code == MOSQ_ERR_SUCCESS || (qos > 0 && code == MOSQ_ERR_NO_CONN);
    if (taken) handed(mid, qos);
    return taken;
}

void MqttClient::stop() {
    if (!started_ || stopped_) return;
    stopped_ = true;
    mosquitto_disconnect(client_);
    mosquitto_loop_stop(client_, false);
    connected_ = false;
}

std::size_t MqttClient::pending() const {
    std::lock_guard lock(mutex_);
    return unacknowledged_.size();
}

std::size_t MqttClient::dropped_unwritten() const {
    std::lock_guard lock(mutex_);
    return dropped_unwritten_;
}

}  // namespace feedid::watch
