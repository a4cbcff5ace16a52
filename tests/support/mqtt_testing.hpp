#pragma once
// Real components for the MQTT tests: a mosquitto broker of the test's own (a config in the test's folder, 127.0.0.1
// and a free port, no persistence unless asked; or a configuration of the test's, e.g. TLS and logins) started with
// posix_spawn and stopped by its PID; processes of the feedid binary; a subscriber (libmosquitto) that keeps what
// feedid watch publishes; the resident memory of a process.

#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <mosquitto.h>
#include <nlohmann/json.hpp>

#include "free_port.hpp"
#include "testing.hpp"

extern char** environ;

namespace feedid::testing {

inline const char* mosquitto_path = "/usr/sbin/mosquitto";

/// A child process with stdout and stderr in files.
class Process {
public:
    Process() = default;
    /// `environment`: NAME=VALUE entries added to the test's own environment.
    Process(const std::vector<std::string>& arguments, const std::filesystem::path& out,
            const std::filesystem::path& err, const std::vector<std::string>& environment = {}) {
        std::vector<char*> env;
        for (char** e = environ; *e != nullptr; ++e) env.push_back(*e);
        for (const auto& e : environment) env.push_back(const_cast<char*>(e.c_str()));
        env.push_back(nullptr);
        std::vector<char*> argv;
        for (const auto& a : arguments) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
        posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), env.data()) != 0) pid_ = -1;
        posix_spawn_file_actions_destroy(&actions);
    }
    Process(const Process&) = delete;
    Process& operator=(const Process&) = delete;
    Process(Process&& other) noexcept : pid_(std::exchange(other.pid_, -1)) {}
    Process& operator=(Process&& other) noexcept {
        if (this != &other) {
            if (pid_ > 0) terminate();
            pid_ = std::exchange(other.pid_, -1);
        }
        return *this;
    }
    ~Process() {
        if (pid_ > 0) {
            ::kill(pid_, SIGKILL);
            wait();
        }
    }
    [[nodiscard]] pid_t pid() const { return pid_; }
    /// Waits for the exit; the exit code, or 128 + signal.
    int wait() {
        if (pid_ <= 0) return -1;
        int status = 0;
        ::waitpid(pid_, &status, 0);
        pid_ = -1;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }
    int terminate() {
        if (pid_ > 0) ::kill(pid_, SIGTERM);
        return wait();
    }
    /// Sends a signal to the process (nothing once it has been waited for).
    void signal(int number) const {
        if (pid_ > 0) ::kill(pid_, number);
    }
    /// True while the process runs (or is stopped); false once it has exited (it is then reaped).
    bool running() {
        if (pid_ <= 0) return false;
        int status = 0;
        const pid_t done = ::waitpid(pid_, &status, WNOHANG);
        if (done == 0) return true;
        exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        pid_ = -1;
        return false;
    }
    /// The exit code once running() found the process gone (-1 before).
    [[nodiscard]] int exit_code() const { return exit_code_; }

private:
    pid_t pid_{-1};
    int exit_code_{-1};
};

/// A field of /proc/PID/status in kB ("VmRSS": resident now, "VmHWM": the most it was resident); 0 when unknown.
inline std::size_t proc_status_kb(pid_t pid, const std::string& field) {
    const std::string text = read_text("/proc/" + std::to_string(pid) + "/status");
    const auto at = text.find(field + ":");
    if (at == std::string::npos) return 0;
    return std::strtoull(text.c_str() + at + field.size() + 1, nullptr, 10);
}

/// A broker's login for the test's own clients ("" = anonymous).
struct Login {
    std::string username;
    std::string password;
};

inline bool broker_answers(int port, const Login& login = {}) {
    mosquitto* client = mosquitto_new(nullptr, true, nullptr);
    if (!login.username.empty()) mosquitto_username_pw_set(client, login.username.c_str(), login.password.c_str());
    const bool ok = mosquitto_connect(client, "127.0.0.1", port, 5) == MOSQ_ERR_SUCCESS;
    if (ok) mosquitto_disconnect(client);
    mosquitto_destroy(client);
    return ok;
}

/// A mosquitto of the test's own. `persistent`: it saves sessions, subscriptions and queued messages in the test's
/// folder every second and when stopped, and loads them when started (as a production broker with persistence
/// does; killed, it loses what changed since its last save), else it forgets them.
class Broker {
public:
    /// A broker with the test's own configuration (listeners, TLS, logins); `port` is the one it answers on, `login`
    /// a user that may connect there.
    Broker(const std::filesystem::path& dir, int port, const std::string& configuration, Login login)
        : dir_(dir), port_(port), login_(std::move(login)) {
        write_text(dir / "mosquitto.conf", configuration);
        start();
    }
    Broker(const std::filesystem::path& dir, int port, bool persistent = false) : dir_(dir), port_(port) {
        const std::string persistence =
            persistent ? "persistence true\npersistence_location " + dir.string() + "/\nautosave_interval 1\n"
                       : "persistence false\n";
        write_text(dir / "mosquitto.conf", "listener " + std::to_string(port) + " 127.0.0.1\nallow_anonymous true\n" +
                                               persistence + "max_queued_messages 100000\n");
        start();
    }
    /// Starts it (again): its output in mosquitto.out.N and mosquitto.err.N for the Nth start.
    void start() {
        ++starts_;
        process_ = Process({mosquitto_path, "-c", (dir_ / "mosquitto.conf").string()},
                           dir_ / ("mosquitto.out." + std::to_string(starts_)),
                           dir_ / ("mosquitto.err." + std::to_string(starts_)));
        for (int attempt = 0; attempt < 100 && !broker_answers(port_, login_); ++attempt)
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    int stop() { return process_.terminate(); }
    /// SIGKILL: no shutdown, no last save (a crash, the OOM killer, a power cut of its host).
    int kill() {
        process_.signal(SIGKILL);
        return process_.wait();
    }
    [[nodiscard]] std::string url() const { return "mqtt://127.0.0.1:" + std::to_string(port_); }
    [[nodiscard]] int port() const { return port_; }

private:
    std::filesystem::path dir_;
    int port_;
    Login login_;
    int starts_{0};
    Process process_;
};

/// Keeps what feedid watch publishes: the last estimate per machine/axis, every error and alarm, the status.
class Listener {
public:
    explicit Listener(int port, const Login& login = {}) {
        client_ = mosquitto_new(nullptr, true, this);
        if (!login.username.empty()) mosquitto_username_pw_set(client_, login.username.c_str(), login.password.c_str());
        mosquitto_connect_callback_set(client_, [](mosquitto* c, void* self, int code) {
            if (code == 0) mosquitto_subscribe(c, nullptr, "plant/#", 1);
            if (code == 0) ++static_cast<Listener*>(self)->connections_;
        });
        mosquitto_message_callback_set(
            client_, [](mosquitto*, void* self, const mosquitto_message* m) { static_cast<Listener*>(self)->keep(m); });
        mosquitto_reconnect_delay_set(client_, 1, 2, false);
        mosquitto_connect(client_, "127.0.0.1", port, 30);
        mosquitto_loop_start(client_);
    }
    ~Listener() {
        mosquitto_disconnect(client_);
        mosquitto_loop_stop(client_, false);
        mosquitto_destroy(client_);
    }
    Listener(const Listener&) = delete;
    Listener& operator=(const Listener&) = delete;

    std::map<std::string, nlohmann::json> estimates() {
        std::lock_guard lock(mutex_);
        return estimates_;
    }
    std::vector<nlohmann::json> errors() {
        std::lock_guard lock(mutex_);
        return errors_;
    }
    std::vector<nlohmann::json> alarms() {
        std::lock_guard lock(mutex_);
        return alarms_;
    }
    std::vector<nlohmann::json> runs() {
        std::lock_guard lock(mutex_);
        return runs_;
    }
    /// Connections made (a reconnect after a broker restart counts).
    [[nodiscard]] std::size_t connections() const { return connections_; }
    std::vector<std::string> status() {
        std::lock_guard lock(mutex_);
        return status_;
    }

private:
    void keep(const mosquitto_message* m) {
        const std::string topic = m->topic;
        const std::string payload(static_cast<const char*>(m->payload), static_cast<std::size_t>(m->payloadlen));
        std::lock_guard lock(mutex_);
        if (topic.ends_with("/feedid/status")) {
            status_.push_back(payload);
            return;
        }
        const auto json = nlohmann::json::parse(payload, nullptr, false);
        if (topic.ends_with("/feedid/estimate"))
            estimates_[topic] = json;
        else if (topic.ends_with("/feedid/error"))
            errors_.push_back(json);
        else if (topic.ends_with("/feedid/alarm"))
            alarms_.push_back(json);
        else if (topic.ends_with("/feedid/run"))
            runs_.push_back(json);
    }

    mosquitto* client_{nullptr};
    std::atomic<std::size_t> connections_{0};
    std::mutex mutex_;
    std::map<std::string, nlohmann::json> estimates_;
    std::vector<nlohmann::json> errors_, alarms_, runs_;
    std::vector<std::string> status_;
};

/// Publishes raw payloads (the malformed ones) from the test.
class Sender {
public:
    explicit Sender(int port, const Login& login = {}) {
        client_ = mosquitto_new(nullptr, true, this);
        if (!login.username.empty()) mosquitto_username_pw_set(client_, login.username.c_str(), login.password.c_str());
        mosquitto_publish_callback_set(
            client_, [](mosquitto*, void* self, int) { ++static_cast<Sender*>(self)->acknowledged_; });
        mosquitto_reconnect_delay_set(client_, 1, 2, false);
        mosquitto_connect(client_, "127.0.0.1", port, 30);
        mosquitto_loop_start(client_);
    }
    ~Sender() {
        mosquitto_disconnect(client_);
        mosquitto_loop_stop(client_, false);
        mosquitto_destroy(client_);
    }
    Sender(const Sender&) = delete;
    Sender& operator=(const Sender&) = delete;
    bool send(const std::string& topic, const std::string& payload) {
        const bool sent = mosquitto_publish(client_, nullptr, topic.c_str(), static_cast<int>(payload.size()),
                                            payload.data(), 1, false) == MOSQ_ERR_SUCCESS;
        sent_ += sent;
        return sent;
    }
    /// Messages handed to the library and not yet acknowledged by the broker.
    [[nodiscard]] std::size_t in_flight() const { return sent_ - acknowledged_; }

private:
    mosquitto* client_{nullptr};
    std::atomic<std::size_t> sent_{0}, acknowledged_{0};
};

}  // namespace feedid::testing
