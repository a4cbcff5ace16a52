// feedid watch: the live service over MQTT (subscribe, identify per axis, publish estimates and alarms, record runs);
// feedid publish: streams a trace to a broker as an NC would (tests, demos).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>

#include <fmt/core.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/io/config_file.hpp"
#include "feedid/io/import.hpp"
#include "feedid/history/record.hpp"
#include "feedid/stream/service.hpp"

namespace feedid::cli {
namespace {

/// [broker] url username password_file cafile cert key connect_timeout_s (a password itself is never taken here).
/// True when it gives the url.
bool read_broker_config(ConfigSection& t, watch::BrokerOptions& broker) {
    const auto url = t.text("url");
    if (url) {
        const watch::BrokerOptions parsed = watch::parse_broker(*url);
        broker.host = parsed.host;
        broker.port = parsed.port;
        broker.tls = parsed.tls;
        if (!parsed.username.empty()) broker.username = parsed.username;
    }
    for (const auto& [key, field] :
         {std::pair{"username", &broker.username}, std::pair{"password_file", &broker.password_file},
          std::pair{"cafile", &broker.cafile}, std::pair{"cert", &broker.certfile}, std::pair{"key", &broker.keyfile}})
        if (auto value = t.text(key)) *field = *value;
    if (const auto v = t.number("connect_timeout_s", {0.1, 3600.0, "s"})) broker.connect_timeout_s = *v;
    t.reject_unknown();
    return url.has_value();
}

/// [service] estimate_interval_s queue_mb max_samples min_dt_s max_axes axes_mb max_window_samples held_mb
/// trust_payload_names.
void read_service_config(ConfigSection& t, watch::ServiceOptions& options) {
    auto& w = options.watch;
    const auto megabytes = [&](const char* key, std::size_t& bytes) {
        if (const auto v = t.number(key, {1.0, 65536.0, "MiB"})) bytes = static_cast<std::size_t>(*v * (1u << 20));
    };
    const auto count = [&](const char* key, std::size_t& value, ValueRange range) {
        if (const auto v = t.number(key, range)) value = static_cast<std::size_t>(*v);
    };
    if (const auto v = t.number("estimate_interval_s", {0.01, 3600.0, "s"})) options.estimate_interval_s = *v;
    megabytes("queue_mb", options.queue_bytes);
    count("max_samples", w.limits.max_samples, {1.0, 1e8, "samples"});
    if (const auto v = t.number("min_dt_s", {1e-9, 10.0, "s"})) w.limits.min_dt_s = *v;
    count("max_axes", w.max_axes, {1.0, 1e7, "axes"});
    megabytes("axes_mb", w.axes_bytes);
    count("max_window_samples", w.max_window_samples, {100.0, 1e9, "samples"});
    megabytes("held_mb", w.held_bytes);
    if (const auto v = t.boolean("trust_payload_names")) w.trust_payload_names = *v;
    t.reject_unknown();
}

/// [history] spool_dir spool_mb db_retry_s.
void read_history_config(ConfigSection& t, watch::ServiceOptions& options) {
    if (auto dir = t.text("spool_dir")) options.spool_dir = *dir;
    if (const auto v = t.number("spool_mb", {1.0, 1e6, "MiB"}))
        options.spool_bytes = static_cast<std::size_t>(*v * (1u << 20));
    if (const auto v = t.number("db_retry_s", {0.0, 1e7, "s"})) options.db_retry_s = *v;
    t.reject_unknown();
}

/// watch.toml: [broker] url username password_file cafile cert key; [online] window_s offset robust cutoff_hz;
/// [force_constants] AXIS or "MACHINE/AXIS" = N/A; [run] windows period_s gap_s reorder_s; [service] (above);
/// [history] spool_dir spool_mb db_retry_s. True when it names the broker ([broker] url).
bool read_config(const std::string& path, watch::ServiceOptions& options) {
    const nlohmann::json document = parse_toml(read_file_bytes(path), path);
    ConfigSection root(document, path);
    bool names_broker = false;
    if (auto t = root.section("broker")) names_broker = read_broker_config(*t, options.broker);
    auto& online = options.watch.online;
    if (auto t = root.section("online")) {
        if (const auto v = t->number("window_s", {0.1, 600.0, "s"})) online.window_s = *v;
        if (const auto v = t->number("cutoff_hz", {1e-3, 1e6, "Hz"})) online.cutoff_hz = *v;
        if (const auto v = t->boolean("offset")) online.offset = *v;
        if (const auto v = t->boolean("robust")) online.robust = *v;
        if (const auto v = t->text("delay")) {
            // auto: estimated, its uncertainty in every parameter, and a significant one corrected to first order (a
            // stream is not run twice); none: the drive signal as logged; a time: applied to every window
            if (const auto problem = delay_problem(*v); !problem.empty()) t->refuse("delay", problem);
            online.estimate_delay = *v == "auto";
            online.drive_delay_s = *v == "auto" || *v == "none" ? 0.0 : parse_delay(*v);
            if (const auto problem = online.validate(); !problem.empty()) t->refuse("delay", problem);
        }
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
    if (auto t = root.section("service")) read_service_config(*t, options);
    if (auto t = root.section("history")) read_history_config(*t, options);
    root.reject_unknown();
    return names_broker;
}

/// How to reach and log in to the broker, as watch and publish both take it: the command line wins over watch.toml.
struct BrokerArguments {
    std::string url;
    std::string username, password_file, cafile, certfile, keyfile;

    void add_to(CLI::App& sub, bool required) {
        auto* broker = sub.add_option("--broker", url,
                                      "The broker: mqtt://HOST[:PORT], or mqtts://HOST[:PORT] for TLS (port 8883); a "
                                      "password in the URL is refused");
        if (required) broker->required();
        sub.add_option("--username", username, "MQTT username (also mqtt://USER@HOST)");
        sub.add_option("--password-file", password_file,
                       fmt::format("File whose first line is the MQTT password (else the environment variable {}; "
                                   "never on the command line)",
                                   watch::broker_password_variable));
        sub.add_option("--cafile", cafile,
                       "mqtts://: PEM file of the CA that signed the broker's certificate (default: the system's)");
        sub.add_option("--cert", certfile, "mqtts://: PEM client certificate, for a broker that asks for one");
        sub.add_option("--key", keyfile, "mqtts://: its private key (PEM, not encrypted)");
    }

    /// Applies what was given to `broker` (which may hold watch.toml's settings already).
    void apply(watch::BrokerOptions& broker) const {
        if (!url.empty()) {
            const watch::BrokerOptions parsed = watch::parse_broker(url);
            broker.host = parsed.host;
            broker.port = parsed.port;
            broker.tls = parsed.tls;
            if (!parsed.username.empty()) broker.username = parsed.username;
        }
        for (const auto& [given, field] :
             {std::pair{&username, &broker.username}, std::pair{&password_file, &broker.password_file},
              std::pair{&cafile, &broker.cafile}, std::pair{&certfile, &broker.certfile},
              std::pair{&keyfile, &broker.keyfile}})
            if (!given->empty()) *field = *given;
        if (auto problem = broker.validate(); !problem.empty())
            throw InputError(fmt::format("--broker {}: {}", broker.url(), problem));
    }
};

struct WatchCommand {
    BrokerArguments broker;
    std::string config;
    std::optional<double> idle_exit_s;
    watch::ServiceOptions options;
    bool quiet{false};

    int run() {
        bool broker_configured = !broker.url.empty();
        if (!config.empty()) broker_configured = read_config(config, options) || broker_configured;
        if (!broker_configured)
            throw InputError("feedid watch needs the broker: --broker mqtt://HOST[:PORT] or [broker] url in --config");
        broker.apply(options.broker);
        if (!options.database.empty()) history::check_recordable(options.database);
        options.idle_exit_s = idle_exit_s;
        options.print = !quiet;
        return watch::run_watch(options);
    }
};

struct PublishCommand {
    TraceArguments trace;
    DriveArguments drive;
    BrokerArguments broker;
    std::string rate{fmt::format("{:g}x", watch::PublishOptions{}.rate)};  // the library's rate as written here
    double time_offset_s{0.0};
    std::optional<double> duration_s;
    watch::PublishOptions options;

    int run() {
        broker.apply(options.broker);
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
    command->broker.add_to(*sub, false);
    sub->add_option(
           "--topic", command->options.topic_filter,
           "Topic filter of the data; machine and axis are the 2nd and 3rd levels (plant/<machine>/<axis>/...)")
        ->capture_default_str();
    sub->add_option(
        "--db", command->options.database,
        "History (a SQLite file or a postgresql:// database) to record each completed identification in, and to "
        "check for drift");
    sub->add_option("--config", command->config,
                    "watch.toml: [broker] url username password_file cafile cert key, [online] window_s offset robust "
                    "cutoff_hz, [force_constants] X = 52.0 or \"M1/X\" = 52.0 [N/A], [run] windows period_s gap_s "
                    "reorder_s, [service] estimate_interval_s queue_mb max_samples min_dt_s max_axes axes_mb "
                    "max_window_samples held_mb trust_payload_names, [history] spool_dir spool_mb db_retry_s");
    sub->add_option("--status-topic", command->options.status_topic,
                    "Where online/offline (the last will) goes (default: <first level>/feedid/status)");
    sub->add_option("--client-id", command->options.client_id,
                    "MQTT client id: a persistent session under it (the broker keeps QoS 1 messages while watch is "
                    "away); default feedid-watch-PID with a clean session");
    sub->add_option("--idle-exit", command->idle_exit_s,
                    "Stop as on SIGTERM after this many seconds without a message (tests, demos) [s]")
        ->check(allowed_range(0.01, 1e6, "s"));
    sub->add_flag("--quiet", command->quiet, "No line per published estimate on stdout");
    sub->footer(
        "Example: feedid watch --broker mqtts://broker.plant:8883 --username feedid --password-file "
        "/etc/feedid/mqtt.pw --cafile /etc/feedid/ca.pem --db shop.db --config watch.toml");
    return [command] { return command->run(); };
}

Action add_publish_command(CLI::App& app) {
    auto command = std::make_shared<PublishCommand>();
    auto* sub = app.add_subcommand("publish", "Stream a trace to an MQTT broker as an NC would (tests, demos)");
    command->trace.add_to(*sub);
    command->drive.add_to(*sub);
    command->broker.add_to(*sub, true);
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
