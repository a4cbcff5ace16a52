// feedid watch without the network: binary (and JSON) batches of 1,000 axes decoded, routed and identified on one
// thread. The target is 1 million samples per second on one core for the whole service; this is the part that
// is feedid's own (scripts/bench_watch.sh measures the service with a broker).
#include <benchmark/benchmark.h>

#include <cmath>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "feedid/stream/watcher.hpp"

namespace {

/// Batches of `samples` of one axis moving back and forth at several speeds with friction and inertia forces.
std::vector<std::string> payloads(std::size_t axes, std::size_t batches, std::size_t samples, bool binary) {
    std::vector<std::string> out;
    const double dt = 1e-3;
    for (std::size_t b = 0; b < batches; ++b) {
        for (std::size_t a = 0; a < axes; ++a) {
            feedid::watch::Batch batch;
            batch.t0 = static_cast<double>(b * samples) * dt;
            batch.dt = dt;
            batch.force_constant = 50.0;
            for (std::size_t k = 0; k < samples; ++k) {
                const double t = batch.t0 + static_cast<double>(k) * dt;
                const double w = 2.0 + 0.01 * static_cast<double>(a % 7);
                const double x = 0.05 * std::sin(w * t) + 0.01 * std::sin(3.1 * w * t);
                const double v = 0.05 * w * std::cos(w * t) + 0.031 * w * std::cos(3.1 * w * t);
                const double acc = -0.05 * w * w * std::sin(w * t) - 0.0961 * w * w * std::sin(3.1 * w * t);
                batch.position.push_back(x);
                batch.drive.push_back((180.0 * acc + 150.0 * v + 210.0 * (v > 0 ? 1.0 : -1.0)) / 50.0);
            }
            out.push_back(binary ? feedid::watch::encode_binary(batch) : feedid::watch::encode_json(batch));
        }
    }
    return out;
}

// range(0): binary (1) or JSON (0); range(1): the windows judged twice, without and with the offset (1, watch's
// default: two identifiers an axis), or once (0: the offset not selected, [online] offset = true's cost)
void BM_WatchIngest(benchmark::State& state) {
    const bool binary = state.range(0) != 0;
    const bool twice = state.range(1) != 0;
    feedid::watch::WatchOptions options;
    options.online.select_offset = twice;
    options.axes_bytes = std::size_t{2} << 30;  // every axis admitted (the default 128 MB holds about 130 at 1 kHz)
    const std::size_t axes = 1000, batches = 20, samples = 100;
    const auto messages = payloads(axes, batches, samples, binary);
    std::vector<std::string> topics;
    for (std::size_t a = 0; a < axes; ++a) topics.push_back(fmt::format("plant/B{}/X/axis", a));
    std::size_t total = 0;
    for (auto _ : state) {
        state.PauseTiming();
        feedid::watch::Watcher watcher(options);
        state.ResumeTiming();
        for (std::size_t m = 0; m < messages.size(); ++m)
            benchmark::DoNotOptimize(watcher.ingest(topics[m % axes], std::as_bytes(std::span(messages[m]))));
        total += messages.size() * samples;
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(total));
    state.SetLabel(fmt::format("{}, 1000 axes x 100-sample batches, windows judged {}", binary ? "binary" : "JSON",
                               twice ? "twice" : "once"));
}
BENCHMARK(BM_WatchIngest)
    ->Args({1, 1})
    ->Args({1, 0})
    ->Args({0, 1})
    ->Args({0, 0})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
