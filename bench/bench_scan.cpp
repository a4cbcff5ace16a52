// `feedid scan` of an 8-hour, 1 kHz trace of one axis (issue 15: 28.8 million samples in under 20 s and 300 MB), as a
// user runs it: the command started afresh each iteration, its wall and CPU time and peak resident memory from
// wait4. The file is a CSV (t, x_ref, x, v_cmd, i: `feedid synth`'s demo trace, 45.6 s, repeated end to end by
// bench/long_trace.py, time and position carried on), made once in the build tree's bench-data folder (1.5 GB); scan
// reads a CSV this large in blocks.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>

#include "run_program.hpp"

namespace {

namespace fs = std::filesystem;

const fs::path& long_trace() {
    static const fs::path path = [] {
        const fs::path folder(FEEDID_BENCH_DATA);
        fs::create_directories(folder);
        const fs::path out = folder / "scan-8h.csv";
        if (fs::exists(out)) return out;
        const fs::path base = folder / "scan-base.csv";
        const auto synth = feedid::bench::run({FEEDID_CLI, "synth", "--seed", "1", "--out", base.string()});
        const auto repeat =
            feedid::bench::run({"/usr/bin/python3", std::string(FEEDID_SOURCE_DIR) + "/bench/long_trace.py",
                                base.string(), out.string(), "--hours", "8"});
        if (synth.exit_code != 0 || repeat.exit_code != 0) fs::remove(out);
        return out;
    }();
    return path;
}

void BM_ScanEightHours(benchmark::State& state) {
    if (!fs::exists(long_trace())) {
        state.SkipWithError("could not make the 8-hour trace (feedid synth, /usr/bin/python3 with numpy)");
        return;
    }
    double peak = 0.0, cpu = 0.0;
    for (auto _ : state) {
        const auto outcome = feedid::bench::run(
            {FEEDID_CLI, "scan", long_trace().string(), "--kt", "1.444", "--lead", "20", "--json", "-"});
        if (outcome.exit_code != 0) {
            state.SkipWithError(("feedid scan exited with " + std::to_string(outcome.exit_code)).c_str());
            return;
        }
        state.SetIterationTime(outcome.seconds);
        peak = std::max(peak, outcome.peak_megabytes);
        cpu += outcome.cpu_seconds;
    }
    state.counters["peak_MB"] = peak;
    state.counters["cpu_s"] = cpu / static_cast<double>(state.iterations());
}
BENCHMARK(BM_ScanEightHours)->UseManualTime()->Iterations(3)->Unit(benchmark::kSecond);

}  // namespace

BENCHMARK_MAIN();
