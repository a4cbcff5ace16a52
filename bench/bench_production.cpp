// Production-trace synthesis speed (issue 15's test data): synthesize_production on each example program, the whole
// chain (plan the reference, cutting forces, three axes through the closed loop and sensors). The scan tests run 10
// seeds x 3 programs; target: each program well under a second.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>

#include "feedid/plan/gcode_reader.hpp"
#include "feedid/sim/production_synth.hpp"

namespace {

const std::filesystem::path programs = std::filesystem::path(FEEDID_SOURCE_DIR) / "examples" / "programs";

void BM_SynthesizeProduction(benchmark::State& state, const std::string& name) {
    const auto program = feedid::read_gcode_file(programs / name);
    const auto machine = feedid::default_machine();
    feedid::ProductionOptions options;
    std::size_t samples = 0;
    for (auto _ : state) {
        const auto trace = feedid::synthesize_production(program, machine, options);
        samples = trace.samples();
        benchmark::DoNotOptimize(trace.channels.data());
        ++options.seed;
    }
    state.counters["samples"] = static_cast<double>(samples);
    state.counters["axis_samples_per_s"] =
        benchmark::Counter(3.0 * static_cast<double>(samples), benchmark::Counter::kIsIterationInvariantRate);
}

BENCHMARK_CAPTURE(BM_SynthesizeProduction, pocket, std::string("pocket.ngc"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SynthesizeProduction, contour, std::string("contour.ngc"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SynthesizeProduction, drilling, std::string("drilling.ngc"))->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
