// feedid identify end to end on a 1,000,000-sample CSV (read, map, convert, preprocess, both steps): under 1 s.
// And the EMPS recording (24841 samples) with the default options.
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "feedid/identify.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"

namespace {

// A drive on a feed ladder with slow passes, 1 kHz, 1,000,000 samples: t, x (50 nm encoder), i.
std::filesystem::path million_sample_csv() {
    const auto path = std::filesystem::temp_directory_path() / "feedid-bench-identify-1M.csv";
    if (std::filesystem::exists(path)) return path;
    const std::size_t n = 1'000'000;
    const double dt = 1e-3;
    feedid::Trace trace;
    std::vector<double> t(n), x(n), i(n);
    double position = 0.0;
    std::uint32_t state = 12345;
    const double feeds[] = {0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2};
    for (std::size_t k = 0; k < n; ++k) {
        const double time = static_cast<double>(k) * dt;
        // 10 s per feed, a sinusoidal back-and-forth stroke whose peak speed is the feed
        const double feed = feeds[(k / 10000) % 9];
        const double w = 2.0 * std::numbers::pi / 2.0;
        const double v = feed * std::sin(w * time), a = feed * w * std::cos(w * time);
        position += v * dt;
        const double speed = std::abs(v);
        const double friction = speed > 0 ? (54.0 * speed + 740.0 + 200.0 * std::exp(-speed / 0.005)) : 0.0;
        state = state * 1664525u + 1013904223u;
        const double noise = (static_cast<double>(state >> 8) / 16777216.0 - 0.5) * 0.02;
        t[k] = time;
        x[k] = 50e-9 * std::round(position / 50e-9);
        i[k] = (69.0 * a + std::copysign(friction, v)) / 450.0 + noise;
    }
    trace.set("t", feedid::Role::time, "s", std::move(t));
    trace.set("x", feedid::Role::position, "m", std::move(x));
    trace.set("i", feedid::Role::current, "A", std::move(i));
    trace.constants["force_constant"] = 450.0;
    std::ofstream(path) << feedid::write_csv(trace);
    return path;
}

void BM_IdentifyMillionSampleCsv(benchmark::State& state) {
    const auto path = million_sample_csv();
    feedid::IdentifyOptions options;
    options.drive.force_constant_name = "force_constant";
    for (auto _ : state) {
        const auto trace = feedid::read_trace(path);
        const auto result = feedid::identify(trace, options);
        benchmark::DoNotOptimize(result.status);
        if (result.status == feedid::Status::failed) state.SkipWithError("identification failed");
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * 1'000'000);
}
BENCHMARK(BM_IdentifyMillionSampleCsv)->Unit(benchmark::kMillisecond)->MinTime(3.0);

void BM_IdentifyEmps(benchmark::State& state) {
    const auto path = std::filesystem::path(FEEDID_SHARED_DATA) / "emps" / "DATA_EMPS.mat";
    if (!std::filesystem::exists(path)) {
        state.SkipWithError("../shared/data/emps/DATA_EMPS.mat not found");
        return;
    }
    feedid::ImportOptions import;
    import.channels = {{feedid::Role::position, "qm"}, { feedid::Role::current, "vir" }};
    const auto trace = feedid::read_trace(path, import);
    feedid::IdentifyOptions options;
    options.offset = true;
    options.drive.force_constant_name = "gtau";
    for (auto _ : state) benchmark::DoNotOptimize(feedid::identify(trace, options).status);
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * trace.samples()));
}
BENCHMARK(BM_IdentifyEmps)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
