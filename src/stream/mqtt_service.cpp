// feedid watch / publish over MQTT with libmosquitto (its threaded network loop; see service.hpp).
#include "feedid/stream/service.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstring>
#include <deque>
#include <memory>
#include <mutex>
#include <set>
#include <thread>

#include <mosquitto.h>
#include <unistd.h>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/history/sha256.hpp"
#include "feedid/history/store.hpp"
#include "feedid/history/trend.hpp"
#include "feedid/core/version.hpp"

namespace feedid::watch {
namespace {

using Clock = std::chrono::steady_clock;

std::atomic<bool> stop_requested{false};
extern "C" void request_stop(int) {
    stop_requested = true;
}

/// mosquitto_lib_init / cleanup around one command.
struct Library {
    Library() { mosquitto_lib_init(); }
    ~Library() { mosquitto_lib_cleanup(); }
    Library(const Library&) = delete;
    Library& operator=(const Library&) = delete;
};

struct ClientDeleter {
    void operator()(mosquitto* client) const { mosquitto_destroy(client); }
};
using Client = std::unique_ptr<mosquitto, ClientDeleter>;

struct Message {
    std::string topic;
    std::string payload;
};

/// A publishing side of a connection (network thread and publishing thread): whether it is up, how often it came up,
/// and the message ids the library holds until the broker acknowledges them.
struct Link {
    std::mutex mutex;
    std::atomic<bool> connected{false};
    std::atomic<std::size_t> connects{0};
    std::multiset<int> unacknowledged;  ///< mids handed to the library and not acknowledged (QoS 0: not written) yet
    std::multiset<int> early;           ///< mids acknowledged before mosquitto_publish returned them
    bool at_most_once{false};           ///< QoS 0: what is not written when the connection drops is gone
    std::size_t dropped_unwritten{0};   ///< QoS 0 messages gone that way

    void handed(int mid) {
        std::lock_guard lock(mutex);
        if (const auto it = early.find(mid); it != early.end())
            early.erase(it);
        else
            unacknowledged.insert(mid);
    }
    void acknowledged(int mid) {
        std::lock_guard lock(mutex);
        if (const auto it = unacknowledged.find(mid); it != unacknowledged.end())
            unacknowledged.erase(it);
        else
            early.insert(mid);
    }
    void disconnected() {
        connected = false;
        std::lock_guard lock(mutex);
        if (!at_most_once) return;  // QoS 1: the library keeps them and sends them again
        dropped_unwritten += unacknowledged.size();
        unacknowledged.clear();
    }
    [[nodiscard]] std::size_t pending() {
        std::lock_guard lock(mutex);
        return unacknowledged.size();
    }
};

/// What the network thread and the service thread share.
struct Shared {
    std::mutex mutex;
    std::condition_variable arrived;
    std::deque<Message> queue;
    std::size_t queued_bytes{0};
    std::size_t queue_limit{0};
    std::size_t dropped{0};
    std::string filter;
    std::string status_topic;
    std::atomic<std::size_t> connects{0};
    std::atomic<bool> connected{false};
    std::atomic<bool> closing{false};
    Link last;  ///< the final estimates and "offline", waited for before the disconnect
};

void on_connect(mosquitto* client, void* user, int code) {
    auto* shared = static_cast<Shared*>(user);
    if (code != 0) return;
    mosquitto_subscribe(client, nullptr, shared->filter.c_str(), 1);
    mosquitto_publish(client, nullptr, shared->status_topic.c_str(), 6, "online", 1, true);
    ++shared->connects;
    shared->connected = true;
}

void on_disconnect(mosquitto*, void* user, int) {
    static_cast<Shared*>(user)->connected = false;
}

void on_publish(mosquitto*, void* user, int mid) {
    auto* shared = static_cast<Shared*>(user);
    if (shared->closing) shared->last.acknowledged(mid);
}

void on_message(mosquitto*, void* user, const mosquitto_message* message) {
    auto* shared = static_cast<Shared*>(user);
    const std::string_view topic = message->topic;
    if (topic.find("/feedid/") != std::string_view::npos || topic.starts_with("feedid/")) return;  // our own
    const auto bytes = static_cast<std::size_t>(std::max(0, message->payloadlen));
    {
        std::lock_guard lock(shared->mutex);
        if (shared->queued_bytes + bytes + topic.size() > shared->queue_limit) {
            ++shared->dropped;
            return;
        }
        shared->queue.push_back({std::string(topic), std::string(static_cast<const char*>(message->payload), bytes)});
        shared->queued_bytes += bytes + topic.size();
    }
    shared->arrived.notify_one();
}

std::string default_client_id(const char* role) {
    return fmt::format("feedid-{}-{}", role, ::getpid());
}

/// '<first level>/<machine>/<axis>' of a data topic, or the topic's first level alone.
std::string prefix_of(const std::string& topic, const std::string& machine, const std::string& axis) {
    const std::string first = topic.substr(0, topic.find('/'));
    return machine.empty() ? first : first + "/" + machine + "/" + axis;
}

Client make_client(const std::string& client_id, void* user, bool clean_session = true) {
    Client client(mosquitto_new(client_id.c_str(), clean_session, user));
    if (!client) throw InputError("cannot create an MQTT client (out of memory)");
    return client;
}

void connect_or_throw(mosquitto* client, const BrokerAddress& broker) {
    const int code = mosquitto_connect(client, broker.host.c_str(), broker.port, 30);
    if (code != MOSQ_ERR_SUCCESS) {
        const std::string reason = code == MOSQ_ERR_ERRNO ? std::strerror(errno) : mosquitto_strerror(code);
        throw InputError(fmt::format("cannot reach the MQTT broker at {}: {}", broker.url(), reason));
    }
}

std::string estimate_line(const std::string& machine, const std::string& axis, const nlohmann::json& document) {
    std::string line = fmt::format("{}/{}:", machine, axis);
    const auto& p = document["parameters"];
    const ParameterNaming naming;  // the watch identifies a linear axis's symmetric model
    for (const auto term : {Term::mass, Term::viscous, Term::coulomb}) {
        const std::string symbol = ParameterNaming::symbol(term, Direction::both);
        const auto& e = p[naming.key(term)];
        if (e["value"].is_number() && e["stderr"].is_number())
            line += fmt::format("  {} {:.4g} ± {:.2g} {}", symbol, e["value"].get<double>(), e["stderr"].get<double>(),
                                naming.unit(term));
        else
            line += fmt::format("  {} -", symbol);
    }
    line +=
        fmt::format("  ({} of {} windows, {} samples)", document["windows"]["qualified"].get<std::size_t>(),
                    document["windows"]["total"].get<std::size_t>(), document["stream"]["samples"].get<std::size_t>());
    return line;
}

/// The service: the watcher, the history, and what it publishes.
class Service {
public:
    Service(const ServiceOptions& options, Shared& shared, mosquitto* client)
        : options_(options), shared_(shared), client_(client), watcher_(options.watch) {
        if (!options.database.empty()) store_ = history::open_store(options.database);
    }

    void handle(const Message& message) {
        const std::string error = watcher_.ingest(message.topic, std::as_bytes(std::span(message.payload)));
        if (error.empty()) return;
        const auto names = machine_axis_of_topic(message.topic);
        const std::string topic =
            prefix_of(message.topic, names ? names->first : "", names ? names->second : "") + "/feedid/error";
        const nlohmann::json report = {{"topic", message.topic}, {"error", error}, {"malformed", watcher_.malformed()}};
        publish(topic, report.dump(), 0, false);
        if (watcher_.malformed() <= 10)
            fmt::print(stderr, "feedid watch: dropped a message on {}: {}\n", message.topic, error);
    }

    void publish_estimates(bool all) {
        (void)all;
        for (const auto& [machine, axis] : watcher_.take_changed()) {
            nlohmann::json document = watcher_.estimate_document(machine, axis);
            // the service's counts, so that drops are visible where the estimates are read
            document["service"] = {{"messages", watcher_.messages()},
                                   {"malformed", watcher_.malformed()},
                                   {"dropped_queue_full", dropped()}};
            publish(fmt::format("{}/feedid/estimate", prefix_for(machine, axis)), document.dump(), 1, true);
            if (options_.print) fmt::print("{}\n", estimate_line(machine, axis, document));
        }
        if (options_.print) std::fflush(stdout);
    }

    void record_runs() {
        for (const CompletedRun& run : watcher_.take_completed_runs()) record(run);
    }

    void finish() {
        watcher_.flush();
        publish_estimates(true);
        fmt::print(stderr,
                   "feedid watch: {} messages, {} malformed (dropped), {} dropped by the full queue, {} axes, {} "
                   "connections\n",
                   watcher_.messages(), watcher_.malformed(), dropped(), watcher_.axes(), shared_.connects.load());
    }

    [[nodiscard]] std::size_t dropped() {
        std::lock_guard lock(shared_.mutex);
        return shared_.dropped;
    }

private:
    std::string prefix_for(const std::string& machine, const std::string& axis) const {
        const std::string first = options_.topic_filter.substr(0, options_.topic_filter.find('/'));
        return (first == "+" || first == "#" ? std::string("feedid") : first) + "/" + machine + "/" + axis;
    }

    void publish(const std::string& topic, const std::string& payload, int qos, bool retain) {
        int mid = 0;
        const int code = mosquitto_publish(client_, &mid, topic.c_str(), static_cast<int>(payload.size()),
                                           payload.data(), qos, retain);
        if (shared_.closing && qos > 0 && (code == MOSQ_ERR_SUCCESS || code == MOSQ_ERR_NO_CONN))
            shared_.last.handed(mid);
    }

    void record(const CompletedRun& run) {
        const std::string prefix = prefix_for(run.machine, run.axis);
        if (!store_) return;
        const std::string source = fmt::format("{}/{}#run{}", options_.broker.url(), prefix, run.sequence);
        if (run.estimate.windows.qualified() == 0) {
            fmt::print(stderr, "feedid watch: {}/{} run {} not recorded: no window qualified\n", run.machine, run.axis,
                       run.sequence);
            return;
        }
        const nlohmann::json document =
            online_result_document(run.estimate, options_.watch.online, source, run.t_end - run.t_start);
        history::RunRecord record = history::run_from_result(document, source);
        record.machine = run.machine;
        record.axis = run.axis;
        record.recorded_at = history::now_utc();
        record.trace_path = source;
        record.trace_sha256 = history::sha256_hex(
            fmt::format("{}/{}/{:.17g}/{:.17g}/{}", run.machine, run.axis, run.t_start, run.t_end, run.samples));
        record.options = {{"kind", "watch"},
                          {"window_s", options_.watch.online.window_s},
                          {"offset", options_.watch.online.offset},
                          {"robust", options_.watch.online.robust}};
        if (record.feedid_version.empty()) record.feedid_version = feedid::version;
        try {
            const history::AddOutcome outcome = store_->add_run(record);
            publish(prefix + "/feedid/run",
                    nlohmann::json{{"run", outcome.id}, {"inserted", outcome.inserted}, {"result", document}}.dump(), 1,
                    false);
            if (!outcome.inserted) return;
            history::RunFilter filter;
            filter.machine = run.machine;
            filter.axis = run.axis;
            history::TrendOptions trend;
            trend.keep_points = false;
            for (const auto& series : history::analyse_trends(store_->series(filter), store_->pins(), trend)) {
                for (const history::Alarm& alarm : series.alarms) {
                    if (alarm.run_id != outcome.id) continue;
                    publish(prefix + "/feedid/alarm", history::alarm_document(alarm).dump(), 1, false);
                    if (options_.print) fmt::print("ALARM {}\n", alarm.message());
                }
            }
        } catch (const std::exception& e) {  // a full disk, a locked file: said, and the service goes on
            fmt::print(stderr, "feedid watch: {}/{} run {} not recorded: {}\n", run.machine, run.axis, run.sequence,
                       e.what());
        }
    }

    const ServiceOptions& options_;
    Shared& shared_;
    mosquitto* client_;
    Watcher watcher_;
    std::unique_ptr<history::HistoryStore> store_;
};

/// Store and forward, as an NC's gateway does. While the broker is away, messages are held (at most `limit`; beyond,
/// the oldest is dropped and counted) and sent in order once it is back. A QoS 1 message handed to libmosquitto
/// stays with it until the broker acknowledges it, over reconnects (it resends it itself: holding it here too sent
/// it twice, and counting acknowledgements against sends then ended the stream before its last message was
/// acknowledged). An acknowledgement only says that the broker has the message, not that a subscriber got it: a
/// broker killed loses what it acknowledged since its last save. So after every reconnect the messages of the last
/// `replay_s` seconds before the connection was lost are sent again (the subscriber skips what it has by time stamp).
class Outbox {
public:
    Outbox(mosquitto* client, Link& link, const PublishOptions& options, std::size_t limit)
        : client_(client), link_(link), options_(options), limit_(limit) {}

    void send(const std::string& topic, std::string payload) {
        flush();
        if (held_.empty() && link_.connected && publish(topic, payload)) {
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
        if (!link_.connected) return held_.empty();
        if (const std::size_t connects = link_.connects; connects != connects_seen_) {
            connects_seen_ = connects;
            if (connects > 1) replay();
        }
        while (!held_.empty() && link_.connected && publish(held_.front().first, held_.front().second)) {
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
    /// true when the library took the message: sent, or (QoS 1) queued to be sent when the connection is back.
    bool publish(const std::string& topic, const std::string& payload) {
        int mid = 0;
        const int code = mosquitto_publish(client_, &mid, topic.c_str(), static_cast<int>(payload.size()),
                                           payload.data(), options_.qos, false);
        // QoS > 0: the library queues the message before it tries to send it, and keeps it when the connection is
        // down (MOSQ_ERR_NO_CONN)
        const bool taken = code == MOSQ_ERR_SUCCESS || (options_.qos > 0 && code == MOSQ_ERR_NO_CONN);
        if (taken) link_.handed(mid);
        return taken;
    }
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
            if (!publish(r.topic, r.payload)) break;
            ++replayed_;
        }
    }
    struct Recent {
        Clock::time_point sent;
        std::string topic, payload;
    };
    mosquitto* client_;
    Link& link_;
    const PublishOptions& options_;
    std::size_t limit_;
    std::deque<std::pair<std::string, std::string>> held_;  ///< topic, payload
    std::deque<Recent> recent_;
    std::size_t connects_seen_{0};
    std::size_t sent_{0}, lost_{0}, held_total_{0}, replayed_{0};
};

}  // namespace

bool mqtt_available() {
    return true;
}

int run_watch(const ServiceOptions& options) {
    if (auto e = check_topic_filter(options.topic_filter); !e.empty())
        throw InputError(fmt::format("--topic '{}': {}", options.topic_filter, e));
    if (auto e = options.watch.validate(); !e.empty()) throw InputError(e);
    Library library;
    Shared shared;
    shared.queue_limit = options.queue_bytes;
    shared.filter = options.topic_filter;
    const std::string first = options.topic_filter.substr(0, options.topic_filter.find('/'));
    shared.status_topic = !options.status_topic.empty()    ? options.status_topic
                          : (first == "+" || first == "#") ? std::string("feedid/status")
                                                           : first + "/feedid/status";
    // a client id of the user's: a persistent session (the broker keeps QoS 1 messages while feedid watch is away)
    Client client = make_client(options.client_id.empty() ? default_client_id("watch") : options.client_id, &shared,
                                options.client_id.empty());
    mosquitto_reconnect_delay_set(client.get(), 1, 32, true);  // 1, 2, 4, ... 32 s
    mosquitto_will_set(client.get(), shared.status_topic.c_str(), 7, "offline", 1, true);
    mosquitto_connect_callback_set(client.get(), on_connect);
    mosquitto_disconnect_callback_set(client.get(), on_disconnect);
    mosquitto_message_callback_set(client.get(), on_message);
    mosquitto_publish_callback_set(client.get(), on_publish);
    Service service(options, shared, client.get());  // opens the history: exit 2 before connecting when it cannot
    connect_or_throw(client.get(), options.broker);
    stop_requested = false;
    std::signal(SIGTERM, request_stop);
    std::signal(SIGINT, request_stop);
    mosquitto_loop_start(client.get());
    const auto interval = std::chrono::duration<double>(options.estimate_interval_s);
    auto next_estimate = Clock::now() + std::chrono::duration_cast<Clock::duration>(interval);
    auto last_message = Clock::now();
    std::deque<Message> batch;
    const auto drain = [&] {
        {
            std::lock_guard lock(shared.mutex);
            batch.swap(shared.queue);
            shared.queued_bytes = 0;
        }
        if (!batch.empty()) last_message = Clock::now();
        for (const Message& message : batch) service.handle(message);
        batch.clear();
        service.record_runs();
    };
    while (!stop_requested) {
        {
            std::unique_lock lock(shared.mutex);
            shared.arrived.wait_for(lock, std::chrono::milliseconds(50), [&] { return !shared.queue.empty(); });
        }
        drain();
        if (Clock::now() >= next_estimate) {
            service.publish_estimates(false);
            next_estimate = Clock::now() + std::chrono::duration_cast<Clock::duration>(interval);
        }
        if (options.idle_exit_s &&
            std::chrono::duration<double>(Clock::now() - last_message).count() > *options.idle_exit_s)
            break;
    }
    drain();
    shared.closing = true;
    service.finish();
    service.record_runs();
    int mid = 0;
    if (const int code = mosquitto_publish(client.get(), &mid, shared.status_topic.c_str(), 7, "offline", 1, true);
        code == MOSQ_ERR_SUCCESS || code == MOSQ_ERR_NO_CONN)
        shared.last.handed(mid);
    // the final estimates and "offline" acknowledged by the broker (at most 5 s: a broker away keeps its last will)
    for (const auto until = Clock::now() + std::chrono::seconds(5);
         (shared.last.pending() > 0 || !shared.connected) && Clock::now() < until;)
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    mosquitto_disconnect(client.get());
    mosquitto_loop_stop(client.get(), false);
    // libmosquitto acknowledges a message as it takes it: what came after the last drain is gone, and said
    if (const std::size_t late = shared.queue.size(); late > 0)
        fmt::print(stderr, "feedid watch: {} messages came after the final estimates and were not identified\n", late);
    std::signal(SIGTERM, SIG_DFL);
    std::signal(SIGINT, SIG_DFL);
    return 0;
}

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

int run_publish(const Batch& stream, const PublishOptions& options) {
    if (options.topic.empty() || options.topic.find_first_of("+#") != std::string::npos)
        throw InputError(fmt::format("--topic '{}': a topic to publish to has no wildcards", options.topic));
    if (options.copies > 1 && options.topic.find("{n}") == std::string::npos)
        throw InputError(fmt::format("--copies {}: the topic '{}' needs a '{{n}}' to tell the copies apart",
                                     options.copies, options.topic));
    Library library;
    Link link;
    // a client id of the user's: a persistent session (the broker keeps the QoS 1 exchange in flight over a restart)
    Client client = make_client(options.client_id.empty() ? default_client_id("publish") : options.client_id, &link,
                                options.client_id.empty());
    mosquitto_reconnect_delay_set(client.get(), 1, 1, false);  // an NC's gateway retries every second
    link.at_most_once = options.qos == 0;
    mosquitto_disconnect_callback_set(client.get(),
                                      [](mosquitto*, void* user, int) { static_cast<Link*>(user)->disconnected(); });
    mosquitto_publish_callback_set(
        client.get(), [](mosquitto*, void* user, int mid) { static_cast<Link*>(user)->acknowledged(mid); });
    mosquitto_connect_callback_set(client.get(), [](mosquitto*, void* user, int code) {
        if (code != 0) return;
        auto* link = static_cast<Link*>(user);
        ++link->connects;
        link->connected = true;
    });
    connect_or_throw(client.get(), options.broker);
    mosquitto_loop_start(client.get());
    // the first CONNACK: publishing before it would only queue in the library
    for (const auto until = Clock::now() + std::chrono::seconds(30); !link.connected && Clock::now() < until;)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    stop_requested = false;
    std::signal(SIGTERM, request_stop);
    std::signal(SIGINT, request_stop);
    const std::size_t n = stream.samples();
    const auto per_message = static_cast<std::size_t>(std::max(1.0, std::round(options.batch_s / stream.dt)));
    Batch part;
    part.machine = stream.machine;
    part.axis = stream.axis;
    part.dt = stream.dt;
    part.drive_is_force = stream.drive_is_force;
    part.force_constant = stream.force_constant;
    const std::vector<std::string> topics = copy_topics(options);
    const auto start = Clock::now();
    Outbox outbox(
        client.get(), link, options,
        static_cast<std::size_t>(std::ceil(options.buffer_s / (static_cast<double>(per_message) * stream.dt))));
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
    // what is held, and what the library holds (QoS 1 awaiting acknowledgement, each by its message id), leaves
    // before the disconnect: the stream's last message too
    const auto give_up = Clock::now() + std::chrono::seconds(60);
    while ((!outbox.flush() || link.pending() > 0 || !link.connected) && Clock::now() < give_up && !stop_requested)
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const std::size_t unacknowledged = link.pending();
    mosquitto_disconnect(client.get());
    mosquitto_loop_stop(client.get(), false);
    std::signal(SIGTERM, SIG_DFL);
    std::signal(SIGINT, SIG_DFL);
    fmt::print(stderr,
               "feedid publish: {} messages sent to {} on {} ({} held while the broker was away, {} sent again after "
               "a reconnect), {} lost, {} not acknowledged\n",
               outbox.sent(), topics.size() == 1 ? topics[0] : options.topic, options.broker.url(), outbox.held_total(),
               outbox.replayed(), outbox.lost() + link.dropped_unwritten, unacknowledged);
    return 0;
}

}  // namespace feedid::watch
