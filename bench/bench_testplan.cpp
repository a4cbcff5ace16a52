// Test design: a three-centre plan with slow passes (about 250 s of motion, 250,000 reference samples at 1 kHz).
#include <benchmark/benchmark.h>

#include "feedid/plan/gcode_writer.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/plan/test_plan.hpp"

namespace {

feedid::TestPlanOptions three_centres() {
    feedid::TestPlanOptions options;
    options.travel_min = -0.4;
    options.travel_max = 0.4;
    options.centers = {-0.3, 0.0, 0.3};
    return options;
}

void BM_MakePlan(benchmark::State& state) {
    const auto options = three_centres();
    for (auto _ : state) benchmark::DoNotOptimize(feedid::make_test_plan(options));
}
BENCHMARK(BM_MakePlan)->Unit(benchmark::kMicrosecond);

void BM_ReferenceTrajectory(benchmark::State& state) {
    const auto plan = feedid::make_test_plan(three_centres());
    std::size_t samples = 0;
    for (auto _ : state) {
        const auto trace = feedid::reference_trajectory(plan);
        samples = trace.samples();
        benchmark::DoNotOptimize(trace);
    }
    state.counters["samples"] = static_cast<double>(samples);
    state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * samples));
}
BENCHMARK(BM_ReferenceTrajectory)->Unit(benchmark::kMillisecond);

void BM_ReferenceCsv(benchmark::State& state) {
    const auto trace = feedid::reference_trajectory(feedid::make_test_plan(three_centres()));
    for (auto _ : state) benchmark::DoNotOptimize(feedid::write_csv(trace));
}
BENCHMARK(BM_ReferenceCsv)->Unit(benchmark::kMillisecond);

void BM_PredictIdentifiability(benchmark::State& state) {
    const auto plan = feedid::make_test_plan(three_centres());
    for (auto _ : state) benchmark::DoNotOptimize(feedid::predict_identifiability(plan));
}
BENCHMARK(BM_PredictIdentifiability)->Unit(benchmark::kMillisecond);

void BM_EmitLinuxcnc(benchmark::State& state) {
    const auto plan = feedid::make_test_plan(three_centres());
    for (auto _ : state) benchmark::DoNotOptimize(feedid::emit_part_program(plan, feedid::Dialect::linuxcnc));
}
BENCHMARK(BM_EmitLinuxcnc)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
