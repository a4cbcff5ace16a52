#pragma once
// A PostgreSQL server of a test or benchmark program's own (Debian's postgresql: initdb, pg_ctl), for the history
// on PostgreSQL. The data folder is given (in the build tree), owned by the unprivileged `postgres` user when the
// program runs as root (PostgreSQL refuses to run as root), with the unix socket in it; the server listens on
// 127.0.0.1 on a port the kernel found free, so that programs running in parallel (ctest -j) never collide. Roles:
// feedid_admin (superuser, trust), feedid_password (a password, scram-sha-256: the authentication tests),
// feedid_reader (no rights on feedid's tables: the permission tests).

#include <netinet/in.h>
#include <pwd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "free_port.hpp"

#ifdef FEEDID_HAVE_POSTGRESQL
#include <libpq-fe.h>
#endif

namespace feedid::testing {

/// The password of the feedid_password role (the authentication tests check it is never printed).
inline constexpr const char* test_password = "s3cret-Never-Shown";

class PostgresServer {
public:
    /// A server with its files in `folder` (made; removed by stop() unless `keep`: then an existing cluster there is
    /// started again, with its databases). Check available() before use.
    explicit PostgresServer(std::filesystem::path folder, bool keep = false) : data_(std::move(folder)), keep_(keep) {
#ifndef FEEDID_HAVE_POSTGRESQL
        why_not_ = "feedid was built without libpq (libpq-dev)";
#else
        if (!find_binaries()) return;
        if (::geteuid() == 0) {
            const passwd* user = ::getpwnam("postgres");
            if (!user) {
                why_not_ = "running as root and there is no 'postgres' user to run the server as";
                return;
            }
            uid_ = user->pw_uid;
            gid_ = user->pw_gid;
            runas_ = "runuser -u postgres -- ";
        }
        start();
#endif
    }
    PostgresServer(const PostgresServer&) = delete;
    PostgresServer& operator=(const PostgresServer&) = delete;
    ~PostgresServer() {
        stop();
    }

    [[nodiscard]] bool available() const {
        return why_not_.empty();
    }
    /// Why there is no server (binaries absent, no unprivileged user, the server did not start).
    [[nodiscard]] const std::string& why_not() const {
        return why_not_;
    }
    [[nodiscard]] int port() const {
        return port_;
    }
    [[nodiscard]] const std::filesystem::path& data() const {
        return data_;
    }

    /// postgresql://ROLE@127.0.0.1:PORT/DATABASE
    [[nodiscard]] std::string location(const std::string& database, const std::string& role = "feedid_admin") const {
        return fmt::format("postgresql://{}@127.0.0.1:{}/{}", role, port_, database);
    }

    /// A new empty database (a fresh one for every call); its location for feedid_admin.
    std::string create_database() {
        static std::atomic<int> counter{0};
        const std::string name = fmt::format("history_{}_{}", ::getpid(), ++counter);
        execute(fmt::format("CREATE DATABASE {}", name));
        return location(name);
    }

    /// The database `name`, created when the server has none of that name (a kept server's from an earlier run).
    std::string database(const std::string& name) {
        if (value(fmt::format("SELECT 1 FROM pg_database WHERE datname = '{}'", name), "postgres") != "1")
            execute(fmt::format("CREATE DATABASE {}", name));
        return location(name);
    }

    /// Writes a file (the configuration; the tests' own helpers are not at hand here).
    static void write_text(const std::filesystem::path& path, const std::string& text) {
        std::ofstream(path, std::ios::binary) << text;
    }
    static std::string read_text(const std::filesystem::path& path) {
        std::ifstream file(path, std::ios::binary);
        return {std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
    }
    static std::string quoted(const std::filesystem::path& path) {
        return "'" + path.string() + "'";
    }

    /// Runs SQL as feedid_admin on a database ("postgres" by default); "" on success, else the server's message.
    std::string execute(const std::string& sql, const std::string& database = "postgres") const {
#ifdef FEEDID_HAVE_POSTGRESQL
        PGconn* connection = PQconnectdb(location(database).c_str());
        std::string error;
        if (PQstatus(connection) != CONNECTION_OK) {
            error = PQerrorMessage(connection);
        } else {
            PGresult* result = PQexec(connection, sql.c_str());
            const auto status = PQresultStatus(result);
            if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK) error = PQerrorMessage(connection);
            PQclear(result);
        }
        PQfinish(connection);
        return error;
#else
        (void)sql;
        (void)database;
        return "built without libpq";
#endif
    }

    /// The first column of the first row of a query as text ("" when none).
    std::string value(const std::string& sql, const std::string& database) const {
#ifdef FEEDID_HAVE_POSTGRESQL
        PGconn* connection = PQconnectdb(location(database).c_str());
        std::string text;
        PGresult* result = PQexec(connection, sql.c_str());
        if (PQresultStatus(result) == PGRES_TUPLES_OK && PQntuples(result) > 0) text = PQgetvalue(result, 0, 0);
        PQclear(result);
        PQfinish(connection);
        return text;
#else
        (void)sql;
        (void)database;
        return {};
#endif
    }

    /// Stops the server (as a restart or a crash of the database host would take it away) and keeps its data; true
    /// when it stopped. resume() starts it again on the same port.
    bool pause() {
        if (!started_) return false;
        return as_server_user(
                   fmt::format("{} -D {} -m fast -w stop", quoted(bin_ / "pg_ctl"), quoted(data_ / "cluster"))) == 0;
    }
    /// Starts the server paused by pause() again, on the same port; true when it is up.
    bool resume() {
        if (!started_) return false;
        return as_server_user(fmt::format("{} -D {} -l {} -w -t 60 -o '-p {}' start", quoted(bin_ / "pg_ctl"),
                                          quoted(data_ / "cluster"), quoted(data_ / "server.log"), port_)) == 0;
    }

    void stop() {
        if (!started_) return;
        started_ = false;
        as_server_user(fmt::format("{} -D {} -m fast -w stop", quoted(bin_ / "pg_ctl"), quoted(data_ / "cluster")));
        if (keep_) return;
        std::error_code error;
        std::filesystem::remove_all(data_, error);
    }

private:
    bool find_binaries() {
        const char* given = std::getenv("FEEDID_TEST_POSTGRES_BIN");
        std::vector<std::filesystem::path> candidates;
        if (given) candidates.emplace_back(given);
        std::error_code error;
        for (const auto& entry : std::filesystem::directory_iterator("/usr/lib/postgresql", error))
            candidates.push_back(entry.path() / "bin");
        std::sort(candidates.begin() + (given ? 1 : 0), candidates.end(),
                  [](const auto& a, const auto& b) { return a.string() > b.string(); });  // the newest first
        for (const auto& bin : candidates)
            if (std::filesystem::exists(bin / "initdb") && std::filesystem::exists(bin / "pg_ctl")) {
                bin_ = bin;
                return true;
            }
        why_not_ = "PostgreSQL's server binaries (initdb, pg_ctl) are not installed (Debian: postgresql)";
        return false;
    }

    int as_server_user(const std::string& command) const {
        const int status = std::system((runas_ + command + " >/dev/null 2>&1").c_str());
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
    }

    /// Stops and removes the servers of earlier programs that died without stopping theirs (a crash): sibling folders
    /// named <program>-<pid> whose process is gone.
    void reap_orphans() const {
        std::error_code error;
        for (const auto& entry : std::filesystem::directory_iterator(data_.parent_path(), error)) {
            const std::string name = entry.path().filename().string();
            const auto dash = name.rfind('-');
            if (dash == std::string::npos || entry.path() == data_) continue;
            const long pid = std::strtol(name.c_str() + dash + 1, nullptr, 10);
            if (pid <= 0 || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;
            // only what a server of these tests left (a cluster or its log), nothing else of that name
            if (!std::filesystem::exists(entry.path() / "cluster", error) &&
                !std::filesystem::exists(entry.path() / "server.log", error))
                continue;
            if (std::filesystem::exists(entry.path() / "cluster" / "postmaster.pid", error))
                as_server_user(fmt::format("{} -D {} -m immediate -w stop", quoted(bin_ / "pg_ctl"),
                                           quoted(entry.path() / "cluster")));
            std::filesystem::remove_all(entry.path(), error);
        }
    }

    /// Makes the data folder, the server's user's own; false (why_not_ says why) when it cannot be.
    bool make_data_folder(bool reuse) {
        std::error_code error;
        if (!reuse) std::filesystem::remove_all(data_, error);
        std::filesystem::create_directories(data_, error);
        if (error) {
            why_not_ = fmt::format("cannot create {}: {}", data_.string(), error.message());
            return false;
        }
        if (uid_ != 0 && ::chown(data_.c_str(), uid_, gid_) != 0) {
            why_not_ = "cannot give the data folder to the postgres user";
            return false;
        }
        ::chmod(data_.c_str(), 0700);
        return true;
    }

    void start() {
        std::error_code error;
        const bool reuse = keep_ && std::filesystem::exists(data_ / "cluster" / "PG_VERSION", error);
        if (!make_data_folder(reuse)) return;
        // A build tree the server's user may not reach (a home folder of mode 0750): the cluster goes to the system's
        // temporary folder instead.
        if (!runas_.empty() && as_server_user("test -w " + quoted(data_)) != 0) {
            std::filesystem::remove_all(data_, error);
            data_ = std::filesystem::temp_directory_path() / "feedid-pg" / data_.filename();
            std::filesystem::create_directories(data_.parent_path(), error);
            if (!make_data_folder(reuse)) return;
        }
        if (!keep_) reap_orphans();
        const auto cluster = data_ / "cluster";
        if (!reuse && as_server_user(fmt::format("{} -D {} -U feedid_admin -A trust --no-sync -E UTF8 --no-locale",
                                                 quoted(bin_ / "initdb"), quoted(cluster))) != 0) {
            why_not_ = fmt::format("initdb failed in {}", cluster.string());
            return;
        }
        if (!reuse) write_configuration(cluster);
        for (int attempt = 0; attempt < 5 && !started_; ++attempt) {
            port_ = free_port();
            started_ = as_server_user(fmt::format("{} -D {} -l {} -w -t 60 -o '-p {}' start", quoted(bin_ / "pg_ctl"),
                                                  quoted(cluster), quoted(data_ / "server.log"), port_)) == 0;
        }
        if (!started_) {
            why_not_ = fmt::format("the test server did not start (see {})", (data_ / "server.log").string());
            return;
        }
        if (reuse) return;
        const auto problem = execute(fmt::format(
            "CREATE ROLE feedid_password LOGIN PASSWORD '{}'; CREATE ROLE feedid_reader LOGIN", test_password));
        if (!problem.empty()) why_not_ = "cannot create the test roles: " + problem;
    }

    /// Trust for the test roles, a password for feedid_password; 127.0.0.1 and the socket in the cluster's folder.
    void write_configuration(const std::filesystem::path& cluster) const {
        write_text(cluster / "pg_hba.conf",
                   "local all all trust\n"
                   "host all feedid_password 127.0.0.1/32 scram-sha-256\n"
                   "host all all 127.0.0.1/32 trust\n");
        // fsync off: the tests kill clients, never the server, and a test cluster need not survive a power cut.
        // The unix socket in the cluster's folder, or none where that path is too long for a socket's name (107
        // bytes): the tests connect by TCP.
        const bool socket_fits = (cluster / ".s.PGSQL.65535").string().size() <= 107;
        const std::string settings =
            read_text(cluster / "postgresql.conf") +
            fmt::format(
                "\nlisten_addresses = '127.0.0.1'\nunix_socket_directories = '{}'\nmax_connections = 250\n"
                "fsync = off\nfull_page_writes = off\n",
                socket_fits ? cluster.string() : std::string());
        write_text(cluster / "postgresql.conf", settings);
        for (const char* name : {"pg_hba.conf", "postgresql.conf"})
            if (uid_ != 0 && ::chown((cluster / name).c_str(), uid_, gid_) != 0) {
                // the server reads them as its user; a failure shows in its log
            }
    }

    std::filesystem::path bin_;
    std::filesystem::path data_;
    std::string runas_;
    uid_t uid_{0};
    gid_t gid_{0};
    int port_{0};
    bool keep_{false};
    bool started_{false};
    std::string why_not_;
};

}  // namespace feedid::testing
