// Where identify's time goes on a 1,000,000-sample trace from arrays (the Python module's path, README "Python
// speed"): the import chain on in-memory columns, each of the four stages, and identify end to end. The trace is
// bench_identify's: a drive with Stribeck friction on sinusoidal strokes at nine speeds, 1 kHz, 50 nm encoder.
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "feedid/identify/friction_only.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/io/import.hpp"
#include "feedid/identify/preprocess.hpp"
#include "feedid/identify/selection.hpp"
#include "feedid/identify/step1.hpp"
#include "feedid/identify/step2.hpp"
#include "stribeck_trace.hpp"

namespace {

constexpr std::size_t samples = 1'000'000;

const feedid::bench::StribeckColumns& columns() {
    static const feedid::bench::StribeckColumns out = feedid::bench::stribeck_columns(samples);
    return out;
}

feedid::Trace trace_from_columns() {
    feedid::Trace trace;
    trace.set("time", feedid::Role::other, "", columns().time);
    trace.set("position", feedid::Role::other, "", columns().position);
    trace.set("current", feedid::Role::other, "", columns().current);
    feedid::ImportOptions options;
    options.channels = {
        {feedid::Role::time, "time"}, {feedid::Role::position, "position"}, {feedid::Role::current, "current"}};
    feedid::prepare_trace(trace, options);
    return trace;
}

feedid::IdentifyOptions identify_options() {
    feedid::IdentifyOptions options;
    options.drive.force_constant = 450.0;
    return options;
}

/// The stages' inputs, computed once.
struct Stages {
    feedid::Trace trace = trace_from_columns();
    feedid::IdentifyOptions options = identify_options();
    std::vector<double> force = feedid::drive_force(trace, options.drive);
    feedid::Derivatives derivatives = feedid::preprocess(trace, force, options.preprocess);
    feedid::Regressors regressors = feedid::build_regressors(derivatives, options.model, options.offset);
    feedid::Selection selection = feedid::select_samples(derivatives, regressors, options.selection);
    feedid::Step1Fit step1 = feedid::fit_step1(regressors, derivatives, selection.step1, options.step1);
};

const Stages& stages() {
    static const Stages out;
    return out;
}

void BM_ImportFromArrays(benchmark::State& state) {
    for (auto _ : state) benchmark::DoNotOptimize(trace_from_columns().samples());
}
BENCHMARK(BM_ImportFromArrays)->Unit(benchmark::kMillisecond);

void BM_Preprocess(benchmark::State& state) {
    const auto& s = stages();
    for (auto _ : state) benchmark::DoNotOptimize(feedid::preprocess(s.trace, s.force, s.options.preprocess).total);
}
BENCHMARK(BM_Preprocess)->Unit(benchmark::kMillisecond);

void BM_SelectSamples(benchmark::State& state) {
    const auto& s = stages();
    for (auto _ : state) {
        benchmark::DoNotOptimize(feedid::select_samples(s.derivatives, s.regressors, s.options.selection).step1.size());
    }
}
BENCHMARK(BM_SelectSamples)->Unit(benchmark::kMillisecond);

void BM_AssessResolution(benchmark::State& state) {
    const auto& s = stages();
    for (auto _ : state)
        benchmark::DoNotOptimize(feedid::assess_resolution(s.derivatives, s.options.friction_only).coarse());
}
BENCHMARK(BM_AssessResolution)->Unit(benchmark::kMillisecond);

void BM_Step1(benchmark::State& state) {
    const auto& s = stages();
    for (auto _ : state) {
        benchmark::DoNotOptimize(
            feedid::fit_step1(s.regressors, s.derivatives, s.selection.step1, s.options.step1).samples);
    }
}
BENCHMARK(BM_Step1)->Unit(benchmark::kMillisecond);

void BM_Step2(benchmark::State& state) {
    const auto& s = stages();
    for (auto _ : state) {
        benchmark::DoNotOptimize(
            feedid::fit_friction_curve(s.derivatives, s.selection, s.step1, s.options.friction).nonlinear.has_value());
    }
}
BENCHMARK(BM_Step2)->Unit(benchmark::kMillisecond);

void BM_IdentifyFromArrays(benchmark::State& state) {
    const auto& s = stages();
    for (auto _ : state) benchmark::DoNotOptimize(feedid::identify(s.trace, s.options).status);
    state.counters["step1_samples"] = static_cast<double>(s.selection.step1.size());
    state.counters["step2_samples"] = static_cast<double>(s.selection.step2.size());
}
BENCHMARK(BM_IdentifyFromArrays)->Unit(benchmark::kMillisecond);

}  // namespace
BENCHMARK_MAIN();
