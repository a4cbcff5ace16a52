#pragma once
// Real components for the MQTT tests: a mosquitto broker of the test's own (a config in the test's folder, 127.0.0.1
// and a free port, no persistence) started with posix_spawn and stopped by its PID; processes of the feedid binary;
// and a subscriber (libmosquitto) that keeps what feedid watch publishes.

#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
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
    Process(const std::vector<std::string>& arguments, const std::filesystem::path& out,
            const std::filesystem::path& err) {
        std::vector<char*> argv;
        for (const auto& a : arguments) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
        posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
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

private:
    pid_t pid_{-1};
};

inline bool broker_answers(int port) {
    mosquitto* client = mosquitto_new(nullptr, true, nullptr);
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
        for (int attempt = 0; attempt < 100 && !broker_answers(port_); ++attempt)
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    int stop() { return process_.terminate(); }
    /// SIGKILL: no shutdown, no last save (a crash, the OOM killer, a power cut of its host).
    int kill() {
        ::kill(process_.pid(), SIGKILL);
        return process_.wait();
    }
    [[nodiscard]] std::string url() const { return "mqtt://127.0.0.1:" + std::to_string(port_); }
    [[nodiscard]] int port() const { return port_; }

private:
    std::filesystem::path dir_;
    int port_;
    int starts_{0};
    Process process_;
};

/// Keeps what feedid watch publishes: the last estimate per machine/axis, every error and alarm, the status.
class Listener {
public:
    explicit Listener(int port) {
        client_ = mosquitto_new(nullptr, true, this);
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
    explicit Sender(int port) {
        client_ = mosquitto_new(nullptr, true, nullptr);
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
        return mosquitto_publish(client_, nullptr, topic.c_str(), static_cast<int>(payload.size()), payload.data(), 1,
                                 false) == MOSQ_ERR_SUCCESS;
    }

private:
    mosquitto* client_{nullptr};
};

}  // namespace feedid::testing
