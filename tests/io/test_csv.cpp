// CSV import: the edge cases real exports produce, the SI conversion as the CLI reports it, and one clear message
// with exit code 2 for each kind of bad file. Expected values are written out by hand from the file text.
#include "feedid/io/csv.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <new>
#include <numbers>
#include <random>
#include <string>

#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/import.hpp"
#include "testing.hpp"

// Sums the bytes requested from operator new while `counting` is set: what the parser asks for, touched or not. The
// replacement allocates with malloc, so its delete frees with free (GCC cannot see that they pair).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
namespace {
std::atomic<bool> counting{false};
std::atomic<std::size_t> requested_bytes{0};
}  // namespace

void* operator new(std::size_t size) {
    if (counting.load(std::memory_order_relaxed)) requested_bytes.fetch_add(size, std::memory_order_relaxed);
    if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
    std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
    std::free(p);
}

using namespace feedid;
using feedid::testing::count_lines;
using feedid::testing::run_cli;
using feedid::testing::write_text;

namespace {

std::string error_of(std::string_view text, const std::string& source = "data.csv") {
    try {
        (void)parse_csv(text, source);
    } catch (const InputError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no InputError for:\n" << text;
    return {};
}

const Channel& channel(const Trace& trace, std::string_view name) {
    const auto* found = trace.find(name);
    if (found == nullptr) throw std::runtime_error("no channel " + std::string(name));
    return *found;
}

bool contains(const std::string& text, std::string_view part) {
    return text.find(part) != std::string::npos;
}

}  // namespace

TEST(Csv, SplitsNameAndUnitInEveryNotation) {
    EXPECT_EQ(split_name_unit("x [mm]"), (std::pair<std::string, std::string>{"x", "mm"}));
    EXPECT_EQ(split_name_unit("v (mm/min)"), (std::pair<std::string, std::string>{"v", "mm/min"}));
    EXPECT_EQ(split_name_unit("i/A"), (std::pair<std::string, std::string>{"i", "A"}));
    EXPECT_EQ(split_name_unit("v/mm/min"), (std::pair<std::string, std::string>{"v", "mm/min"}));
    EXPECT_EQ(split_name_unit("time"), (std::pair<std::string, std::string>{"time", ""}));
    EXPECT_EQ(split_name_unit(" \"x_act [um]\" "), (std::pair<std::string, std::string>{"x_act", "um"}));
    EXPECT_EQ(split_name_unit("pos (axis 1) [mm]"), (std::pair<std::string, std::string>{"pos (axis 1)", "mm"}));
}

TEST(Csv, CommaSeparatedWithUnitsInAllThreeNotations) {
    const auto trace = parse_csv("t [s],x (mm),i/A\n0,1.5,-2\n0.001,2.25,3e-1\n", "a.csv");
    ASSERT_EQ(trace.channels.size(), 3u);
    EXPECT_EQ(trace.format, "csv");
    EXPECT_EQ(trace.source_path, "a.csv");
    EXPECT_EQ(channel(trace, "t").source_unit, "s");
    EXPECT_EQ(channel(trace, "x").source_unit, "mm");
    EXPECT_EQ(channel(trace, "i").source_unit, "A");
    EXPECT_EQ(channel(trace, "t").values, (std::vector<double>{0.0, 0.001}));
    EXPECT_EQ(channel(trace, "x").values, (std::vector<double>{1.5, 2.25}));
    EXPECT_EQ(channel(trace, "i").values, (std::vector<double>{-2.0, 0.3}));
}

TEST(Csv, SemicolonWithDecimalComma) {
    const auto trace =
        parse_csv("Zeit [s];Position [mm];Strom [A]\n0;0;0\n0,001;12,5;-1,25\n0,002;-0,75;3\n", "de.csv");
    ASSERT_EQ(trace.channels.size(), 3u);
    EXPECT_EQ(channel(trace, "Zeit").values, (std::vector<double>{0.0, 0.001, 0.002}));
    EXPECT_EQ(channel(trace, "Position").values, (std::vector<double>{0.0, 12.5, -0.75}));
    EXPECT_EQ(channel(trace, "Strom").values, (std::vector<double>{0.0, -1.25, 3.0}));
}

TEST(Csv, SemicolonWithDecimalPoint) {
    const auto trace = parse_csv("t;x\n0;1\n0.5;2.5\n", "s.csv");
    EXPECT_EQ(channel(trace, "t").values, (std::vector<double>{0.0, 0.5}));
    EXPECT_EQ(channel(trace, "x").values, (std::vector<double>{1.0, 2.5}));
}

TEST(Csv, ExcelSeparatorLine) {
    // "sep=" states the separator; here a single column would leave nothing to detect it from
    const auto trace = parse_csv("sep=;\r\nt [s]\r\n0\r\n0,5\r\n", "excel.csv");
    ASSERT_EQ(trace.channels.size(), 1u);
    EXPECT_EQ(trace.channels[0].values, (std::vector<double>{0.0, 0.5}));
}

TEST(Csv, TabSeparated) {
    const auto trace = parse_csv("time [s]\tx [mm]\tv [mm/min]\n0\t1.5\t600\n0.002\t  2\t-1200\n", "tab.txt");
    ASSERT_EQ(trace.channels.size(), 3u);
    EXPECT_EQ(channel(trace, "v").source_unit, "mm/min");
    EXPECT_EQ(channel(trace, "time").values, (std::vector<double>{0.0, 0.002}));
    EXPECT_EQ(channel(trace, "x").values, (std::vector<double>{1.5, 2.0}));
    EXPECT_EQ(channel(trace, "v").values, (std::vector<double>{600.0, -1200.0}));
}

TEST(Csv, CommentsAndConstants) {
    const auto trace = parse_csv(
        "# recorded on the test rig, axis X\n"
        "# gtau = 35.15\n"
        "#kt=1.45\n"
        "# lead_mm = 10\n"
        "# note = not a number\n"
        "# with spaces = 3\n"
        "\n"
        "t [s],x [mm]\n"
        "# a comment between data rows\n"
        "0,1\n"
        "\n"
        "0.001,2\n",
        "c.csv");
    EXPECT_EQ(trace.constants.size(), 3u);
    EXPECT_EQ(trace.constants.at("gtau"), 35.15);
    EXPECT_EQ(trace.constants.at("kt"), 1.45);
    EXPECT_EQ(trace.constants.at("lead_mm"), 10.0);
    EXPECT_EQ(channel(trace, "x").values, (std::vector<double>{1.0, 2.0}));
}

TEST(Csv, ConstantWithDecimalComma) {
    const auto trace = parse_csv("# gtau = 35,15\nt;x\n0;1\n", "c.csv");
    EXPECT_EQ(trace.constants.at("gtau"), 35.15);
}

TEST(Csv, QuotedHeadersMayHoldTheSeparator) {
    const auto trace = parse_csv("\"time [s]\",\"pos, actual [mm]\",\"i (A)\"\n0,1.5,2\n0.001,1.75,-2\n", "q.csv");
    ASSERT_EQ(trace.channels.size(), 3u);
    EXPECT_EQ(trace.channels[0].name, "time");
    EXPECT_EQ(trace.channels[1].name, "pos, actual");
    EXPECT_EQ(trace.channels[1].source_unit, "mm");
    EXPECT_EQ(trace.channels[2].name, "i");
    EXPECT_EQ(trace.channels[2].source_unit, "A");
    EXPECT_EQ(trace.channels[1].values, (std::vector<double>{1.5, 1.75}));
}

TEST(Csv, QuotedNumbersAreRead) {
    const auto trace = parse_csv("\"t\";\"x\"\n\"0\";\"1,5\"\n\"0,001\";\"-2\"\n", "q.csv");
    EXPECT_EQ(channel(trace, "t").values, (std::vector<double>{0.0, 0.001}));
    EXPECT_EQ(channel(trace, "x").values, (std::vector<double>{1.5, -2.0}));
}

TEST(Csv, MissingValuesAreNaN) {
    const auto trace = parse_csv("t,x,note\n0,1,\n0.001,,5\n0.002,NaN,NA\n0.003,4,-\n", "m.csv");
    const auto& x = channel(trace, "x").values;
    const auto& note = channel(trace, "note").values;
    ASSERT_EQ(x.size(), 4u);
    EXPECT_EQ(x[0], 1.0);
    EXPECT_TRUE(std::isnan(x[1]));
    EXPECT_TRUE(std::isnan(x[2]));
    EXPECT_EQ(x[3], 4.0);
    EXPECT_TRUE(std::isnan(note[0]));
    EXPECT_EQ(note[1], 5.0);
    EXPECT_TRUE(std::isnan(note[2]));
    EXPECT_TRUE(std::isnan(note[3]));
}

TEST(Csv, MissingValueInARoleChannelIsRefusedWithChannelAndSample) {
    const auto dir = feedid::testing::temp_dir();
    write_text(dir / "gap.csv", "t [s],x [mm],note\n0,1,\n0.001,,5\n0.002,3,\n");
    try {
        (void)read_trace(dir / "gap.csv");
        FAIL() << "a missing position value was accepted";
    } catch (const InputError& e) {
        const std::string message = e.what();
        EXPECT_TRUE(contains(message, (dir / "gap.csv").string())) << message;
        EXPECT_TRUE(contains(message, "'x'")) << message;
        EXPECT_TRUE(contains(message, "position")) << message;
        EXPECT_TRUE(contains(message, "sample 2")) << message;
    }
    // ... while gaps in a channel no analysis uses are kept as NaN
    write_text(dir / "note.csv", "t [s],x [mm],note\n0,1,\n0.001,2,5\n0.002,3,\n");
    const auto trace = read_trace(dir / "note.csv");
    EXPECT_TRUE(std::isnan(channel(trace, "note").values[0]));
    EXPECT_EQ(channel(trace, "note").values[1], 5.0);
}

TEST(Csv, RaggedRowsNameTheLine) {
    const std::string short_row = error_of("t,x,i\n0,1,2\n0.001,1\n0.002,1,2\n");
    EXPECT_TRUE(contains(short_row, "data.csv:3:")) << short_row;
    EXPECT_TRUE(contains(short_row, "2 cells")) << short_row;
    EXPECT_TRUE(contains(short_row, "3 columns")) << short_row;

    const std::string long_row = error_of("# comment\nt,x,i\n0,1,2\n0.001,1,2\n0.002,1,2,7\n");
    EXPECT_TRUE(contains(long_row, "data.csv:5:")) << long_row;
    EXPECT_TRUE(contains(long_row, "more cells")) << long_row;
}

TEST(Csv, TrailingSeparatorIsNoExtraColumn) {
    const auto trace = parse_csv("t;x;\n0;1,5;\n0,001;2;\n", "t.csv");
    ASSERT_EQ(trace.channels.size(), 2u);
    EXPECT_EQ(channel(trace, "x").values, (std::vector<double>{1.5, 2.0}));
}

TEST(Csv, CrLfLineEndingsAndByteOrderMark) {
    const auto trace = parse_csv("\xEF\xBB\xBF# k = 2\r\ntime [s],x [mm]\r\n0,1\r\n0.001,2.5\r\n\r\n", "w.csv");
    ASSERT_EQ(trace.channels.size(), 2u);
    EXPECT_EQ(trace.channels[0].name, "time");
    EXPECT_EQ(trace.channels[1].name, "x");
    EXPECT_EQ(trace.channels[1].source_unit, "mm");
    EXPECT_EQ(trace.constants.at("k"), 2.0);
    EXPECT_EQ(trace.channels[0].values, (std::vector<double>{0.0, 0.001}));
    EXPECT_EQ(trace.channels[1].values, (std::vector<double>{1.0, 2.5}));
    // the same without a final line break, and CRLF with semicolons and decimal commas
    const auto last = parse_csv("t;x\r\n0;1,5\r\n0,001;2", "w.csv");
    EXPECT_EQ(last.channels[1].values, (std::vector<double>{1.5, 2.0}));
}

TEST(Csv, NonNumericCellNamesLineColumnAndCell) {
    const std::string message = error_of("t,x,i\n0,1,2\n0.001,1,2\n0.002,abc,2\n");
    EXPECT_TRUE(contains(message, "data.csv:4:")) << message;
    EXPECT_TRUE(contains(message, "column 2")) << message;
    EXPECT_TRUE(contains(message, "'x'")) << message;
    EXPECT_TRUE(contains(message, "'abc'")) << message;
    // a number followed by junk is not a number either (in a column of numbers; in the first row it makes a column
    // of text, left out with a finding)
    const std::string junk = error_of("t,x\n0,1\n0.001,1.5mm\n");
    EXPECT_TRUE(contains(junk, "data.csv:3:")) << junk;
    EXPECT_TRUE(contains(junk, "'1.5mm'")) << junk;
}

TEST(Csv, BinaryIsNotText) {
    EXPECT_TRUE(contains(error_of(std::string("t,x\n0,1\n\0\0\x01", 11)), "not a text file"));
    EXPECT_TRUE(contains(error_of("\x1F\x8B\x08\x00garbage"), "not a text file"));  // a gzip header
}

TEST(Csv, Utf16IsNamed) {
    const std::string utf16le("\xFF\xFEt\0,\0x\0\n\0", 10);
    EXPECT_TRUE(contains(error_of(utf16le), "UTF-16")) << error_of(utf16le);
}

TEST(Csv, HeaderProblems) {
    EXPECT_TRUE(contains(error_of(""), "empty file"));
    EXPECT_TRUE(contains(error_of(" \n\r\n"), "empty file"));
    EXPECT_TRUE(contains(error_of("# only a comment\n"), "no header row"));
    EXPECT_TRUE(contains(error_of("t,x\n"), "no data rows"));
    EXPECT_TRUE(contains(error_of("0,1\n0.001,2\n"), "holds numbers, not a header"));
    EXPECT_TRUE(contains(error_of("t,,x\n0,1,2\n"), "column 2 has no name"));
}

// A header of many columns: its repeated names are found however far apart (a set of names, not a search of the
// columns before each one, which took seconds for 10000 columns), and a wide file is read.
TEST(Csv, WideHeaderDuplicatesAreFoundAndAWideFileIsRead) {
    constexpr int columns = 20000;
    std::string header;
    std::string row;
    for (int c = 0; c < columns; ++c) {
        header += (c > 0 ? "," : "") + std::string("c") + std::to_string(c);
        row += (c > 0 ? "," : "") + std::to_string(c % 10);
    }
    const auto trace = parse_csv(header + "\n" + row + "\n", "wide.csv");
    ASSERT_EQ(trace.channels.size(), std::size_t{columns});
    EXPECT_EQ(trace.channels[12345].name, "c12345");
    ASSERT_EQ(trace.channels[12345].values.size(), 1U);
    EXPECT_EQ(trace.channels[12345].values[0], 5.0);
    const auto repeated = parse_csv(header + ",c0\n" + row + ",1\n", "wide.csv");
    EXPECT_EQ(repeated.channels.back().name, "c0#2");
}

// A wide header over many blank lines made the parser reserve columns x lines values (gigabytes
// for a file of kilobytes; kept in tests/fuzz/regressions/csv/). A row of n cells takes at least n bytes, so the
// columns never need more than 8 bytes of reserve per byte of text.
TEST(Csv, ReserveIsBoundedByTheTextNotByColumnsTimesLines) {
    constexpr int columns = 2000;
    std::string text;
    for (int c = 0; c < columns; ++c) text += (c > 0 ? "," : "") + std::string("c") + std::to_string(c);
    text += std::string(100000, '\n');
    for (int c = 0; c < columns; ++c) text += (c > 0 ? ",1" : "1");
    text += "\n";
    requested_bytes = 0;
    counting = true;
    const auto trace = parse_csv(text, "blank_lines.csv");
    counting = false;
    ASSERT_EQ(trace.channels.size(), std::size_t{columns});
    EXPECT_EQ(trace.samples(), 1U);
    // before the bound: 2000 columns x 100002 estimated rows x 8 bytes = 1.6 GB
    EXPECT_LT(requested_bytes.load(), 16 * text.size()) << "text of " << text.size() << " bytes";
}

TEST(Csv, WriteThenParseIsExact) {
    Trace original;
    original.constants["gtau"] = 35.15;
    original.constants["tiny"] = 1e-300;
    original.constants["third"] = 1.0 / 3.0;
    std::vector<double> time;
    std::vector<double> position;
    std::mt19937_64 generator(42);
    std::uniform_real_distribution<double> uniform(-1.0, 1.0);
    for (int k = 0; k < 500; ++k) {
        time.push_back(k * 0.001);
        position.push_back(uniform(generator) * std::pow(10.0, k % 40 - 20));
    }
    // values whose shortest decimal form is tricky: extremes, subnormals, negative zero
    const std::vector<double> special{0.1,
                                      -0.0,
                                      std::numeric_limits<double>::denorm_min(),
                                      std::numeric_limits<double>::max(),
                                      std::numeric_limits<double>::lowest(),
                                      std::numeric_limits<double>::min(),
                                      std::numbers::pi,
                                      123456789012345680.0,
                                      2.5e-7,
                                      std::numeric_limits<double>::quiet_NaN(),
                                      std::numeric_limits<double>::infinity(),
                                      -std::numeric_limits<double>::infinity()};
    std::vector<double> other(time.size(), 0.5);
    for (std::size_t k = 0; k < special.size(); ++k) other[k * 7] = special[k];
    original.set("t", Role::time, "s", time);
    original.set("x", Role::position, "m", position);
    original.set("pos, raw", Role::other, "", other);

    const auto text = write_csv(original);
    const auto back = parse_csv(text, "roundtrip.csv");
    ASSERT_EQ(back.channels.size(), 3u);
    EXPECT_EQ(back.constants, original.constants);
    for (std::size_t c = 0; c < 3; ++c) {
        const auto& a = original.channels[c];
        const auto& b = back.channels[c];
        EXPECT_EQ(b.name, a.name);
        EXPECT_EQ(b.source_unit, a.unit);
        ASSERT_EQ(b.values.size(), a.values.size());
        for (std::size_t k = 0; k < a.values.size(); ++k) {
            // bit for bit: NaN compares by its bits, -0.0 differs from 0.0
            EXPECT_EQ(std::bit_cast<std::uint64_t>(b.values[k]), std::bit_cast<std::uint64_t>(a.values[k]))
                << a.name << "[" << k << "] = " << a.values[k] << " read back as " << b.values[k];
        }
    }
}

TEST(Csv, WrittenTextIsTheExpectedCsv) {
    Trace trace;
    trace.constants["kt"] = 1.45;
    trace.set("t", Role::time, "s", {0.0, 0.001});
    trace.set("x", Role::position, "m", {-0.25, 1e-6});
    EXPECT_EQ(write_csv(trace), "# kt = 1.45\nt [s],x [m]\n0,-0.25\n0.001,1e-06\n");
}

TEST(Csv, ReadCsvFromAFileMatchesParse) {
    const auto dir = feedid::testing::temp_dir();
    std::string text = "# gtau = 35.15\ntime [s];x [mm];i [A]\n";
    for (int k = 0; k < 20000; ++k) text += std::to_string(k) + ",5;" + std::to_string(k % 17) + ",25;-1,5\n";
    write_text(dir / "big.csv", text);
    const auto from_file = read_csv(dir / "big.csv");
    const auto from_text = parse_csv(text, (dir / "big.csv").string());
    ASSERT_EQ(from_file.channels.size(), 3u);
    EXPECT_EQ(from_file.constants.at("gtau"), 35.15);
    for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(from_file.channels[c].values, from_text.channels[c].values);
    ASSERT_EQ(from_file.channels[0].values.size(), 20000u);
    EXPECT_EQ(from_file.channels[0].values[19999], 19999.5);
    EXPECT_EQ(from_file.channels[1].values[19999], 19999 % 17 + 0.25);
    EXPECT_EQ(from_file.channels[2].values[123], -1.5);
}

// `feedid info --json -` on the header of the issue: every channel converted to SI, roles guessed from the names.
TEST(CsvCli, InfoReportsSiConversions) {
    const auto dir = feedid::testing::temp_dir();
    const auto path = dir / "axis.csv";
    write_text(path,
               "time [s],x_ref [mm],x [mm],v_set [mm/min],i [A]\n"
               "0.000,0,0,0,0.5\n"
               "0.001,1.5,1.25,600,-2.5\n"
               "0.002,3,2.5,1200,1.75\n"
               "0.003,-4.5,-4.25,-300,0.25\n");
    const auto result = run_cli("info '" + path.string() + "' --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    EXPECT_EQ(document.at("format"), "csv");
    EXPECT_EQ(document.at("samples"), 4);
    EXPECT_NEAR(document.at("sample_time_s").get<double>(), 0.001, 1e-15);
    EXPECT_NEAR(document.at("duration_s").get<double>(), 0.003, 1e-15);

    struct Expected {
        std::string name, role, unit, source_unit;
        double min, max;
    };
    // by hand: 1 mm = 0.001 m; 1 mm/min = 0.001 m / 60 s, so 1200 mm/min = 0.02 m/s and -300 mm/min = -0.005 m/s
    const std::vector<Expected> expected{
        {"time", "time", "s", "s", 0.0, 0.003},         {"x_ref", "reference_position", "m", "mm", -0.0045, 0.003},
        {"x", "position", "m", "mm", -0.00425, 0.0025}, {"v_set", "velocity_command", "m/s", "mm/min", -0.005, 0.02},
        {"i", "current", "A", "A", -2.5, 1.75},
    };
    const auto& channels = document.at("channels");
    ASSERT_EQ(channels.size(), expected.size());
    for (std::size_t c = 0; c < expected.size(); ++c) {
        SCOPED_TRACE(expected[c].name);
        EXPECT_EQ(channels[c].at("name"), expected[c].name);
        EXPECT_EQ(channels[c].at("role"), expected[c].role);
        EXPECT_EQ(channels[c].at("unit"), expected[c].unit);
        EXPECT_EQ(channels[c].at("source_unit"), expected[c].source_unit);
        EXPECT_NEAR(channels[c].at("min").get<double>(), expected[c].min, 1e-15 * std::abs(expected[c].min));
        EXPECT_NEAR(channels[c].at("max").get<double>(), expected[c].max, 1e-15 * std::abs(expected[c].max));
    }
    // every role was guessed from a name, and that is said
    std::size_t guesses = 0;
    for (const auto& finding : document.at("findings")) guesses += contains(finding.get<std::string>(), "guessed");
    EXPECT_EQ(guesses, 5u);  // time, x_ref, x, v_set and i
}

// info's min and max: the finite values only (an empty cell, inf), each extreme wherever it lies among the rows, of
// equal values the first (-0 before 0 is -0), and none for a column without a finite value.
TEST(CsvCli, InfoRangesAreTheExtremesOfTheFiniteValues) {
    const auto dir = feedid::testing::temp_dir();
    const auto path = dir / "ranges.csv";
    write_text(path,
               "t [s],x [mm],y,z,w\n"
               "0,1,1,,\n"
               "1,2,-0,inf,\n"
               "2,3,2,5,\n"
               "3,-7,3,,\n"
               "4,5,0,-inf,\n"
               "5,6,4,-2,\n"
               "6,9,,3,\n");
    const auto result = run_cli("info '" + path.string() + "' --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto channels = nlohmann::json::parse(result.out).at("channels");
    ASSERT_EQ(channels.size(), 5u);
    EXPECT_DOUBLE_EQ(channels[1].at("min").get<double>(), -0.007);
    EXPECT_DOUBLE_EQ(channels[1].at("max").get<double>(), 0.009);
    EXPECT_EQ(channels[2].at("min").get<double>(), 0.0);
    EXPECT_TRUE(std::signbit(channels[2].at("min").get<double>())) << "-0 came before 0";
    EXPECT_EQ(channels[2].at("max").get<double>(), 4.0);
    EXPECT_EQ(channels[3].at("min").get<double>(), -2.0);
    EXPECT_EQ(channels[3].at("max").get<double>(), 5.0);
    EXPECT_TRUE(channels[4].at("min").is_null());
    EXPECT_TRUE(channels[4].at("max").is_null());
}

TEST(CsvCli, InfoValuesAreConvertedOnImport) {
    // the same file through the library: every value, not only min and max
    const auto dir = feedid::testing::temp_dir();
    write_text(dir / "axis.csv",
               "time [s],x_ref [mm],x [mm],v_set [mm/min],i [mA]\n"
               "0.000,0,0,0,500\n"
               "0.001,1.5,1.25,600,-2500\n");
    const auto trace = read_trace(dir / "axis.csv");
    EXPECT_EQ(trace.find(Role::position)->name, "x");
    EXPECT_EQ(trace.find(Role::reference_position)->name, "x_ref");
    const auto x = trace.column(Role::position);
    const auto v = trace.column(Role::velocity_command);
    const auto i = trace.column(Role::current);
    EXPECT_NEAR(x[1], 0.00125, 1e-18);
    EXPECT_NEAR(v[1], 0.01, 1e-17);
    EXPECT_NEAR(i[0], 0.5, 1e-15);
    EXPECT_NEAR(i[1], -2.5, 1e-15);
}

// Bad input through the CLI: exit code 2 and one line on stderr naming the file and the problem.
class CsvBadInput : public ::testing::Test {
protected:
    void expect_refused(const std::string& file_name, const std::string& content,
                        const std::vector<std::string>& message_parts) {
        const auto path = feedid::testing::temp_dir() / file_name;
        write_text(path, content);
        const auto result = run_cli("info '" + path.string() + "'");
        EXPECT_EQ(result.exit_code, 2) << result.err;
        EXPECT_EQ(count_lines(result.err), 1) << result.err;
        EXPECT_TRUE(result.out.empty()) << result.out;
        EXPECT_TRUE(contains(result.err, path.string())) << result.err;
        for (const auto& part : message_parts) EXPECT_TRUE(contains(result.err, part)) << result.err;
    }
};

TEST_F(CsvBadInput, EmptyFile) {
    expect_refused("empty.csv", "", {"empty file"});
}

TEST_F(CsvBadInput, BinaryGarbage) {
    std::mt19937 generator(7);
    std::string garbage(4096, '\0');
    for (auto& byte : garbage) byte = static_cast<char>(generator() & 0xFF);
    expect_refused("garbage.csv", garbage, {"not a text file"});
}

TEST_F(CsvBadInput, BinaryGarbageWithoutNulBytes) {
    std::mt19937 generator(11);
    std::string garbage(4096, '\0');
    for (auto& byte : garbage) byte = static_cast<char>(1 + generator() % 255);
    expect_refused("garbage.dat", garbage, {"not a text file"});
}

TEST_F(CsvBadInput, HeaderOnly) {
    expect_refused("header.csv", "time [s],x [mm],i [A]\n", {"header but no data rows"});
}

TEST_F(CsvBadInput, NonNumericCell) {
    expect_refused("cell.csv", "time [s],x [mm],i [A]\n0,1,2\n0.001,1.5,2\n0.002,1.5,two\n",
                   {":4:", "column 3", "'i'", "'two'", "not a number"});
}

TEST_F(CsvBadInput, NonMonotonicTime) {
    expect_refused("time.csv", "time [s],x [mm],i [A]\n0,1,2\n0.002,1.5,2\n0.001,1.5,2\n",
                   {"time is not strictly increasing", "sample 3"});
}

TEST_F(CsvBadInput, NaNInARoleChannel) {
    expect_refused("nan.csv", "time [s],x [mm],i [A]\n0,1,2\n0.001,NaN,2\n0.002,1.5,2\n",
                   {"'x'", "position", "sample 2"});
}

TEST_F(CsvBadInput, UnknownUnitOfARoleChannel) {
    expect_refused("unit.csv", "time [s],x [furlong],i [A]\n0,1,2\n0.001,1.5,2\n", {"'x'", "'furlong'"});
}

TEST_F(CsvBadInput, MissingFile) {
    const auto path = feedid::testing::temp_dir() / "absent.csv";
    const auto result = run_cli("info '" + path.string() + "'");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_EQ(count_lines(result.err), 1) << result.err;
    EXPECT_TRUE(contains(result.err, path.string())) << result.err;
}

TEST_F(CsvBadInput, RpmWithoutALead) {
    expect_refused("rpm.csv", "time [s],x [mm],v [rpm]\n0,1,0\n0.001,1.5,3000\n", {"'v'", "'rpm'", "--lead"});
}

TEST(CsvCli, RpmWithALeadIsATableVelocity) {
    const auto path = feedid::testing::temp_dir() / "rpm.csv";
    write_text(path, "time [s],x [mm],v [rpm]\n0,1,-600\n0.001,1.5,3000\n");
    const auto result = run_cli("info '" + path.string() + "' --lead 10 --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    const auto& v = document.at("channels").at(2);
    EXPECT_EQ(v.at("role"), "velocity");
    EXPECT_EQ(v.at("unit"), "m/s");
    // 3000 rev/min * 10 mm/rev = 30 m/min = 0.5 m/s; -600 rev/min -> -0.1 m/s
    EXPECT_NEAR(v.at("max").get<double>(), 0.5, 1e-15);
    EXPECT_NEAR(v.at("min").get<double>(), -0.1, 1e-15);
}

// ---- What real files add (issue 12): unit rows, repeated names, text columns, an index, a preamble, no time ---------

TEST(Csv, UnitRowUnderTheHeaderGivesTheUnits) {
    const auto trace = parse_csv("t,x,v,i,n\ns,mm,mm/min,A,\n0,1,2,3,4\n0.001,1.5,2.5,3.5,4.5\n", "units.csv");
    ASSERT_EQ(trace.channels.size(), 5U);
    EXPECT_EQ(trace.channels[0].source_unit, "s");
    EXPECT_EQ(trace.channels[1].source_unit, "mm");
    EXPECT_EQ(trace.channels[2].source_unit, "mm/min");
    EXPECT_EQ(trace.channels[3].source_unit, "A");
    EXPECT_EQ(trace.channels[4].source_unit, "");
    EXPECT_EQ(trace.channels[1].values, (std::vector<double>{1.0, 1.5}));
    ASSERT_EQ(trace.findings.size(), 1U);
    EXPECT_TRUE(contains(trace.findings[0], "line 2")) << trace.findings[0];
    // units that need context (rpm, %) count as units; a header cell's unit still works beside the row
    const auto mixed = parse_csv("t [s],v,torque\n,r/min,%\n0,1,2\n", "mixed.csv");
    EXPECT_EQ(mixed.channels[0].source_unit, "s");
    EXPECT_EQ(mixed.channels[1].source_unit, "r/min");
    EXPECT_EQ(mixed.channels[2].source_unit, "%");
    // a header unit the row contradicts is an error naming both
    const std::string message = error_of("t [s],x [mm]\ns,um\n0,1\n");
    EXPECT_TRUE(contains(message, "data.csv:2:")) << message;
    EXPECT_TRUE(contains(message, "'mm'")) << message;
    EXPECT_TRUE(contains(message, "'um'")) << message;
    // a vendor unit among known ones is kept as the column's unit (import judges it), not taken for text
    const auto vendor = parse_csv("t,x,droop\ns,mm,pulse\n0,1,2\n", "vendor.csv");
    ASSERT_EQ(vendor.channels.size(), 3U);
    EXPECT_EQ(vendor.channels[2].source_unit, "pulse");
    EXPECT_EQ(vendor.channels[2].values, (std::vector<double>{2.0}));
    // a row of mostly text is data: its columns are text
    const auto words = parse_csv("t,step,tool\n0,Prep,unworn\n0.1,Cut,unworn\n", "words.csv");
    EXPECT_EQ(words.channels.size(), 1U);
    // a first data row is no unit row, even of ones and blanks
    const auto data = parse_csv("t,x\n1,\n2,1\n", "data.csv");
    EXPECT_EQ(data.channels[0].values, (std::vector<double>{1.0, 2.0}));
}

TEST(Csv, RepeatedColumnNamesAreNumbered) {
    const auto trace = parse_csv("t,x,t,x,x#2\n0,1,2,3,4\n", "twice.csv");
    std::vector<std::string> names;
    for (const auto& c : trace.channels) names.push_back(c.name);
    // the third x would be x#2, which the file already has: it takes the next free number
    EXPECT_EQ(names, (std::vector<std::string>{"t", "x", "t#2", "x#3", "x#2"}));
    EXPECT_EQ(channel(trace, "t#2").values, (std::vector<double>{2.0}));
    ASSERT_EQ(trace.findings.size(), 2U);
    EXPECT_TRUE(contains(trace.findings[0], "'t' appears more than once")) << trace.findings[0];
}

TEST(Csv, TextColumnsAreLeftOutWithOneFinding) {
    const auto trace = parse_csv(
        "t,x,Machining_Process,note,tool_condition\n0,1,Starting,,unworn\n0.001,2,Prep,\"a, b\",unworn\n"
        "0.002,3,Layer 1 Up,7,worn\n",
        "mill.csv");
    std::vector<std::string> names;
    for (const auto& c : trace.channels) names.push_back(c.name);
    EXPECT_EQ(names, (std::vector<std::string>{"t", "x"}));
    EXPECT_EQ(channel(trace, "x").values, (std::vector<double>{1.0, 2.0, 3.0}));
    ASSERT_EQ(trace.findings.size(), 1U);
    const auto& finding = trace.findings[0];
    EXPECT_TRUE(contains(finding, "'Machining_Process' ('Starting' at line 2)")) << finding;
    EXPECT_TRUE(contains(finding, "'note' (")) << finding;  // empty first, then text: text
    EXPECT_TRUE(contains(finding, "'tool_condition' ('unworn' at line 2)")) << finding;
    // a column of numbers with one cell that is not is still an error naming the line and the cell
    EXPECT_TRUE(contains(error_of("t,x\n0,1\n0.001,oops\n"), "data.csv:3: column 2 ('x') holds 'oops'"));
    // a text column given for a role is an error naming it
    CsvOptions options;
    options.numeric_columns = {"Machining_Process"};
    try {
        (void)parse_csv("t,Machining_Process\n0,Prep\n", "mill.csv", options);
        ADD_FAILURE() << "a text column given for a role was accepted";
    } catch (const InputError& e) {
        EXPECT_TRUE(contains(e.what(), "mill.csv:2: column 2 ('Machining_Process') holds 'Prep'")) << e.what();
    }
    EXPECT_TRUE(contains(error_of("a,b\nx,y\n"), "no column holds numbers"));
}

TEST(Csv, UnnamedIndexColumnIsLeftOut) {
    const auto trace = parse_csv(",t,x\n0,0.1,5\n1,0.2,6\n2,0.3,7\n", "pandas.csv");
    ASSERT_EQ(trace.channels.size(), 2U);
    EXPECT_EQ(trace.channels[0].name, "t");
    EXPECT_EQ(trace.channels[1].values, (std::vector<double>{5.0, 6.0, 7.0}));
    ASSERT_EQ(trace.findings.size(), 1U);
    EXPECT_TRUE(contains(trace.findings[0], "index")) << trace.findings[0];
    EXPECT_EQ(parse_csv("Unnamed: 0,t\n0,1\n1,2\n", "again.csv").channels.size(), 1U);
    // unnamed and not counting 0, 1, 2: a column without a name
    const std::string message = error_of(",t\n5,1\n6,2\n");
    EXPECT_TRUE(contains(message, "data.csv:1: column 1 has no name")) << message;
}

TEST(Csv, SkipRowsPassesAPreambleNoReaderKnows) {
    CsvOptions options;
    options.skip_rows = 2;
    const auto trace = parse_csv("Recorder 7, serial 1234\nexported by hand\nt,x\n0,1\n0.5,2\n", "pre.csv", options);
    ASSERT_EQ(trace.channels.size(), 2U);
    EXPECT_EQ(trace.channels[1].values, (std::vector<double>{1.0, 2.0}));
    options.skip_rows = 9;
    try {
        (void)parse_csv("a\nb\nc\n", "short.csv", options);
        ADD_FAILURE() << "skipping past the end was accepted";
    } catch (const InputError& e) {
        EXPECT_TRUE(contains(e.what(), "--skip-rows 9 skips the whole file (3 lines)")) << e.what();
    }
}

TEST(CsvCli, NoTimeColumnTakesTheSampleTimeOrAsksForIt) {
    const auto dir = feedid::testing::temp_dir();
    const auto path = dir / "log.csv";
    write_text(path, "x [mm],i [A]\n1,2\n2,3\n3,4\n");
    const auto result = run_cli("info '" + path.string() + "' --sample-time 0.1 --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    EXPECT_NEAR(document.at("sample_time_s").get<double>(), 0.1, 1e-15);
    EXPECT_NEAR(document.at("duration_s").get<double>(), 0.2, 1e-15);
    EXPECT_EQ(document.at("channels").at(2).at("role"), "time");
    EXPECT_TRUE(contains(document.at("findings").dump(), "--sample-time 0.1 s")) << document.at("findings").dump();
    // an analysis refuses it and asks for the sample time; info describes it without a time base and asks too
    const auto described = run_cli("info '" + path.string() + "' --json -");
    ASSERT_EQ(described.exit_code, 0) << described.err;
    EXPECT_TRUE(contains(described.out, "--sample-time SECONDS")) << described.out;
    const auto refused = run_cli("identify '" + path.string() + "'");
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_EQ(count_lines(refused.err), 1) << refused.err;
    EXPECT_TRUE(contains(refused.err, "no time column")) << refused.err;
    EXPECT_TRUE(contains(refused.err, "--sample-time SECONDS")) << refused.err;
    // --skip-rows from the command line, and a text column given for a role names it
    write_text(dir / "pre.csv", "Recorder 7\nt,x,step\n0,1,Prep\n0.1,2,Cut\n");
    EXPECT_EQ(run_cli("info '" + (dir / "pre.csv").string() + "' --skip-rows 1").exit_code, 0);
    const auto text_role = run_cli("info '" + (dir / "pre.csv").string() + "' --skip-rows 1 --channel position=step");
    EXPECT_EQ(text_role.exit_code, 2);
    EXPECT_TRUE(contains(text_role.err, "'step' holds 'Prep'") || contains(text_role.err, "('step') holds 'Prep'"))
        << text_role.err;
}

TEST(CsvCli, MillLogWrittenByPandasReads) {
    const auto file = feedid::testing::shared_data() / "umich-cnc-mill/experiment_01.csv";
    FEEDID_REQUIRE_SHARED("umich-cnc-mill/experiment_01.csv");
    const auto result =
        run_cli("info '" + file.string() + "' --sample-time 0.1 --channel position=X1_ActualPosition --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    // 1055 rows, 100 ms apart; the index and the two text columns left out, a time channel made
    EXPECT_EQ(document.at("samples"), 1055);
    EXPECT_NEAR(document.at("duration_s").get<double>(), 105.4, 1e-9);
    const auto& channels = document.at("channels");
    EXPECT_EQ(channels.size(), 47U + 1U);
    for (const auto& c : channels) {
        EXPECT_NE(c.at("name"), "Machining_Process");
        EXPECT_NE(c.at("name"), "tool_condition");
    }
    const std::string findings = document.at("findings").dump();
    EXPECT_TRUE(contains(findings, "'Machining_Process' ('Starting' at line 2)")) << findings;
    EXPECT_TRUE(contains(findings, "index")) << findings;
    // X1_ActualPosition as the raw text has it (column 2 of each row): 198 mm at the start, rounded to 1 mm
    EXPECT_EQ(channels.at(0).at("name"), "X1_ActualPosition");
    EXPECT_EQ(channels.at(0).at("role"), "position");
    const std::string text = feedid::testing::read_text(file);
    double low = 1e300;
    double high = -1e300;
    std::size_t line_start = text.find('\n') + 1;
    while (line_start < text.size()) {
        const auto comma = text.find(',', line_start);
        const double x = std::stod(text.substr(comma + 1, text.find(',', comma + 1) - comma - 1));
        low = std::min(low, x);
        high = std::max(high, x);
        line_start = text.find('\n', line_start) + 1;
        if (line_start == 0) break;
    }
    EXPECT_EQ(channels.at(0).at("min").get<double>(), low);
    EXPECT_EQ(channels.at(0).at("max").get<double>(), high);
}

// ---- Role guessing from drive and CNC log names, and the --axis prefix filter (issue 12) ---------------------------

namespace {
const char* const mill_log = "umich-cnc-mill/experiment_01.csv";

std::map<std::string, std::string> roles_of(const nlohmann::json& document) {
    std::map<std::string, std::string> roles;
    for (const auto& c : document.at("channels")) roles[c.at("name")] = c.at("role");
    return roles;
}
}  // namespace

TEST(CsvCli, AxisPrefixChoosesTheMillAxisAndItsRolesAreGuessed) {
    FEEDID_REQUIRE_SHARED(mill_log);
    const auto file = feedid::testing::shared_data() / mill_log;
    const auto result = run_cli("info '" + file.string() + "' --axis x1 --sample-time 0.1 --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    const auto roles = roles_of(document);
    EXPECT_EQ(roles.at("X1_ActualPosition"), "position");
    EXPECT_EQ(roles.at("X1_CommandPosition"), "reference_position");
    EXPECT_EQ(roles.at("X1_ActualVelocity"), "velocity");
    EXPECT_EQ(roles.at("X1_CommandVelocity"), "velocity_command");
    EXPECT_EQ(roles.at("X1_CurrentFeedback"), "current");
    EXPECT_EQ(roles.at("X1_OutputCurrent"), "other");
    EXPECT_EQ(roles.at("M1_CURRENT_FEEDRATE"), "other");  // no axis: kept, never guessed
    for (const auto& [name, role] : roles) {
        EXPECT_FALSE(name.starts_with("Y1_") || name.starts_with("Z1_") || name.starts_with("S1_")) << name;
    }
    EXPECT_TRUE(contains(document.at("findings").dump(), "other axes (Y1, Z1, S1) left out"))
        << document.at("findings").dump();
}

TEST(CsvCli, SeveralAxesWithoutAChoiceAreNamedNotGuessed) {
    FEEDID_REQUIRE_SHARED(mill_log);
    const auto file = feedid::testing::shared_data() / mill_log;
    // an analysis refuses to guess; info describes every channel and lists the axes (test_axis_kind.cpp)
    const auto refused = run_cli("identify '" + file.string() + "' --sample-time 0.1");
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_EQ(count_lines(refused.err), 1) << refused.err;
    EXPECT_TRUE(contains(refused.err, "several axes (X1, Y1, Z1, S1)")) << refused.err;
    EXPECT_TRUE(contains(refused.err, "--axis")) << refused.err;
    const auto unknown = run_cli("info '" + file.string() + "' --sample-time 0.1 --axis B2");
    EXPECT_EQ(unknown.exit_code, 2);
    EXPECT_TRUE(contains(unknown.err, "--axis B2")) << unknown.err;
    EXPECT_TRUE(contains(unknown.err, "X1, Y1, Z1, S1")) << unknown.err;
    // explicit roles work without --axis; nothing is guessed from the axes' names then
    const auto explicit_roles =
        run_cli("info '" + file.string() + "' --sample-time 0.1 --channel position=Y1_ActualPosition --json -");
    ASSERT_EQ(explicit_roles.exit_code, 0) << explicit_roles.err;
    const auto roles = roles_of(nlohmann::json::parse(explicit_roles.out));
    EXPECT_EQ(roles.at("Y1_ActualPosition"), "position");
    EXPECT_EQ(roles.at("X1_ActualPosition"), "other");
    EXPECT_EQ(roles.at("Y1_CurrentFeedback"), "other");
}

TEST(CsvCli, DriveExportNamesAreGuessedAndAUnitNeedingARatingIsSaid) {
    const auto path = feedid::testing::temp_dir() / "drive.csv";
    write_text(path, "time [ms],Servo motor speed [mm/s],Torque [%]\n0,0,10\n1,5,-20\n2,10,30\n");
    const auto without = run_cli("info '" + path.string() + "' --json -");
    ASSERT_EQ(without.exit_code, 0) << without.err;
    const auto document = nlohmann::json::parse(without.out);
    auto roles = roles_of(document);
    EXPECT_EQ(roles.at("Servo motor speed"), "velocity");
    EXPECT_EQ(roles.at("Torque"), "other");  // % without --rated: no role, and a finding says what it needs
    EXPECT_TRUE(contains(document.at("findings").dump(), "--rated")) << document.at("findings").dump();
    const auto rated = run_cli("info '" + path.string() + "' --rated 4 --json -");
    ASSERT_EQ(rated.exit_code, 0) << rated.err;
    const auto with_rating = nlohmann::json::parse(rated.out);
    roles = roles_of(with_rating);
    EXPECT_EQ(roles.at("Torque"), "current");
    // 30 % and -20 % of 4 A
    EXPECT_NEAR(with_rating.at("channels").at(2).at("max").get<double>(), 1.2, 1e-15);
    EXPECT_NEAR(with_rating.at("channels").at(2).at("min").get<double>(), -0.8, 1e-15);
}

TEST(CsvCli, MrConfiguratorExportGetsItsRolesFromTheSlotNames) {
    const auto file = feedid::testing::shared_data() / "mitsubishi-mr/a3MR.csv";
    FEEDID_REQUIRE_SHARED("mitsubishi-mr/a3MR.csv");
    const auto result = run_cli("info '" + file.string() + "' --lead 20 --rated 1 --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    const auto roles = roles_of(document);
    EXPECT_EQ(roles.at("Time"), "time");
    EXPECT_EQ(roles.at("Servo motor speed"), "velocity");
    EXPECT_EQ(roles.at("Torque"), "current");
    // the rig authors' own conversion: v = rpm * 20 mm / 1000 / 60; the slowest sample is -1981 r/min
    const auto& speed = document.at("channels").at(1);
    EXPECT_NEAR(speed.at("min").get<double>(), -1981.0 * 0.020 / 60.0, 1e-12);
}
