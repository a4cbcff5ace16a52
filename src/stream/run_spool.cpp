// The on-disk spool of completed identifications (run_spool.hpp).
#include "feedid/stream/run_spool.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <iterator>

#include <fmt/core.h>

#include "feedid/core/error.hpp"

namespace feedid::watch {
namespace {

namespace fs = std::filesystem;

constexpr const char* prefix = "run-";
constexpr const char* suffix = ".json";

/// The sequence number of a spool file's name ("run-000000000042.json"), nullopt for any other name.
std::optional<std::uint64_t> number_of(const std::string& name) {
    if (!name.starts_with(prefix) || !name.ends_with(suffix)) return std::nullopt;
    const std::string_view digits(name.data() + 4, name.size() - 4 - 5);
    std::uint64_t number = 0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), number);
    if (error != std::errc{} || end != digits.data() + digits.size() || number == 0) return std::nullopt;
    return number;
}

/// Writes `text` to `path` whole: a temporary file, fsync, rename, fsync of the folder (a crash leaves the old state
/// or the new one, never a torn file).
void write_durably(const fs::path& path, const std::string& text) {
    const fs::path temporary = path.string() + ".tmp";
    const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0) throw InputError(fmt::format("{}: cannot write ({})", temporary.string(), std::strerror(errno)));
    std::size_t written = 0;
    while (written < text.size()) {
        const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            const int error = errno;
            ::close(fd);
            ::unlink(temporary.c_str());
            throw InputError(fmt::format("{}: cannot write ({})", temporary.string(), std::strerror(error)));
        }
        written += static_cast<std::size_t>(n);
    }
    const bool synced = ::fsync(fd) == 0;
    ::close(fd);
    if (!synced || ::rename(temporary.c_str(), path.c_str()) != 0) {
        const int error = errno;
        ::unlink(temporary.c_str());
        throw InputError(fmt::format("{}: cannot write ({})", path.string(), std::strerror(error)));
    }
    if (const int folder = ::open(path.parent_path().c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); folder >= 0) {
        ::fsync(folder);
        ::close(folder);
    }
}

}  // namespace

RunSpool::RunSpool(fs::path folder, std::size_t max_bytes) : folder_(std::move(folder)), max_bytes_(max_bytes) {
    std::error_code error;
    fs::create_directories(folder_, error);
    if (error || !fs::is_directory(folder_))
        throw InputError(fmt::format("spool {}: cannot make the folder ({})", folder_.string(),
                                     error ? error.message() : "not a folder"));
    const fs::path lock = folder_ / "lock";
    lock_fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    if (lock_fd_ < 0)
        throw InputError(fmt::format("spool {}: cannot write in it ({})", folder_.string(), std::strerror(errno)));
    if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
        ::close(lock_fd_);
        lock_fd_ = -1;
        throw InputError(fmt::format("spool {}: another process (feedid watch) uses it", folder_.string()));
    }
    for (const auto& file : fs::directory_iterator(folder_, error)) {
        const std::string name = file.path().filename().string();
        if (name.ends_with(".tmp")) {  // a write a crash interrupted: it never counted
            fs::remove(file.path(), error);
            continue;
        }
        const auto number = number_of(name);
        if (!number) continue;
        const auto size = static_cast<std::size_t>(fs::file_size(file.path(), error));
        files_[*number] = size;
        bytes_ += size;
        next_ = std::max(next_, *number + 1);
    }
}

RunSpool::~RunSpool() {
    if (lock_fd_ >= 0) ::close(lock_fd_);  // releases the lock
}

fs::path RunSpool::path_of(std::uint64_t number) const {
    return folder_ / fmt::format("{}{:012}{}", prefix, number, suffix);
}

bool RunSpool::put(const nlohmann::json& entry) {
    const std::string text = entry.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    std::lock_guard lock(mutex_);
    if (bytes_ + text.size() > max_bytes_) return false;
    const std::uint64_t number = next_++;
    write_durably(path_of(number), text);
    files_[number] = text.size();
    bytes_ += text.size();
    return true;
}

std::optional<SpooledRun> RunSpool::front() {
    while (true) {
        std::uint64_t number = 0;
        {
            std::lock_guard lock(mutex_);
            if (files_.empty()) return std::nullopt;
            number = files_.begin()->first;
        }
        std::ifstream file(path_of(number), std::ios::binary);
        const std::string text{std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
        auto entry = nlohmann::json::parse(text, nullptr, false);
        if (file && !entry.is_discarded() && entry.is_object()) return SpooledRun{number, std::move(entry)};
        set_aside(number, "the file is not a readable spool entry");
    }
}

void RunSpool::remove(std::uint64_t number) {
    std::error_code error;
    fs::remove(path_of(number), error);
    std::lock_guard lock(mutex_);
    if (const auto it = files_.find(number); it != files_.end()) {
        bytes_ -= it->second;
        files_.erase(it);
    }
}

void RunSpool::reject(std::uint64_t number, const std::string& reason) {
    set_aside(number, reason);
}

void RunSpool::set_aside(std::uint64_t number, const std::string& reason) {
    std::error_code error;
    const fs::path rejected = folder_ / "rejected";
    fs::create_directories(rejected, error);
    const fs::path from = path_of(number);
    fs::rename(from, rejected / from.filename(), error);
    if (!error) std::ofstream(rejected / (from.stem().string() + ".reason.txt")) << reason << '\n';
    // where it cannot be moved, it stays where it is, and this process skips it
    std::lock_guard lock(mutex_);
    if (const auto it = files_.find(number); it != files_.end()) {
        bytes_ -= it->second;
        files_.erase(it);
    }
}

std::size_t RunSpool::size() const {
    std::lock_guard lock(mutex_);
    return files_.size();
}

std::size_t RunSpool::bytes() const {
    std::lock_guard lock(mutex_);
    return bytes_;
}

}  // namespace feedid::watch
