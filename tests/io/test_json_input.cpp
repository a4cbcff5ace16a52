// JSON documents from users: nesting, size and number limits, and every value's type checked against the result
// document's schema, each refusal exit 2 naming the key, before anything is written.

#include <gtest/gtest.h>

#include <sqlite3.h>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/json_input.hpp"
#include "feedid/identify/result_document.hpp"
#include "history_testing.hpp"
#include "testing.hpp"

namespace {

using namespace feedid::testing;
namespace fs = std::filesystem;

std::string nested_objects(std::size_t depth) {
    std::string text;
    for (std::size_t i = 0; i < depth; ++i) text += "{\"a\":";
    text += "1";
    text += std::string(depth, '}');
    return text;
}

/// The message of the InputError `parse` throws ("" when it throws none).
template <class Parse>
std::string refusal(Parse&& parse) {
    try {
        parse();
    } catch (const feedid::InputError& e) {
        return e.what();
    }
    return "";
}

TEST(JsonInput, NestingUpToTheLimitIsReadAndDeeperIsRefusedNamingWhere) {
    const auto document = feedid::parse_json(nested_objects(64), "ok.json");
    EXPECT_EQ(document["a"]["a"]["a"].size(), 1u);
    const std::string message = refusal([] { (void)feedid::parse_json(nested_objects(65), "deep.json"); });
    EXPECT_NE(message.find("deep.json: nested deeper than 64 levels at a.a.a.a … (64 levels) … a.a"), std::string::npos)
        << message;
    // 60,000 levels crashed feedid (a stack overflow); now the parser stops at level 65
    const std::string deep = refusal([] { (void)feedid::parse_json(nested_objects(60000), "deep.json"); });
    EXPECT_NE(deep.find("nested deeper than 64 levels"), std::string::npos) << deep;
    const std::string arrays =
        refusal([] { (void)feedid::parse_json(std::string(100000, '[') + std::string(100000, ']'), "arrays.json"); });
    EXPECT_NE(arrays.find("at [0][0][0][0]"), std::string::npos) << arrays;
}

TEST(JsonInput, NumbersBeyondADoubleAreRefusedNamingTheKey) {
    for (const std::string& number : {std::string("1e400"), std::string("-1e400"), std::string(5000, '9')}) {
        const std::string text = R"({"fit": {"samples_used": 10, "condition_number": )" + number + "}}";
        const std::string message = refusal([&] { (void)feedid::parse_json(text, "r.json"); });
        EXPECT_NE(message.find("r.json: the number at fit.condition_number is out of range"), std::string::npos)
            << message;
    }
    const std::string in_array = refusal([] { (void)feedid::parse_json(R"({"series": [1, 2, 1e999]})", "s.json"); });
    EXPECT_NE(in_array.find("the number at series[2] is out of range"), std::string::npos) << in_array;
    // the largest doubles and integers are fine
    EXPECT_DOUBLE_EQ(feedid::parse_json("[1.7e308]", "x")[0].get<double>(), 1.7e308);
    EXPECT_EQ(feedid::parse_json("[18446744073709551615]", "x")[0].get<std::uint64_t>(), 18446744073709551615u);
}

TEST(JsonInput, SizeAndSyntax) {
    feedid::JsonLimits small;
    small.max_bytes = 100;
    const std::string big = refusal([&] { (void)feedid::parse_json(std::string(101, ' ') + "1", "big.json", small); });
    EXPECT_NE(big.find("big.json: larger than"), std::string::npos) << big;
    const std::string broken = refusal([] { (void)feedid::parse_json(R"({"a": [1, 2,)", "broken.json"); });
    EXPECT_NE(broken.find("broken.json: not a JSON document (byte"), std::string::npos) << broken;
}

/// A real identify result document, made once per test process.
const nlohmann::json& identify_document() {
    static const nlohmann::json document = [] {
        const auto folder = suite_dir("json-input");
        const auto trace = folder / "trace.csv";
        const auto result = folder / "result.json";
        const auto made = run_shell(fmt::format("{} synth --seed 5 --out {} && {} identify {} --force-constant "
                                                "force_constant_N_per_A --json {}",
                                                cli(), quoted(trace), cli(), quoted(trace), quoted(result)),
                                    folder);
        EXPECT_EQ(made.exit_code, 0) << made.err;
        return nlohmann::json::parse(read_text(result));
    }();
    return document;
}

/// from_json's refusal of a document, "" when it reads it.
std::string schema_refusal(const nlohmann::json& document) {
    return refusal([&] {
        feedid::IdentifyResult result;
        feedid::from_json(document, result);
    });
}

TEST(ResultSchema, AValueOfTheWrongTypeIsRefusedNamingItsKey) {
    auto document = identify_document();
    ASSERT_EQ(schema_refusal(document), "");
    const std::vector<std::pair<std::string, nlohmann::json>> wrong{
        {"/rotary", "no"},
        {"/status", 5},
        {"/status", "fine"},
        {"/trace/samples", "many"},
        {"/trace/samples", -3},
        {"/parameters/mass_kg/value", "heavy"},
        {"/parameters/mass_kg/stderr", nlohmann::json::array()},
        {"/parameters/mass_kg/uncertainty", "small"},
        {"/preprocessing/filter_order", 2.5},
        {"/selection/notes", "one note"},
        {"/rls/settled", "yes"},
        {"/rls/final/mass_kg", true},
        {"/fit/r_diagonal", 1.0},
        {"/diagnostics", {1, 2}},
        {"/options", "fast"},
    };
    for (const auto& [pointer, value] : wrong) {
        auto bad = document;
        bad[nlohmann::json::json_pointer(pointer)] = value;
        std::string key = pointer.substr(1);
        for (auto& c : key) c = c == '/' ? '.' : c;
        const std::string message = schema_refusal(bad);
        EXPECT_EQ(message.rfind(key, 0), 0u) << pointer << ": " << message;
        EXPECT_NE(message.find("must be"), std::string::npos) << message;
    }
    // the estimation's optional keys are numbers or null
    auto extended = document;
    extended["parameters"]["mass_kg"]["systematic"] = 0.4;
    extended["parameters"]["mass_kg"]["uncertainty"] = nullptr;
    EXPECT_EQ(schema_refusal(extended), "");
}

/// Executes SQL on a file through SQLite itself (to damage a history as a disk or another program might).
void execute(const fs::path& path, const std::string& sql) {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    char* message = nullptr;
    const int code = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &message);
    const std::string text = message ? message : "";
    sqlite3_free(message);
    sqlite3_close(db);
    ASSERT_EQ(code, SQLITE_OK) << text;
}

/// Runs a command that must be refused with exit 2 and one line naming `says`, leaving `untouched` as it was and
/// creating none of `not_created`.
void expect_refused(const std::string& arguments, const std::string& says, const fs::path& untouched,
                    const std::vector<fs::path>& not_created, const fs::path& folder) {
    const std::string before = fs::exists(untouched) ? read_text(untouched) : std::string();
    const auto r = run_shell(cli() + " " + arguments, folder);
    EXPECT_EQ(r.exit_code, 2) << arguments << "\n" << r.err;
    EXPECT_EQ(count_lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(says), std::string::npos) << arguments << "\n" << r.err;
    if (!before.empty()) {
        EXPECT_TRUE(read_text(untouched) == before) << untouched << " changed";
    }
    for (const auto& path : not_created) EXPECT_FALSE(fs::exists(path)) << path << " was written";
}

// The issue's crashes (exit 139) and internal errors (exit 1), each now exit 2 with the key, nothing written.
TEST(ResultSchemaCli, BadDocumentsAreRefusedAtRecordAndReportTime) {
    const auto folder = temp_dir();
    const auto results = write_small_results(folder, "run", 2);
    const auto database = folder / "shop.db";
    const auto trace = folder / "run-1.csv";
    const auto write = [&](const std::string& name, const std::string& text) {
        write_text(folder / name, text);
        return quoted(folder / name);
    };
    const auto record = [&](const std::string& result) {
        return fmt::format("history {} --record {} --trace {} --machine M --axis X", quoted(database), result,
                           quoted(trace));
    };
    // a database that does not exist yet is not created by a refused record
    expect_refused(record(write("deep.json", nested_objects(60000))), "nested deeper than 64 levels", database,
                   {database}, folder);
    // options nested 100,000 deep (written as text: nlohmann's own dump() of it would overflow the test's stack)
    std::string document = small_result(trace, 740.0).dump();
    document.pop_back();
    document += ",\"options\":" + nested_objects(100000) + "}";
    expect_refused(fmt::format("report {} -o {}", write("options.json", document), quoted(folder / "r.html")),
                   "nested deeper than 64 levels", folder / "options.json", {folder / "r.html"}, folder);

    ASSERT_EQ(run_shell(cli() + " " + record(quoted(results[0])), folder).exit_code, 0);
    const std::string small = small_result(trace, 741.0).dump();
    std::string huge = small;
    huge.replace(huge.find("3.1"), 3, "1e400");
    expect_refused(record(write("huge.json", huge)), "the number at fit.relative_error_pct is out of range", database,
                   {}, folder);
    std::string digits = small;
    digits.replace(digits.find("3.1"), 3, std::string(5000, '7'));
    expect_refused(record(write("digits.json", digits)), "fit.relative_error_pct is out of range", database, {},
                   folder);
    auto rotary = small_result(trace, 741.0);
    rotary["rotary"] = "no";
    expect_refused(record(write("rotary.json", rotary.dump())), "rotary: must be true or false, not a string", database,
                   {}, folder);
    auto status = small_result(trace, 741.0);
    status["status"] = 5;
    expect_refused(record(write("status.json", status.dump())), "status: must be a string, not a number", database, {},
                   folder);
    expect_refused(fmt::format("report {} -o {}", quoted(folder / "rotary.json"), quoted(folder / "r.html")),
                   "rotary: must be true or false", folder / "rotary.json", {folder / "r.html"}, folder);
    // the history still reports: no bad run got in
    const auto report =
        run_shell(fmt::format("{} report {} -o {}", cli(), quoted(database), quoted(folder / "history.html")), folder);
    EXPECT_EQ(report.exit_code, 0) << report.err;
}

// A stored document damaged after the fact: listings and --check read typed columns and go on; what needs the
// document names the run; --record still works and is exit 0; --verify finds it.
TEST(ResultSchemaCli, ADamagedStoredDocumentIsNamedWhereItIsNeeded) {
    const auto folder = temp_dir();
    const auto results = write_small_results(folder, "run", 3);
    const auto database = folder / "shop.db";
    for (int i = 0; i < 2; ++i)
        ASSERT_EQ(run_shell(fmt::format("{} history {} --record {} --machine M --axis X", cli(), quoted(database),
                                        quoted(results[static_cast<std::size_t>(i)])),
                            folder)
                      .exit_code,
                  0);
    execute(database, "UPDATE runs SET fit_json = '{broken' WHERE id = 1");
    for (const std::string& arguments :
         {fmt::format("history {}", quoted(database)), fmt::format("history {} --check", quoted(database)),
          fmt::format("history {} --csv -", quoted(database))}) {
        const auto r = run_shell(cli() + " " + arguments, folder);
        EXPECT_EQ(r.exit_code, 0) << arguments << "\n" << r.err;
    }
    const auto json = run_shell(fmt::format("{} history {} --json -", cli(), quoted(database)), folder);
    EXPECT_EQ(json.exit_code, 2);
    EXPECT_NE(json.err.find("run #1's fit"), std::string::npos) << json.err;
    const auto recorded = run_shell(
        fmt::format("{} history {} --record {} --machine M --axis X", cli(), quoted(database), quoted(results[2])),
        folder);
    EXPECT_EQ(recorded.exit_code, 0) << recorded.err;
    const auto verify = run_shell(fmt::format("{} history {} --verify", cli(), quoted(database)), folder);
    EXPECT_EQ(verify.exit_code, 2);
    EXPECT_EQ(verify.out, "run #1: its fit is not readable JSON\n");
}

}  // namespace
