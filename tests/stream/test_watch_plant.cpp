// feedid watch on a plant network, against real components: a mosquitto with TLS (a CA and a server certificate made
// by openssl in the test), logins from a password file and an access control list per machine; floods of hostile
// messages with the watch's resident memory read from /proc; a broker restarted without persistence; a PostgreSQL
// history stopped for 30 s while runs complete; a publisher that loses messages. Skipped, saying why, where
// mosquitto, openssl, libmosquitto or PostgreSQL's server are absent.
#ifdef FEEDID_HAVE_MQTT

#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <fmt/core.h>
#include <gtest/gtest.h>

#include "feedid/history/store.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/sim/synth.hpp"
#include "feedid/stream/payload.hpp"
#include "mqtt_testing.hpp"
#include "postgres_testing.hpp"
#include "production_traces.hpp"

namespace feedid::testing {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

bool have_mosquitto() {
    return fs::exists(mosquitto_path) && fs::exists("/usr/bin/mosquitto_passwd");
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

/// A production-like trace of the demo drive written as an NC's CSV; its force constant [N/A].
double write_trace(const fs::path& path, std::uint64_t seed, double duration_s) {
    ProductionOptions options;
    options.duration_s = duration_s;
    SynthSpec spec = demo_spec();
    spec.seed = seed;
    const ProductionTrace p = production_trace(seed, options);
    write_text(path, write_csv(synthesize(spec, p.reference, p.cutting_force)));
    return spec.force_constant_N_per_A();
}

/// Samples of a CSV trace (its lines after the header and the `# ` lines).
std::size_t samples_of(const fs::path& csv) {
    const std::string text = read_text(csv);
    std::size_t lines = 0;
    for (std::size_t at = 0; at < text.size();) {
        const auto end = text.find('\n', at);
        if (text[at] != '#') ++lines;
        at = end == std::string::npos ? text.size() : end + 1;
    }
    return lines - 1;
}

std::vector<std::string> publish_arguments(const fs::path& csv, double force_constant, const std::string& broker,
                                           const std::string& topic) {
    return {FEEDID_CLI,
            "publish",
            csv.string(),
            "--force-constant",
            fmt::format("{:.17g}", force_constant),
            "--broker",
            broker,
            "--topic",
            topic,
            "--qos",
            "1"};
}

int run_shell_quietly(const std::string& command) {
    const int status = std::system((command + " >/dev/null 2>&1").c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

/// A CA, a server certificate for 127.0.0.1 signed by it, and a client certificate, made by openssl in `dir`; ""
/// on success, else what failed.
std::string make_certificates(const fs::path& dir) {
    const auto q = [&](const char* name) { return "'" + (dir / name).string() + "'"; };
    const std::string key = "-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes";
    write_text(dir / "server.ext", "subjectAltName=IP:127.0.0.1\n");
    const std::vector<std::string> commands = {
        fmt::format("openssl req -x509 {} -keyout {} -out {} -days 2 -subj '/CN=feedid test CA'", key, q("ca.key"),
                    q("ca.pem")),
        fmt::format("openssl req {} -keyout {} -out {} -subj '/CN=127.0.0.1'", key, q("server.key"), q("server.csr")),
        fmt::format("openssl x509 -req -in {} -CA {} -CAkey {} -CAcreateserial -out {} -days 2 -extfile {}",
                    q("server.csr"), q("ca.pem"), q("ca.key"), q("server.pem"), q("server.ext")),
        fmt::format("openssl req {} -keyout {} -out {} -subj '/CN=M1'", key, q("client.key"), q("client.csr")),
        fmt::format("openssl x509 -req -in {} -CA {} -CAkey {} -CAcreateserial -out {} -days 2", q("client.csr"),
                    q("ca.pem"), q("ca.key"), q("client.pem")),
    };
    for (const auto& command : commands)
        if (run_shell_quietly(command) != 0) return "failed: " + command;
    // the broker drops its root privileges before it reads the key: readable in the test's folder
    ::chmod((dir / "server.key").c_str(), 0644);
    return "";
}

struct Passwords {
    std::string watch{"Watch-Pw-4711"}, machine{"M1-Pw-0815"}, observer{"Observer-Pw-42"};
};

/// The deployment the docs describe: TLS, no anonymous clients, a password file, an ACL that lets each machine write
/// its own topics only and watch read the data and write its results. A plain listener for the test's observer.
std::string plant_configuration(const fs::path& dir, int plain, int tls, int client_certificate) {
    write_text(dir / "acl",
               "# feedid watch: reads every machine's data, writes its results and its status\n"
               "user feedid\n"
               "topic read plant/+/+/axis/#\n"
               "topic write plant/+/+/feedid/#\n"
               "topic write plant/feedid/status\n"
               "# the test's observer\n"
               "user observer\n"
               "topic read plant/#\n"
               "# each machine (user name = machine name) writes its own axes only\n"
               "pattern write plant/%u/+/axis/#\n");
    const auto tls_files = fmt::format("cafile {}\ncertfile {}\nkeyfile {}\n", (dir / "ca.pem").string(),
                                       (dir / "server.pem").string(), (dir / "server.key").string());
    return fmt::format(
        "per_listener_settings false\nallow_anonymous false\npassword_file {}\nacl_file {}\npersistence false\n"
        "max_queued_messages 100000\n"
        "listener {} 127.0.0.1\n"
        "listener {} 127.0.0.1\n{}"
        "listener {} 127.0.0.1\n{}require_certificate true\n",
        (dir / "passwd").string(), (dir / "acl").string(), plain, tls, tls_files, client_certificate, tls_files);
}

/// Every process's command line as `ps` shows it to any user of the host, appended to `file`.
void append_ps(const fs::path& file) {
    ASSERT_EQ(std::system(("ps -eo pid,args >>'" + file.string() + "'").c_str()), 0);
}

std::size_t online_count(Listener& listener) {
    std::size_t n = 0;
    for (const auto& s : listener.status()) n += s == "online";
    return n;
}

// The acceptance of a plant deployment: watch and publish over TLS with logins identify end to end; a wrong password
// is exit 2 within 15 s and no password appears in any output; a publisher the broker refuses exits non-zero; the
// ACL keeps a machine to its own topics, and a payload naming another machine is refused and counted.
TEST(WatchPlant, TlsWithLoginsIdentifiesEndToEndAndRefusalsAreExitTwo) {
    if (!have_mosquitto()) GTEST_SKIP() << "no " << mosquitto_path << " or mosquitto_passwd (apt install mosquitto)";
    if (run_shell_quietly("openssl version") != 0) GTEST_SKIP() << "no openssl (apt install openssl)";
    Library library;
    const auto dir = temp_dir();
    ASSERT_EQ(make_certificates(dir), "");
    const Passwords pw;
    write_text(dir / "passwd", fmt::format("feedid:{}\nM1:{}\nobserver:{}\n", pw.watch, pw.machine, pw.observer));
    ASSERT_EQ(run_shell_quietly("mosquitto_passwd -U '" + (dir / "passwd").string() + "'"), 0);
    const int plain = free_port(), tls = free_port(), client_certificate = free_port();
    const Login observer{"observer", pw.observer};
    Broker broker(dir, plain, plant_configuration(dir, plain, tls, client_certificate), observer);
    ASSERT_TRUE(broker_answers(plain, observer)) << read_text(dir / "mosquitto.err.1");
    Listener listener(plain, observer);
    write_text(dir / "watch.pw", pw.watch + "\n");
    write_text(dir / "watch.toml", fmt::format("[broker]\nurl = \"mqtts://feedid@127.0.0.1:{}\"\npassword_file = "
                                               "\"{}\"\ncafile = \"{}\"\n[service]\nestimate_interval_s = 0.5\n",
                                               tls, (dir / "watch.pw").string(), (dir / "ca.pem").string()));
    Process watch({FEEDID_CLI, "watch", "--config", (dir / "watch.toml").string(), "--quiet"}, dir / "watch.out",
                  dir / "watch.err");
    ASSERT_TRUE(wait_until([&] { return online_count(listener) >= 1; }, 15)) << read_text(dir / "watch.err");
    // a machine publishes over TLS, its password from the environment
    const double k = write_trace(dir / "x.csv", 3, 60.0);
    const std::string tls_url = fmt::format("mqtts://127.0.0.1:{}", tls);
    auto arguments = publish_arguments(dir / "x.csv", k, tls_url, "plant/M1/X/axis");
    for (const char* a : {"--username", "M1", "--cafile"}) arguments.emplace_back(a);
    arguments.push_back((dir / "ca.pem").string());
    for (const char* a : {"--rate", "max"}) arguments.emplace_back(a);
    const std::vector<std::string> machine_password = {"FEEDID_MQTT_PASSWORD=" + pw.machine};
    Process publish(arguments, dir / "publish.out", dir / "publish.err", machine_password);
    append_ps(dir / "ps.txt");  // watch and publish running, with their passwords
    EXPECT_NE(read_text(dir / "ps.txt").find(fmt::format("{} {} watch --config", watch.pid(), FEEDID_CLI)),
              std::string::npos)
        << read_text(dir / "ps.txt");
    EXPECT_EQ(publish.wait(), 0) << read_text(dir / "publish.err");
    // ... and with a client certificate, where the broker asks for one
    auto with_certificate = publish_arguments(
        dir / "x.csv", k, fmt::format("mqtts://M1@127.0.0.1:{}", client_certificate), "plant/M1/Y/axis");
    for (const std::string& a :
         {std::string("--cafile"), (dir / "ca.pem").string(), std::string("--cert"), (dir / "client.pem").string(),
          std::string("--key"), (dir / "client.key").string(), std::string("--rate"), std::string("max")})
        with_certificate.push_back(a);
    Process certified(with_certificate, dir / "cert.out", dir / "cert.err", machine_password);
    EXPECT_EQ(certified.wait(), 0) << read_text(dir / "cert.err");
    const std::size_t n = samples_of(dir / "x.csv");
    const auto identified = [&](const char* topic) {
        const auto e = listener.estimates();
        return e.count(topic) && e.at(topic)["stream"]["samples"].get<std::size_t>() == n;
    };
    EXPECT_TRUE(wait_until([&] { return identified("plant/M1/X/feedid/estimate"); }, 30))
        << read_text(dir / "watch.err");
    EXPECT_TRUE(wait_until([&] { return identified("plant/M1/Y/feedid/estimate"); }, 30));
    const auto x = listener.estimates()["plant/M1/X/feedid/estimate"];
    ASSERT_TRUE(x["parameters"]["mass_kg"]["value"].is_number()) << x.dump();
    const AxisModel truth = demo_spec().axis;
    EXPECT_LT(std::abs(x["parameters"]["mass_kg"]["value"].get<double>() / truth.mass - 1.0), 0.03) << x.dump();
    // the ACL: M1 may not write M2's topics (the broker drops it), and a payload of M1's naming M2 is refused
    auto intruding =
        publish_arguments(dir / "x.csv", k, fmt::format("mqtts://M1@127.0.0.1:{}", tls), "plant/M2/X/axis");
    for (const std::string& a :
         {std::string("--cafile"), (dir / "ca.pem").string(), std::string("--rate"), std::string("max")})
        intruding.push_back(a);
    Process intruder(intruding, dir / "intruder.out", dir / "intruder.err", machine_password);
    (void)intruder.wait();
    watch::Batch named;
    named.machine = "M2";
    named.axis = "X";
    named.t0 = 1000.0;
    named.dt = 1e-3;
    named.position = {0.0, 1e-6, 2e-6};
    named.drive = {1.0, 1.0, 1.0};
    named.force_constant = k;
    Sender machine(plain, {"M1", pw.machine});
    ASSERT_TRUE(wait_until([&] { return machine.send("plant/M1/X/axis", watch::encode_binary(named)); }, 10));
    EXPECT_TRUE(wait_until(
        [&] {
            for (const auto& e : listener.errors())
                if (e["error"].get<std::string>().find("names machine 'M2'") != std::string::npos) return true;
            return false;
        },
        15));
    EXPECT_FALSE(listener.estimates().count("plant/M2/X/feedid/estimate"));
    EXPECT_EQ(watch.terminate(), 0) << read_text(dir / "watch.err");
    EXPECT_NE(read_text(dir / "watch.err").find("1 naming another machine or axis than their topic"), std::string::npos)
        << read_text(dir / "watch.err");
    // a wrong password: exit 2 within 15 s, the reason said
    write_text(dir / "wrong.pw", "Not-The-Password-99\n");
    const auto started = Clock::now();
    Process refused({FEEDID_CLI, "watch", "--broker", tls_url, "--cafile", (dir / "ca.pem").string(), "--username",
                     "feedid", "--password-file", (dir / "wrong.pw").string()},
                    dir / "refused.out", dir / "refused.err");
    append_ps(dir / "ps.txt");
    EXPECT_EQ(refused.wait(), 2);
    const double refused_s = std::chrono::duration<double>(Clock::now() - started).count();
    std::cout << fmt::format("a wrong password: exit 2 after {:.2f} s\n", refused_s);
    EXPECT_LT(refused_s, 15.0);
    EXPECT_NE(read_text(dir / "refused.err").find("refused the login of user 'feedid'"), std::string::npos)
        << read_text(dir / "refused.err");
    // a publisher the broker refuses, one that does not trust the broker's certificate, a password in the URL
    auto refused_arguments =
        publish_arguments(dir / "x.csv", k, fmt::format("mqtts://M1@127.0.0.1:{}", tls), "plant/M1/X/axis");
    for (const std::string& a : {std::string("--cafile"), (dir / "ca.pem").string()}) refused_arguments.push_back(a);
    Process refused_publish(refused_arguments, dir / "refused_publish.out", dir / "refused_publish.err",
                            {"FEEDID_MQTT_PASSWORD=Not-The-Password-99"});
    EXPECT_NE(refused_publish.wait(), 0);
    EXPECT_NE(read_text(dir / "refused_publish.err").find("refused the login"), std::string::npos);
    const auto untrusted = run_cli(fmt::format("publish '{}' --force-constant 50 --broker {} --topic plant/M1/X/axis",
                                               (dir / "x.csv").string(), tls_url));
    EXPECT_EQ(untrusted.exit_code, 2);
    EXPECT_NE(untrusted.err.find("TLS failed"), std::string::npos) << untrusted.err;
    const auto in_url = run_cli(fmt::format("watch --broker mqtts://feedid:{}@127.0.0.1:{}", pw.watch, tls));
    EXPECT_EQ(in_url.exit_code, 2);
    EXPECT_NE(in_url.err.find("mqtts://feedid:***@127.0.0.1"), std::string::npos) << in_url.err;
    // no password in any output, nor in what `ps` showed while watch and publish ran
    std::string everything = in_url.out + in_url.err + untrusted.out + untrusted.err;
    for (const char* file :
         {"watch.out", "watch.err", "publish.out", "publish.err", "cert.out", "cert.err", "intruder.out",
          "intruder.err", "refused.out", "refused.err", "refused_publish.out", "refused_publish.err", "ps.txt"})
        everything += read_text(dir / file);
    for (const std::string& secret : {pw.watch, pw.machine, std::string("Not-The-Password-99")})
        EXPECT_EQ(everything.find(secret), std::string::npos) << "a password was shown";
}

/// A TCP port on 127.0.0.1 that takes connections (the kernel completes the handshake) and never answers: a broker
/// that hangs, a firewall that lets the SYN through to a dead service. Closed with the object.
class SilentPort {
public:
    SilentPort() {
        fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
        sockaddr_in address{};
        address.sin_family = AF_INET;
        address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        socklen_t length = sizeof address;
        if (fd_ >= 0 && ::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
            ::listen(fd_, 16) == 0 && ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &length) == 0)
            port_ = ntohs(address.sin_port);
    }
    ~SilentPort() {
        if (fd_ >= 0) ::close(fd_);
    }
    SilentPort(const SilentPort&) = delete;
    SilentPort& operator=(const SilentPort&) = delete;
    [[nodiscard]] int port() const { return port_; }

private:
    int fd_{-1};
    int port_{0};
};

// A broker that takes the connection and never answers (neither CONNACK nor a TLS handshake) is exit 2 with the
// reason within the connect timeout (10 s by default), for watch and publish: once, watch ran on silently, exit 0.
TEST(WatchPlant, ABrokerThatNeverAnswersIsExitTwoWithinTheConnectTimeout) {
    const auto dir = temp_dir();
    const SilentPort silent;
    ASSERT_GT(silent.port(), 0);
    const double k = write_trace(dir / "x.csv", 7, 5.0);
    const auto started = Clock::now();
    Process watch({FEEDID_CLI, "watch", "--broker", fmt::format("mqtt://127.0.0.1:{}", silent.port())},
                  dir / "watch.out", dir / "watch.err");
    Process publish(publish_arguments(dir / "x.csv", k, fmt::format("mqtts://127.0.0.1:{}", silent.port()),
                                      "plant/M1/X/axis"),
                    dir / "publish.out", dir / "publish.err");
    EXPECT_EQ(watch.wait(), 2) << read_text(dir / "watch.err");
    const double watch_s = std::chrono::duration<double>(Clock::now() - started).count();
    EXPECT_EQ(publish.wait(), 2) << read_text(dir / "publish.err");
    const double publish_s = std::chrono::duration<double>(Clock::now() - started).count();
    std::cout << fmt::format("a broker that never answers: watch exit 2 after {:.1f} s, publish (TLS) after {:.1f} s\n",
                             watch_s, publish_s);
    EXPECT_LT(watch_s, 15.0);
    EXPECT_LT(publish_s, 15.0);
    for (const char* err : {"watch.err", "publish.err"}) {
        const std::string text = read_text(dir / err);
        // one line, the last (publish says first which channels of the trace it took)
        const auto line = text.rfind('\n', text.size() - 2) + 1;
        EXPECT_EQ(text.substr(line), fmt::format("feedid: cannot reach the MQTT broker at mqtt{}://127.0.0.1:{}: no "
                                                 "answer within 10 s{}\n",
                                                 err[0] == 'p' ? "s" : "", silent.port(),
                                                 err[0] == 'p' ? "" : " (a TLS port? then give mqtts://)"))
            << text;
    }
}

/// The watch's resident memory now and at most so far [MB].
struct Memory {
    double now_mb{0.0}, peak_mb{0.0};
};
Memory memory_of(const Process& process) {
    return {static_cast<double>(proc_status_kb(process.pid(), "VmRSS")) / 1024.0,
            static_cast<double>(proc_status_kb(process.pid(), "VmHWM")) / 1024.0};
}

/// A batch of `n` samples at `dt` (a slow sine), binary, with its force constant.
std::string flood_batch(double t0, double dt, std::size_t n, const std::string& machine = "") {
    watch::Batch b;
    b.machine = machine;
    b.t0 = t0;
    b.dt = dt;
    b.force_constant = 50.0;
    for (std::size_t k = 0; k < n; ++k) {
        b.position.push_back(0.01 * std::sin(t0 + static_cast<double>(k) * dt));
        b.drive.push_back(std::cos(t0 + static_cast<double>(k) * dt));
    }
    return watch::encode_binary(b);
}

// The documented bound on the watch's memory with its default settings: queue_mb + held_mb + axes_mb and the
// process itself.
constexpr double memory_bound_mb = 300.0;

// Floods of hostile messages against a watch with its default settings: its resident memory (VmHWM: the most it ever
// held) stays below the documented bound after each; it stays alive, identifies the stream sent between the floods,
// and counts every message.
TEST(WatchPlant, FloodsOfHostileMessagesLeaveTheWatchAliveWithinItsMemoryBound) {
    if (!have_mosquitto()) GTEST_SKIP() << "no " << mosquitto_path << " (apt install mosquitto)";
    Library library;
    const auto dir = temp_dir();
    const int port = free_port();
    Broker broker(dir, port);
    ASSERT_TRUE(broker_answers(port));
    Listener listener(port);
    Process watch({FEEDID_CLI, "watch", "--broker", broker.url(), "--quiet"}, dir / "watch.out", dir / "watch.err");
    ASSERT_TRUE(wait_until([&] { return online_count(listener) >= 1; }, 15)) << read_text(dir / "watch.err");
    Sender sender(port);
    std::size_t sent = 0;
    const auto send = [&](const std::string& topic, const std::string& payload) {
        ++sent;
        // at most 16 MB unacknowledged in the test's own client
        ASSERT_TRUE(wait_until([&] { return sender.in_flight() * payload.size() < (16u << 20); }, 60));
        ASSERT_TRUE(wait_until([&] { return sender.send(topic, payload); }, 10));
    };
    // a probe axis, admitted first: each probe batch shows the watch's counts once it has taken all before it
    double probe_t = 0.0;
    const auto probe = [&](std::size_t batches) {
        for (std::size_t b = 0; b < batches; ++b, probe_t += 1.0)
            send("plant/P/X/axis", flood_batch(probe_t, 1e-3, 1000));
        const double until = probe_t;
        EXPECT_TRUE(wait_until(
            [&] {
                const auto e = listener.estimates();
                const auto it = e.find("plant/P/X/feedid/estimate");
                return it != e.end() && it->second["stream"]["time_s"].get<double>() >= until - 1e-6 &&
                       it->second["service"]["messages"].get<std::size_t>() +
                               it->second["service"]["dropped_queue_full"].get<std::size_t>() ==
                           sent;
            },
            120))
            << read_text(dir / "watch.err");
        return listener.estimates()["plant/P/X/feedid/estimate"]["service"];
    };
    probe(35);  // past the first 30 s of stream that an axis holds
    // single messages that once stopped the service or slipped past its checks: a 200-byte binary batch whose
    // machine is not UTF-8, one with a NUL, with a terminal's escape, too long; a topic level with a bidirectional
    // override (a broker refuses topics that are not UTF-8 or hold controls, so those come in payloads only)
    std::size_t hostile = 0;
    for (const std::string& name : {std::string("M\xff"), std::string("M\0X", 3), std::string("M\x1b[2J"),
                                    std::string(65, 'M')}) {
        const std::string payload = flood_batch(0.0, 1e-3, 10, name);
        EXPECT_LT(payload.size(), 300u);
        send("plant/M1/X/axis", payload);
        ++hostile;
    }
    send("plant/evil\xe2\x80\xae/X/axis", flood_batch(0.0, 1e-3, 10));
    ++hostile;
    const auto after_hostile = probe(1);
    EXPECT_TRUE(watch.running()) << read_text(dir / "watch.err");
    EXPECT_EQ(after_hostile["malformed"].get<std::size_t>(), hostile) << after_hostile.dump();
    const Memory start = memory_of(watch);
    // 1,200 held batches: 100 axes, each batch 0 at t = 0 and batches 2 to 12 (a hole at 1), 20,000 samples each at
    // 10 kHz (320 kB)
    for (int k = 0; k < 1200; ++k) {
        const int index = k / 100;
        send(fmt::format("plant/H{}/X/axis", k % 100), flood_batch((index == 0 ? 0 : index + 1) * 2.0, 1e-4, 20'000));
    }
    const auto held = probe(1);
    const Memory after_held = memory_of(watch);
    // sample times of 1e-7 s: 1,000 batches of 2 kB on 1,000 axes
    for (int k = 0; k < 1000; ++k) send(fmt::format("plant/T{}/X/axis", k), flood_batch(0.0, 1e-7, 128));
    const auto fine = probe(1);
    const Memory after_fine = memory_of(watch);
    // 100,000 distinct axes, a batch of 200 samples each
    for (int k = 0; k < 100'000; ++k) send(fmt::format("plant/F{}/X/axis", k), flood_batch(0.0, 1e-3, 200));
    const auto axes = probe(1);
    const Memory after_axes = memory_of(watch);
    std::cout << fmt::format(
        "watch resident memory (VmRSS now / VmHWM peak): {:.1f} / {:.1f} MB at the start; {:.1f} / {:.1f} MB after "
        "1,200 held batches ({} holds given up early); {:.1f} / {:.1f} MB after 1,000 batches at 1e-7 s; {:.1f} / "
        "{:.1f} MB after 100,000 distinct axes ({} refused by the limits); {} messages, {} refused, {} dropped by the "
        "full queue; bound {:.0f} MB\n",
        start.now_mb, start.peak_mb, after_held.now_mb, after_held.peak_mb, held["evicted_holds"].get<std::size_t>(),
        after_fine.now_mb, after_fine.peak_mb, after_axes.now_mb, after_axes.peak_mb,
        axes["refused_axes"].get<std::size_t>(), axes["messages"].get<std::size_t>(),
        axes["malformed"].get<std::size_t>(), axes["dropped_queue_full"].get<std::size_t>(), memory_bound_mb);
    for (const Memory& m : {after_held, after_fine, after_axes}) {
        EXPECT_GT(m.peak_mb, 0.0);
        EXPECT_LT(m.peak_mb, memory_bound_mb);
    }
    EXPECT_GT(held["evicted_holds"].get<std::size_t>(), 0u);
    EXPECT_GE(fine["malformed"].get<std::size_t>(), hostile + 1000u);
    EXPECT_GT(axes["refused_axes"].get<std::size_t>(), 90'000u);
    EXPECT_TRUE(watch.running());
    EXPECT_EQ(watch.terminate(), 0) << read_text(dir / "watch.err");
}

// A broker restarted without persistence (mosquitto's default without `persistence true`) forgets watch's session
// and its subscription: watch subscribes again on the new connection and identifies what comes after. Both with a
// clean session (watch's default; the broker never keeps one) and with a persistent one asked for under --client-id
// (which this broker forgets when it restarts).
class WatchPlantRestart : public ::testing::TestWithParam<bool> {};

TEST_P(WatchPlantRestart, ABrokerRestartedWithoutPersistenceIsSubscribedToAgain) {
    if (!have_mosquitto()) GTEST_SKIP() << "no " << mosquitto_path << " (apt install mosquitto)";
    Library library;
    const auto dir = temp_dir();
    const int port = free_port();
    Broker broker(dir, port);  // no persistence
    ASSERT_TRUE(broker_answers(port));
    Listener listener(port);
    write_text(dir / "watch.toml", "[service]\nestimate_interval_s = 0.5\n");
    std::vector<std::string> arguments = {FEEDID_CLI, "watch", "--broker", broker.url(), "--config",
                                          (dir / "watch.toml").string(), "--quiet"};
    if (GetParam()) {
        arguments.emplace_back("--client-id");
        arguments.emplace_back("feedid-watch-plant");
    }
    Process watch(arguments, dir / "watch.out", dir / "watch.err");
    ASSERT_TRUE(wait_until([&] { return online_count(listener) >= 1; }, 15)) << read_text(dir / "watch.err");
    const double k = write_trace(dir / "x.csv", 11, 60.0);
    const std::size_t n = samples_of(dir / "x.csv");
    auto before = publish_arguments(dir / "x.csv", k, broker.url(), "plant/M1/X/axis");
    for (const char* a : {"--rate", "max"}) before.emplace_back(a);
    Process first(before, dir / "first.out", dir / "first.err");
    ASSERT_EQ(first.wait(), 0) << read_text(dir / "first.err");
    const auto samples = [&] {
        const auto e = listener.estimates();
        const auto it = e.find("plant/M1/X/feedid/estimate");
        return it == e.end() ? std::size_t{0} : it->second["stream"]["samples"].get<std::size_t>();
    };
    ASSERT_TRUE(wait_until([&] { return samples() == n; }, 30)) << samples() << " of " << n;
    EXPECT_EQ(broker.stop(), 0);
    broker.start();
    ASSERT_TRUE(broker_answers(port));
    ASSERT_TRUE(wait_until([&] { return online_count(listener) >= 2; }, 40)) << read_text(dir / "watch.err");
    // a later recording of the same axis, after the restart
    auto after = before;
    for (const char* a : {"--time-offset", "3600"}) after.emplace_back(a);
    Process second(after, dir / "second.out", dir / "second.err");
    ASSERT_EQ(second.wait(), 0) << read_text(dir / "second.err");
    EXPECT_TRUE(wait_until([&] { return samples() == 2 * n; }, 30)) << samples() << " of " << 2 * n << "\n"
                                                                    << read_text(dir / "watch.err");
    EXPECT_EQ(watch.terminate(), 0);
    EXPECT_NE(read_text(dir / "watch.err").find("subscribed again: the broker had no session"), std::string::npos)
        << read_text(dir / "watch.err");
}

INSTANTIATE_TEST_SUITE_P(Sessions, WatchPlantRestart, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "PersistentSession" : "CleanSession"; });

// A publisher that loses messages (the broker away longer than its --buffer) says how many and exits 1.
TEST(WatchPlant, APublisherThatLostMessagesExitsNonZeroNamingTheCount) {
    if (!have_mosquitto()) GTEST_SKIP() << "no " << mosquitto_path << " (apt install mosquitto)";
    Library library;
    const auto dir = temp_dir();
    const int port = free_port();
    Broker broker(dir, port);
    ASSERT_TRUE(broker_answers(port));
    const double k = write_trace(dir / "x.csv", 5, 120.0);
    auto arguments = publish_arguments(dir / "x.csv", k, broker.url(), "plant/M1/X/axis");
    for (const char* a : {"--rate", "20x", "--buffer", "0.5", "--batch", "0.25"}) arguments.emplace_back(a);
    Process publish(arguments, dir / "publish.out", dir / "publish.err");
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    EXPECT_EQ(broker.kill(), 128 + SIGKILL);
    std::this_thread::sleep_for(std::chrono::milliseconds(2500));  // 50 s of stream, 0.5 s of it held
    broker.start();
    EXPECT_EQ(publish.wait(), 1) << read_text(dir / "publish.err");
    const std::string err = read_text(dir / "publish.err");
    EXPECT_NE(err.find("of the stream's messages did not reach the broker"), std::string::npos) << err;
    const auto lost = err.find(" lost, ");
    ASSERT_NE(lost, std::string::npos) << err;
    EXPECT_GT(std::stoul(err.substr(err.rfind(", ", lost - 1) + 2)), 100u) << err;
}

/// A PostgreSQL outage: how long the server is stopped, and the stream time each of three axes publishes at 2x.
struct Outage {
    int stopped_s;
    double stream_s;
};

// PostgreSQL stopped (pg_ctl stop, then start on the same port) while watch records runs (every 5 s of stream on three
// axes, as a role with INSERT and SELECT only): every completed run is in the history afterwards, exactly once;
// meanwhile the runs wait in the spool. For 8 s (an outage that once lost 6 runs, exit 0) and for 30 s.
class WatchPlantPostgres : public ::testing::TestWithParam<Outage> {};

TEST_P(WatchPlantPostgres, StoppedWhileRunsCompleteLosesNoRunAndStoresNoneTwice) {
    const Outage outage = GetParam();
    if (!have_mosquitto()) GTEST_SKIP() << "no " << mosquitto_path << " (apt install mosquitto)";
    if (!test_server().available()) GTEST_SKIP() << "PostgreSQL: " << test_server().why_not();
    Library library;
    const auto dir = temp_dir();
    const int port = free_port();
    Broker broker(dir, port);
    ASSERT_TRUE(broker_answers(port));
    const std::string owner_location = test_server().create_database();
    const std::string database = owner_location.substr(owner_location.rfind('/') + 1);
    // the tables made once by the owner; watch records as a role with the rights docs/deploying.md lists, no more
    (void)history::open_store(owner_location);
    ASSERT_EQ(
        test_server().execute(
            fmt::format("DO $$ BEGIN CREATE ROLE feedid_watch LOGIN; EXCEPTION WHEN duplicate_object THEN NULL; END $$;"
                        "GRANT CONNECT ON DATABASE {0} TO feedid_watch; GRANT USAGE ON SCHEMA public TO feedid_watch;"
                        "GRANT SELECT, INSERT ON runs, parameters, documents TO feedid_watch;"
                        "GRANT SELECT ON baselines, feedid_schema TO feedid_watch;",
                        database),
            database),
        "");
    const std::string location = test_server().location(database, "feedid_watch");
    write_text(dir / "watch.toml", fmt::format("[run]\nperiod_s = 5\n[service]\nestimate_interval_s = 0.5\n"
                                               "[history]\nspool_dir = \"{}\"\n",
                                               (dir / "spool").string()));
    Listener listener(port);
    Process watch({FEEDID_CLI, "watch", "--broker", broker.url(), "--db", location, "--config",
                   (dir / "watch.toml").string(), "--quiet"},
                  dir / "watch.out", dir / "watch.err");
    ASSERT_TRUE(wait_until([&] { return online_count(listener) >= 1; }, 15)) << read_text(dir / "watch.err");
    std::vector<Process> publishers;
    for (const char* axis : {"X", "Y", "Z"}) {
        const auto csv = dir / fmt::format("{}.csv", axis);
        const double k = write_trace(csv, 100 + static_cast<std::uint64_t>(axis[0]), outage.stream_s);
        auto arguments = publish_arguments(csv, k, broker.url(), fmt::format("plant/M1/{}/axis", axis));
        for (const char* a : {"--rate", "2x", "--buffer", "600"}) arguments.emplace_back(a);
        publishers.emplace_back(arguments, dir / fmt::format("publish_{}.out", axis),
                                dir / fmt::format("publish_{}.err", axis));
    }
    std::this_thread::sleep_for(std::chrono::seconds(15));
    ASSERT_TRUE(test_server().pause());
    const auto stopped = Clock::now();
    std::size_t most_spooled = 0;
    while (Clock::now() - stopped < std::chrono::seconds(outage.stopped_s)) {
        std::size_t spooled = 0;
        std::error_code error;
        for (const auto& f : fs::directory_iterator(dir / "spool", error))
            spooled += f.path().filename().string().starts_with("run-");
        most_spooled = std::max(most_spooled, spooled);
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    ASSERT_TRUE(test_server().resume());
    for (std::size_t i = 0; i < publishers.size(); ++i) EXPECT_EQ(publishers[i].wait(), 0);
    // the last runs written, then SIGTERM
    std::this_thread::sleep_for(std::chrono::seconds(3));
    EXPECT_EQ(watch.terminate(), 0) << read_text(dir / "watch.err");
    const std::string err = read_text(dir / "watch.err");
    // "N completed run(s); M recorded in the history, 0 set aside as refused, 0 lost"
    const auto summary = err.find(" completed run(s); ");
    ASSERT_NE(summary, std::string::npos) << err;
    const std::size_t completed = std::stoul(err.substr(err.rfind("feedid watch: ", summary) + 14));
    EXPECT_NE(err.find(fmt::format("{} completed run(s); {} recorded in the history, 0 set aside as refused, 0 lost",
                                   completed, completed)),
              std::string::npos)
        << err;
    const auto count = [&](const std::string& sql) { return std::stoul(test_server().value(sql, database)); };
    const std::size_t stored = count("SELECT count(*) FROM runs");
    const std::size_t distinct = count("SELECT count(DISTINCT trace_path) FROM runs");
    std::cout << fmt::format(
        "PostgreSQL stopped for {} s: {} runs completed, {} in the history ({} distinct), {} lost, at most {} "
        "waiting in the spool meanwhile\n",
        outage.stopped_s, completed, stored, distinct, completed - std::min(completed, distinct), most_spooled);
    // a run per 5 s of stream and axis, but for the first 30 s or so (the first windows, a new axis held) and the end
    EXPECT_GE(completed, static_cast<std::size_t>(3.0 * (outage.stream_s / 5.0 - 8.0)));
    EXPECT_EQ(stored, completed);
    EXPECT_EQ(distinct, completed);
    EXPECT_GT(most_spooled, 3u) << "the outage did not hold back any run";
    std::error_code error;
    std::size_t left = 0;
    for (const auto& f : fs::directory_iterator(dir / "spool", error))
        left += f.path().filename().string().starts_with("run-");
    EXPECT_EQ(left, 0u);
}

INSTANTIATE_TEST_SUITE_P(Outages, WatchPlantPostgres, ::testing::Values(Outage{8, 60.0}, Outage{30, 120.0}),
                         [](const auto& info) { return fmt::format("{}s", info.param.stopped_s); });

}  // namespace
}  // namespace feedid::testing

#else
#include <gtest/gtest.h>
TEST(WatchPlant, Skipped) {
    GTEST_SKIP() << "feedid was built without libmosquitto (apt install libmosquitto-dev)";
}
#endif
