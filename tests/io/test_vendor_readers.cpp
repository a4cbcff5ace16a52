// Vendor CSV readers (issue 12): Mitsubishi MR Configurator2 graph exports and National Instruments DAQ CSV files.
// The real files in ../shared/data/mitsubishi-mr are checked against the facts its README publishes and against their
// raw text split independently here; hand-made fixtures pin the preamble checks and the error messages.
#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/import.hpp"
#include "feedid/io/mr_configurator.hpp"
#include "feedid/io/ni_daq.hpp"
#include "testing.hpp"

using namespace feedid;
namespace fs = std::filesystem;
using feedid::testing::count_lines;
using feedid::testing::run_cli;
using feedid::testing::shared_data;

namespace {

const char* const mr_file = "mitsubishi-mr/a3MR.csv";
const char* const ni_file = "mitsubishi-mr/a3NI.csv";

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// The numeric rows of a CSV text from `first_row` (0-based line) on, split on ',' with std::stod: independent of the
// readers' scanning.
std::vector<std::vector<double>> raw_rows(const std::string& text, std::size_t first_row) {
    std::istringstream in(text);
    std::string line;
    std::vector<std::vector<double>> rows;
    for (std::size_t k = 0; std::getline(in, line); ++k) {
        if (k < first_row || line.find_first_not_of("\r ") == std::string::npos) continue;
        std::vector<double> row;
        std::istringstream cells(line);
        std::string cell;
        while (std::getline(cells, cell, ',')) row.push_back(std::stod(cell));
        rows.push_back(row);
    }
    return rows;
}

std::string error_of(Trace (*parse)(std::string_view, const std::string&), const std::string& text) {
    try {
        (void)parse(text, "fixture.csv");
    } catch (const InputError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no InputError for:\n" << text;
    return {};
}

// ---- MR Configurator2 ----------------------------------------------------------------------------------------------

const std::string mr_header =
    "Axis1\r\nNumber of sampling data,3\r\nSampling time interval(ms),0.444\r\n"
    "Time,Analog 1,Analog 2,Analog 3,Digital 1,Digital 2\r\n"
    "ms,Servo motor speed,Torque,Not selected,INP,Not selected\r\n";
const std::string mr_rows = "0.000000,0.0,-1.0,0,2.5,0\r\n0.444444,10.0,-2.0,0,2.5,0\r\n0.888888,20.0,-3.5,0,0,0\r\n";

}  // namespace

TEST(MrConfigurator, TheRigsExportReadsAsItsReadmeDescribesIt) {
    FEEDID_REQUIRE_SHARED(mr_file);
    const std::string text = feedid::testing::read_text(shared_data() / mr_file);
    const Trace trace = parse_mr_configurator(text, "a3MR.csv");
    EXPECT_EQ(trace.format, "mr-configurator");
    // "Not selected" slots dropped; channels named by the row of what each slot holds
    std::vector<std::string> names;
    for (const auto& channel : trace.channels) names.push_back(channel.name);
    EXPECT_EQ(names,
              (std::vector<std::string>{"Time", "Servo motor speed", "Torque", "Droop pulses (by 1 pls.)", "INP"}));
    EXPECT_EQ(trace.channels[0].source_unit, "ms");
    EXPECT_EQ(trace.channels[1].source_unit, "r/min");
    EXPECT_EQ(trace.channels[2].source_unit, "%");
    EXPECT_EQ(trace.channels[3].source_unit, "pulse");
    EXPECT_EQ(trace.channels[4].source_unit, "");
    // 1024 samples (the preamble's count, so no finding about it); speed 0..-1981 r/min, droop saturated at -32768
    EXPECT_EQ(trace.samples(), 1024U);
    EXPECT_TRUE(trace.findings.empty()) << trace.findings.front();
    const auto& speed = trace.channels[1].values;
    EXPECT_EQ(*std::min_element(speed.begin(), speed.end()), -1981.0);
    EXPECT_EQ(*std::max_element(speed.begin(), speed.end()), 0.0);
    EXPECT_EQ(*std::min_element(trace.channels[3].values.begin(), trace.channels[3].values.end()), -32768.0);
    // every value as the raw text has it: columns 0, 1, 2, 3 and 8 (Digital 1 = INP)
    const auto rows = raw_rows(text, 5);
    ASSERT_EQ(rows.size(), 1024U);
    const std::size_t columns[] = {0, 1, 2, 3, 8};
    for (std::size_t k = 0; k < rows.size(); ++k) {
        for (std::size_t c = 0; c < 5; ++c)
            ASSERT_EQ(trace.channels[c].values[k], rows[k][columns[c]]) << k << "," << c;
    }
}

TEST(MrConfigurator, InfoDetectsItAndGivesTheSampleTimeInSeconds) {
    FEEDID_REQUIRE_SHARED(mr_file);
    // --lead 20: the rig's 20 mm of rack per motor revolution (its README), for the speed in r/min
    const auto result = run_cli("info '" + (shared_data() / mr_file).string() + "' --lead 20 --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    EXPECT_EQ(document.at("format"), "mr-configurator");
    EXPECT_EQ(document.at("samples"), 1024);
    // 0.666666 ms steps in the file (1.5 kHz); the preamble rounds them to 0.667
    EXPECT_NEAR(document.at("sample_time_s").get<double>(), 0.666666e-3, 1e-12);
    EXPECT_NEAR(document.at("duration_s").get<double>(), 0.681999318, 1e-12);
    const auto& time = document.at("channels").at(0);
    EXPECT_EQ(time.at("role"), "time");
    EXPECT_EQ(time.at("unit"), "s");
    // the droop pulses stay in pulses, and a finding says why
    bool said = false;
    for (const auto& finding : document.at("findings")) said = said || contains(finding, "Droop pulses");
    EXPECT_TRUE(said) << document.at("findings").dump();
    // Torque in % without --rated: no role, said once
    int torque_findings = 0;
    for (const auto& finding : document.at("findings")) torque_findings += contains(finding, "'Torque'") ? 1 : 0;
    EXPECT_EQ(torque_findings, 1) << document.at("findings").dump();
    EXPECT_TRUE(contains(document.at("findings").dump(), "not taken as current")) << document.at("findings").dump();
}

TEST(MrConfigurator, FixtureChannelsUnitsAndValues) {
    const Trace trace = parse_mr_configurator(mr_header + mr_rows, "fixture.csv");
    ASSERT_EQ(trace.channels.size(), 4U);
    EXPECT_EQ(trace.channels[2].name, "Torque");
    EXPECT_EQ(trace.channels[2].values, (std::vector<double>{-1.0, -2.0, -3.5}));
    EXPECT_EQ(trace.channels[3].name, "INP");
    EXPECT_EQ(trace.channels[3].values, (std::vector<double>{2.5, 2.5, 0.0}));
}

TEST(MrConfigurator, PreambleFiguresAreCheckedAgainstTheRows) {
    // a count that differs from the rows is a finding naming both figures
    std::string counted = mr_header;
    counted.replace(counted.find(",3\r\n"), 4, ",5\r\n");
    const Trace trace = parse_mr_configurator(counted + mr_rows, "fixture.csv");
    ASSERT_EQ(trace.findings.size(), 1U);
    EXPECT_TRUE(contains(trace.findings[0], "5 samples")) << trace.findings[0];
    EXPECT_TRUE(contains(trace.findings[0], "3 rows")) << trace.findings[0];
    // an interval that differs from the time column's beyond its rounding is an error naming both
    std::string slower = mr_header;
    slower.replace(slower.find("0.444"), 5, "0.445");
    const std::string message = error_of(parse_mr_configurator, slower + mr_rows);
    EXPECT_TRUE(contains(message, "0.445 ms")) << message;
    EXPECT_TRUE(contains(message, "0.444444 ms")) << message;
}

TEST(MrConfigurator, BadFilesGiveOneMessageWithFileAndPlace) {
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, ""), "empty file"));
    // missing preamble lines are named
    std::string no_interval = mr_header;
    no_interval.erase(no_interval.find("Sampling"), std::string("Sampling time interval(ms),0.444\r\n").size());
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, no_interval + mr_rows), "'Sampling time interval(ms)'"));
    std::string no_count = mr_header;
    no_count.erase(no_count.find("Number"), std::string("Number of sampling data,3\r\n").size());
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, no_count + mr_rows), "'Number of sampling data'"));
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, "Axis1\r\nNumber of sampling data,x\r\n"),
                         "fixture.csv:2: 'Number of sampling data' is followed by 'x'"));
    // no header, no meaning row, no data
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, "Axis1\r\nNumber of sampling data,3\r\n"), "no header row"));
    const std::string header_only = mr_header.substr(0, mr_header.find("ms,"));
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, header_only), "ends after the header row"));
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, mr_header), "no data rows"));
    // a truncated last row and a cell that is not a number name the line
    const std::string truncated = mr_header + mr_rows.substr(0, mr_rows.size() - 12);
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, truncated), "fixture.csv:8: row has 3 cells"))
        << error_of(parse_mr_configurator, truncated);
    std::string junk = mr_header + mr_rows;
    junk.replace(junk.find("-3.5"), 4, "-3x5");
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, junk), "fixture.csv:8: slot 3 ('Torque') holds '-3x5'"));
    // a time column in no unit of time
    std::string no_time = mr_header;
    no_time.replace(no_time.find("ms,"), 2, "mm");
    EXPECT_TRUE(contains(error_of(parse_mr_configurator, no_time + mr_rows), "not a unit of time"));
}

// ---- NI DAQ --------------------------------------------------------------------------------------------------------

namespace {
const std::string ni_header =
    "\xEF\xBB\xBFTimestamp,2020-03-16 17:04:51,Timestamp,2020-03-16 17:04:51\r\n"
    "Interval,0.0005,Interval,0.0005\r\n"
    "Channel name,\"Force\",Channel name,\"Input 1\"\r\n"
    "Unit,\"V\",Unit,\"V\"\r\n";
const std::string ni_rows = "0,-0.5,0,1.25\r\n0.0005,-0.25,0.0005,1.5\r\n0.001,0,0.001,1.75\r\n";
}  // namespace

TEST(NiDaq, TheRigsLoadCellFileReadsAsItsRawText) {
    FEEDID_REQUIRE_SHARED(ni_file);
    const std::string text = feedid::testing::read_text(shared_data() / ni_file);
    const Trace trace = parse_ni_daq(text, "a3NI.csv");
    EXPECT_EQ(trace.format, "ni-daq");
    ASSERT_EQ(trace.channels.size(), 3U);
    EXPECT_EQ(trace.channels[0].name, "Time");
    EXPECT_EQ(trace.channels[0].source_unit, "s");
    EXPECT_EQ(trace.channels[1].name, "Force");
    EXPECT_EQ(trace.channels[1].source_unit, "V");  // the load cell's voltage, as the file states
    EXPECT_EQ(trace.channels[2].name, "Input 1");
    const auto rows = raw_rows(text, 4);
    ASSERT_EQ(trace.samples(), rows.size());
    for (std::size_t k = 0; k < rows.size(); ++k) {
        ASSERT_EQ(trace.channels[0].values[k], rows[k][0]) << k;
        ASSERT_EQ(trace.channels[1].values[k], rows[k][1]) << k;
        ASSERT_EQ(trace.channels[2].values[k], rows[k][3]) << k;
    }
    // 2 kHz, as the README says
    const auto result = run_cli("info '" + (shared_data() / ni_file).string() + "' --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    EXPECT_EQ(document.at("format"), "ni-daq");
    EXPECT_NEAR(document.at("sample_time_s").get<double>(), 0.0005, 1e-15);
    // "Force" looks like the force role by its name, but volts are no force: no role, and a finding says why
    EXPECT_EQ(document.at("channels").at(1).at("role"), "other");
    EXPECT_TRUE(contains(document.at("findings").dump(), "unit 'V' is not one for force"))
        << document.at("findings").dump();
}

TEST(NiDaq, FixtureWithDecimalCommaAndRepeatedNames) {
    std::string text = ni_header + ni_rows;
    text.replace(text.find("Input 1"), 7, "Force");
    const Trace trace = parse_ni_daq(text, "fixture.csv");
    ASSERT_EQ(trace.channels.size(), 3U);
    EXPECT_EQ(trace.channels[2].name, "Force#2");
    EXPECT_EQ(trace.channels[2].values, (std::vector<double>{1.25, 1.5, 1.75}));
    ASSERT_EQ(trace.findings.size(), 1U);
    EXPECT_TRUE(contains(trace.findings[0], "'Force'")) << trace.findings[0];
    const Trace semicolons =
        parse_ni_daq("Timestamp;t0\nInterval;0,5\nChannel name;x\nUnit;mm\n0;1,5\n0,5;2,5\n1;3\n", "semicolons.csv");
    EXPECT_EQ(semicolons.channels[0].values, (std::vector<double>{0.0, 0.5, 1.0}));
    EXPECT_EQ(semicolons.channels[1].values, (std::vector<double>{1.5, 2.5, 3.0}));
    EXPECT_EQ(semicolons.channels[1].source_unit, "mm");
}

TEST(NiDaq, ChannelsOnDifferentTimeBasesAreNamed) {
    std::string shifted = ni_header + ni_rows;
    shifted.replace(shifted.rfind("0.001,1.75"), 5, "0.002");
    const std::string message = error_of(parse_ni_daq, shifted);
    EXPECT_TRUE(contains(message, "fixture.csv:7:")) << message;
    EXPECT_TRUE(contains(message, "'Input 1'")) << message;
    EXPECT_TRUE(contains(message, "'Force'")) << message;
    std::string other_interval = ni_header + ni_rows;
    other_interval.replace(other_interval.find("Interval,0.0005\r\n") + 9, 6, "0.0010");
    const std::string intervals = error_of(parse_ni_daq, other_interval);
    EXPECT_TRUE(contains(intervals, "'Force' and 'Input 1' have different Interval")) << intervals;
    std::string wrong_interval = ni_header + ni_rows;
    for (auto at = wrong_interval.find("0.0005,I"); at != std::string::npos; at = wrong_interval.find("0.0005,I"))
        wrong_interval.replace(at, 6, "0.0004");
    wrong_interval.replace(wrong_interval.find("Interval,0.0005\r"), 15, "Interval,0.0004");
    EXPECT_TRUE(contains(error_of(parse_ni_daq, wrong_interval), "Interval of 0.0004 s"));
}

TEST(NiDaq, BadFilesGiveOneMessageWithFileAndPlace) {
    EXPECT_TRUE(contains(error_of(parse_ni_daq, "\xEF\xBB\xBF"), "empty file"));
    std::string no_names = ni_header + ni_rows;
    no_names.erase(no_names.find("Channel name"), no_names.find("Unit") - no_names.find("Channel name"));
    EXPECT_TRUE(contains(error_of(parse_ni_daq, no_names), "no 'Channel name' row"));
    EXPECT_TRUE(contains(error_of(parse_ni_daq, ni_header), "no data rows"));
    const std::string truncated = ni_header + ni_rows.substr(0, ni_rows.size() - 8);
    EXPECT_TRUE(contains(error_of(parse_ni_daq, truncated), "fixture.csv:7: row has 3 cells"))
        << error_of(parse_ni_daq, truncated);
    std::string odd = ni_header;
    odd.replace(odd.find("Unit,\"V\",Unit"), 13, "Unit,\"V\",Unix");
    EXPECT_TRUE(contains(error_of(parse_ni_daq, odd + ni_rows), "fixture.csv:4: cell 3 is 'Unix'"));
    std::string junk = ni_header + ni_rows;
    junk.replace(junk.find("-0.25"), 5, "oops!");
    EXPECT_TRUE(contains(error_of(parse_ni_daq, junk), "fixture.csv:6: the value of channel 'Force' is 'oops!'"));
}

TEST(VendorReaders, DetectedFromContentWhateverTheExtension) {
    const auto dir = feedid::testing::temp_dir();
    feedid::testing::write_text(dir / "drive.txt", mr_header + mr_rows);
    feedid::testing::write_text(dir / "daq.dat", ni_header + ni_rows);
    EXPECT_EQ(detect_format(dir / "drive.txt"), "mr-configurator");
    EXPECT_EQ(detect_format(dir / "daq.dat"), "ni-daq");
    // a bad file through the CLI: exit 2 and one line naming the file
    feedid::testing::write_text(dir / "bad.csv", mr_header + "0,1,2\r\n");
    const auto result = run_cli("info '" + (dir / "bad.csv").string() + "'");
    EXPECT_EQ(result.exit_code, 2) << result.err;
    EXPECT_EQ(count_lines(result.err), 1) << result.err;
    EXPECT_TRUE(contains(result.err, (dir / "bad.csv").string() + ":6:")) << result.err;
}
