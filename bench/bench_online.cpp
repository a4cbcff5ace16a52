// The online identifier's throughput (issue 15, item 5): samples per second on one core, windowing, filtering,
// robust fitting and pooling included, on a production-like trace with cutting forces. The target: at least one
// million samples per second (1,000 axes at 1 kHz).
#include <benchmark/benchmark.h>

#include <vector>

#include "production_traces.hpp"
#include "feedid/model/drive.hpp"
#include "feedid/identify/online_identifier.hpp"

namespace {

struct Columns {
    std::vector<double> t, x, force;
};

const Columns& trace() {
    static const Columns columns = [] {
        const feedid::Trace trace = feedid::testing::production_synth(1);
        feedid::DriveConstants drive;
        drive.force_constant = feedid::demo_spec().force_constant_N_per_A();
        Columns c;
        const auto t = trace.column(feedid::Role::time);
        const auto x = trace.column(feedid::Role::position);
        c.t.assign(t.begin(), t.end());
        c.x.assign(x.begin(), x.end());
        c.force = feedid::drive_force(trace, drive);
        return c;
    }();
    return columns;
}

// A whole 240 s trace per iteration: construction, every push, the last window, the estimate.
void BM_OnlineIdentifier(benchmark::State& state) {
    const Columns& c = trace();
    feedid::OnlineOptions options;
    options.robust = state.range(0) != 0;
    for (auto _ : state) {
        feedid::OnlineIdentifier online(options);
        online.push(c.t, c.x, c.force);
        online.flush();
        benchmark::DoNotOptimize(online.estimate());
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * c.t.size()));
    state.SetLabel(options.robust ? "robust" : "least squares");
}
BENCHMARK(BM_OnlineIdentifier)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
