// feedid watch over MQTT (service.hpp): the source side of the MQTT client (mqtt_client.hpp) feeding a Watcher,
// its estimates, errors and status published back, its completed runs recorded through the spool (run_recorder.hpp).
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include <unistd.h>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/core/terminal_text.hpp"
#include "feedid/history/sha256.hpp"
#include "feedid/history/store.hpp"
#include "feedid/stream/service.hpp"
#include "mqtt_client.hpp"
#include "run_recorder.hpp"

namespace feedid::watch {
namespace {

using Clock = std::chrono::steady_clock;

std::atomic<bool> stop_requested{false};
extern "C" void watch_request_stop(int) {
    stop_requested = true;
}

struct Message {
    std::string topic;
    std::string payload;
};
/// What a queued message costs beyond its bytes (the strings and the deque's slot) [bytes].
constexpr std::size_t message_overhead = sizeof(Message) + 64;

/// From the network thread to the service thread: the messages, bounded in bytes (what would overflow is dropped and
/// counted).
struct Inbox {
    std::mutex mutex;
    std::condition_variable arrived;
    std::deque<Message> queue;
    std::size_t bytes{0};
    std::size_t limit{0};
    std::size_t dropped{0};

    void take(const mosquitto_message& message) {
        const std::string_view topic = message.topic;
        if (topic.find("/feedid/") != std::string_view::npos || topic.starts_with("feedid/")) return;  // our own
        const auto size = static_cast<std::size_t>(std::max(0, message.payloadlen));
        {
            std::lock_guard lock(mutex);
            const std::size_t cost = size + topic.size() + message_overhead;
            if (bytes + cost > limit) {
                ++dropped;
                return;
            }
            queue.push_back({std::string(topic), std::string(static_cast<const char*>(message.payload), size)});
            bytes += cost;
        }
        arrived.notify_one();
    }
};

std::string estimate_line(const std::string& machine, const std::string& axis, const nlohmann::json& document) {
    std::string line = fmt::format("{}/{}:", terminal_text(machine), terminal_text(axis));
    const auto& p = document["parameters"];
    const ParameterNaming naming;  // the watch identifies a linear axis's symmetric model
    for (const auto term : {Term::mass, Term::viscous, Term::coulomb, Term::offset}) {
        // the offset where the estimate's model has one (selected from the data, or --offset)
        if (term == Term::offset && !p.contains(naming.key(term))) continue;
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

std::string dump(const nlohmann::json& document) {
    return document.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

/// '<first level of the filter>' ("feedid" when that level is a wildcard): where the service publishes.
std::string first_level(const std::string& filter) {
    const std::string first = filter.substr(0, filter.find('/'));
    return first == "+" || first == "#" ? std::string("feedid") : first;
}

/// The service: the watcher and what it publishes; completed runs go to the recorder.
class Service {
public:
    Service(const ServiceOptions& options, MqttClient& client, Inbox& inbox, RunRecorder* recorder)
        : options_(options),
          client_(client),
          inbox_(inbox),
          recorder_(recorder),
          watcher_(options.watch),
          first_(first_level(options.topic_filter)) {}

    /// One message: identified, or refused with its reason on `error`; nothing in it stops the service.
    void handle(const Message& message) {
        std::string error;
        try {
            error = watcher_.ingest(message.topic, std::as_bytes(std::span(message.payload)));
        } catch (const std::exception& e) {  // ingest never throws; this is the last line of defence
            error = fmt::format("cannot take the message: {}", terminal_text(e.what()));
        }
        if (error.empty()) return;
        try {
            const auto names = machine_axis_of_topic(message.topic);
            const bool named =
                names && name_problem(names->first, 64).empty() && name_problem(names->second, 64).empty();
            const std::string topic =
                named ? prefix_for(names->first, names->second) + "/feedid/error" : first_ + "/feedid/error";
            const nlohmann::json report = {{"topic", terminal_text(message.topic.substr(0, 256))},
                                           {"error", error},
                                           {"malformed", watcher_.malformed()}};
            client_.publish(topic, dump(report), 0, false);
            if (watcher_.malformed() <= 10)
                fmt::print(stderr, "feedid watch: dropped a message on {}: {}\n",
                           terminal_text(message.topic.substr(0, 256)), terminal_text(error));
        } catch (const std::exception&) {  // the report itself failed (out of memory): the count is kept
        }
    }

    /// The estimates of the axes that received data (while connected: a broker that is away gets the latest later).
    void publish_estimates(bool final) {
        if (!client_.connected() && !final) return;
        for (const auto& [machine, axis] : watcher_.take_changed()) {
            try {
                nlohmann::json document = watcher_.estimate_document(machine, axis);
                document["service"] = service_counts();
                client_.publish(prefix_for(machine, axis) + "/feedid/estimate", dump(document), 1, true);
                if (options_.print) fmt::print("{}\n", estimate_line(machine, axis, document));
            } catch (const std::exception& e) {
                fmt::print(stderr, "feedid watch: the estimate of {}/{} was not published: {}\n",
                           terminal_text(machine), terminal_text(axis), terminal_text(e.what()));
            }
        }
        if (options_.print) std::fflush(stdout);
    }

    void record_runs() {
        for (const CompletedRun& run : watcher_.take_completed_runs()) {
            try {
                record(run);
            } catch (const std::exception& e) {
                fmt::print(stderr, "feedid watch: {}/{} run {} not recorded: {}\n", terminal_text(run.machine),
                           terminal_text(run.axis), run.sequence, terminal_text(e.what()));
            }
        }
    }

    void finish() {
        watcher_.flush();
        publish_estimates(true);
        fmt::print(
            stderr,
            "feedid watch: {} messages, {} malformed (dropped; {} naming another machine or axis than their topic, "
            "{} of axes beyond the limits), {} dropped by the full queue, {} holes given up early for memory, {} "
            "axes, {} connections\n",
            watcher_.messages(), watcher_.malformed(), watcher_.foreign_names(), watcher_.refused_axes(), dropped(),
            watcher_.evicted_holds(), watcher_.axes(), client_.connects());
    }

    [[nodiscard]] std::size_t dropped() {
        std::lock_guard lock(inbox_.mutex);
        return inbox_.dropped;
    }
    [[nodiscard]] std::size_t completed() const { return completed_; }

private:
    std::string prefix_for(const std::string& machine, const std::string& axis) const {
        return first_ + "/" + machine + "/" + axis;
    }

    /// The service's counts, so that refusals and drops are visible where the estimates are read.
    nlohmann::json service_counts() {
        return {{"messages", watcher_.messages()},
                {"malformed", watcher_.malformed()},
                {"foreign_names", watcher_.foreign_names()},
                {"refused_axes", watcher_.refused_axes()},
                {"evicted_holds", watcher_.evicted_holds()},
                {"held_bytes", watcher_.held_bytes()},
                {"dropped_queue_full", dropped()}};
    }

    void record(const CompletedRun& run) {
        if (!recorder_) return;
        const std::string prefix = prefix_for(run.machine, run.axis);
        const std::string source = fmt::format("{}/{}#run{}", options_.broker.url(), prefix, run.sequence);
        if (run.estimate.windows.qualified() == 0) {
            fmt::print(stderr, "feedid watch: {}/{} run {} not recorded: no window qualified\n",
                       terminal_text(run.machine), terminal_text(run.axis), run.sequence);
            return;
        }
        ++completed_;
        const nlohmann::json options = {{"kind", "watch"},
                                        {"window_s", options_.watch.online.window_s},
                                        {"offset", options_.watch.online.offset},
                                        {"robust", options_.watch.online.robust}};
        const nlohmann::json entry = {
            {"machine", run.machine},
            {"axis", run.axis},
            {"sequence", run.sequence},
            {"source", source},
            {"prefix", prefix},
            {"recorded_at", history::now_utc()},
            {"trace_sha256", history::sha256_hex(fmt::format("{}/{}/{:.17g}/{:.17g}/{}", run.machine, run.axis,
                                                             run.t_start, run.t_end, run.samples))},
            {"options", options},
            {"result", online_result_document(run.estimate, options_.watch.online, source, run.t_end - run.t_start)}};
        recorder_->put(entry);
    }

    const ServiceOptions& options_;
    MqttClient& client_;
    Inbox& inbox_;
    RunRecorder* recorder_;
    Watcher watcher_;
    std::string first_;
    std::size_t completed_{0};
};

std::string default_client_id(const char* role) {
    return fmt::format("feedid-{}-{}", role, ::getpid());
}

/// Runs the service loop until a signal (or idle_exit_s): drains the inbox, publishes estimates on their interval.
void serve(const ServiceOptions& options, Inbox& inbox, Service& service) {
    const auto interval = std::chrono::duration<double>(options.estimate_interval_s);
    auto next_estimate = Clock::now() + std::chrono::duration_cast<Clock::duration>(interval);
    auto last_message = Clock::now();
    std::deque<Message> batch;
    const auto drain = [&] {
        {
            std::lock_guard lock(inbox.mutex);
            batch.swap(inbox.queue);
            inbox.bytes = 0;
        }
        if (!batch.empty()) last_message = Clock::now();
        for (const Message& message : batch) service.handle(message);
        batch.clear();
        service.record_runs();
    };
    while (!stop_requested) {
        {
            std::unique_lock lock(inbox.mutex);
            inbox.arrived.wait_for(lock, std::chrono::milliseconds(50), [&] { return !inbox.queue.empty(); });
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
}

}  // namespace

bool mqtt_available() {
    return true;
}

int run_watch(const ServiceOptions& options) {
    if (auto e = check_topic_filter(options.topic_filter); !e.empty())
        throw InputError(fmt::format("--topic '{}': {}", terminal_text(options.topic_filter), e));
    if (auto e = options.watch.validate(); !e.empty()) throw InputError(e);
    MqttLibrary library;
    Inbox inbox;
    inbox.limit = options.queue_bytes;
    ClientRole role;
    // a client id of the user's: a persistent session (the broker keeps QoS 1 messages while feedid watch is away)
    role.client_id = options.client_id.empty() ? default_client_id("watch") : options.client_id;
    role.clean_session = options.client_id.empty();
    role.status_topic =
        options.status_topic.empty() ? first_level(options.topic_filter) + "/feedid/status" : options.status_topic;
    role.subscription = options.topic_filter;
    role.program = "feedid watch";
    MqttClient client(options.broker, role, [&](const mosquitto_message& m) { inbox.take(m); });
    // the history and its spool: exit 2 before connecting when they cannot be opened for writing
    std::optional<RunRecorder> recorder;
    if (!options.database.empty())
        recorder.emplace(options, [&](const std::string& topic, const std::string& payload, int qos) {
            client.publish(topic, payload, qos, false);
        });
    Service service(options, client, inbox, recorder ? &*recorder : nullptr);
    client.start();  // exit 2 when the broker refuses us or does not answer
    if (recorder) recorder->start();
    stop_requested = false;
    std::signal(SIGTERM, watch_request_stop);
    std::signal(SIGINT, watch_request_stop);
    serve(options, inbox, service);
    service.finish();
    service.record_runs();
    if (recorder) {
        // what completed is on disk; what the history does not take within 10 s waits there for the next watch
        if (const std::size_t left = recorder->finish(10.0); left > 0)
            fmt::print(stderr,
                       "feedid watch: {} completed run(s) wait in the spool {}: the next feedid watch on this "
                       "history writes them\n",
                       left, recorder->spool().folder().string());
        fmt::print(stderr,
                   "feedid watch: {} completed run(s); {} recorded in the history, {} set aside as refused, {} lost\n",
                   service.completed(), recorder->recorded(), recorder->rejected(), recorder->lost());
    }
    client.publish(role.status_topic, "offline", 1, true);
    // the final estimates and "offline" acknowledged by the broker (at most 5 s: a broker away keeps its last will)
    for (const auto until = Clock::now() + std::chrono::seconds(5);
         (client.pending() > 0 || !client.connected()) && Clock::now() < until;)
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    client.stop();
    // libmosquitto acknowledges a message as it takes it: what came after the last drain is gone, and said
    if (const std::size_t late = inbox.queue.size(); late > 0)
        fmt::print(stderr, "feedid watch: {} messages came after the final estimates and were not identified\n", late);
    std::signal(SIGTERM, SIG_DFL);
    std::signal(SIGINT, SIG_DFL);
    return 0;
}

}  // namespace feedid::watch
