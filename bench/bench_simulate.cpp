// Closed-loop simulation speed. Target: 60 s of axis motion at 8 kHz (480,000 integration steps, the full P-PI
// controller, current lag and Stribeck friction) in under 50 ms on one core.
#include <benchmark/benchmark.h>

#include <vector>

#include "feedid/sim/simulate.hpp"
#include "feedid/sim/synth.hpp"

namespace {

// The demo drive's constant-velocity test, repeated to 60 s.
std::vector<double> reference_of_60_s(double sample_time_s) {
    feedid::TestReference test;
    const auto once = feedid::test_reference(test, sample_time_s);
    const auto samples = static_cast<std::size_t>(60.0 / sample_time_s);
    std::vector<double> reference(samples);
    for (std::size_t k = 0; k < samples; ++k) reference[k] = once[k % once.size()];
    return reference;
}

// The demo drive on 60 s of its test, sampled every `sample_time_s`, integrated in `substeps` steps per sample.
struct Run {
    feedid::SynthSpec spec = feedid::demo_spec();
    std::vector<double> reference;  // owned here: SimulationInput only views it
    feedid::SimulationInput input;
    feedid::SimulationOptions options;
    Run(double sample_time_s, int substeps) : reference(reference_of_60_s(sample_time_s)) {
        input.sample_time_s = sample_time_s;
        input.reference = reference;
        options.substeps = substeps;
        options.position_resolution_m = 1e-8;
    }
    [[nodiscard]] benchmark::Counter steps_per_second() const {
        return {static_cast<double>(reference.size()) * options.substeps,
                benchmark::Counter::kIsIterationInvariantRate};
    }
};

// 1 kHz samples and controller, 8 integration steps per sample: 8 kHz integration.
void BM_Simulate60s_1kHzSamples_8kHzIntegration(benchmark::State& state) {
    const Run run(1e-3, 8);
    for (auto _ : state) {
        auto out = feedid::simulate(run.spec.axis, run.spec.controller, run.input, run.options);
        benchmark::DoNotOptimize(out.position.data());
    }
    state.counters["steps"] = static_cast<double>(run.reference.size() * 8);
    state.counters["steps_per_s"] = run.steps_per_second();
}
BENCHMARK(BM_Simulate60s_1kHzSamples_8kHzIntegration)->Unit(benchmark::kMillisecond);

// 8 kHz samples and controller (velocity loop at 125 us as on a SINUMERIK), one integration step per sample.
void BM_Simulate60s_8kHzSamplesAndController(benchmark::State& state) {
    const Run run(125e-6, 1);
    for (auto _ : state) {
        auto out = feedid::simulate(run.spec.axis, run.spec.controller, run.input, run.options);
        benchmark::DoNotOptimize(out.position.data());
    }
    state.counters["steps_per_s"] = run.steps_per_second();
}
BENCHMARK(BM_Simulate60s_8kHzSamplesAndController)->Unit(benchmark::kMillisecond);

// The same into a reused output: what the simulation itself costs, without the operating system's first touch of
// 38 MB of fresh output pages per run (which the one-shot figures above include).
void BM_Simulate60s_8kHzSamplesAndController_ReusedOutput(benchmark::State& state) {
    const Run run(125e-6, 1);
    feedid::SimulationOutput out;
    feedid::simulate(run.spec.axis, run.spec.controller, run.input, run.options, out);
    for (auto _ : state) {
        feedid::simulate(run.spec.axis, run.spec.controller, run.input, run.options, out);
        benchmark::DoNotOptimize(out.position.data());
    }
    state.counters["steps_per_s"] = run.steps_per_second();
}
BENCHMARK(BM_Simulate60s_8kHzSamplesAndController_ReusedOutput)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
