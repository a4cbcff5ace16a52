#pragma once
// Completed identifications on their way to the history, kept on disk until the history has them: what `feedid
// watch` records goes here first and is written to the database from here, so that a database that is away (a
// restart, a network cut) loses nothing, and a watch that is stopped or killed meanwhile leaves them for the next one.
//
// One file per run, named by a sequence number (runs are written in the order they completed), written whole before
// it counts (a temporary file, fsync, rename, fsync of the folder) and removed only after the history has the run. A
// run written to the history and not yet removed when the process died is written again by the next watch: the
// history finds it by its content hash (trace hash and options) and stores nothing twice. The folder is locked (a
// lock file held with flock) by one process at a time, and bounded in bytes.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace feedid::watch {

/// One spooled run: the entry as put, and its sequence number in the spool.
struct SpooledRun {
    std::uint64_t number{0};
    nlohmann::json entry;
};

class RunSpool {
public:
    /// Opens the folder (made when missing) and locks it. InputError naming the folder when it cannot be made,
    /// written or locked (another process uses it).
    RunSpool(std::filesystem::path folder, std::size_t max_bytes);
    ~RunSpool();
    RunSpool(const RunSpool&) = delete;
    RunSpool& operator=(const RunSpool&) = delete;

    /// Adds an entry, on disk before it returns. false when it would take the spool beyond its bound (nothing kept),
    /// InputError when the file cannot be written (a full disk).
    bool put(const nlohmann::json& entry);
    /// The oldest entry (nullopt when none). A file that cannot be read back is set aside (rejected/) and skipped.
    [[nodiscard]] std::optional<SpooledRun> front();
    /// Removes the entry `number` (the history has it).
    void remove(std::uint64_t number);
    /// Sets the entry `number` aside in rejected/ with the reason beside it (the history refuses it for good); the
    /// operator can look at it there.
    void reject(std::uint64_t number, const std::string& reason);

    [[nodiscard]] std::size_t size() const;
    [[nodiscard]] std::size_t bytes() const;
    [[nodiscard]] const std::filesystem::path& folder() const { return folder_; }

private:
    [[nodiscard]] std::filesystem::path path_of(std::uint64_t number) const;
    void set_aside(std::uint64_t number, const std::string& reason);

    std::filesystem::path folder_;
    std::size_t max_bytes_;
    int lock_fd_{-1};
    mutable std::mutex mutex_;
    std::map<std::uint64_t, std::size_t> files_;  ///< number -> bytes
    std::size_t bytes_{0};
    std::uint64_t next_{1};
};

}  // namespace feedid::watch
