// Opening the history file (sqlite_access.hpp) and SQLite's errors in words (sqlite_statement.hpp).
#include "sqlite_access.hpp"

#include <sqlite3.h>

#include <cctype>
#include <cerrno>
#include <optional>
#include <system_error>

#include <sys/stat.h>
#include <unistd.h>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "sqlite_statement.hpp"

namespace feedid::history {
namespace {

std::string os_reason(int error) {
    return std::error_code(error, std::generic_category()).message();
}

/// The file's status; nothing when it does not exist. InputError naming why it cannot be looked at.
std::optional<struct stat> status_of(const std::filesystem::path& path) {
    struct stat status {};
    if (::stat(path.c_str(), &status) == 0) return status;
    const int error = errno;
    if (error == ENOENT) return std::nullopt;
    const char* why = error == ELOOP     ? "a loop of symbolic links"
                      : error == EACCES  ? "permission denied (a folder on the path may not be searched)"
                      : error == ENOTDIR ? "a part of the path is not a folder"
                                         : nullptr;
    throw InputError(fmt::format("{}: cannot look at the history database: {}", path.string(),
                                 why ? std::string(why) : os_reason(error)));
}

/// 0 when this process may use the file or folder as asked (access(2)), else the errno.
int access_error(const std::filesystem::path& path, int mode) {
    return ::access(path.c_str(), mode) == 0 ? 0 : errno;
}

std::string folder_of(const std::filesystem::path& path) {
    return path.has_parent_path() ? path.parent_path().string() : std::string(".");
}

/// A file: URI of the path for SQLite (every byte but the unreserved ones percent-encoded).
std::string uri_of(const std::filesystem::path& path, const char* parameter) {
    std::string uri = "file:";
    const std::string absolute = std::filesystem::absolute(path).lexically_normal().string();
    for (std::size_t i = 0; i < absolute.size(); ++i) {
        const auto c = static_cast<unsigned char>(absolute[i]);
        const bool plain = std::isalnum(c) || c == '-' || c == '.' || c == '_' || c == '~' || (c == '/' && i != 1);
        uri += plain ? std::string(1, static_cast<char>(c)) : fmt::format("%{:02X}", c);
    }
    return uri + "?" + parameter;
}

/// Why a writer may not write here: the file, its folder (SQLite creates DB-wal and DB-shm there) or a companion file
/// another user left; "" when it may.
std::string writer_problem(const std::filesystem::path& path, bool exists) {
    const std::string folder = folder_of(path);
    if (const int error = exists ? access_error(path, W_OK) : 0; error != 0)
        return error == EROFS    ? "the file system is mounted read-only"
               : error == EACCES ? "no permission to write the file"
                                 : os_reason(error);
    if (const int error = access_error(folder, W_OK | X_OK); error != 0)
        return error == EROFS ? "the file system is mounted read-only"
               : error == EACCES
                   ? fmt::format(
                         "no permission to write in the folder {} (SQLite keeps DB-wal and DB-shm beside the "
                         "database)",
                         folder)
               : error == ENOENT ? fmt::format("the folder {} does not exist", folder)
                                 : fmt::format("the folder {}: {}", folder, os_reason(error));
    for (const char* suffix : {"-wal", "-shm"}) {
        const std::filesystem::path companion = path.string() + suffix;
        struct stat status {};
        if (::stat(companion.c_str(), &status) != 0) continue;
        // (a companion that vanished meanwhile was removed by the last process that closed the database: fine)
        if (const int error = access_error(companion, R_OK | W_OK); error == EACCES || error == EPERM)
            return fmt::format(
                "{} belongs to user {} and this user may not write it (left by another program or an "
                "older feedid reading the database; remove it when no process has the database open)",
                companion.string(), status.st_uid);
    }
    return {};
}

/// A reader that may not write the file or its folder: it must create nothing.
OpenPlan read_only_plan(const std::filesystem::path& path) {
    std::error_code error;
    const bool wal = std::filesystem::exists(path.string() + "-wal", error);
    const bool shm = std::filesystem::exists(path.string() + "-shm", error);
    // No DB-wal: no writer has the file open and every committed run is in the file itself; immutable reads it
    // without locks and without creating DB-shm.
    if (!wal && !shm) return {uri_of(path, "immutable=1"), SQLITE_OPEN_READONLY | SQLITE_OPEN_URI};
    if (shm && access_error(path.string() + "-shm", R_OK) == 0)
        return {uri_of(path, "mode=ro"), SQLITE_OPEN_READONLY | SQLITE_OPEN_URI};
    throw InputError(fmt::format(
        "{}: {}-wal holds changes that are not yet in the database, and reading them needs {}-shm, which this user "
        "may not {}; run the command once as a user who may write the database and its folder",
        path.string(), path.string(), path.string(), shm ? "read" : "create"));
}

}  // namespace

std::string describe_sqlite_error(int code, sqlite3* db) {
    const int primary = code & 0xff;
    const int os_error = db ? sqlite3_system_errno(db) : 0;
    const std::string os = os_error != 0 ? fmt::format(" ({})", os_reason(os_error)) : std::string();
    if (primary == SQLITE_CORRUPT || primary == SQLITE_NOTADB) return "the file is corrupt or not a SQLite database";
    if (code == SQLITE_READONLY_DIRECTORY) return "the folder is not writable (SQLite keeps DB-wal and DB-shm there)";
    if (primary == SQLITE_READONLY) return "the file (or its -wal or -shm file) is read-only" + os;
    if (primary == SQLITE_FULL || os_error == ENOSPC || os_error == EDQUOT) return "the disk is full";
    if (primary == SQLITE_BUSY || primary == SQLITE_LOCKED) return "another process holds the database locked";
    if (primary == SQLITE_CANTOPEN) return "the file cannot be opened" + os;
    if (primary == SQLITE_IOERR) return "an input/output error of the file system" + os;
    if (primary == SQLITE_PERM || primary == SQLITE_AUTH) return "permission denied" + os;
    return (db ? std::string(sqlite3_errmsg(db)) : std::string(sqlite3_errstr(code))) + os;
}

OpenPlan plan_open(const std::filesystem::path& path, const SqliteOpenOptions& options) {
    const std::string shown = path.string();
    const auto status = status_of(path);
    if (!status) {
        if (options.read_only || !options.create) throw InputError(fmt::format("{}: no such history database", shown));
        if (const auto problem = writer_problem(path, false); !problem.empty())
            throw InputError(fmt::format("{}: cannot create the history database: {}", shown, problem));
        return {shown, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE};
    }
    if (S_ISDIR(status->st_mode)) throw InputError(fmt::format("{}: is a folder, not a history database", shown));
    if (!S_ISREG(status->st_mode))
        throw InputError(
            fmt::format("{}: is not a regular file (a FIFO, a device or a socket), not a history database", shown));
    if (access_error(path, R_OK) != 0)
        throw InputError(fmt::format("{}: no permission to read the history database", shown));
    if (status->st_size > 0 && !looks_like_sqlite(path))
        throw InputError(fmt::format("{}: not a feedid history database (not a SQLite file)", shown));
    const std::string problem = writer_problem(path, true);
    if (!options.read_only) {
        if (!problem.empty()) throw InputError(fmt::format("{}: cannot record: {}", shown, problem));
        return {shown, SQLITE_OPEN_READWRITE};
    }
    // A reader that could write opens as a writer does (query_only keeps it from writing): a connection opened
    // read-only cannot remove DB-wal and DB-shm when it closes last, and would leave them behind.
    if (problem.empty()) return {shown, SQLITE_OPEN_READWRITE};
    return read_only_plan(path);
}

}  // namespace feedid::history
