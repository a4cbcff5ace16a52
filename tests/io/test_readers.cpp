// The controller trace readers (issue 6): SINUMERIK servo trace XML, TwinCAT Scope CSV, LinuxCNC halscope/halsampler.
// Real files from ../shared/data are checked against facts published with them and against their raw text read
// independently here (pugixml for the XML); hand-made fixtures pin the sparse forward-fill rule and the error messages.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <pugixml.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/halscope.hpp"
#include "feedid/io/import.hpp"
#include "feedid/io/mat.hpp"
#include "feedid/io/mr_configurator.hpp"
#include "feedid/io/ni_daq.hpp"
#include "feedid/io/sinumerik_trace.hpp"
#include "feedid/io/twincat_scope.hpp"
#include "testing.hpp"

using namespace feedid;
namespace fs = std::filesystem;
using feedid::testing::count_lines;
using feedid::testing::run_cli;
using feedid::testing::shared_data;
using feedid::testing::temp_dir;
using feedid::testing::write_text;

namespace {

constexpr double nan_value = std::numeric_limits<double>::quiet_NaN();
const char* const sinumerik_file = "sinumerik-trace/X_BK300_1.xml";

std::string quoted(const fs::path& path) {
    return "'" + path.string() + "'";
}

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// Expects exit code 2 and exactly one line on stderr that names the file and the place (`where`).
void expect_one_clear_error(const fs::path& file, const std::string& arguments, const std::string& where) {
    const auto result = run_cli("info " + quoted(file) + arguments);
    EXPECT_EQ(result.exit_code, 2) << result.err << result.out;
    EXPECT_EQ(count_lines(result.err), 1) << result.err;
    EXPECT_TRUE(contains(result.err, file.string())) << result.err;
    EXPECT_TRUE(contains(result.err, where)) << "expected '" << where << "' in: " << result.err;
}

// ---- SINUMERIK fixtures ------------------------------------------------------------------------------------------

// A trace header with the given <dataSignal> lines, then the records.
std::string sinumerik_xml(const std::string& signals, const std::string& records, const std::string& display = {}) {
    return "<?xml version=\"1.0\" encoding=\"utf-8\" ?>\n"
           "<traceSession version=\"01.00.03.02\">\n" +
           display +
           "<traceData dataFrames=\"1\">\n"
           " <dataFrame>\n" +
           signals + records +
           " </dataFrame>\n"
           "</traceData>\n"
           "</traceSession>\n";
}

std::string data_signal(const std::string& id, const std::string& variable, const std::string& units_type,
                        const std::string& interval, const std::string& axis = "1") {
    return "  <dataSignal key=\"s" + id.substr(1) + "\" unitsType=\"" + units_type + "\" name=\"/Nck/!SD/" + variable +
           " [u1, " + axis + "]\" interval=\"" + interval + "\" id=\"" + id + "\"/>\n";
}

// A 2 ms position signal and a 4 ms signal starting 4 ms later; records are sparse (a value only when it changed).
//   time [ms]     0    2    4    6    8   10   12   14   16
//   f1 (2 ms)     1    2    .    .    3    .    .    4    .
//   f2 (4 ms)     .    .   10    .    .    .   20    .    .
const std::string sparse_records =
    "  <rec time=\"0.000000\" f1=\"1\"/>\n"
    "  <rec time=\"0.002000\" f1=\"2\"/>\n"
    "  <rec time=\"0.004000\" f2=\"10\"/>\n"
    "  <rec time=\"0.006000\"/>\n"
    "  <rec time=\"0.008000\" f1=\"3\"/>\n"
    "  <rec time=\"0.010000\"/>\n"
    "  <rec time=\"0.012000\" f2=\"20\"/>\n"
    "  <rec time=\"0.014000\" f1=\"4\"/>\n"
    "  <rec time=\"0.016000\"/>\n";

void expect_values(const std::vector<double>& actual, const std::vector<double>& expected, const std::string& what) {
    ASSERT_EQ(actual.size(), expected.size()) << what;
    for (std::size_t k = 0; k < expected.size(); ++k) {
        if (std::isnan(expected[k])) {
            EXPECT_TRUE(std::isnan(actual[k])) << what << "[" << k << "] = " << actual[k] << ", expected no value";
        } else {
            EXPECT_DOUBLE_EQ(actual[k], expected[k]) << what << "[" << k << "]";
        }
    }
}

}  // namespace

// ---- SINUMERIK: the real trace -------------------------------------------------------------------------------------

TEST(SinumerikTrace, InfoOnTheReferenceTraceGivesItsPublishedFacts) {
    FEEDID_REQUIRE_SHARED(sinumerik_file);
    const auto result = run_cli("info " + quoted(shared_data() / sinumerik_file) + " --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto info = nlohmann::json::parse(result.out);
    EXPECT_EQ(info["format"], "sinumerik-trace");
    EXPECT_EQ(info["samples"], 7199);
    EXPECT_NEAR(info["sample_time_s"].get<double>(), 0.002, 1e-12);
    EXPECT_NEAR(info["duration_s"].get<double>(), 14.4, 0.005);  // 7198 intervals of 2 ms = 14.396 s
    EXPECT_EQ(info["rotary"], false);

    // The ten signals, each with its role (or none) and its SI unit.
    struct Expected {
        std::string name, role, unit, source_unit;
    };
    const std::vector<Expected> expected = {
        {"time", "time", "s", "s"},
        {"nckServoDataCmdPos2ndEnc64", "reference_position", "m", "mm"},
        {"nckServoDataActPos1stEnc64", "motor_position", "m", "mm"},  // the motor encoder beside the scale
        {"nckServoDataActPos2ndEnc64", "position", "m", "mm"},
        {"nckServoDataCmdVelCtrlIn64", "velocity_command", "m/s", "mm/min"},
        {"nckServoDataActVel1stEnc64", "other", "m/s", "mm/min"},
        {"nckServoDataActVel2ndEnc64", "velocity", "m/s", "mm/min"},
        {"nckServoDataCtrlDev64", "other", "m", "mm"},
        {"nckServoDataDrvLoad64", "other", "", "%"},  // a percentage of a rating the trace does not hold
        {"nckServoDataActCurr64", "current", "A", "A"},
        {"nckServoDataCmdTorque64", "other", "N*m", "N*m"},  // unitsType "611DTime1"; the display setup says torque
    };
    const auto& channels = info["channels"];
    ASSERT_EQ(channels.size(), expected.size()) << channels.dump(1);
    for (std::size_t k = 0; k < expected.size(); ++k) {
        SCOPED_TRACE(expected[k].name);
        EXPECT_EQ(channels[k]["name"], expected[k].name);
        EXPECT_EQ(channels[k]["role"], expected[k].role);
        EXPECT_EQ(channels[k]["unit"], expected[k].unit);
        EXPECT_EQ(channels[k]["source_unit"], expected[k].source_unit);
    }
    // Actual position from the direct measuring system (linear scale): about -300 mm, 60 steps of 1 um.
    const auto& position = channels[3];
    EXPECT_GT(position["min"].get<double>(), -0.30005);
    EXPECT_LT(position["max"].get<double>(), -0.29995);
    // iq between -2.51 and 1.97 A (and reaching both ends: the range is the file's, not a clipped one).
    const auto& current = channels[9];
    EXPECT_GE(current["min"].get<double>(), -2.51);
    EXPECT_LT(current["min"].get<double>(), -2.50);
    EXPECT_LE(current["max"].get<double>(), 1.97);
    EXPECT_GT(current["max"].get<double>(), 1.96);
    // The role guesses are said, with the option that sets them, naming the channel (it works pasted as printed).
    const std::string findings = info["findings"].dump();
    EXPECT_TRUE(contains(findings, "taken as position")) << findings;
    EXPECT_TRUE(contains(findings, "--channel position=nckServoDataActPos2ndEnc64")) << findings;
    EXPECT_FALSE(contains(findings, "=NAME")) << findings;
}

TEST(SinumerikTrace, TheSetupsCyclesAreTheTracesConstants) {
    // <sampleRateSettings driveSampleRate1="0.00012500" servoSampleRate="0.002" .../>: the drive's 125 us cycle is
    // the servo cycle `gains` fits the velocity loop at, the NC's 2 ms one the position loop's.
    FEEDID_REQUIRE_SHARED(sinumerik_file);
    const auto result = run_cli("info " + quoted(shared_data() / sinumerik_file) + " --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto info = nlohmann::json::parse(result.out);
    ASSERT_TRUE(info["constants"].contains("servo_cycle_s")) << info["constants"].dump();
    EXPECT_DOUBLE_EQ(info["constants"]["servo_cycle_s"].get<double>(), 125e-6);
    EXPECT_DOUBLE_EQ(info["constants"]["position_cycle_s"].get<double>(), 0.002);
}

TEST(SinumerikTrace, ValuesMatchTheRawXmlReadIndependently) {
    FEEDID_REQUIRE_SHARED(sinumerik_file);
    const auto path = shared_data() / sinumerik_file;
    const Trace trace = read_trace(path);

    // The raw file, read here with pugixml: dataSignal id -> (name, unitsType), then each <rec>'s attributes, held
    // from the last record that wrote them (every signal of this trace runs at the 2 ms of the records).
    pugi::xml_document document;
    ASSERT_TRUE(document.load_file(path.c_str()));
    const auto frame = document.child("traceSession").child("traceData").child("dataFrame");
    std::map<std::string, std::string> name_of;  // "f3" -> "nckServoDataActPos2ndEnc64"
    std::map<std::string, double> to_si;         // "f3" -> 1e-3 (posn in mm)
    for (const auto& signal : frame.children("dataSignal")) {
        std::string name = signal.attribute("name").value();  // "/Nck/!SD/nckServoDataActPos2ndEnc64 [u1, 1]"
        name = name.substr(name.rfind('/') + 1);
        name = name.substr(0, name.find(' '));
        const std::string id = signal.attribute("id").value();
        const std::string type = signal.attribute("unitsType").value();
        name_of[id] = name;
        to_si[id] = type == "posn" ? 1e-3 : type == "velo" ? 1e-3 / 60.0 : 1.0;
    }
    ASSERT_EQ(name_of.size(), 10u);
    std::vector<double> times;
    std::map<std::string, std::vector<double>> raw;
    std::map<std::string, double> held;
    for (const auto& [id, name] : name_of) held[id] = nan_value;
    for (const auto& rec : frame.children("rec")) {
        times.push_back(rec.attribute("time").as_double());
        for (auto attribute = rec.first_attribute(); attribute; attribute = attribute.next_attribute()) {
            if (std::string(attribute.name()) != "time") held[attribute.name()] = attribute.as_double();
        }
        for (const auto& [id, value] : held) raw[id].push_back(value);
    }
    ASSERT_EQ(times.size(), 7199u);
    ASSERT_EQ(trace.samples(), 7199u);

    const auto time = trace.column(Role::time);
    for (std::size_t k = 0; k < times.size(); ++k) ASSERT_NEAR(time[k], times[k], 1e-9) << "time[" << k << "]";
    // Spot checks written out: the first record, one in the middle, the last (values copied from the file).
    const auto* position = trace.find("nckServoDataActPos2ndEnc64");
    const auto* current = trace.find("nckServoDataActCurr64");
    ASSERT_NE(position, nullptr);
    ASSERT_NE(current, nullptr);
    EXPECT_NEAR(position->values.front(), -299.999996e-3, 1e-12);
    EXPECT_NEAR(current->values.front(), -0.737915, 1e-12);
    EXPECT_NEAR(position->values.back(), -299.999996e-3, 1e-12);
    EXPECT_NEAR(current->values.back(), 0.599854, 1e-12);
    EXPECT_NEAR(current->values[1], -1.114014, 1e-12);
    // Every value of every channel against the independent reading, in SI.
    for (const auto& [id, name] : name_of) {
        const auto* channel = trace.find(name);
        ASSERT_NE(channel, nullptr) << name;
        const auto& expected = raw[id];
        const double scale = channel->unit.empty() ? 1.0 : to_si[id];  // % stays as it is
        std::size_t checked = 0;
        for (std::size_t k = 0; k < expected.size(); ++k) {
            ASSERT_FALSE(std::isnan(expected[k])) << name << " has no value at record " << k;
            ASSERT_NEAR(channel->values[k], expected[k] * scale, 1e-12 * std::max(1.0, std::abs(expected[k])))
                << name << "[" << k << "]";
            ++checked;
        }
        EXPECT_EQ(checked, 7199u);
    }
}

TEST(SinumerikTrace, IdentifyOnTheMicroStepTestSaysItCarriesNoMassInformation) {
    FEEDID_REQUIRE_SHARED(sinumerik_file);
    // Channels mapped automatically (no --channel). The trace does not hold the motor's torque constant, so a drive
    // constant must be stated; whether mass is identifiable does not depend on its value, and two very different
    // ones give the same verdict.
    for (const std::string constant : {"1", "250"}) {
        const auto result =
            run_cli("identify " + quoted(shared_data() / sinumerik_file) + " --force-constant " + constant);
        EXPECT_EQ(result.exit_code, 1) << result.err << result.out;
        EXPECT_TRUE(contains(result.err, "no usable mass information")) << result.err;
        EXPECT_TRUE(contains(result.err, "micro-step")) << result.err;
        EXPECT_TRUE(contains(result.err, "taken as position")) << result.err;  // the automatic mapping, said
    }
}

// ---- SINUMERIK: the sparse forward-fill rule ------------------------------------------------------------------------

TEST(SinumerikTrace, SparseSignalsOnTwoIntervalsAreForwardFilledOnTheFinestBase) {
    const std::string xml = sinumerik_xml(data_signal("f1", "nckServoDataActPos2ndEnc64", "posn", "0.002") +
                                              data_signal("f2", "nckServoDataDrvLoad64", "percent", "0.004"),
                                          sparse_records);
    const Trace trace = parse_sinumerik_trace(xml, "sparse.xml");
    ASSERT_EQ(trace.channels.size(), 3u);
    expect_values(trace.channels[0].values, {0.000, 0.002, 0.004, 0.006, 0.008, 0.010, 0.012, 0.014, 0.016}, "time");
    // f1 holds its last written value on its own 2 ms grid.
    expect_values(trace.channels[1].values, {1, 2, 2, 2, 3, 3, 3, 4, 4}, "f1");
    // f2 has no value before its first sample (nothing invented), then holds on its 4 ms grid: its cell from 4 ms
    // covers the 6 ms fine sample, its cell from 12 ms the 14 and 16 ms ones.
    expect_values(trace.channels[2].values, {nan_value, nan_value, 10, 10, 10, 10, 20, 20, 20}, "f2");
    EXPECT_EQ(trace.channels[1].source_unit, "mm");
    EXPECT_EQ(trace.channels[2].source_unit, "%");
}

TEST(SinumerikTrace, RecordsReadTheSameWithCommentsAndEntitiesAmongThem) {
    // Plain records are scanned directly; a comment among them, an entity in a value or single quotes send the
    // file through pugixml's DOM instead. Both must give the same trace.
    const std::string signals = data_signal("f1", "nckServoDataActPos2ndEnc64", "posn", "0.002") +
                                data_signal("f2", "nckServoDataDrvLoad64", "percent", "0.004");
    const Trace plain = parse_sinumerik_trace(sinumerik_xml(signals, sparse_records), "plain.xml");
    std::string commented = sparse_records;
    commented.insert(commented.find("  <rec time=\"0.008"), "  <!-- a note among the records -->\n");
    std::string entity = sparse_records;
    entity.replace(entity.find("f2=\"20\""), 7, "f2='&#50;0'");
    for (const auto& records : {commented, entity}) {
        const Trace other = parse_sinumerik_trace(sinumerik_xml(signals, records), "other.xml");
        ASSERT_EQ(other.channels.size(), plain.channels.size());
        for (std::size_t c = 0; c < plain.channels.size(); ++c) {
            expect_values(other.channels[c].values, plain.channels[c].values, plain.channels[c].name);
        }
    }
}

TEST(SinumerikTrace, TraceStartsWhereEveryRoleChannelHasAValue) {
    // The 4 ms signal is now the iq current (a role): the two fine samples before its first value are dropped.
    const std::string xml = sinumerik_xml(data_signal("f1", "nckServoDataActPos2ndEnc64", "posn", "0.002") +
                                              data_signal("f2", "nckServoDataActCurr64", "current", "0.004"),
                                          sparse_records);
    const Trace trace = parse_sinumerik_trace(xml, "sparse.xml");
    expect_values(trace.channels[0].values, {0.004, 0.006, 0.008, 0.010, 0.012, 0.014, 0.016}, "time");
    expect_values(trace.channels[1].values, {2, 2, 3, 3, 3, 4, 4}, "position");
    expect_values(trace.channels[2].values, {10, 10, 10, 10, 20, 20, 20}, "current");
    EXPECT_EQ(trace.channels[1].role, Role::position);
    EXPECT_EQ(trace.channels[2].role, Role::current);
    const bool said = std::any_of(trace.findings.begin(), trace.findings.end(),
                                  [](const std::string& f) { return contains(f, "first 2 samples were dropped"); });
    EXPECT_TRUE(said);
}

TEST(SinumerikTrace, OneTracePerAxisSelectableByIndex) {
    const std::string xml = sinumerik_xml(data_signal("f1", "nckServoDataActPos2ndEnc64", "posn", "0.002", "1") +
                                              data_signal("f2", "nckServoDataActPos2ndEnc64", "posn", "0.002", "2"),
                                          "  <rec time=\"0\" f1=\"5\" f2=\"7\"/>\n  <rec time=\"0.002\" f1=\"6\"/>\n"
                                          "  <rec time=\"0.004\" f2=\"8\"/>\n");
    const auto axes = parse_sinumerik_trace_axes(xml, "two-axes.xml");
    ASSERT_EQ(axes.size(), 2u);
    expect_values(axes[0].find(Role::position)->values, {5, 6, 6}, "axis 1");
    expect_values(axes[1].find(Role::position)->values, {7, 7, 8}, "axis 2");
    const Trace second = parse_sinumerik_trace(xml, "two-axes.xml", "2");
    expect_values(second.find(Role::position)->values, {7, 7, 8}, "--axis 2");
    EXPECT_THROW((void)parse_sinumerik_trace(xml, "two-axes.xml", "3"), InputError);
}

TEST(SinumerikTrace, UnitFromTheDisplaySetupWhenTheSignalsOwnIsNone) {
    // The non-V20 display setup; the dataSignal's unitsType is not a unit (as the real file's torque setpoint).
    const std::string display =
        "<traceDisplaySetup>\n <signals>\n"
        "  <signal key=\"s2\" unitsType=\"torque\" description=\"Torque setpoint\"/>\n"
        " </signals>\n</traceDisplaySetup>\n";
    const std::string xml = sinumerik_xml(data_signal("f1", "nckServoDataActPos2ndEnc64", "posn", "0.002") +
                                              data_signal("f2", "nckServoDataCmdTorque64", "611DTime1", "0.002"),
                                          "  <rec time=\"0\" f1=\"1\" f2=\"2\"/>\n", display);
    const Trace trace = parse_sinumerik_trace(xml, "display.xml");
    EXPECT_EQ(trace.find("nckServoDataCmdTorque64")->source_unit, "N*m");
}

// ---- SINUMERIK: bad input
// --------------------------------------------------------------------------------------------

TEST(SinumerikTrace, BadFilesGiveOneMessageWithFileAndPlace) {
    const auto dir = temp_dir();
    const std::string signals = data_signal("f1", "nckServoDataActPos2ndEnc64", "posn", "0.002");
    const std::string good = sinumerik_xml(signals, sparse_records);

    auto write = [&](const std::string& name, const std::string& text) {
        write_text(dir / name, text);
        return dir / name;
    };
    // Truncated in the middle of the records.
    expect_one_clear_error(write("truncated.xml", good.substr(0, good.find("time=\"0.008"))), "", "line ");
    // A well-formed document whose root is not <traceSession>.
    expect_one_clear_error(write("root.xml",
                                 "<?xml version=\"1.0\"?>\n<traceSessions>\n<traceSession/>\n"
                                 "</traceSessions>\n"),
                           "", "line 2");
    // A sample that is not a number.
    std::string text = good;
    text.replace(text.find("f1=\"3\""), 6, "f1=\"3x\"");
    expect_one_clear_error(write("nan.xml", text), "", "line 10");
    // A dataSignal without its interval.
    text = good;
    text.replace(text.find(" interval=\"0.002\""), 17, "");
    expect_one_clear_error(write("interval.xml", text), "", "line 5");
    // Records going back in time.
    text = good;
    text.replace(text.find("time=\"0.010000\""), 15, "time=\"0.001000\"");
    expect_one_clear_error(write("back.xml", text), "", "line 11");
    // Empty file.
    expect_one_clear_error(write("empty.xml", ""), "", "empty");
    // Only a declaration, no records.
    expect_one_clear_error(write("norecords.xml", sinumerik_xml(signals, "")), "", "line 4");
}

TEST(SinumerikTrace, HostileIntervalCannotMakeItAllocateWithoutBound) {
    // Two records 1e6 s apart at a 1 ns interval would be 1e15 samples: refused, not attempted.
    const std::string xml = sinumerik_xml(data_signal("f1", "nckServoDataActPos2ndEnc64", "posn", "1e-9"),
                                          "  <rec time=\"0\" f1=\"1\"/>\n  <rec time=\"1e6\" f1=\"2\"/>\n");
    EXPECT_THROW((void)parse_sinumerik_trace(xml, "hostile.xml"), InputError);
}

// ---- TwinCAT Scope
// ---------------------------------------------------------------------------------------------------

namespace {
struct ScopeExport {
    std::string file;
    bool raw_values;  // exported with ScaleValues off (the export does not say so: see the test)
};
const std::vector<ScopeExport> scope_exports = {
    {"tc3_scope_3_4_3145_3-ContainEOF_true.csv", false},
    {"tc3_scope_3_4_3145_3-DecimalMark_,.csv", false},
    {"tc3_scope_3_4_3145_3-ExcludeDoubleTimestamp_false-SortChannels_false.csv", false},
    {"tc3_scope_3_4_3145_3-ExcludeDoubleTimestamp_false-SortChannels_true.csv", false},
    {"tc3_scope_3_4_3145_3-ExcludeDoubleTimestamp_true-SortChannels_false.csv", false},
    {"tc3_scope_3_4_3145_3-Seperator_1.csv", false},
    {"tc3_scope_3_4_3145_3-Seperator_2.csv", false},
    {"tc3_scope_3_4_3145_3-Seperator_3.csv", false},
    {"tc3_scope_3_4_3145_3-Seperator_4.csv", false},
    {"tc3_scope_3_4_3145_3-default.csv", true},
    {"tc3_scope_3_4_3145_3_noOS.csv", false},
};
}  // namespace

TEST(TwinCatScope, EveryExportVariantImportsToTheSameChannelValues) {
    FEEDID_REQUIRE_SHARED("twincat-scope/tc3_scope_3_4_3145_3-ContainEOF_true.csv");
    const auto folder = shared_data() / "twincat-scope";
    // The reference: tab separated, decimal point, channels sorted, one time column per sample time.
    const Trace reference = read_trace(folder / scope_exports[0].file);
    const auto reference_time = reference.column(Role::time);
    ASSERT_EQ(reference.channels.size(), 22u);  // time + 21 channels
    // Every export lists each time stamp with at most 4 significant digits and integer-valued samples or tenths:
    // values agree exactly; times to a float's rounding.
    const double time_tolerance = 1e-9;

    // The default export was written with ScaleValues off: its values are the raw ones, and its header still lists
    // the channel scalings (identical to the scaled exports' header, so the file cannot tell). Applying them to the
    // raw values must give the scaled exports' values: that checks both.
    const std::map<std::string, std::pair<double, double>> header_scaling = {
        {"func_scaled", {-1.0, 1.0}}, {"func_scaled_int", {-1.0, 1.0}}, {"func_units_scaled", {-10.0, 10.0}}};

    for (const auto& variant : scope_exports) {
        SCOPED_TRACE(variant.file);
        const Trace trace = read_trace(folder / variant.file);
        EXPECT_EQ(trace.format, "twincat-scope");
        EXPECT_EQ(detect_format(folder / variant.file), "twincat-scope");
        const auto time = trace.column(Role::time);
        std::size_t compared_channels = 0;
        for (const auto& channel : trace.channels) {
            if (channel.role == Role::time) continue;
            const auto* expected = reference.find(channel.name);
            ASSERT_NE(expected, nullptr) << "channel '" << channel.name << "' is not in the reference export";
            EXPECT_EQ(channel.unit, expected->unit) << channel.name;
            const auto scaling = header_scaling.find(channel.name);
            const bool apply = variant.raw_values && scaling != header_scaling.end();
            // Walk both time bases together, comparing at the shared time stamps.
            std::size_t r = 0;
            std::size_t shared = 0;
            for (std::size_t k = 0; k < time.size(); ++k) {
                while (r < reference_time.size() && reference_time[r] < time[k] - time_tolerance) ++r;
                if (r == reference_time.size()) break;
                if (std::abs(reference_time[r] - time[k]) > time_tolerance) continue;
                const double value =
                    apply ? scaling->second.first * channel.values[k] + scaling->second.second : channel.values[k];
                ASSERT_EQ(value, expected->values[r]) << channel.name << " at " << time[k] << " s";
                ++shared;
            }
            EXPECT_GE(shared, 997u) << channel.name;  // the whole second, at 1 ms at least
            ++compared_channels;
        }
        EXPECT_GE(compared_channels, 19u);  // the export without oversampling lacks func_OS and func_freesample
    }
}

TEST(TwinCatScope, ChannelsOfDifferentSampleTimesShareTheFinestBase) {
    FEEDID_REQUIRE_SHARED("twincat-scope/tc3_scope_3_4_3145_3-ContainEOF_true.csv");
    const Trace trace = read_trace(shared_data() / "twincat-scope/tc3_scope_3_4_3145_3-ContainEOF_true.csv");
    // func_OS at 0.2 ms, the others at 1 ms and func_freesample at 5 ms; common span 0..997 ms.
    EXPECT_EQ(trace.samples(), 4986u);
    EXPECT_NEAR(trace.time_base().sample_time_s, 0.2e-3, 1e-12);
    const auto* oversampled = trace.find("func_OS");
    const auto* slow = trace.find("func_freesample");
    ASSERT_NE(oversampled, nullptr);
    ASSERT_NE(slow, nullptr);
    // At 0.6 ms: the 0.2 ms channel has its own sample (0.6), a 1 ms channel holds its 0 ms one, and the 5 ms
    // channel (time stamps -3, 2, 7, ... ms) holds its -3 ms sample, 997.
    EXPECT_DOUBLE_EQ(oversampled->values[3], 0.6);
    EXPECT_DOUBLE_EQ(trace.find("var_REAL64")->values[3], 0.0);
    EXPECT_DOUBLE_EQ(slow->values[3], 997.0);
    EXPECT_DOUBLE_EQ(slow->values[10], 2.0);  // 2.0 ms: its 2 ms sample
    EXPECT_EQ(trace.find("func_units_unscaled")->unit, "V");
}

TEST(TwinCatScope, BadFilesGiveOneMessageWithFileAndLine) {
    FEEDID_REQUIRE_SHARED("twincat-scope/tc3_scope_3_4_3145_3-Seperator_3.csv");
    const auto dir = temp_dir();
    const std::string good =
        feedid::testing::read_text(shared_data() / "twincat-scope/tc3_scope_3_4_3145_3-Seperator_3.csv");
    auto write = [&](const std::string& name, const std::string& text) {
        write_text(dir / name, text);
        return dir / name;
    };
    // Truncated inside the channel header block: no data rows.
    expect_one_clear_error(write("truncated.csv", good.substr(0, good.find("ScaleFactor;"))), "", "no samples");
    // Truncated inside the Data-Type row (line 7): its columns no longer match the Name row.
    expect_one_clear_error(write("header.csv", good.substr(0, good.find("Data-Type;") + 20)), "", "line 7");
    // Not a Scope export (forced): the first line is not "Name<separator>".
    expect_one_clear_error(write("root.csv", "Title;x\n" + good), " --format twincat-scope", "line 1");
    // A value that is not a number, in the third data row (line 27).
    std::string text = good;
    const auto row = text.find("\n0.4;");
    const auto cell = text.find(';', row + 6);
    text.replace(cell + 1, 1, "x");
    expect_one_clear_error(write("nan.csv", text), "", "line 27");
    // A data row with more cells than the header has columns.
    text = good;
    text.insert(text.find('\n', row + 1), ";1;2;3");
    expect_one_clear_error(write("wide.csv", text), "", "line 27");
    // Empty file.
    expect_one_clear_error(write("empty.csv", ""), " --format twincat-scope", "empty");
}

// ---- halscope / halsampler ---------------------------------------------------------------------------------------

TEST(Halscope, NewLayoutReadsChannelsAndPeriod) {
    const std::string text =
        "# Sampling period is 1000000 ns\n"
        "joint.0.pos-cmd;joint.0.motor-pos-fb;joint.0.vel-cmd\n"
        "# Position: 0;0;0\n"
        "0.000000;0.000000;0.000000\n"
        "0.001000;0.000900;1.000000\n"
        "0.002000;0.001900;1.000000\n";
    Trace trace = parse_halscope(text, "scope.txt");
    ASSERT_EQ(trace.channels.size(), 4u);
    expect_values(trace.channels[0].values, {0.0, 0.001, 0.002}, "time");
    EXPECT_EQ(trace.find(Role::position)->name, "joint.0.motor-pos-fb");
    EXPECT_EQ(trace.find(Role::reference_position)->name, "joint.0.pos-cmd");
    expect_values(trace.find(Role::position)->values, {0.0, 0.0009, 0.0019}, "pos-fb");
}

TEST(Halscope, OldLayoutDropsTheSamplePastTheCapture) {
    const std::string text =
        "Sampling period is 500000 ns\n"
        "joint.0.pos-fb +1.00000000000000 joint.0.pos-cmd +1.00000000000000\n"
        "joint.0.pos-fb +2.00000000000000 joint.0.pos-cmd +2.50000000000000\n"
        "joint.0.pos-fb +3.00000000000000 joint.0.pos-cmd +3.00000000000000\n";
    const Trace trace = parse_halscope(text, "old.txt");
    expect_values(trace.channels[0].values, {0.0, 0.0005}, "time");
    expect_values(trace.find(Role::position)->values, {1, 2}, "pos-fb");
    expect_values(trace.find(Role::reference_position)->values, {1, 2.5}, "pos-cmd");
}

TEST(Halscope, HalsamplerNeedsTheSampleTimeAndFollowsSampleNumbers) {
    const std::string text = "0 1.5 -2\n1 1.6 -2\noverrun\n4 1.9 -1\n";
    EXPECT_THROW((void)parse_halscope(text, "sampler.txt"), InputError);
    const Trace trace = parse_halscope(text, "sampler.txt", 0.001);
    expect_values(trace.channels[0].values, {0.0, 0.001, 0.004}, "time");
    expect_values(trace.find("pin.0")->values, {1.5, 1.6, 1.9}, "pin.0");
    EXPECT_TRUE(looks_like_halsampler(text));
}

TEST(Halscope, BadFilesGiveOneMessageWithFileAndLine) {
    const auto dir = temp_dir();
    auto write = [&](const std::string& name, const std::string& text) {
        write_text(dir / name, text);
        return dir / name;
    };
    const std::string header = "# Sampling period is 1000000 ns\nx;y\n";
    // Truncated in the middle of a row.
    expect_one_clear_error(write("truncated.txt", header + "1;2\n3;4\n5"), "", "line 5");
    // Not a halscope file (forced).
    expect_one_clear_error(write("root.txt", "time,x\n0,1\n"), " --format halscope", "line 1");
    // A value that is not a number.
    expect_one_clear_error(write("nan.txt", header + "1;2\n3;four\n"), "", "line 4");
    // The period stated without a number of ns.
    expect_one_clear_error(write("period.txt", "# Sampling period is ns\nx;y\n1;2\n"), "", "line 1");
    // Old layout with a name whose value is missing.
    expect_one_clear_error(write("pairs.txt", "Sampling period is 1000 ns\nx +1 y\n"), "", "line 2");
    // Header only.
    expect_one_clear_error(write("header.txt", header), "", "no data rows");
    // Empty file.
    expect_one_clear_error(write("empty.txt", ""), " --format halscope", "empty");
}

// ---- Regression inputs found by the fuzzers ------------------------------------------------------------------------

TEST(ReaderFuzzRegressions, EveryKeptInputIsReadOrRefusedWithAnInputError) {
    // tests/fuzz/regressions/<reader>/<input>: inputs that once crashed, hung or tripped a sanitizer.
    // The inputs are kept in the repository: none found means a moved folder or a broken checkout, not a pass.
    const fs::path root = fs::path(FEEDID_TEST_SOURCE_DIR) / "fuzz" / "regressions";
    ASSERT_TRUE(fs::is_directory(root)) << "no regression inputs: " << root << " is not a folder";
    std::size_t inputs = 0;
    for (const auto& entry : fs::recursive_directory_iterator(root)) {
        if (!entry.is_regular_file()) continue;
        const std::string reader = entry.path().parent_path().filename().string();
        const std::string bytes = feedid::testing::read_text(entry.path());
        SCOPED_TRACE(entry.path().string());
        try {
            // each as its fuzz target (fuzz/fuzz_<reader>.cpp) calls the reader
            if (reader == "sinumerik_trace")
                (void)parse_sinumerik_trace_axes(bytes, "fuzz.xml");
            else if (reader == "twincat_scope")
                (void)parse_twincat_scope(bytes, "fuzz.csv");
            else if (reader == "halscope")
                (void)parse_halscope(bytes, "fuzz.txt", 0.001);
            else if (reader == "mr_configurator")
                (void)parse_mr_configurator(bytes, "fuzz.csv");
            else if (reader == "ni_daq")
                (void)parse_ni_daq(bytes, "fuzz.csv");
            else if (reader == "csv")
                (void)parse_csv(bytes, "fuzz.csv");
            else if (reader == "mat")
                (void)read_mat(entry.path());  // libmatio reads files only
            else {
                ADD_FAILURE() << "regression input for an unknown reader '" << reader << "'";
                continue;
            }
        } catch (const InputError&) {}
        ++inputs;
    }
    EXPECT_GT(inputs, 0U) << "no regression inputs found in " << root;
}
