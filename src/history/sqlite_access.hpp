#pragma once
// How the SQLite history store opens its file (internal to src/history): as a writer, as a reader that may write
// the file and its folder (read-write with query_only, so that the last one to close removes DB-wal and DB-shm), or
// as a reader that may not (mode=ro, or immutable when no DB-wal is there: it creates no file). Every problem of the
// file system is named as such before SQLite sees the file: permission, a read-only mount, a missing folder, a loop
// of symbolic links, a FIFO or a device where the database should be.

#include <filesystem>
#include <string>

#include "feedid/history/store.hpp"

namespace feedid::history {

struct OpenPlan {
    std::string name;  ///< the path, or a file: URI with mode=ro or immutable=1
    int flags{0};      ///< SQLITE_OPEN_* flags
};

/// How to open `path` as `options` ask. InputError naming the path and the reason when it cannot be.
OpenPlan plan_open(const std::filesystem::path& path, const SqliteOpenOptions& options);

}  // namespace feedid::history
