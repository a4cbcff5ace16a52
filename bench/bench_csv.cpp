// CSV import speed and memory: a 1,000,000-row, 5-column trace (time, reference and actual position, velocity
// command, current; about 45 MB of text) parsed from memory and read from a file through the whole import chain.
// Targets (issue 2): under 0.25 s per parse on one core (items_per_second >= 4e6 rows/s), and peak memory growth of
// a read within 2x the resulting columns (5 x 1e6 doubles = 40 MB -> at most 80 MB).
//
// Memory is measured in a fresh process (this program run again with --peak-memory MODE FILE) so that nothing earlier
// counts or is reused: it resets its peak resident set (writing 5 to /proc/self/clear_refs resets VmHWM), reads the
// file, and reports VmHWM minus the VmRSS it started from. Mapped file pages count in both.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <utility>

#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"
#include "stribeck_trace.hpp"

namespace {

constexpr std::size_t rows = 1'000'000;
constexpr std::size_t columns = 5;

// A recording at 1 kHz: a slow sine move of the axis with a following error, a velocity command in mm/min and a
// noisy current, written with the digits a controller export carries.
const std::string& csv_text() {
    static const std::string text = [] {
        fmt::memory_buffer out;
        fmt::format_to(std::back_inserter(out), "time [s],x_ref [mm],x [mm],v_set [mm/min],i [A]\n");
        std::uint32_t noise = 12345;
        for (std::size_t k = 0; k < rows; ++k) {
            const double t = static_cast<double>(k) * 1e-3;
            const double x_ref = 150.0 * std::sin(0.5 * t);
            const double x = x_ref - 0.004 * std::cos(0.5 * t);
            const double v = 150.0 * 0.5 * 60.0 * std::cos(0.5 * t);
            noise = noise * 1664525u + 1013904223u;
            const double i = 2.0 * std::cos(0.5 * t) + 0.3 * (static_cast<double>(noise >> 8) / 16777216.0 - 0.5);
            fmt::format_to(std::back_inserter(out), "{:.3f},{:.6f},{:.6f},{:.3f},{:.4f}\n", t, x_ref, x, v, i);
        }
        return fmt::to_string(out);
    }();
    return text;
}

const std::filesystem::path& csv_file() {
    static const std::filesystem::path path = [] {
        const auto file = std::filesystem::temp_directory_path() /
                          fmt::format("feedid-bench-csv-{}.csv", static_cast<long>(::getpid()));
        std::ofstream(file, std::ios::binary) << csv_text();
        std::atexit([] { std::filesystem::remove(csv_file()); });
        return file;
    }();
    return path;
}

double columns_megabytes(const feedid::Trace& trace) {
    double bytes = 0.0;
    for (const auto& channel : trace.channels) bytes += static_cast<double>(channel.values.capacity() * sizeof(double));
    return bytes / 1e6;
}

void BM_ParseCsvInMemory(benchmark::State& state) {
    const std::string& text = csv_text();
    for (auto _ : state) {
        auto trace = feedid::parse_csv(text, "bench.csv");
        benchmark::DoNotOptimize(trace.channels.data());
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rows));
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * text.size()));
    state.counters["columns"] = static_cast<double>(columns);
}
BENCHMARK(BM_ParseCsvInMemory)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The 1,000,000-sample trace bench_identify reads (t, x, i written by write_csv: shortest round-trip digits, about
// 47 MB): the parser's throughput on the file of the end-to-end figure (issue 29: at least 300 MB/s).
const std::string& identify_csv_text() {
    static const std::string text = [] {
        auto [t, x, i] = feedid::bench::stribeck_columns(rows);
        feedid::Trace trace;
        trace.set("t", feedid::Role::time, "s", std::move(t));
        trace.set("x", feedid::Role::position, "m", std::move(x));
        trace.set("i", feedid::Role::current, "A", std::move(i));
        trace.constants["force_constant"] = 450.0;
        return feedid::write_csv(trace);
    }();
    return text;
}

void BM_ParseIdentifyCsvInMemory(benchmark::State& state) {
    const std::string& text = identify_csv_text();
    for (auto _ : state) {
        auto trace = feedid::parse_csv(text, "identify.csv");
        benchmark::DoNotOptimize(trace.channels.data());
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rows));
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * text.size()));
}
BENCHMARK(BM_ParseIdentifyCsvInMemory)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_ReadCsvFile(benchmark::State& state) {
    const auto& path = csv_file();
    for (auto _ : state) {
        auto trace = feedid::read_csv(path);
        benchmark::DoNotOptimize(trace.channels.data());
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rows));
}
BENCHMARK(BM_ReadCsvFile)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The whole chain `feedid info` runs: detect the format, read, guess roles, convert to SI, validate.
void BM_ReadTraceFile(benchmark::State& state) {
    const auto& path = csv_file();
    for (auto _ : state) {
        auto trace = feedid::read_trace(path);
        benchmark::DoNotOptimize(trace.channels.data());
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rows));
}
BENCHMARK(BM_ReadTraceFile)->Unit(benchmark::kMillisecond)->MinTime(2.0);

double status_kilobytes(const char* key) {
    std::FILE* status = std::fopen("/proc/self/status", "r");
    if (status == nullptr) return -1.0;
    char line[256];
    double value = -1.0;
    const std::size_t key_length = std::char_traits<char>::length(key);
    while (std::fgets(line, sizeof line, status) != nullptr) {
        if (std::string_view(line).substr(0, key_length) == key) value = std::strtod(line + key_length, nullptr);
    }
    std::fclose(status);
    return value;
}

// The measurement itself, in a fresh process (see main): resets the peak resident set, reads, and prints the growth
// of the peak over the resident set it started from, and the size of the columns, both in MB.
int measure_in_this_process(std::string_view mode, const std::filesystem::path& path) {
    std::FILE* clear = std::fopen("/proc/self/clear_refs", "w");
    if (clear == nullptr) return 1;
    std::fputs("5", clear);
    std::fclose(clear);
    const double before = status_kilobytes("VmRSS:");
    double columns_mb = 0.0;
    if (mode == "read_trace") {
        columns_mb = columns_megabytes(feedid::read_trace(path));
    } else {
        const std::string bytes = feedid::read_file_bytes(path);
        columns_mb = columns_megabytes(feedid::parse_csv(bytes, path.string()));
    }
    const double peak = status_kilobytes("VmHWM:");
    std::printf("%.3f %.3f\n", (peak - before) * 1024.0 / 1e6, columns_mb);
    return 0;
}

// Runs this program again as a fresh process (a fork alone would inherit the heap this process already grew and
// freed, which the read would reuse unseen); returns {peak growth [MB], columns [MB]}, negative when not possible.
std::pair<double, double> peak_growth_in_fresh_process(const char* mode) {
    int output[2];
    if (::pipe(output) != 0) return {-1.0, -1.0};
    const std::string path = csv_file().string();
    const pid_t child = ::fork();
    if (child == 0) {
        ::dup2(output[1], STDOUT_FILENO);
        ::close(output[0]);
        ::close(output[1]);
        ::execl("/proc/self/exe", "bench_csv", "--peak-memory", mode, path.c_str(), static_cast<char*>(nullptr));
        ::_exit(127);
    }
    ::close(output[1]);
    char text[128] = {};
    std::size_t length = 0;
    while (length + 1 < sizeof text) {
        const auto got = ::read(output[0], text + length, sizeof text - 1 - length);
        if (got <= 0) break;
        length += static_cast<std::size_t>(got);
    }
    ::close(output[0]);
    int status = 0;
    ::waitpid(child, &status, 0);
    double growth = -1.0;
    double columns_mb = -1.0;
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || std::sscanf(text, "%lf %lf", &growth, &columns_mb) != 2) {
        return {-1.0, -1.0};
    }
    return {growth, columns_mb};
}

void report_memory(benchmark::State& state, std::pair<double, double> measured) {
    const auto [growth_mb, columns_mb] = measured;
    if (growth_mb < 0.0) {
        state.SkipWithError("cannot measure peak memory here (/proc/self/clear_refs not writable)");
        return;
    }
    state.counters["peak_growth_MB"] = growth_mb;
    state.counters["columns_MB"] = columns_mb;
    state.counters["growth_per_column_byte"] = growth_mb / columns_mb;
}

void BM_ReadTracePeakMemory(benchmark::State& state) {
    std::pair<double, double> measured;
    for (auto _ : state) measured = peak_growth_in_fresh_process("read_trace");
    report_memory(state, measured);
}
BENCHMARK(BM_ReadTracePeakMemory)->Iterations(1)->Unit(benchmark::kMillisecond);

// For comparison: the file read whole into a string, then parsed (what read_trace did before it mapped the file).
void BM_ReadWholeThenParsePeakMemory(benchmark::State& state) {
    std::pair<double, double> measured;
    for (auto _ : state) measured = peak_growth_in_fresh_process("read_whole_then_parse");
    report_memory(state, measured);
}
BENCHMARK(BM_ReadWholeThenParsePeakMemory)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
    if (argc == 4 && std::string_view(argv[1]) == "--peak-memory") return measure_in_this_process(argv[2], argv[3]);
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
