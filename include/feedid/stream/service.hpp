#pragma once
// `feedid watch` and `feedid publish` over MQTT (Eclipse Mosquitto's C client, libmosquitto). Built only when
// libmosquitto is found (FEEDID_HAVE_MQTT); the declarations are always here so that the CLI can say what is missing.
// Both use one MQTT client (the transport: address, TLS and login, the first connection within a bounded time,
// reconnection with backoff); watch is its source side, publish its sink side.
//
// watch: subscribes to the topic filter (QoS 1) on every connection the broker does not resume as a session, hands
// each message from the network thread to a bounded queue (a message that would overflow it is dropped and counted),
// and feeds a Watcher (watcher.hpp) from it on the calling thread; completed identifications go to the history
// through an on-disk spool, written by a thread of their own (a database that is away delays nothing). Topics
// (prefix = '<first level>/<machine>/<axis>' of the data topic, e.g. plant/M1/X):
//   <prefix>/feedid/estimate  retained, QoS 1, every estimate_interval_s for the axes that received data;
//   <prefix>/feedid/error     one per refused message: {"topic", "error", "malformed"} (QoS 0);
//   <prefix>/feedid/run       QoS 1, each completed identification recorded in the history (run id, document);
//   <prefix>/feedid/alarm     QoS 1, a drift alarm of history --check's logic raised by that run (the alarm
//                             document, history::alarm_document());
//   status_topic              "online" (retained) on connect, "offline" as the last will and on a clean exit.
// The broker refusing or not answering at start: InputError (exit 2) with the reason. The broker going away later:
// the network thread reconnects with exponential backoff (1 s to 32 s); the identifiers keep their state. SIGTERM or
// SIGINT: the queue is drained, the identifiers flushed, the final estimates published, "offline" published, and the
// call returns 0.

#include <cstddef>
#include <optional>
#include <string>

#include "feedid/stream/watcher.hpp"

namespace feedid::watch {

/// Whether this build has MQTT (libmosquitto).
bool mqtt_available();

/// The environment variable a broker's password may come from (when no password file is given).
inline constexpr const char* broker_password_variable = "FEEDID_MQTT_PASSWORD";

/// A broker and how to log in to it. A password is never given here: it is read from password_file or from the
/// environment variable FEEDID_MQTT_PASSWORD when the connection is made, and never printed, logged or stored.
struct BrokerOptions {
    std::string host{"127.0.0.1"};
    int port{1883};
    bool tls{false};            ///< mqtts://: TLS, the broker's certificate checked against cafile and its host name
    std::string username;       ///< "" = none (an anonymous client)
    std::string password_file;  ///< its first line is the password; "" = FEEDID_MQTT_PASSWORD, or none
    std::string cafile;    ///< PEM CA certificate(s) the broker's certificate is checked against; "" = the system's
    std::string certfile;  ///< PEM client certificate, for a broker that asks for one (with keyfile)
    std::string keyfile;   ///< its private key (PEM, not encrypted)
    double connect_timeout_s{10.0};  ///< the first connection made and accepted within this [s], else exit 2

    /// "mqtt://HOST:PORT" or "mqtts://HOST:PORT": the broker as messages name it (never a password).
    [[nodiscard]] std::string url() const;
    /// What is wrong ("" when nothing): TLS files without mqtts://, a certificate without its key.
    [[nodiscard]] std::string validate() const;
};
/// "mqtt://[USER@]HOST[:PORT]", "mqtts://[USER@]HOST[:PORT]" (TLS, port 8883 by default) or "HOST[:PORT]". InputError
/// naming the text (its password masked) otherwise, and when the URL holds a password: it would show in `ps` and in
/// logs.
BrokerOptions parse_broker(const std::string& text);

/// "" when `filter` is a valid MQTT subscription filter, else what is wrong.
std::string check_topic_filter(const std::string& filter);

struct ServiceOptions {
    BrokerOptions broker;
    std::string topic_filter{"plant/+/+/axis/#"};
    std::string status_topic;             ///< default: '<first level of the filter>/feedid/status'
    std::string client_id;                ///< default: feedid-watch-<pid>
    std::string database;                 ///< history to record completed identifications in ("" = none)
    /// Completed identifications not yet in the history wait here, on disk (written when the database is back,
    /// also by a later watch); "" = '<database>.spool' beside a SQLite file, 'feedid-spool-<hash>' in the working
    /// folder for a PostgreSQL database.
    std::string spool_dir;
    std::size_t spool_bytes{64u << 20};   ///< the spool holds this much at most; a run beyond is lost, and said
    double db_retry_s{300.0};             ///< [s] a lost database connection is retried this long, with backoff
    double estimate_interval_s{1.0};      ///< [s] of wall time
    std::size_t queue_bytes{64u << 20};   ///< messages waiting for the identifiers take this much at most [bytes]
    bool print{true};                     ///< a line per published estimate and per alarm on stdout
    /// Stop (as on SIGTERM) after this long without a message [s] (tests, the demo); nullopt = run until a signal.
    std::optional<double> idle_exit_s;
    WatchOptions watch;
};

/// Runs the service until SIGTERM / SIGINT (or idle_exit_s). Returns the exit code (0). InputError (exit 2) when the
/// broker cannot be reached or refuses the login at start, the topic filter is not one, or the history or its spool
/// cannot be opened for writing.
int run_watch(const ServiceOptions& options);

struct PublishOptions {
    BrokerOptions broker;
    std::string topic;
    double rate{1.0};     ///< times real time; 0 = as fast as the broker takes it
    double batch_s{0.1};  ///< stream time per message [s]
    bool binary{false};
    int qos{0};
    /// Stream time held while the broker is away [s], sent in order when it is back (beyond: the oldest is lost)
    double buffer_s{60.0};
    /// QoS 1 and 2: after a reconnect, the messages sent in this much wall time before the connection was lost are
    /// sent again [s] (a broker killed loses what it acknowledged since its last save; subscribers skip repeats)
    double replay_s{5.0};
    /// The same stream on this many topics, '{n}' in the topic replaced by 1..copies (a load for benchmarks)
    std::size_t copies{1};
    std::string client_id;
};

/// Streams a batch's samples (t0, dt, position [m], drive [A] or [N]) as messages of batch_s each, paced to
/// `rate` times real time. Messages the broker does not take while it is away are held (buffer_s of stream) and sent
/// in order when it is back; beyond that they are lost and counted (a control does not buffer forever either).
/// Reconnects every second in the background; with QoS 1, sends the last replay_s of messages again after a
/// reconnect, and returns only when the broker has acknowledged every message (or after 60 s, saying how many it
/// did not). Returns the exit code: 0 when every message left (and, QoS 1 and 2, was acknowledged), 1 naming the count
/// when any was lost or not acknowledged. InputError (exit 2) when the broker cannot be reached or refuses the login.
int run_publish(const Batch& stream, const PublishOptions& options);

}  // namespace feedid::watch
