// feedid publish over MQTT (service.hpp): the sink side of the MQTT client (mqtt_client.hpp), as an NC's gateway.
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <deque>
#include <thread>

#include <unistd.h>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/terminal_text.hpp"
#include "feedid/stream/service.hpp"
#include "mqtt_client.hpp"

namespace feedid::watch {
namespace {

using Clock = std::chrono::steady_clock;

std::atomic<bool> stop_requested{false};
extern "C" void publish_request_stop(int) {
    stop_requested = true;
}

/// Store and forward, as an NC's gateway does. While the broker is away, messages are held (at most `limit`; beyond,
/// the oldest is dropped and counted) and sent in order once it is back. A QoS 1 message handed to libmosquitto
/// stays with it until the broker acknowledges it, over reconnects (it resends it itself: holding it here too sent
/// it twice, and counting acknowledgements against sends then ended the stream before its last message was
/// acknowledged). An acknowledgement only says that the broker has the message, not that a subscriber got it: a
/// broker killed loses what it acknowledged since its last save. So after every reconnect the messages of the last
/// `replay_s` seconds before the connection was lost are sent again (the subscriber skips what it has by time stamp).
class Outbox {
public:
    Outbox(MqttClient& client, const PublishOptions& options, std::size_t limit)
        : client_(client), options_(options), limit_(limit) {}

    void send(const std::string& topic, std::string payload) {
        flush();
        if (held_.empty() && client_.connected() && client_.publish(topic, payload, options_.qos, false)) {
            remember(topic, payload);
            ++sent_;
            return;
        }
        held_.emplace_back(topic, std::move(payload));
        ++held_total_;
        if (held_.size() > limit_) {
            held_.pop_front();
            ++lost_;
        }
    }
    /// After a reconnect: the recent messages again, then what is held, in order; true when nothing is left.
    bool flush() {
        if (!client_.connected()) return held_.empty();
        if (const std::size_t connects = client_.connects(); connects != connects_seen_) {
            connects_seen_ = connects;
            if (connects > 1) replay();
        }
        while (!held_.empty() && client_.connected() &&
               client_.publish(held_.front().first, held_.front().second, options_.qos, false)) {
            remember(held_.front().first, held_.front().second);
            held_.pop_front();
            ++sent_;
        }
        return held_.empty();
    }
    [[nodiscard]] std::size_t sent() const { return sent_; }
    [[nodiscard]] std::size_t lost() const { return lost_ + held_.size(); }
    [[nodiscard]] std::size_t held_total() const { return held_total_; }
    [[nodiscard]] std::size_t replayed() const { return replayed_; }

private:
    void remember(const std::string& topic, const std::string& payload) {
        if (options_.qos == 0 || options_.replay_s <= 0.0) return;
        const auto now = Clock::now();
        recent_.push_back({now, topic, payload});
        const auto horizon =
            now - std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options_.replay_s));
        while (!recent_.empty() && recent_.front().sent < horizon) recent_.pop_front();
    }
    void replay() {
        // recent_ holds what was sent in the replay_s before the connection was lost (nothing is added while it is
        // down); sent again, oldest first, before anything newer
        for (const Recent& r : recent_) {
            if (!client_.publish(r.topic, r.payload, options_.qos, false)) break;
            ++replayed_;
        }
    }
    struct Recent {
        Clock::time_point sent;
        std::string topic, payload;
    };
    MqttClient& client_;
    const PublishOptions& options_;
    std::size_t limit_;
    std::deque<std::pair<std::string, std::string>> held_;  ///< topic, payload
    std::deque<Recent> recent_;
    std::size_t connects_seen_{0};
    std::size_t sent_{0}, lost_{0}, held_total_{0}, replayed_{0};
};

// --copies N: the same stream on N topics, '{n}' in the topic replaced by 1..N (a load for the benchmark).
std::vector<std::string> copy_topics(const PublishOptions& options) {
    std::vector<std::string> topics;
    for (std::size_t c = 1; c <= options.copies; ++c) {
        std::string topic = options.topic;
        if (const auto at = topic.find("{n}"); at != std::string::npos) topic.replace(at, 3, std::to_string(c));
        topics.push_back(std::move(topic));
    }
    return topics;
}

/// Sends the stream's messages, paced to the rate; stops early on a signal.
void stream_messages(const Batch& stream, const PublishOptions& options, const std::vector<std::string>& topics,
                     Outbox& outbox) {
    const std::size_t n = stream.samples();
    const auto per_message = static_cast<std::size_t>(std::max(1.0, std::round(options.batch_s / stream.dt)));
    Batch part;
    part.machine = stream.machine;
    part.axis = stream.axis;
    part.dt = stream.dt;
    part.drive_is_force = stream.drive_is_force;
    part.force_constant = stream.force_constant;
    const auto start = Clock::now();
    for (std::size_t first = 0; first < n && !stop_requested; first += per_message) {
        const std::size_t count = std::min(per_message, n - first);
        part.t0 = stream.t0 + static_cast<double>(first) * stream.dt;
        part.position.assign(stream.position.begin() + static_cast<std::ptrdiff_t>(first),
                             stream.position.begin() + static_cast<std::ptrdiff_t>(first + count));
        part.drive.assign(stream.drive.begin() + static_cast<std::ptrdiff_t>(first),
                          stream.drive.begin() + static_cast<std::ptrdiff_t>(first + count));
        if (options.rate > 0.0) {  // the message leaves when its last sample would have been recorded
            const double due = static_cast<double>(first + count) * stream.dt / options.rate;
            std::this_thread::sleep_until(
                start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(due)));
        }
        const std::string payload = options.binary ? encode_binary(part) : encode_json(part);
        for (const std::string& topic : topics) outbox.send(topic, payload);
    }
}

}  // namespace

int run_publish(const Batch& stream, const PublishOptions& options) {
    if (options.topic.empty() || options.topic.find_first_of("+#") != std::string::npos)
        throw InputError(
            fmt::format("--topic '{}': a topic to publish to has no wildcards", terminal_text(options.topic)));
    if (options.copies > 1 && options.topic.find("{n}") == std::string::npos)
        throw InputError(fmt::format("--copies {}: the topic '{}' needs a '{{n}}' to tell the copies apart",
                                     options.copies, terminal_text(options.topic)));
    MqttLibrary library;
    ClientRole role;
    // a client id of the user's: a persistent session (the broker keeps the QoS 1 exchange in flight over a restart)
    role.client_id = options.client_id.empty() ? fmt::format("feedid-publish-{}", ::getpid()) : options.client_id;
    role.clean_session = options.client_id.empty();
    role.reconnect_min_s = role.reconnect_max_s = 1;  // an NC's gateway retries every second
    role.program = "feedid publish";
    MqttClient client(options.broker, role);
    client.start();  // exit 2 when the broker refuses us or does not answer
    stop_requested = false;
    std::signal(SIGTERM, publish_request_stop);
    std::signal(SIGINT, publish_request_stop);
    const auto per_message = static_cast<std::size_t>(std::max(1.0, std::round(options.batch_s / stream.dt)));
    const std::vector<std::string> topics = copy_topics(options);
    Outbox outbox(
        client, options,
        static_cast<std::size_t>(std::ceil(options.buffer_s / (static_cast<double>(per_message) * stream.dt))));
    stream_messages(stream, options, topics, outbox);
    // what is held, and what the library holds (QoS 1 awaiting acknowledgement, each by its message id), leaves
    // before the disconnect: the stream's last message too
    const auto give_up = Clock::now() + std::chrono::seconds(60);
    while ((!outbox.flush() || client.pending() > 0 || !client.connected()) && Clock::now() < give_up &&
           !stop_requested)
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const std::size_t unacknowledged = client.pending();
    client.stop();
    std::signal(SIGTERM, SIG_DFL);
    std::signal(SIGINT, SIG_DFL);
    const std::size_t lost = outbox.lost() + client.dropped_unwritten();
    fmt::print(stderr,
               "feedid publish: {} messages sent to {} on {} ({} held while the broker was away, {} sent again after "
               "a reconnect), {} lost, {} not acknowledged\n",
               outbox.sent(), terminal_text(topics.size() == 1 ? topics[0] : options.topic), client.url(),
               outbox.held_total(), outbox.replayed(), lost, unacknowledged);
    if (lost == 0 && unacknowledged == 0) return 0;
    fmt::print(stderr, "feedid publish: {} of the stream's messages did not reach the broker{}\n",
               lost + unacknowledged, stop_requested ? " (stopped by a signal)" : "");
    return 1;
}

}  // namespace feedid::watch
