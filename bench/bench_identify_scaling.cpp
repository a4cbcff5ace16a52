// identify's memory and time against the trace's length (issue 14: at most ~100 bytes per sample end to end, time
// within 10 % of linear from 1M to 16M samples). Each measurement runs in a child process of its own, so that its
// peak resident set (wait4's ru_maxrss) is identify's alone: the child builds the trace's three columns (time,
// position, current: bench_stages' drive, sinusoidal strokes at nine speeds, 1 kHz, 50 nm encoder), imports them as
// the Python module does, runs identify with its default options (the preprocessing family included) and reports
// identify's wall and CPU time through a pipe. Counters: bytes per sample (peak resident set over samples, the
// columns included), seconds per million samples (wall), CPU seconds per million samples (user and system time of
// identify alone: the figure to compare on a machine shared with other work, whose load stretches the wall time) and
// the minor page faults per sample.
#include <benchmark/benchmark.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <vector>

#include "feedid/identify/identify.hpp"
#include "feedid/io/import.hpp"
#include "stribeck_trace.hpp"

namespace {

feedid::Trace make_trace(std::size_t samples) {
    auto [time, position, current] = feedid::bench::stribeck_columns(samples);
    feedid::Trace trace;
    // moved in: the trace holds the only copy of each column, as the Python module's import does
    trace.set("time", feedid::Role::other, "", std::move(time));
    trace.set("position", feedid::Role::other, "", std::move(position));
    trace.set("current", feedid::Role::other, "", std::move(current));
    feedid::ImportOptions options;
    options.channels = {
        {feedid::Role::time, "time"}, {feedid::Role::position, "position"}, {feedid::Role::current, "current"}};
    feedid::prepare_trace(trace, options);
    return trace;
}

struct ChildFigures {
    double identify_s{0.0};
    double cpu_s{0.0};
    double page_faults{0.0};
    long peak_kB{0};
    bool ok{false};
};

/// User and system time [s] and minor page faults of this process so far.
std::array<double, 2> cpu_and_faults() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    const auto seconds = [](const timeval& t) {
        return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
    };
    return {seconds(usage.ru_utime) + seconds(usage.ru_stime), static_cast<double>(usage.ru_minflt)};
}

// identify on `samples` in a child process; its wall time and the child's peak resident set.
ChildFigures run_in_child(std::size_t samples, unsigned threads) {
    int fds[2];
    if (pipe(fds) != 0) return {};
    const pid_t pid = fork();
    if (pid == 0) {
        close(fds[0]);
        const feedid::Trace trace = make_trace(samples);
        feedid::IdentifyOptions options;
        options.drive.force_constant = 450.0;
        options.threads = threads;
        const auto before = cpu_and_faults();
        const auto start = std::chrono::steady_clock::now();
        const auto result = feedid::identify(trace, options);
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const auto after = cpu_and_faults();
        benchmark::DoNotOptimize(result.parameters.data());
        const std::array<double, 3> figures{seconds, after[0] - before[0], after[1] - before[1]};
        const ssize_t written = write(fds[1], figures.data(), sizeof figures);
        _exit(written == sizeof figures ? 0 : 1);
    }
    close(fds[1]);
    ChildFigures figures;
    std::array<double, 3> sent{};
    const ssize_t got = read(fds[0], sent.data(), sizeof sent);
    close(fds[0]);
    figures.identify_s = sent[0];
    figures.cpu_s = sent[1];
    figures.page_faults = sent[2];
    int status = 0;
    rusage usage{};
    wait4(pid, &status, 0, &usage);
    figures.peak_kB = usage.ru_maxrss;
    figures.ok = got == sizeof sent && WIFEXITED(status) && WEXITSTATUS(status) == 0;
    return figures;
}

void BM_IdentifyScaling(benchmark::State& state) {
    const auto samples = static_cast<std::size_t>(state.range(0));
    ChildFigures last;
    double seconds = 0.0, cpu = 0.0;
    for (auto _ : state) {
        last = run_in_child(samples, static_cast<unsigned>(state.range(1)));
        if (!last.ok) {
            state.SkipWithError("the child process failed");
            return;
        }
        state.SetIterationTime(last.identify_s);
        seconds += last.identify_s;
        cpu += last.cpu_s;
    }
    const double n = static_cast<double>(samples);
    state.counters["bytes_per_sample"] = static_cast<double>(last.peak_kB) * 1024.0 / n;
    state.counters["peak_MB"] = static_cast<double>(last.peak_kB) / 1024.0;
    state.counters["s_per_M_samples"] = seconds / static_cast<double>(state.iterations()) / (n / 1e6);
    state.counters["cpu_s_per_M_samples"] = cpu / static_cast<double>(state.iterations()) / (n / 1e6);
    state.counters["faults_per_sample"] = last.page_faults / n;
}
BENCHMARK(BM_IdentifyScaling)
    ->ArgNames({"samples", "threads"})
    ->Args({1'000'000, 0})
    ->Args({4'000'000, 0})
    ->Args({16'000'000, 0})
    ->Args({1'000'000, 1})
    ->Args({16'000'000, 1})
    ->UseManualTime()
    ->Iterations(2)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
