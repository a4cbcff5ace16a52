// Progress on a terminal (see progress.hpp).

#include "feedid/core/progress.hpp"

#include <unistd.h>

#include <algorithm>

#include <fmt/core.h>

namespace feedid {

bool is_terminal(std::FILE* stream) {
    return stream && ::isatty(::fileno(stream)) == 1;
}

Progress::Progress(std::string label, std::size_t total, std::FILE* stream)
    : Progress(std::move(label), total, stream, is_terminal(stream)) {}

Progress::Progress(std::string label, std::size_t total, std::FILE* stream, bool force_enabled)
    : label_(std::move(label)),
      total_(total),
      stream_(stream),
      enabled_(force_enabled && stream != nullptr),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

Progress::~Progress() {
    finish();
}

void Progress::update(std::size_t done) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    // Nothing for the first half second (short runs stay silent), then at most ten redraws a second.
    if (now - start_ < std::chrono::milliseconds(500)) return;
    if (drawn_ && now - last_draw_ < std::chrono::milliseconds(100) && done != total_) return;
    last_draw_ = now;
    draw(done);
}

void Progress::draw(std::size_t done) {
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    std::string line;
    if (total_ > 0) {
        const double fraction = std::min(1.0, static_cast<double>(done) / static_cast<double>(total_));
        constexpr int width = 30;
        const int filled = static_cast<int>(fraction * width);
        line = fmt::format("{} [{}{}] {:3.0f} % ({}/{})", label_, std::string(static_cast<std::size_t>(filled), '#'),
                           std::string(static_cast<std::size_t>(width - filled), '.'), 100.0 * fraction, done, total_);
        if (fraction > 0.0 && fraction < 1.0) line += fmt::format(", {:.0f} s left", elapsed * (1.0 / fraction - 1.0));
    } else {
        line = fmt::format("{}: {} done, {:.0f} s", label_, done, elapsed);
    }
    fmt::print(stream_, "\r\x1b[2K{}", line);
    std::fflush(stream_);
    drawn_ = true;
}

void Progress::finish() {
    if (!enabled_ || !drawn_) return;
    fmt::print(stream_, "\r\x1b[2K");
    std::fflush(stream_);
    drawn_ = false;
}

}  // namespace feedid
