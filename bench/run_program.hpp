#pragma once
// Runs a program as a user does (fork + exec, stdout captured to a file in FEEDID_BENCH_DATA, stderr discarded) and
// waits for it: wall time, CPU time and peak resident memory of the process (wait4's rusage). For the benchmarks that
// time feedid's commands end to end.

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/core.h>

namespace feedid::bench {

/// What one run of a program did.
struct Outcome {
    double seconds{0.0};      ///< wall
    double cpu_seconds{0.0};  ///< user + system
    double peak_megabytes{0.0};
    int exit_code{-1};
    std::string out;
};

/// Runs `argv` (stdout captured, stderr to /dev/null) and waits for it.
inline Outcome run(const std::vector<std::string>& argv) {
    const std::filesystem::path capture =
        std::filesystem::path(FEEDID_BENCH_DATA) / fmt::format("out-{}.txt", ::getpid());
    const auto start = std::chrono::steady_clock::now();
    const pid_t pid = ::fork();
    if (pid == 0) {
        if (!std::freopen(capture.c_str(), "w", stdout) || !std::freopen("/dev/null", "w", stderr)) ::_exit(126);
        std::vector<char*> args;
        for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
        args.push_back(nullptr);
        ::execv(args[0], args.data());
        ::_exit(127);
    }
    int status = 0;
    struct rusage usage {};
    ::wait4(pid, &status, 0, &usage);
    Outcome outcome;
    outcome.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const auto seconds = [](const timeval& t) {
        return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
    };
    outcome.cpu_seconds = seconds(usage.ru_utime) + seconds(usage.ru_stime);
    outcome.peak_megabytes = static_cast<double>(usage.ru_maxrss) / 1024.0;
    outcome.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (FILE* file = std::fopen(capture.c_str(), "r")) {
        char buffer[4096];
        std::size_t n = 0;
        while ((n = std::fread(buffer, 1, sizeof buffer, file)) > 0) outcome.out.append(buffer, n);
        std::fclose(file);
    }
    std::filesystem::remove(capture);
    return outcome;
}

}  // namespace feedid::bench
