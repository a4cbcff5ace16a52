// feedid watch against a real mosquitto (issue 16's acceptance, scaled to two cores; see the README): machines x 3
// axes of synthetic production traces replayed by feedid publish at 20x real time, the broker stopped and started
// again mid-run, malformed messages interleaved; a drift scenario through the history; bad configurations.
// Skipped with a message where /usr/sbin/mosquitto or libmosquitto is absent.
#ifdef FEEDID_HAVE_MQTT

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <fmt/core.h>
#include <gtest/gtest.h>

#include "feedid/model/drive.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"
#include "feedid/identify/online_identifier.hpp"
#include "feedid/identify/online_selection.hpp"
#include "feedid/sim/synth.hpp"
#include "feedid/stream/payload.hpp"
#include "mqtt_testing.hpp"
#include "production_traces.hpp"

namespace feedid::testing {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

const std::vector<std::string> axes = {"X", "Y", "Z"};

bool have_mosquitto() {
    return fs::exists(mosquitto_path);
}

struct Library {
    Library() { mosquitto_lib_init(); }
    ~Library() { mosquitto_lib_cleanup(); }
};

template <typename Predicate>
bool wait_until(Predicate predicate, double seconds) {
    const auto end = Clock::now() + std::chrono::milliseconds(static_cast<int>(seconds * 1000));
    while (Clock::now() < end) {
        if (predicate()) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return predicate();
}

/// A production-like trace of the demo drive (production_traces.hpp: moves at many speeds, cutting forces on some)
/// with its Coulomb friction scaled, written as an NC's CSV; the force constant to publish it with.
double write_production_csv(const fs::path& path, std::uint64_t seed, double duration_s, double coulomb_factor = 1.0) {
    ProductionOptions options;
    options.duration_s = duration_s;
    SynthSpec spec = demo_spec();
    spec.seed = seed;
    for (auto* branch : {&spec.axis.friction.forward, &spec.axis.friction.reverse}) branch->coulomb *= coulomb_factor;
    const ProductionTrace p = production_trace(seed, options);
    write_text(path, write_csv(synthesize(spec, p.reference, p.cutting_force)));
    return spec.force_constant_N_per_A();
}

/// What a clean, uninterrupted stream of the axis gives: the CSV read as publish reads it, straight into the
/// watch's identifiers (the windows judged without and with the offset).
OnlineEstimate direct_estimate(const fs::path& csv, double force_constant) {
    const Trace trace = read_trace(csv);
    DriveConstants drive;
    drive.force_constant = force_constant;
    const auto force = drive_force(trace, drive);
    const auto t = trace.column(Role::time), x = trace.column(Role::position);
    SelectingIdentifier online({});
    for (std::size_t k = 0; k < t.size(); ++k) online.push(t[k], x[k], force[k]);
    online.flush();
    return online.estimate();
}

/// Malformed payloads of the kinds the issue names, cycling: bad JSON, wrong units, NaN, huge arrays, wrong types.
std::string malformed(std::size_t k) {
    const std::string units = R"("units": {"position": "mm", "current": "A"})";
    switch (k % 8) {
        case 0: return "{\"t0\": 1, \"dt\": 0.001, \"position\": [1, 2";  // cut off
        case 1:
            return R"({"t0": 1, "dt": 0.001, "position": [1], "current": [1], "units": {"position": "kg", "current": "A"}})";
        case 2: return R"({"t0": 1, "dt": 0.001, "position": [NaN], "current": [1], )" + units + "}";
        case 3: {
            watch::Batch b;
            b.t0 = 1;
            b.dt = 0.001;
            b.position = {1.0, std::numeric_limits<double>::quiet_NaN()};
            b.drive = {1.0, 2.0};
            b.force_constant = 10.0;
            return watch::encode_binary(b);
        }
        case 4: return R"({"t0": 1, "dt": 0.001, "position": "1", "current": [1], )" + units + "}";
        case 5: return R"({"t0": [1], "dt": 0.001, "position": [1], "current": [1], )" + units + "}";
        case 6: {
            if (k % 80 != 6) return R"({"t0": 1, "dt": 0.001, "position": [1], "current": [true], )" + units + "}";
            std::string huge = R"({"t0": 1, "dt": 0.001, "current": [1], )" + units + R"(, "position": [0)";
            for (int i = 0; i < 1'000'000; ++i) huge += ",0";
            return huge + "]}";
        }
        default: return "\x01\x02 not a batch";
    }
}

/// Issue 16's restart acceptance in named steps: start (a broker that saves its state every second as a production
/// broker with persistence does, the traces and what an uninterrupted stream of each gives, feedid watch), replay
/// (500 malformed messages, then 30 publishers at 20x with QoS 1 until every stream is under way), restart (every
/// publisher checked to be still sending, the broker killed with SIGKILL mid-run and started again on the same port,
/// 500 more malformed messages), finish (every publisher acknowledged, every sample
/// accounted for, SIGTERM), judge (every sample identified once, every estimate the uninterrupted stream's within one
/// of its standard errors and the truth within the production-traces tolerances).
class WatchBrokerKill : public ::testing::Test {
protected:
    static constexpr int machines = 10;
    static constexpr double duration_s = 240.0;  // as test_online's accuracy test: the tolerances were set for 4 min

    struct Axis {
        std::string name;            ///< "M<m>_<axis>"
        std::string data_topic;      ///< plant/M<m>/<axis>/axis
        std::string estimate_topic;  ///< plant/M<m>/<axis>/feedid/estimate
        double force_constant{0.0};
        OnlineEstimate uninterrupted;  ///< the identifier on the whole stream, without a restart
    };

    void start() {
        broker_.emplace(dir_, port_, true);  // persistence: it saves its sessions every second
        ASSERT_TRUE(broker_answers(port_)) << read_text(dir_ / "mosquitto.err.1");
        for (int m = 1; m <= machines; ++m)
            for (std::size_t a = 0; a < axes.size(); ++a) {
                Axis axis;
                axis.name = fmt::format("M{}_{}", m, axes[a]);
                axis.data_topic = fmt::format("plant/M{}/{}/axis", m, axes[a]);
                axis.estimate_topic = fmt::format("plant/M{}/{}/feedid/estimate", m, axes[a]);
                axis.force_constant = write_production_csv(csv(axis), 10 * m + a, duration_s);
                axis.uninterrupted = direct_estimate(csv(axis), axis.force_constant);
                axes_.push_back(std::move(axis));
            }
        write_text(dir_ / "watch.toml", "[service]\nestimate_interval_s = 0.5\n");
        listener_.emplace(port_);
        watch_ = Process({FEEDID_CLI, "watch", "--broker", broker_->url(), "--config", (dir_ / "watch.toml").string(),
                          "--client-id", "feedid-watch-test"},
                         dir_ / "watch.out", dir_ / "watch.err");
        ASSERT_TRUE(wait_until([&] { return online_count() >= 1; }, 10)) << read_text(dir_ / "watch.err");
        // the broker's first save after watch subscribed holds its session (autosave_interval 1)
        std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    }

    void replay() {
        // The first 500 malformed messages, their errors out before the streams start: nothing slow stands between
        // the publishers' start and the kill, which waits only for every stream to be under way (the progress signal)
        sender_.emplace(port_);
        send_malformed(500);
        EXPECT_TRUE(wait_until([&] { return listener_->errors().size() >= 500u; }, 60)) << listener_->errors().size();
        for (std::size_t i = 0; i < axes_.size(); ++i) {
            const Axis& axis = axes_[i];
            std::vector<std::string> arguments = {FEEDID_CLI,
                                                  "publish",
                                                  csv(axis).string(),
                                                  "--force-constant",
                                                  fmt::format("{:.17g}", axis.force_constant),
                                                  "--broker",
                                                  broker_->url(),
                                                  "--topic",
                                                  axis.data_topic,
                                                  "--rate",
                                                  "20x",
                                                  "--batch",
                                                  "0.25",
                                                  "--qos",
                                                  "1",
                                                  "--client-id",
                                                  "publish-" + axis.name};
            if (i % 2 == 1) arguments.push_back("--binary");
            publishers_.emplace_back(arguments, dir_ / ("publish_" + axis.name + ".out"),
                                     dir_ / ("publish_" + axis.name + ".err"));
        }
        // every stream under way (the publishers read their traces first), so that each spans the broker's kill
        EXPECT_TRUE(wait_until([&] { return listener_->estimates().size() == axes_.size(); }, 60))
            << listener_->estimates().size() << " axes streaming";
    }

    void restart() {
        // the kill comes while every publisher is still sending, with stream left (provably: checked here)
        const auto estimates = listener_->estimates();
        for (std::size_t i = 0; i < publishers_.size(); ++i) {
            ASSERT_TRUE(publishers_[i].running()) << axes_[i].name << " ended before the kill";
            const auto it = estimates.find(axes_[i].estimate_topic);
            ASSERT_NE(it, estimates.end()) << axes_[i].name;
            EXPECT_LT(it->second["stream"]["time_s"].get<double>(), 0.75 * duration_s) << axes_[i].name;
        }
        EXPECT_EQ(broker_->kill(), 128 + SIGKILL);
        const auto killed = Clock::now();
        std::this_thread::sleep_for(std::chrono::milliseconds(300));
        broker_->start();
        ASSERT_TRUE(broker_answers(port_));
        EXPECT_TRUE(wait_until([&] { return online_count() >= 2; }, 40)) << "feedid watch did not reconnect";
        reconnected_s_ = std::chrono::duration<double>(Clock::now() - killed).count();
        EXPECT_TRUE(wait_until([&] { return listener_->connections() >= 2; }, 40)) << "the listener did not reconnect";
        std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the sender reconnects too
        send_malformed(500);
    }

    void finish() {
        for (std::size_t i = 0; i < publishers_.size(); ++i) {
            EXPECT_EQ(publishers_[i].wait(), 0) << read_text(dir_ / ("publish_" + axes_[i].name + ".err"));
            // its stream spanned the kill: it held messages while the broker was away
            const std::string err = read_text(dir_ / ("publish_" + axes_[i].name + ".err"));
            const auto held = err.find(" held while the broker was away");
            ASSERT_NE(held, std::string::npos) << err;
            EXPECT_GT(std::stoul(err.substr(err.rfind('(', held) + 1)), 0u) << err;
        }
        const auto published = Clock::now();
        // every publisher had each of its messages acknowledged: the watch has every sample when each axis's
        // estimate accounts for all of them (pushed, or given up as missing)
        const auto all_accounted = [&] {
            const auto estimates = listener_->estimates();
            for (const Axis& axis : axes_) {
                const auto it = estimates.find(axis.estimate_topic);
                if (it == estimates.end() || !it->second.contains("stream")) return false;
                const auto& stream = it->second["stream"];
                if (stream["samples"].get<std::size_t>() + stream["missing_samples"].get<std::size_t>() <
                    axis.uninterrupted.samples)
                    return false;
            }
            return true;
        };
        EXPECT_TRUE(wait_until(all_accounted, 60)) << "samples not accounted for 60 s after the last publisher";
        wait_until([&] { return listener_->errors().size() >= 1000u; }, 10);
        std::cout << fmt::format("every sample accounted for {:.1f} s after the last publisher; {} errors\n",
                                 std::chrono::duration<double>(Clock::now() - published).count(),
                                 listener_->errors().size());
        EXPECT_EQ(watch_.terminate(), 0) << read_text(dir_ / "watch.err");  // SIGTERM: flush, publish, exit 0
        ASSERT_TRUE(
            wait_until([&] { return !listener_->status().empty() && listener_->status().back() == "offline"; }, 5));
    }

    void judge() {
        const std::string watch_err = read_text(dir_ / "watch.err");
        std::cout << watch_err;
        // every malformed message counted and reported on the error topic
        EXPECT_NE(watch_err.find("1000 malformed"), std::string::npos) << watch_err;
        EXPECT_EQ(listener_->errors().size(), 1000u);
        const auto estimates = listener_->estimates();
        EXPECT_EQ(estimates.size(), axes_.size());
        std::size_t compared = 0, undetermined = 0, repeated = 0, reordered = 0, missing = 0, axes_missing = 0;
        double largest_sigma = 0.0;
        const AxisModel truth = demo_spec().axis;
        for (const Axis& axis : axes_) {
            ASSERT_TRUE(estimates.count(axis.estimate_topic)) << axis.estimate_topic;
            const auto& document = estimates.at(axis.estimate_topic);
            const auto& p = document["parameters"];
            // every sample identified once: none missing, none twice (QoS 1 redeliveries and the publishers'
            // replays skipped by time stamp), none held back
            const auto& stream = document["stream"];
            EXPECT_EQ(stream["samples"].get<std::size_t>(), axis.uninterrupted.samples)
                << axis.estimate_topic << " " << stream.dump();
            EXPECT_EQ(stream["missing_samples"].get<std::size_t>(), 0u)
                << axis.estimate_topic << " " << stream.dump() << "\n"
                << read_text(dir_ / ("publish_" + axis.name + ".err"));
            EXPECT_TRUE(stream["holes_s"].empty()) << axis.estimate_topic << " " << stream.dump();
            EXPECT_EQ(stream["held_samples"].get<std::size_t>(), 0u) << axis.estimate_topic;
            EXPECT_EQ(document["service"]["dropped_queue_full"].get<std::size_t>(), 0u) << axis.estimate_topic;
            repeated += stream["repeated_samples"].get<std::size_t>();
            reordered += stream["reordered_batches"].get<std::size_t>();
            missing += stream["missing_samples"].get<std::size_t>();
            axes_missing += stream["missing_samples"].get<std::size_t>() > 0;
            const auto check = [&](const char* key, double true_value, double tolerance, const Estimate& reference) {
                if (!reference.standard_error) {
                    // the identifier cannot say how good its value is on this stream (too few windows qualify):
                    // the watch publishes null, with the reason
                    ++undetermined;
                    EXPECT_TRUE(p[key]["value"].is_null()) << axis.estimate_topic << " " << key << " " << p[key].dump();
                    EXPECT_FALSE(document["diagnostics"].empty()) << axis.estimate_topic;
                    return;
                }
                ASSERT_TRUE(p[key]["value"].is_number()) << axis.estimate_topic << " " << key;
                const double value = p[key]["value"].get<double>();
                // the tolerances of the production-traces issue (tests/identify/test_online.cpp)
                EXPECT_LT(std::abs(value - true_value), tolerance * std::abs(true_value))
                    << axis.estimate_topic << " " << key << " " << value << " truth " << true_value;
                // the same estimate as without the restart, within one standard error
                const double sigmas = std::abs(value - *reference.value) / *reference.standard_error;
                EXPECT_LE(sigmas, 1.0) << axis.estimate_topic << " " << key << ": " << value << " against "
                                       << *reference.value << " ± " << *reference.standard_error
                                       << " without the restart";
                largest_sigma = std::max(largest_sigma, sigmas);
                ++compared;
            };
            check("mass_kg", truth.mass, 0.03, axis.uninterrupted.mass);
            check("viscous_Ns_per_m", truth.friction.forward.viscous, 0.10, axis.uninterrupted.viscous);
            check("coulomb_N", truth.friction.forward.coulomb, 0.03, axis.uninterrupted.coulomb);
        }
        std::cout << fmt::format(
            "broker killed, watch online again after {:.1f} s; {} parameters within tolerance of the truth and within "
            "1 sigma of the uninterrupted stream's (largest difference {:.2g} sigma), {} that the identifier cannot "
            "determine on its stream published as null; {} repeated samples skipped, {} batches put back in order, "
            "{} samples missing on {} axes\n",
            reconnected_s_, compared, largest_sigma, undetermined, repeated, reordered, missing, axes_missing);
        EXPECT_GE(compared, 3u * 3u * (machines - 1));
    }

private:
    [[nodiscard]] fs::path csv(const Axis& axis) const { return dir_ / (axis.name + ".csv"); }
    std::size_t online_count() {
        std::size_t n = 0;
        for (const auto& s : listener_->status()) n += s == "online";
        return n;
    }
    void send_malformed(std::size_t count) {
        for (std::size_t i = 0; i < count; ++i, ++sent_) {
            const std::string topic = fmt::format("plant/M{}/{}/axis", 1 + sent_ % machines, axes[sent_ % 3]);
            // the sender's own client may still be reconnecting after the restart
            ASSERT_TRUE(wait_until([&] { return sender_->send(topic, malformed(sent_)); }, 10));
            std::this_thread::sleep_for(std::chrono::milliseconds(2));
        }
    }

    Library library_;
    fs::path dir_{temp_dir()};
    int port_{free_port()};
    std::optional<Broker> broker_;
    std::vector<Axis> axes_;
    std::optional<Listener> listener_;
    Process watch_;
    std::vector<Process> publishers_;
    std::optional<Sender> sender_;
    std::size_t sent_{0};
    double reconnected_s_{0.0};
};

TEST_F(WatchBrokerKill, MachinesTimesThreeAxesAt20xSurviveASigkillOfTheBrokerWithTheSameEstimates) {
    if (!have_mosquitto()) GTEST_SKIP() << "no " << mosquitto_path << " (apt install mosquitto)";
    ASSERT_NO_FATAL_FAILURE(start());
    ASSERT_NO_FATAL_FAILURE(replay());
    ASSERT_NO_FATAL_FAILURE(restart());
    ASSERT_NO_FATAL_FAILURE(finish());
    judge();
}

// Coulomb friction of X constant for 10 simulated days, then rising 1 % a day (as tests/history/test_history_drift.cpp's
// runs): each day's recording is one completed identification (the day's pause ends it), recorded in the history;
// the alarm must come where the history test allows it (run 11 to 16) and only on X.
TEST(WatchMqtt, DriftingCoulombFrictionAlarmsOnThatAxisOnly) {
    if (!have_mosquitto()) GTEST_SKIP() << "no " << mosquitto_path << " (apt install mosquitto)";
    Library library;
    const auto dir = temp_dir();
    const int port = free_port();
    Broker broker(dir, port);
    ASSERT_TRUE(broker_answers(port));
    constexpr int days = 20;
    constexpr double day_s = 120.0;  // stream time of each day's recording [s]
    write_text(dir / "watch.toml", "[run]\ngap_s = 600\n[service]\nestimate_interval_s = 0.5\n");
    Listener listener(port);
    Process watch({FEEDID_CLI, "watch", "--broker", broker.url(), "--config", (dir / "watch.toml").string(), "--db",
                   (dir / "history.db").string(), "--quiet"},
                  dir / "watch.out", dir / "watch.err");
    ASSERT_TRUE(wait_until([&] { return !listener.status().empty(); }, 10)) << read_text(dir / "watch.err");
    for (int day = 1; day <= days + 1; ++day) {  // day 21's recording ends day 20's run
        std::vector<Process> publishers;
        for (std::size_t a = 0; a < axes.size(); ++a) {
            const auto trace = dir / fmt::format("day{}_{}.csv", day, axes[a]);
            const double factor = a == 0 ? 1.0 + 0.01 * std::max(0, day - 10) : 1.0;
            const double force_constant = write_production_csv(trace, 1000 * day + a, day_s, factor);
            publishers.emplace_back(
                std::vector<std::string>{FEEDID_CLI, "publish", trace.string(), "--force-constant",
                                         fmt::format("{:.17g}", force_constant), "--broker", broker.url(), "--topic",
                                         "plant/M1/" + axes[a] + "/axis", "--rate", "max", "--batch", "1", "--binary",
                                         "--qos", "1", "--time-offset", std::to_string(86400 * day)},
                dir / ("publish_" + axes[a] + ".out"), dir / ("publish_" + axes[a] + ".err"));
        }
        for (auto& p : publishers) ASSERT_EQ(p.wait(), 0) << read_text(dir / "publish_X.err");
        for (const auto& axis : axes) fs::remove(dir / fmt::format("day{}_{}.csv", day, axis));
    }
    ASSERT_TRUE(wait_until([&] { return listener.runs().size() >= 3u * days; }, 120))
        << listener.runs().size() << " runs recorded\n"
        << read_text(dir / "watch.err");
    EXPECT_EQ(watch.terminate(), 0);
    // the runs of X in order: the day of a run is its place in that list
    std::vector<std::int64_t> x_runs;
    for (const auto& run : listener.runs())
        if (run["result"]["trace"]["path"].get<std::string>().find("/M1/X#") != std::string::npos)
            x_runs.push_back(run["run"].get<std::int64_t>());
    ASSERT_EQ(x_runs.size(), static_cast<std::size_t>(days));
    int first_alarm_day = 0;
    for (const auto& alarm : listener.alarms()) {
        EXPECT_EQ(alarm["axis"], "X") << alarm.dump();
        EXPECT_EQ(alarm["parameter"], "coulomb_N") << alarm.dump();
        EXPECT_EQ(alarm["direction"], "up") << alarm.dump();
        const auto at = std::find(x_runs.begin(), x_runs.end(), alarm["run"].get<std::int64_t>());
        const int day = static_cast<int>(at - x_runs.begin()) + 1;
        if (first_alarm_day == 0 || day < first_alarm_day) first_alarm_day = day;
    }
    std::cout << fmt::format("first alarm on day {}; {} alarm message(s)\n", first_alarm_day, listener.alarms().size());
    EXPECT_GE(first_alarm_day, 11);
    EXPECT_LE(first_alarm_day, 16) << "no alarm by day 16";
    // the history holds what was published, and its own check agrees
    const auto check = run_cli("history '" + (dir / "history.db").string() + "' --check");
    EXPECT_EQ(check.exit_code, 1) << check.out << check.err;
    EXPECT_NE(check.out.find("axis 'X' parameter coulomb_N"), std::string::npos) << check.out;
    EXPECT_EQ(check.out.find("axis 'Y'"), std::string::npos) << check.out;
    EXPECT_EQ(check.out.find("axis 'Z'"), std::string::npos) << check.out;
    // One alarm document: each alarm watch published is the one history --check --json lists for that run and
    // parameter, key for key (recorded_at included) and value for value.
    const auto checked = run_cli("history '" + (dir / "history.db").string() + "' --check --json -");
    EXPECT_EQ(checked.exit_code, 1) << checked.err;
    const auto document = nlohmann::json::parse(checked.out);
    std::vector<nlohmann::json> listed;
    for (const auto& series : document.at("trends"))
        for (const auto& alarm : series.at("alarms")) listed.push_back(alarm);
    ASSERT_FALSE(listener.alarms().empty());
    for (const auto& published : listener.alarms()) {
        EXPECT_TRUE(published.contains("recorded_at")) << published.dump();
        const auto same = std::find_if(listed.begin(), listed.end(), [&](const nlohmann::json& alarm) {
            return alarm.at("run") == published.at("run") && alarm.at("parameter") == published.at("parameter");
        });
        ASSERT_NE(same, listed.end()) << "history --check --json does not list " << published.dump();
        std::vector<std::string> published_keys, listed_keys;
        for (const auto& item : published.items()) published_keys.push_back(item.key());
        for (const auto& item : same->items()) listed_keys.push_back(item.key());
        EXPECT_EQ(published_keys, listed_keys);
        EXPECT_EQ(published, *same);
    }
}

// A flood: the queue between the network thread and the identifiers holds at most queue_mb; what does not fit is
// dropped and counted, and every message is either taken or counted as dropped.
TEST(WatchMqtt, AFloodFillsTheBoundedQueueAndTheDropsAreCounted) {
    if (!have_mosquitto()) GTEST_SKIP() << "no " << mosquitto_path << " (apt install mosquitto)";
    Library library;
    const auto dir = temp_dir();
    const int port = free_port();
    Broker broker(dir, port);
    ASSERT_TRUE(broker_answers(port));
    write_text(dir / "watch.toml", "[service]\nqueue_mb = 1\nestimate_interval_s = 0.2\n");
    Listener listener(port);
    Process watch({FEEDID_CLI, "watch", "--broker", broker.url(), "--config", (dir / "watch.toml").string(), "--quiet"},
                  dir / "watch.out", dir / "watch.err");
    ASSERT_TRUE(wait_until([&] { return !listener.status().empty(); }, 10)) << read_text(dir / "watch.err");
    // 400 JSON batches of 10,000 samples (about 400 kB each, 160 MB in all) as fast as the broker takes them
    watch::Batch b;
    b.dt = 1e-3;
    b.force_constant = 50.0;
    for (int k = 0; k < 10000; ++k) {
        b.position.push_back(0.1 * std::sin(1e-3 * k));
        b.drive.push_back(std::cos(1e-3 * k));
    }
    Sender sender(port);
    constexpr std::size_t flood = 400;
    for (std::size_t m = 0; m < flood; ++m) {
        b.t0 = 10.0 * static_cast<double>(m);
        const std::string payload = watch::encode_json(b);
        ASSERT_TRUE(wait_until([&] { return sender.send("plant/F1/X/axis", payload); }, 10));
    }
    const auto counts = [&] {
        const auto e = listener.estimates();
        return e.count("plant/F1/X/feedid/estimate") ? e.at("plant/F1/X/feedid/estimate")["service"] : nlohmann::json();
    };
    EXPECT_TRUE(wait_until(
        [&] {
            const auto c = counts();
            return c.is_object() &&
                   c["messages"].get<std::size_t>() + c["dropped_queue_full"].get<std::size_t>() == flood;
        },
        60))
        << counts().dump();
    const auto c = counts();
    std::cout << fmt::format("{} messages taken, {} dropped by the full queue\n", c["messages"].get<std::size_t>(),
                             c["dropped_queue_full"].get<std::size_t>());
    EXPECT_GT(c["dropped_queue_full"].get<std::size_t>(), 0u);
    EXPECT_EQ(watch.terminate(), 0);
    EXPECT_NE(read_text(dir / "watch.err").find("dropped by the full queue"), std::string::npos);
}

TEST(WatchMqtt, BadConfigurationIsExit2WithOneLineNamingIt) {
    const auto dir = temp_dir();
    const int nobody = free_port();  // nothing listens there
    const auto unreachable = run_cli(fmt::format("watch --broker mqtt://127.0.0.1:{}", nobody));
    EXPECT_EQ(unreachable.exit_code, 2);
    EXPECT_NE(unreachable.err.find(fmt::format("cannot reach the MQTT broker at mqtt://127.0.0.1:{}", nobody)),
              std::string::npos)
        << unreachable.err;
    EXPECT_EQ(count_lines(unreachable.err), 1) << unreachable.err;
    const auto filter = run_cli(fmt::format("watch --broker mqtt://127.0.0.1:{} --topic 'plant/#/x'", nobody));
    EXPECT_EQ(filter.exit_code, 2);
    EXPECT_NE(filter.err.find("--topic 'plant/#/x'"), std::string::npos) << filter.err;
    EXPECT_EQ(count_lines(filter.err), 1) << filter.err;
    const auto database = run_cli(fmt::format("watch --broker mqtt://127.0.0.1:{} --db /proc/feedid-watch.db", nobody));
    EXPECT_EQ(database.exit_code, 2);
    EXPECT_NE(database.err.find("/proc/feedid-watch.db"), std::string::npos) << database.err;
    EXPECT_EQ(count_lines(database.err), 1) << database.err;
    write_text(dir / "watch.toml", "[run]\nwindowz = 3\n");
    const auto config =
        run_cli(fmt::format("watch --broker mqtt://127.0.0.1:{} --config '{}'", nobody, (dir / "watch.toml").string()));
    EXPECT_EQ(config.exit_code, 2);
    EXPECT_NE(config.err.find("watch.toml: unknown key 'run.windowz'"), std::string::npos) << config.err;
    for (const auto& [delay, why] : {std::pair{"\"soon\"", "not auto, none or a time"},
                                     std::pair{"\"9ms\"", "within +-5 ms"}}) {
        write_text(dir / "watch.toml", fmt::format("[online]\ndelay = {}\n", delay));
        const auto timing = run_cli(
            fmt::format("watch --broker mqtt://127.0.0.1:{} --config '{}'", nobody, (dir / "watch.toml").string()));
        EXPECT_EQ(timing.exit_code, 2) << delay;
        EXPECT_NE(timing.err.find("online.delay"), std::string::npos) << timing.err;
        EXPECT_NE(timing.err.find(why), std::string::npos) << timing.err;
        EXPECT_EQ(count_lines(timing.err), 1) << timing.err;
    }
    const auto url = run_cli("watch --broker http://127.0.0.1:1883");
    EXPECT_EQ(url.exit_code, 2);
    EXPECT_NE(url.err.find("--broker 'http://127.0.0.1:1883'"), std::string::npos) << url.err;
    const auto publish =
        run_cli(fmt::format("publish /nonexistent.csv --broker mqtt://127.0.0.1:{} --topic plant/M1/X/axis", nobody));
    EXPECT_EQ(publish.exit_code, 2);
}

}  // namespace
}  // namespace feedid::testing

#else
#include <gtest/gtest.h>
TEST(WatchMqtt, Skipped) {
    GTEST_SKIP() << "feedid was built without libmosquitto (apt install libmosquitto-dev)";
}
#endif
