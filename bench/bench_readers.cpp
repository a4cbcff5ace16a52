// Controller trace readers. Targets (issue 6): SINUMERIK trace XML import at least 100 MB/s; the reference trace
// ../shared/data/sinumerik-trace/X_BK300_1.xml (1 MB, 7199 records x 10 signals) read end to end in under 30 ms.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <filesystem>
#include <string>

#include <fmt/core.h>

#include "feedid/io/import.hpp"
#include "feedid/io/sinumerik_trace.hpp"
#include "feedid/io/twincat_scope.hpp"

namespace {

// A SINUMERIK servo trace like the reference one, made up in memory: 10 signals at 2 ms (one of them at 4 ms),
// `records` records, sparse where a value did not change (as the trace tool writes them).
std::string synthetic_sinumerik_trace(std::size_t records) {
    static constexpr const char* variables[] = {"nckServoDataCmdPos2ndEnc64", "nckServoDataActPos1stEnc64",
                                                "nckServoDataActPos2ndEnc64", "nckServoDataCmdVelCtrlIn64",
                                                "nckServoDataActVel1stEnc64", "nckServoDataActVel2ndEnc64",
                                                "nckServoDataCtrlDev64",      "nckServoDataDrvLoad64",
                                                "nckServoDataActCurr64",      "nckServoDataCmdTorque64"};
    static constexpr const char* units[] = {"posn", "posn", "posn",    "velo",    "velo",
                                            "velo", "posn", "percent", "current", "torque"};
    std::string xml =
        "<?xml version=\"1.0\" encoding=\"utf-8\" ?>\n<traceSession version=\"01.00.03.02\">\n"
        "<traceData dataFrames=\"1\">\n <dataFrame>\n";
    for (int k = 0; k < 10; ++k) {
        xml += fmt::format(
            "  <dataSignal key=\"s{0}\" event=\"255\" unitsType=\"{1}\" name=\"/Nck/!SD/{2} [u1, 1]\" "
            "datapointCount=\"{3}\" domain=\"NCU_1\" description=\"signal {0}\" interval=\"{4}\" "
            "displayRes=\"5\" eventChannel=\"1\" dataType=\"double\" id=\"f{0}\"/>\n",
            k + 1, units[k], variables[k], records, k == 7 ? "0.004000" : "0.002000");
    }
    std::uint64_t state = 12345;
    auto next = [&state] {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        return static_cast<double>(state >> 11) / 9007199254740992.0;
    };
    for (std::size_t r = 0; r < records; ++r) {
        xml += fmt::format("  <rec time=\"{:.6f}\"", 0.002 * static_cast<double>(r));
        for (int k = 0; k < 10; ++k) {
            if (r > 0 && (k == 0 || k == 3) && r % 50 != 0) continue;  // setpoints change rarely
            if (k == 7 && r % 2 != 0) continue;                        // the 4 ms signal
            xml += fmt::format(" f{}=\"{:.6f}\"", k + 1, -300.0 + 600.0 * next());
        }
        xml += "/>\n";
    }
    xml += " </dataFrame>\n</traceData>\n</traceSession>\n";
    return xml;
}

void BM_SinumerikTraceXmlImport(benchmark::State& state) {
    const std::string xml = synthetic_sinumerik_trace(static_cast<std::size_t>(state.range(0)));
    for (auto _ : state) {
        auto trace = feedid::parse_sinumerik_trace(xml, "synthetic.xml");
        benchmark::DoNotOptimize(trace.channels.data());
    }
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(xml.size()));
    state.counters["MB"] = static_cast<double>(xml.size()) / 1e6;
}
BENCHMARK(BM_SinumerikTraceXmlImport)->Arg(200000)->Unit(benchmark::kMillisecond);

// The whole chain on the reference file: read from disk, parse, map roles, convert to SI, validate.
void BM_SinumerikReferenceTraceEndToEnd(benchmark::State& state) {
    const std::filesystem::path path = std::filesystem::path(FEEDID_SHARED_DATA) / "sinumerik-trace/X_BK300_1.xml";
    if (!std::filesystem::exists(path)) {
        state.SkipWithError("reference data not found (../shared/data/sinumerik-trace/X_BK300_1.xml)");
        return;
    }
    for (auto _ : state) {
        auto trace = feedid::read_trace(path);
        benchmark::DoNotOptimize(trace.channels.data());
    }
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                            static_cast<std::int64_t>(std::filesystem::file_size(path)));
}
BENCHMARK(BM_SinumerikReferenceTraceEndToEnd)->Unit(benchmark::kMillisecond);

// For information: the largest TwinCAT Scope reference export (one time column per channel, 22 channels).
void BM_TwinCatScopeReferenceEndToEnd(benchmark::State& state) {
    const std::filesystem::path path =
        std::filesystem::path(FEEDID_SHARED_DATA) /
        "twincat-scope/tc3_scope_3_4_3145_3-ExcludeDoubleTimestamp_false-SortChannels_false.csv";
    if (!std::filesystem::exists(path)) {
        state.SkipWithError("reference data not found (../shared/data/twincat-scope)");
        return;
    }
    for (auto _ : state) {
        auto trace = feedid::read_trace(path);
        benchmark::DoNotOptimize(trace.channels.data());
    }
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                            static_cast<std::int64_t>(std::filesystem::file_size(path)));
}
BENCHMARK(BM_TwinCatScopeReferenceEndToEnd)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
