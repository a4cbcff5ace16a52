#pragma once
// Progress of long runs (large traces, many files) on stderr — only when stderr is a terminal, so that logs, pipes
// and CI output stay clean. Redrawn at most ten times a second; the line is cleared when the work is done.

#include <chrono>
#include <cstddef>
#include <cstdio>
#include <string>

namespace feedid {

class Progress {
public:
    /// `label` names the work ("identifying", "recording runs"); `total` is the number of steps (0: unknown).
    /// Shown only when `stream` is a terminal, unless `force` says otherwise (tests).
    Progress(std::string label, std::size_t total, std::FILE* stream = stderr);
    Progress(std::string label, std::size_t total, std::FILE* stream, bool force_enabled);
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;
    ~Progress();

    /// Reports that `done` of `total` steps are complete. Cheap when nothing is drawn (one clock read at most).
    void update(std::size_t done);
    /// Clears the line (also done by the destructor).
    void finish();
    [[nodiscard]] bool enabled() const { return enabled_; }

private:
    void draw(std::size_t done);

    std::string label_;
    std::size_t total_;
    std::FILE* stream_;
    bool enabled_;
    bool drawn_{false};
    std::chrono::steady_clock::time_point start_;
    std::chrono::steady_clock::time_point last_draw_;
};

/// True when the stream is a terminal (isatty).
bool is_terminal(std::FILE* stream);

}  // namespace feedid
