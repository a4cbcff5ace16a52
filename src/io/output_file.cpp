// Atomic replacement of output files, and the check that an output is not an input (output_file.hpp).
#include "feedid/io/output_file.hpp"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <optional>
#include <system_error>

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/core.h>

#include "feedid/core/error.hpp"

namespace feedid {
namespace fs = std::filesystem;
namespace {

std::string reason(int error) {
    return std::error_code(error, std::generic_category()).message();
}

[[noreturn]] void fail(const fs::path& path, int error) {
    throw InputError(fmt::format("{}: cannot write the file: {}", path.string(), reason(error)));
}

/// A temporary that cannot be made: a folder the user may not write is said as such (the file itself may be
/// writable, but it is replaced, never written in place).
[[noreturn]] void fail_in_folder(const fs::path& target, const fs::path& folder, int error) {
    if (error == EACCES || error == EPERM)
        throw InputError(
            fmt::format("{}: cannot write the file: the folder {} is not writable (feedid writes a new "
                        "file beside the old one and renames it over)",
                        target.string(), folder.string()));
    fail(target, error);
}

/// Writes all of `text`; the errno of the first failed write, 0 when everything was written.
int write_all(int fd, std::string_view text) {
    while (!text.empty()) {
        const ssize_t written = ::write(fd, text.data(), text.size());
        if (written < 0) {
            if (errno == EINTR) continue;
            return errno;
        }
        if (written == 0) return EIO;
        text.remove_prefix(static_cast<std::size_t>(written));
    }
    return 0;
}

// The temporary's name: ".NAME.feedid-PID.tmp", NAME cut so that the whole stays within the usual 255 bytes.
std::string temporary_prefix(const std::string& name) {
    return "." + name.substr(0, 200) + ".feedid-";
}

std::string temporary_name(const std::string& name) {
    return temporary_prefix(name) + std::to_string(::getpid()) + ".tmp";
}

// Removes the temporaries of this output that processes killed between naming and renaming them left behind (their
// process no longer runs; a running writer's temporary is left alone).
void remove_stale_temporaries(const fs::path& folder, const std::string& name) {
    DIR* directory = ::opendir(folder.c_str());
    if (directory == nullptr) return;
    const std::string prefix = temporary_prefix(name);
    while (const dirent* entry = ::readdir(directory)) {
        const std::string_view file = entry->d_name;
        if (!file.starts_with(prefix) || !file.ends_with(".tmp")) continue;
        const std::string pid_text(file.substr(prefix.size(), file.size() - prefix.size() - 4));
        if (pid_text.empty() || pid_text.find_first_not_of("0123456789") != std::string::npos) continue;
        const long pid = std::strtol(pid_text.c_str(), nullptr, 10);
        if (pid <= 0 || pid == ::getpid() || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;
        ::unlinkat(::dirfd(directory), entry->d_name, 0);
    }
    ::closedir(directory);
}

/// The file a path finally names: symbolic links followed (a dangling one to where it points).
fs::path final_target(const fs::path& path) {
    std::error_code error;
    if (!fs::is_symlink(fs::symlink_status(path, error))) return path;
    if (const auto resolved = fs::canonical(path, error); !error) return resolved;
    fs::path link = fs::read_symlink(path, error);
    if (error) return path;
    return link.is_absolute() ? link : path.parent_path() / link;
}

/// A target that is not a regular file (a terminal, /dev/null, /dev/full, a FIFO): written in place, every write
/// and the close checked.
void write_in_place(const fs::path& path, std::string_view text) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
    if (fd < 0) fail(path, errno);
    const int error = write_all(fd, text);
    if (error != 0) {
        ::close(fd);
        fail(path, error);
    }
    if (::close(fd) != 0) fail(path, errno);
}

/// The new file's permissions and owner are the old one's (a new file gets 0666 less the umask, as any).
void keep_mode_and_owner(int fd, const std::optional<struct stat>& old) {
    if (!old) return;
    ::fchmod(fd, old->st_mode & 07777);
    if (old->st_uid != ::geteuid() || old->st_gid != ::getegid()) {
        if (::fchown(fd, old->st_uid, old->st_gid) != 0) {
            // only root may give a file away: the new file is then the writer's, as any new file is
        }
    }
}

/// Blocks every signal that can be blocked (SIGINT, SIGTERM, SIGHUP, ...) while the temporary has a name, so that
/// only SIGKILL can leave it behind; restores the mask when it goes out of scope.
class SignalsHeld {
public:
    SignalsHeld() {
        sigset_t all;
        sigfillset(&all);
        ::pthread_sigmask(SIG_BLOCK, &all, &previous_);
    }
    SignalsHeld(const SignalsHeld&) = delete;
    SignalsHeld& operator=(const SignalsHeld&) = delete;
    ~SignalsHeld() { ::pthread_sigmask(SIG_SETMASK, &previous_, nullptr); }

private:
    sigset_t previous_{};
};

/// Gives the unnamed temporary (O_TMPFILE) a name; the errno on failure.
int name_anonymous(int fd, const fs::path& temporary) {
    const std::string self = fmt::format("/proc/self/fd/{}", fd);
    if (::linkat(AT_FDCWD, self.c_str(), AT_FDCWD, temporary.c_str(), AT_SYMLINK_FOLLOW) == 0) return 0;
    if (errno == EEXIST) {  // our own pid's leftover from before a pid was reused: ours to replace
        ::unlink(temporary.c_str());
        if (::linkat(AT_FDCWD, self.c_str(), AT_FDCWD, temporary.c_str(), AT_SYMLINK_FOLLOW) == 0) return 0;
    }
    if (::linkat(fd, "", AT_FDCWD, temporary.c_str(), AT_EMPTY_PATH) == 0) return 0;  // without /proc
    return errno;
}

/// Flushes the folder so that the rename itself survives a power cut; file systems that cannot are not an error.
void sync_folder(const fs::path& folder, const fs::path& target) {
    const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) return;
    const int result = ::fsync(fd);
    const int error = errno;
    ::close(fd);
    if (result != 0 && error != EINVAL && error != EROFS && error != EBADF) fail(target, error);
}

void replace_regular_file(const fs::path& target, std::string_view text, const std::optional<struct stat>& old) {
    const fs::path folder = target.parent_path().empty() ? fs::path(".") : target.parent_path();
    const std::string name = target.filename().string();
    remove_stale_temporaries(folder, name);
    const fs::path temporary = folder / temporary_name(name);
    int fd = ::open(folder.c_str(), O_TMPFILE | O_WRONLY | O_CLOEXEC, 0666);
    const bool anonymous = fd >= 0;
    if (!anonymous) {
        if (errno != EOPNOTSUPP && errno != EISDIR && errno != EINVAL) fail_in_folder(target, folder, errno);
        fd = ::open(temporary.c_str(), O_CREAT | O_EXCL | O_WRONLY | O_CLOEXEC, 0666);
        if (fd < 0) fail_in_folder(target, folder, errno);
    }
    bool named = !anonymous;
    const auto give_up = [&](int error) {
        ::close(fd);
        if (named) ::unlink(temporary.c_str());
        fail(target, error);
    };
    keep_mode_and_owner(fd, old);
    if (const int error = write_all(fd, text); error != 0) give_up(error);
    if (::fsync(fd) != 0) give_up(errno);
    {
        const SignalsHeld held;
        if (anonymous) {
            if (const int error = name_anonymous(fd, temporary); error != 0) give_up(error);
            named = true;
        }
        if (::close(fd) != 0) {
            const int error = errno;
            ::unlink(temporary.c_str());
            fail(target, error);
        }
        if (::rename(temporary.c_str(), target.c_str()) != 0) {
            const int error = errno;
            ::unlink(temporary.c_str());
            fail(target, error);
        }
    }
    sync_folder(folder, target);
}

}  // namespace

void write_output_file(const fs::path& path, std::string_view text) {
    const fs::path target = final_target(path);
    struct stat status {};
    std::optional<struct stat> old;
    if (::stat(target.c_str(), &status) == 0) {
        if (S_ISDIR(status.st_mode)) throw InputError(fmt::format("{}: is a folder, not a file", path.string()));
        if (!S_ISREG(status.st_mode)) return write_in_place(target, text);
        old = status;
    } else if (errno != ENOENT) {
        fail(path, errno);
    }
    replace_regular_file(target, text, old);
}

void write_output(const std::string& path, std::string_view text) {
    if (path != "-") return write_output_file(path, text);
    if (std::fflush(stdout) != 0) throw InputError(fmt::format("stdout: cannot write: {}", reason(errno)));
    if (const int error = write_all(STDOUT_FILENO, text); error != 0)
        throw InputError(fmt::format("stdout: cannot write: {}", reason(error)));
}

namespace {

/// Whether two paths name the same file: the same device and inode when both exist as regular files, else the same
/// absolute path with symbolic links and ".." resolved. Paths that are not regular files (a terminal, /dev/null)
/// never count: writing to them destroys no file.
bool same_file(const std::string& a, const std::string& b) {
    struct stat sa {};
    struct stat sb {};
    const bool a_exists = ::stat(a.c_str(), &sa) == 0;
    const bool b_exists = ::stat(b.c_str(), &sb) == 0;
    if ((a_exists && !S_ISREG(sa.st_mode)) || (b_exists && !S_ISREG(sb.st_mode))) return false;
    if (a_exists && b_exists) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    if (a_exists != b_exists) return false;
    std::error_code error_a;
    std::error_code error_b;
    const fs::path resolved_a = fs::weakly_canonical(fs::absolute(a, error_a), error_a);
    const fs::path resolved_b = fs::weakly_canonical(fs::absolute(b, error_b), error_b);
    if (error_a || error_b) return fs::absolute(a).lexically_normal() == fs::absolute(b).lexically_normal();
    return resolved_a == resolved_b;
}

bool skipped(const std::string& path) {
    return path.empty() || path == "-";
}

}  // namespace

void require_separate_outputs(const std::vector<OutputPath>& outputs, const std::vector<GuardedFile>& guarded) {
    for (std::size_t i = 0; i < outputs.size(); ++i) {
        const auto& output = outputs[i];
        if (skipped(output.path)) continue;
        for (const auto& file : guarded) {
            if (skipped(file.path)) continue;
            std::vector<std::pair<std::string, std::string>> names{{file.path, file.what}};
            if (file.database)
                for (const char* companion : {"-wal", "-shm", "-journal"})
                    names.emplace_back(file.path + companion, fmt::format("a companion file of {}", file.what));
            for (const auto& [name, what] : names)
                if (same_file(output.path, name))
                    throw InputError(fmt::format("{} {}: is {} ({}); refusing to overwrite it, give another path",
                                                 output.option, output.path, what, name));
        }
        for (std::size_t j = 0; j < i; ++j)
            if (!skipped(outputs[j].path) && same_file(output.path, outputs[j].path))
                throw InputError(fmt::format("{} {}: is also the output of {} ({}); give two different paths",
                                             output.option, output.path, outputs[j].option, outputs[j].path));
    }
}

}  // namespace feedid
