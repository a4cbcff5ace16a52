// feedid watch: the live service over MQTT (subscribe, identify per axis, publish estimates and alarms, record runs);
// feedid publish: streams a trace to a broker as an NC would (tests, demos).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>

#include <fmt/core.h>
#include <toml++/toml.h>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/history/record.hpp"
#include "feedid/stream/service.hpp"

namespace feedid::cli {
namespace {

/// A number from a TOML table, checked to lie in [low, high]; InputError naming file and key otherwise.
double config_number(const toml::table& table, const std::string& section, const std::string& key, double fallback,
                     double low, double high, const std::string& path) {
    const toml::node* node = table.get(key);
    if (!node) return fallback;
    const auto value = node->value<double>();
    if (!value || !std::isfinite(*value) || *value < low || *value > high)
        throw InputError(fmt::format("{}: [{}] {} must be a number from {} to {}", path, section, key, low, high));
    return *value;
}

void check_keys(const toml::table& table, const std::string& section, std::initializer_list<std::string_view> known,
                const std::string& path) {
    for (const auto& [key, node] : table) {
        bool found = false;
        for (const auto k : known) found = found || key.str() == k;
        if (!found) throw InputError(fmt::format("{}: unknown key '{}' in [{}]", path, key.str(), section));
    }
}

const toml::table* config_table(const toml::table& root, const char* name, const std::string& path) {
    const toml::node* node = root.get(name);
    if (node && !node->is_table()) throw InputError(fmt::format("{}: '{}' must be a table", path, name));
    return node ? node->as_table() : nullptr;
}

std::optional<std::string> config_text(const toml::table& table, const std::string& section, const char* key,
                                       const std::string& path) {
    const toml::node* node = table.get(key);
    if (!node) return std::nullopt;
    if (!node->is_string()) throw InputError(fmt::format("{}: [{}] {} must be a string", path, section, key));
    return node->value<std::string>();
}

bool config_flag(const toml::table& table, const std::string& section, const char* key, bool fallback,
                 const std::string& path) {
    const toml::node* node = table.get(key);
    if (!node) return fallback;
    if (!node->is_boolean()) throw InputError(fmt::format("{}: [{}] {} must be true or false", path, section, key));
    return node->value<bool>().value();
}

/// [broker] url username password_file cafile cert key connect_timeout_s (a password itself is never taken here).
/// True when it gives the url.
bool read_broker_config(const toml::table& t, watch::BrokerOptions& broker, const std::string& path) {
    check_keys(t, "broker", {"url", "username", "password_file", "cafile", "cert", "key", "connect_timeout_s"}, path);
    if (auto url = config_text(t, "broker", "url", path)) {
        const watch::BrokerOptions parsed = watch::parse_broker(*url);
        broker.host = parsed.host;
        broker.port = parsed.port;
        broker.tls = parsed.tls;
        if (!parsed.username.empty()) broker.username = parsed.username;
    }
    for (const auto& [key, field] :
         {std::pair{"username", &broker.username}, std::pair{"password_file", &broker.password_file},
          std::pair{"cafile", &broker.cafile}, std::pair{"cert", &broker.certfile}, std::pair{"key", &broker.keyfile}})
        if (auto value = config_text(t, "broker", key, path)) *field = *value;
    broker.connect_timeout_s =
        config_number(t, "broker", "connect_timeout_s", broker.connect_timeout_s, 0.1, 3600.0, path);
    return t.get("url") != nullptr;
}

/// [service] estimate_interval_s queue_mb max_samples min_dt_s max_axes axes_mb max_window_samples held_mb
/// trust_payload_names.
void read_service_config(const toml::table& t, watch::ServiceOptions& options, const std::string& path) {
    check_keys(t, "service",
               {"estimate_interval_s", "queue_mb", "max_samples", "min_dt_s", "max_axes", "axes_mb",
                "max_window_samples", "held_mb", "trust_payload_names"},
               path);
    auto& w = options.watch;
    const auto megabytes = [&](const char* key, std::size_t bytes) {
        return static_cast<std::size_t>(
            config_number(t, "service", key, static_cast<double>(bytes >> 20), 1, 65536, path) * (1u << 20));
    };
    const auto count = [&](const char* key, std::size_t value, double low, double high) {
        return static_cast<std::size_t>(config_number(t, "service", key, static_cast<double>(value), low, high, path));
    };
    options.estimate_interval_s =
        config_number(t, "service", "estimate_interval_s", options.estimate_interval_s, 0.01, 3600.0, path);
    options.queue_bytes = megabytes("queue_mb", options.queue_bytes);
    w.limits.max_samples = count("max_samples", w.limits.max_samples, 1, 1e8);
    w.limits.min_dt_s = config_number(t, "service", "min_dt_s", w.limits.min_dt_s, 1e-9, 10.0, path);
    w.max_axes = count("max_axes", w.max_axes, 1, 1e7);
    w.axes_bytes = megabytes("axes_mb", w.axes_bytes);
    w.max_window_samples = count("max_window_samples", w.max_window_samples, 100, 1e9);
    w.held_bytes = megabytes("held_mb", w.held_bytes);
    w.trust_payload_names = config_flag(t, "service", "trust_payload_names", w.trust_payload_names, path);
}

/// watch.toml: [broker] url username password_file cafile cert key; [online] window_s offset robust cutoff_hz;
/// [force_constants] AXIS or "MACHINE/AXIS" = N/A; [run] windows period_s gap_s reorder_s; [service] (above);
/// [history] spool_dir spool_mb db_retry_s. True when it names the broker ([broker] url).
bool read_config(const std::string& path, watch::ServiceOptions& options) {
    toml::table root;
    try {
        root = toml::parse_file(path);
    } catch (const toml::parse_error& e) {
        throw InputError(fmt::format("{}: line {}: {}", path, e.source().begin.line, e.description()));
    }
    check_keys(root, "", {"broker", "online", "force_constants", "run", "service", "history"}, path);
    bool names_broker = false;
    if (const auto* t = config_table(root, "broker", path)) names_broker = read_broker_config(*t, options.broker, path);
    auto& online = options.watch.online;
    if (const auto* t = config_table(root, "online", path)) {
        check_keys(*t, "online", {"window_s", "offset", "robust", "cutoff_hz"}, path);
        online.window_s = config_number(*t, "online", "window_s", online.window_s, 0.1, 600.0, path);
        if (t->get("cutoff_hz")) online.cutoff_hz = config_number(*t, "online", "cutoff_hz", 0.0, 1e-3, 1e6, path);
        online.offset = config_flag(*t, "online", "offset", online.offset, path);
        online.robust = config_flag(*t, "online", "robust", online.robust, path);
    }
    if (const auto* t = config_table(root, "force_constants", path)) {
        for (const auto& [key, node] : *t) {
            const auto value = node.value<double>();
            if (!value || !std::isfinite(*value) || *value == 0.0)
                throw InputError(
                    fmt::format("{}: [force_constants] {} must be a non-zero number [N/A]", path, key.str()));
            options.watch.force_constants[std::string(key.str())] = *value;
        }
    }
    if (const auto* t = config_table(root, "run", path)) {
        check_keys(*t, "run", {"windows", "period_s", "gap_s", "reorder_s"}, path);
        options.watch.run_windows = static_cast<std::size_t>(config_number(*t, "run", "windows", 0, 0, 1e9, path));
        options.watch.run_period_s = config_number(*t, "run", "period_s", 0.0, 0.0, 1e9, path);
        options.watch.run_gap_s = config_number(*t, "run", "gap_s", options.watch.run_gap_s, 1e-3, 1e9, path);
        options.watch.reorder_s = config_number(*t, "run", "reorder_s", options.watch.reorder_s, 0.0, 3600.0, path);
    }
    if (const auto* t = config_table(root, "service", path)) read_service_config(*t, options, path);
    if (const auto* t = config_table(root, "history", path)) {
        check_keys(*t, "history", {"spool_dir", "spool_mb", "db_retry_s"}, path);
        if (auto dir = config_text(*t, "history", "spool_dir", path)) options.spool_dir = *dir;
        options.spool_bytes = static_cast<std::size_t>(
            config_number(*t, "history", "spool_mb", static_cast<double>(options.spool_bytes >> 20), 1, 1e6, path) *
            (1u << 20));
        options.db_retry_s = config_number(*t, "history", "db_retry_s", options.db_retry_s, 0.0, 1e7, path);
    }
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
    std::string rate{"1x"};
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
        ->default_val("plant/+/+/axis/#");
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
    sub->add_option("--rate", command->rate, "Times real time ('20x'), or 'max'")->default_val("1x");
    sub->add_option("--batch", command->options.batch_s, "Stream time per message [s]")
        ->default_val(0.1)
        ->check(allowed_range(1e-4, 60.0, "s"));
    sub->add_option("--client-id", command->options.client_id,
                    "MQTT client id: a persistent session under it; default feedid-publish-PID with a clean session");
    sub->add_option("--duration", command->duration_s, "Publish only the first this many seconds of the trace [s]")
        ->check(allowed_range(1e-3, 1e9, "s"));
    sub->add_option("--buffer", command->options.buffer_s,
                    "Stream time held while the broker is away, sent when it is back [s]")
        ->default_val(60.0)
        ->check(allowed_range(0.0, 1e6, "s"));
    sub->add_option("--replay", command->options.replay_s,
                    "QoS 1/2: after a reconnect, send again what was sent in this much time before the connection "
                    "was lost (a killed broker loses what it acknowledged since its last save) [s]")
        ->default_val(5.0)
        ->check(allowed_range(0.0, 3600.0, "s"));
    sub->add_option("--copies", command->options.copies,
                    "Publish the stream on N topics at once, '{n}' in --topic replaced by 1..N (a benchmark's load)")
        ->check(CLI::Range(1, 100000));
    sub->add_flag("--binary", command->options.binary, "The binary payload (default JSON)");
    sub->add_option("--qos", command->options.qos, "MQTT QoS of the data messages")
        ->default_val(0)
        ->check(CLI::Range(0, 2));
    sub->add_option("--time-offset", command->time_offset_s, "Added to the trace's time stamps [s] (a later recording)")
        ->check(allowed_range(-1e12, 1e12, "s"));
    sub->footer(
        "Example: feedid publish trace.csv --axis X --broker mqtt://127.0.0.1:1883 --topic plant/M1/X/axis "
        "--rate 20x");
    return [command] { return command->run(); };
}

}  // namespace feedid::cli
