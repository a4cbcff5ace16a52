// feedid watch: the live service over MQTT (subscribe, identify per axis, publish estimates and alarms, record runs);
// feedid publish: streams a trace to a broker as an NC would (tests, demos).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/io/config_file.hpp"
#include "feedid/io/import.hpp"
#include "feedid/history/record.hpp"
#include "feedid/stream/service.hpp"

namespace feedid::cli {
namespace {

/// watch.toml: [online] window_s offset robust cutoff_hz; [force_constants] AXIS or "MACHINE/AXIS" = N/A;
/// [run] windows period_s gap_s reorder_s; [service] estimate_interval_s queue_mb max_samples.
void read_config(const std::string& path, watch::ServiceOptions& options) {
    const nlohmann::json document = parse_toml(read_file_bytes(path), path);
    ConfigSection root(document, path);
    auto& online = options.watch.online;
    if (auto t = root.section("online")) {
        if (const auto v = t->number("window_s", {0.1, 600.0, "s"})) online.window_s = *v;
        if (const auto v = t->number("cutoff_hz", {1e-3, 1e6, "Hz"})) online.cutoff_hz = *v;
        if (const auto v = t->boolean("offset")) online.offset = *v;
        if (const auto v = t->boolean("robust")) online.robust = *v;
        t->reject_unknown();
    }
    if (auto t = root.section("force_constants")) {
        for (const auto& key : t->keys()) {
            const auto value = t->number(key);
            if (!value || *value == 0.0) t->refuse(key, "must be a non-zero number [N/A]");
            options.watch.force_constants[key] = *value;
        }
    }
    if (auto t = root.section("run")) {
        if (const auto v = t->number("windows", {0.0, 1e9, "windows"}))
            options.watch.run_windows = static_cast<std::size_t>(*v);
        if (const auto v = t->number("period_s", {0.0, 1e9, "s"})) options.watch.run_period_s = *v;
        if (const auto v = t->number("gap_s", {1e-3, 1e9, "s"})) options.watch.run_gap_s = *v;
        if (const auto v = t->number("reorder_s", {0.0, 3600.0, "s"})) options.watch.reorder_s = *v;
        t->reject_unknown();
    }
    if (auto t = root.section("service")) {
        if (const auto v = t->number("estimate_interval_s", {0.01, 3600.0, "s"})) options.estimate_interval_s = *v;
        if (const auto v = t->number("queue_mb", {1.0, 65536.0, "MiB"}))
            options.queue_bytes = static_cast<std::size_t>(*v * (1u << 20));
        if (const auto v = t->number("max_samples", {1.0, 1e8, "samples"}))
            options.watch.limits.max_samples = static_cast<std::size_t>(*v);
        t->reject_unknown();
    }
    root.reject_unknown();
}

struct WatchCommand {
    std::string broker;
    std::string config;
    std::optional<double> idle_exit_s;
    watch::ServiceOptions options;
    bool quiet{false};

    int run() {
        options.broker = watch::parse_broker(broker);
        if (!config.empty()) read_config(config, options);
        if (!options.database.empty()) history::check_recordable(options.database);
        options.idle_exit_s = idle_exit_s;
        options.print = !quiet;
        return watch::run_watch(options);
    }
};

struct PublishCommand {
    TraceArguments trace;
    DriveArguments drive;
    std::string broker;
    std::string rate{fmt::format("{:g}x", watch::PublishOptions{}.rate)};  // the library's rate as written here
    double time_offset_s{0.0};
    std::optional<double> duration_s;
    watch::PublishOptions options;

    int run() {
        options.broker = watch::parse_broker(broker);
        if (rate == "max") {
            options.rate = 0.0;
        } else {
            std::string number = rate;
            if (!number.empty() && number.back() == 'x') number.pop_back();
            char* end = nullptr;
            options.rate = std::strtod(number.c_str(), &end);
            if (number.empty() || *end != '\0' || !std::isfinite(options.rate) || options.rate <= 0.0 ||
                options.rate > 1e6)
                throw InputError(fmt::format("--rate '{}': give a factor of real time (10x) or 'max'", rate));
        }
        Trace source = read_trace_for_drive(trace, drive);
        if (duration_s) {  // the first duration_s of the trace
            const auto t = source.column(Role::time);
            const auto end = std::upper_bound(t.begin(), t.end(), t.front() + *duration_s);
            source = source.slice(0, static_cast<std::size_t>(end - t.begin()));
        }
        if (source.samples() < 2) throw InputError(fmt::format("{}: fewer than two samples to publish", trace.file));
        watch::Batch stream;
        const auto time = source.column(Role::time);
        const auto base = source.time_base();
        if (!source.has(Role::position))
            throw InputError(fmt::format("{}: no position channel to publish", trace.file));
        stream.t0 = time.front() + time_offset_s;
        stream.dt = base.sample_time_s;
        const auto position = source.column(Role::position);
        stream.position.assign(position.begin(), position.end());
        if (source.has(Role::force)) {
            stream.drive_is_force = true;
            const auto force = source.column(Role::force);
            stream.drive.assign(force.begin(), force.end());
        } else if (source.has(Role::current)) {
            const auto current = source.column(Role::current);
            stream.drive.assign(current.begin(), current.end());
            stream.force_constant = drive.constants().force_per_signal(source);
        } else {
            throw InputError(fmt::format("{}: no current or force channel to publish", trace.file));
        }
        return watch::run_publish(stream, options);
    }
};

}  // namespace

Action add_watch_command(CLI::App& app) {
    auto command = std::make_shared<WatchCommand>();
    auto* sub = app.add_subcommand(
        "watch", "Live over MQTT: identify every axis that publishes samples, publish estimates and drift alarms");
    sub->add_option("--broker", command->broker, "The broker: mqtt://HOST[:PORT]")->required();
    sub->add_option(
           "--topic", command->options.topic_filter,
           "Topic filter of the data; machine and axis are the 2nd and 3rd levels (plant/<machine>/<axis>/...)")
        ->capture_default_str();
    sub->add_option(
        "--db", command->options.database,
        "History (a SQLite file or a postgresql:// database) to record each completed identification in, and to "
        "check for drift");
    sub->add_option(
        "--config", command->config,
        "watch.toml: [online] window_s offset robust cutoff_hz, [force_constants] X = 52.0 or "
        "\"M1/X\" = 52.0 [N/A], [run] windows period_s gap_s reorder_s, [service] estimate_interval_s queue_mb "
        "max_samples");
    sub->add_option("--status-topic", command->options.status_topic,
                    "Where online/offline (the last will) goes (default: <first level>/feedid/status)");
    sub->add_option("--client-id", command->options.client_id,
                    "MQTT client id: a persistent session under it (the broker keeps QoS 1 messages while watch is "
                    "away); default feedid-watch-PID with a clean session");
    sub->add_option("--idle-exit", command->idle_exit_s,
                    "Stop as on SIGTERM after this many seconds without a message (tests, demos) [s]")
        ->check(allowed_range(0.01, 1e6, "s"));
    sub->add_flag("--quiet", command->quiet, "No line per published estimate on stdout");
    sub->footer("Example: feedid watch --broker mqtt://127.0.0.1:1883 --db shop.db --config watch.toml");
    return [command] { return command->run(); };
}

Action add_publish_command(CLI::App& app) {
    auto command = std::make_shared<PublishCommand>();
    auto* sub = app.add_subcommand("publish", "Stream a trace to an MQTT broker as an NC would (tests, demos)");
    command->trace.add_to(*sub);
    command->drive.add_to(*sub);
    sub->add_option("--broker", command->broker, "The broker: mqtt://HOST[:PORT]")->required();
    sub->add_option("--topic", command->options.topic, "Topic to publish to, e.g. plant/M1/X/axis")->required();
    sub->add_option("--rate", command->rate, "Times real time ('20x'), or 'max'")->capture_default_str();
    sub->add_option("--batch", command->options.batch_s, "Stream time per message [s]")
        ->capture_default_str()
        ->check(allowed_range(1e-4, 60.0, "s"));
    sub->add_option("--client-id", command->options.client_id,
                    "MQTT client id: a persistent session under it; default feedid-publish-PID with a clean session");
    sub->add_option("--duration", command->duration_s, "Publish only the first this many seconds of the trace [s]")
        ->check(allowed_range(1e-3, 1e9, "s"));
    sub->add_option("--buffer", command->options.buffer_s,
                    "Stream time held while the broker is away, sent when it is back [s]")
        ->capture_default_str()
        ->check(allowed_range(0.0, 1e6, "s"));
    sub->add_option("--replay", command->options.replay_s,
                    "QoS 1/2: after a reconnect, send again what was sent in this much time before the connection "
                    "was lost (a killed broker loses what it acknowledged since its last save) [s]")
        ->capture_default_str()
        ->check(allowed_range(0.0, 3600.0, "s"));
    sub->add_option("--copies", command->options.copies,
                    "Publish the stream on N topics at once, '{n}' in --topic replaced by 1..N (a benchmark's load)")
        ->check(CLI::Range(1, 100000));
    sub->add_flag("--binary", command->options.binary, "The binary payload (default JSON)");
    sub->add_option("--qos", command->options.qos, "MQTT QoS of the data messages")
        ->capture_default_str()
        ->check(CLI::Range(0, 2));
    sub->add_option("--time-offset", command->time_offset_s, "Added to the trace's time stamps [s] (a later recording)")
        ->check(allowed_range(-1e12, 1e12, "s"));
    sub->footer(
        "Example: feedid publish trace.csv --axis X --broker mqtt://127.0.0.1:1883 --topic plant/M1/X/axis "
        "--rate 20x");
    return [command] { return command->run(); };
}

}  // namespace feedid::cli
