// From a result document to a run: the checks identify --record and history --add share, the trace a result names
// (relative to where identify ran, else to the result's folder), and the database check made before a long command.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "feedid/core/error.hpp"
#include "feedid/history/record.hpp"
#include "history_testing.hpp"
#include "testing.hpp"

namespace {

using namespace feedid::testing;
namespace fs = std::filesystem;
namespace history = feedid::history;

history::RecordContext named_context() {
    history::RecordContext context;
    context.machine = "DMU50";
    context.axis = "X";
    return context;
}

TEST(RecordFromResult, ContextNeedsMachineAxisAndAnIsoTime) {
    auto context = named_context();
    EXPECT_EQ(context.validate(), "");
    context.recorded_at = "2026-11-23T09:30:00Z";
    EXPECT_EQ(context.validate(), "");
    context.recorded_at = "yesterday";
    EXPECT_EQ(context.validate(), "--recorded-at 'yesterday': not an ISO 8601 UTC time (e.g. 2026-11-23T09:30:00Z)");
    context.axis.clear();
    EXPECT_EQ(context.validate("--record"), "--record needs the axis (--axis X)");
    context.machine.clear();
    EXPECT_EQ(context.validate(), "recording a run needs the machine's name (--machine NAME)");
}

TEST(RecordFromResult, TraceOfAResultIsFoundBesideTheResultWhenNotInTheWorkingFolder) {
    const auto folder = temp_dir();
    const auto trace = folder / "beside.csv";
    write_text(trace, "t [s],x [mm]\n0,1\n0.001,2\n");
    // Relative to a folder that is not the working one: found beside the result.
    auto result = small_result("beside.csv", 740.0);
    EXPECT_EQ(history::trace_of_result(result, (folder / "result.json").string()), folder / "beside.csv");
    // Absolute: as named.
    result = small_result(trace, 740.0);
    EXPECT_EQ(history::trace_of_result(result, "anywhere/result.json"), trace);
}

TEST(RecordFromResult, AResultWithoutATraceOrNotAResultIsRefusedNamingTheFile) {
    auto result = small_result("t.csv", 740.0);
    result.erase("trace");
    try {
        (void)history::trace_of_result(result, "r.json");
        FAIL() << "no trace named";
    } catch (const feedid::InputError& e) {
        EXPECT_STREQ(e.what(), "r.json: the result names no trace file; give it with --trace FILE");
    }
    try {
        (void)history::trace_of_result(nlohmann::json{{"foo", 1}}, "w.json");
        FAIL() << "not a result";
    } catch (const feedid::InputError& e) {
        EXPECT_STREQ(e.what(), "w.json: not a feedid identify result document (it has no \"parameters\" object)");
    }
}

TEST(RecordFromResult, ADatabaseCanTakeARunWhenMissingEmptyOrAHistory) {
    const auto folder = temp_dir();
    EXPECT_NO_THROW(history::check_recordable(folder / "missing.db"));
    write_text(folder / "empty.db", "");
    EXPECT_NO_THROW(history::check_recordable(folder / "empty.db"));
    (void)history::open_sqlite_store(folder / "history.db");
    EXPECT_NO_THROW(history::check_recordable(folder / "history.db"));
    write_text(folder / "text.db", "not a database\n");
    EXPECT_THROW(history::check_recordable(folder / "text.db"), feedid::InputError);
    EXPECT_EQ(read_text(folder / "text.db"), "not a database\n");
}

}  // namespace
