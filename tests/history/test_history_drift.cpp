// The drift alarm end to end: synthetic runs of one axis (feedid synth, different seeds), each identified with
// feedid identify --json and recorded with feedid history --record; feedid history --check after every run.
// Runs 1-10 have the demo drive's Coulomb friction; from run 11 it rises 1 % of that value per run.

#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "history_testing.hpp"
#include "postgres_testing.hpp"
#include "testing.hpp"

namespace {

using namespace feedid::testing;

constexpr int runs_per_series = 20;
constexpr double coulomb_N = 742.8;  // the demo drive's F_C (feedid synth --help)

/// Coulomb friction of run i (1-based) of the rising series [N].
double rising_coulomb(int i) {
    return i <= 10 ? coulomb_N : coulomb_N * (1.0 + 0.01 * (i - 10));
}

/// The demo drive (feedid synth --print-drive) with the given Coulomb friction, and a short test (four feedrates, no
/// slow passes) so that 40 runs take seconds, not minutes.
nlohmann::json drive_file(double coulomb, int seed) {
    return {
        {"seed", seed},
        {"axis",
         {{"mass_kg", 69.1},
          {"offset_N", 0.0},
          {"viscous_forward_Ns_per_m", 54.2},
          {"viscous_reverse_Ns_per_m", 54.2},
          {"coulomb_forward_N", coulomb},
          {"coulomb_reverse_N", coulomb},
          {"breakaway_forward_N", 946.2},
          {"breakaway_reverse_N", 946.2},
          {"stribeck_velocity_forward_m_per_s", 0.005},
          {"stribeck_velocity_reverse_m_per_s", 0.005}}},
        {"test", {{"feedrates_mm_per_min", {1500, 3000, 4500, 6000}}, {"stroke_mm", 20.0}, {"slow_passes", false}}}};
}

/// Synthesises and identifies run i of a series; returns the result document's path.
std::filesystem::path make_run(const std::filesystem::path& folder, const std::string& series, int i, double coulomb) {
    const auto drive = folder / fmt::format("{}-{:02}-drive.json", series, i);
    const auto trace = folder / fmt::format("{}-{:02}.csv", series, i);
    const auto result = folder / fmt::format("{}-{:02}-result.json", series, i);
    write_text(drive, drive_file(coulomb, 1000 + i).dump());
    const auto synth =
        run_shell(fmt::format("{} synth --drive {} --out {}", cli(), quoted(drive), quoted(trace)), folder);
    EXPECT_EQ(synth.exit_code, 0) << synth.err;
    const auto identify = run_shell(fmt::format("{} identify {} --force-constant force_constant_N_per_A --json {}",
                                                cli(), quoted(trace), quoted(result)),
                                    folder);
    EXPECT_EQ(identify.exit_code, 0) << identify.err;
    return result;
}

/// Makes every run of a series on two threads (the machine's two cores).
std::vector<std::filesystem::path> make_series(const std::filesystem::path& folder, const std::string& series,
                                               bool rising) {
    std::vector<std::filesystem::path> results(runs_per_series);
    std::vector<std::thread> workers;
    for (int w = 0; w < 2; ++w) {
        workers.emplace_back([&, w] {
            for (int i = 1 + w; i <= runs_per_series; i += 2)
                results[static_cast<std::size_t>(i - 1)] =
                    make_run(folder, series, i, rising ? rising_coulomb(i) : coulomb_N);
        });
    }
    for (auto& worker : workers) worker.join();
    return results;
}

struct CheckOutcome {
    std::vector<int> exit_codes;  // --check after run i is exit_codes[i - 1]
    std::string first_alarm_message;
};

/// Records the runs one by one (one recording day each) and runs --check after each.
CheckOutcome record_and_check(const std::filesystem::path& folder, const std::string& database,
                              const std::vector<std::filesystem::path>& results) {
    CheckOutcome outcome;
    for (std::size_t i = 0; i < results.size(); ++i) {
        const auto record = run_shell(fmt::format("{} history {} --record {} --machine 'DMU 50' --axis X "
                                                  "--recorded-at 2026-03-{:02}T06:00:00Z",
                                                  cli(), quoted(database), quoted(results[i]), i + 1),
                                      folder);
        EXPECT_EQ(record.exit_code, 0) << record.err;
        EXPECT_NE(record.err.find("recorded"), std::string::npos) << record.err;
        const auto check = run_shell(fmt::format("{} history {} --check", cli(), quoted(database)), folder);
        outcome.exit_codes.push_back(check.exit_code);
        if (check.exit_code == 1 && outcome.first_alarm_message.empty()) outcome.first_alarm_message = check.out;
        EXPECT_TRUE(check.exit_code == 0 || check.exit_code == 1) << check.err;
    }
    return outcome;
}

// Both backends: the same runs recorded in a SQLite file and in a PostgreSQL database give the same alarms.
class HistoryDriftOn : public HistoryBackendTest {};
INSTANTIATE_TEST_SUITE_P(Backends, HistoryDriftOn, ::testing::Values(Backend::sqlite, Backend::postgresql),
                         backend_name);

TEST_P(HistoryDriftOn, RisingCoulombFrictionAlarmsByRun16AndNotBefore11) {
    const auto folder = folder_;
    const auto results = make_series(folder, "rising", true);
    const auto database = new_location("rising");
    const auto outcome = record_and_check(folder, database, results);
    ASSERT_EQ(outcome.exit_codes.size(), static_cast<std::size_t>(runs_per_series));
    for (int i = 1; i <= 10; ++i) EXPECT_EQ(outcome.exit_codes[static_cast<std::size_t>(i - 1)], 0) << "run " << i;
    int first_alarm = 0;
    for (int i = 1; i <= runs_per_series && first_alarm == 0; ++i)
        if (outcome.exit_codes[static_cast<std::size_t>(i - 1)] == 1) first_alarm = i;
    EXPECT_GE(first_alarm, 11);
    EXPECT_LE(first_alarm, 16) << "the alarm did not fire by run 16";
    // Once fired, the alarm stays until a new baseline is pinned.
    for (int i = std::max(first_alarm, 1); i <= runs_per_series; ++i)
        EXPECT_EQ(outcome.exit_codes[static_cast<std::size_t>(i - 1)], 1) << "run " << i;
    // The message names machine, axis, the parameter that drifted and its direction.
    EXPECT_NE(outcome.first_alarm_message.find("machine 'DMU 50' axis 'X' parameter coulomb_N"), std::string::npos)
        << outcome.first_alarm_message;
    EXPECT_NE(outcome.first_alarm_message.find("rose"), std::string::npos) << outcome.first_alarm_message;
    EXPECT_EQ(outcome.first_alarm_message.find("parameter mass_kg"), std::string::npos) << outcome.first_alarm_message;
    fmt::print("first alarm after run {}: {}", first_alarm, outcome.first_alarm_message);

    // The JSON document agrees and names the run.
    const auto listing = run_shell(fmt::format("{} history {} --json -", cli(), quoted(database)), folder);
    ASSERT_EQ(listing.exit_code, 0) << listing.err;
    const auto document = nlohmann::json::parse(listing.out);
    EXPECT_TRUE(document["alarm"].get<bool>());
    ASSERT_EQ(document["runs"].size(), static_cast<std::size_t>(runs_per_series));
    ASSERT_EQ(document["trends"].size(), 1u);
    const auto& alarms = document["trends"][0]["alarms"];
    ASSERT_FALSE(alarms.empty());
    EXPECT_EQ(alarms[0]["parameter"], "coulomb_N");
    EXPECT_EQ(alarms[0]["direction"], "up");
    // Run ids are in recording order here; the alarm is at the first run whose --check failed.
    EXPECT_EQ(alarms[0]["run"].get<int>(),
              document["runs"][static_cast<std::size_t>(first_alarm - 1)]["id"].get<int>());
}

TEST_P(HistoryDriftOn, ConstantFrictionRaisesNoAlarmIn20Runs) {
    const auto folder = folder_;
    const auto results = make_series(folder, "constant", false);
    const auto outcome = record_and_check(folder, new_location("constant"), results);
    ASSERT_EQ(outcome.exit_codes.size(), static_cast<std::size_t>(runs_per_series));
    for (int i = 1; i <= runs_per_series; ++i)
        EXPECT_EQ(outcome.exit_codes[static_cast<std::size_t>(i - 1)], 0)
            << "false alarm after run " << i << ": " << outcome.first_alarm_message;
}

}  // namespace
