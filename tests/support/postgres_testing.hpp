#pragma once
// The program's own PostgreSQL server for the history tests (postgres_server.hpp: in FEEDID_TEST_TMP/pg/<program>-
// <pid>, started on first use, stopped when the program ends) and the fixture that runs a history test on both
// backends.

#include <gtest/gtest.h>

#include <cerrno>
#include <memory>

#include "feedid/history/store.hpp"
#include "history_testing.hpp"
#include "postgres_server.hpp"
#include "testing.hpp"

namespace feedid::testing {

/// Where the program's server lives once started (none until a test asks for it).
inline std::unique_ptr<PostgresServer>& server_slot() {
    static std::unique_ptr<PostgresServer> server;
    return server;
}

/// The program's server, started on the first call.
inline PostgresServer& test_server() {
    auto& server = server_slot();
    if (!server) {
        const std::string program = std::filesystem::path(program_invocation_name).filename().string();
        server = std::make_unique<PostgresServer>(test_files_root() / "pg" /
                                                  fmt::format("{}-{}", program.substr(0, 40), ::getpid()));
    }
    return *server;
}

/// Stops the program's server (when one was started) as the program ends.
class PostgresEnvironment : public ::testing::Environment {
public:
    void TearDown() override {
        if (server_slot()) server_slot()->stop();
    }
};
inline ::testing::Environment* const postgres_environment =
    ::testing::AddGlobalTestEnvironment(new PostgresEnvironment);

enum class Backend { sqlite, postgresql };

inline std::string backend_name(const ::testing::TestParamInfo<Backend>& info) {
    return info.param == Backend::sqlite ? "SQLite" : "PostgreSQL";
}

/// A history test on one backend: new_location() gives a fresh, empty history (a file in the test's folder, or a new
/// database on the program's server); on PostgreSQL the test is skipped, with the reason, where no server can run.
class HistoryBackendTest : public ::testing::TestWithParam<Backend> {
protected:
    void SetUp() override {
        folder_ = temp_dir();
        if (GetParam() == Backend::postgresql && !test_server().available())
            GTEST_SKIP() << "PostgreSQL: " << test_server().why_not();
    }

    [[nodiscard]] bool postgresql() const { return GetParam() == Backend::postgresql; }

    std::string new_location(const std::string& stem = "h") {
        if (postgresql()) return test_server().create_database();
        return (folder_ / (stem + ".db")).string();
    }

    static std::unique_ptr<history::HistoryStore> open(const std::string& location, bool read_only = false) {
        history::OpenOptions options;
        options.read_only = read_only;
        return history::open_store(location, options);
    }

    std::filesystem::path folder_;
};

}  // namespace feedid::testing
