// feedid identify end to end on a 1,000,000-sample CSV (read, map, convert, preprocess, both steps): under 1 s.
// And the EMPS recording (24841 samples) with the default options.
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "feedid/identify/identify.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"
#include "stribeck_trace.hpp"

namespace {

// stribeck_trace.hpp's drive, 1,000,000 samples, as a CSV: t, x (50 nm encoder), i.
std::filesystem::path million_sample_csv() {
    const auto path = std::filesystem::temp_directory_path() / "feedid-bench-identify-1M.csv";
    if (std::filesystem::exists(path)) return path;
    auto [t, x, i] = feedid::bench::stribeck_columns(1'000'000);
    feedid::Trace trace;
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
