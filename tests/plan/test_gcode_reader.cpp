// The G-code reader against LinuxCNC's own interpreter (`rs274 -g FILE`, Debian's linuxcnc-uspace; skipped when
// absent): for each part program of examples/programs/, the canonical STRAIGHT_TRAVERSE / STRAIGHT_FEED / ARC_FEED /
// DWELL commands match the reader's blocks move for move (end points, arc centres and turning sense, feed rates,
// dwell times); and the reader's own rules on small programs.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "feedid/core/error.hpp"
#include "feedid/plan/gcode_reader.hpp"
#include "testing.hpp"

namespace {

const std::filesystem::path programs = std::filesystem::path(FEEDID_TEST_SOURCE_DIR) / ".." / "examples" / "programs";

struct Canonical {
    feedid::BlockKind kind;
    std::vector<double> values;  // as printed [mm, mm/min, s]
    double feed_mm_per_min;
    std::string line;
    double tolerance_mm{0.0};  // half the last printed digit
};

std::vector<double> numbers(const std::string& list) {
    std::vector<double> out;
    std::stringstream stream(list);
    std::string value;
    while (std::getline(stream, value, ',')) out.push_back(std::stod(value));
    return out;
}

// rs274 prints 4 decimals (of a millimetre, or of an inch after G20).
constexpr double printed = 5.1e-5;

// The canonical motion commands rs274 prints for a program (run in a folder of its own).
std::vector<Canonical> canonical_moves(const std::filesystem::path& rs274, const std::filesystem::path& program) {
    const auto dir = feedid::testing::temp_dir() / "rs274";
    std::filesystem::create_directories(dir);
    const int status = feedid::testing::run_rs274(rs274, program, dir);
    const auto out = feedid::testing::read_text(dir / "out.txt");
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "rs274 failed on " << program << ":\n"
                                                               << feedid::testing::read_text(dir / "err.txt") << out;
    const std::regex command_pattern(R"((STRAIGHT_TRAVERSE|STRAIGHT_FEED|ARC_FEED|DWELL|SET_FEED_RATE)\(([^)]*)\))");
    std::vector<Canonical> canonical;
    double feed = 0.0;
    double mm_per_unit = 1.0;  // rs274 prints in the program's units (inch after G20)
    std::istringstream lines(out);
    std::string line;
    std::smatch match;
    while (std::getline(lines, line)) {
        if (line.find("USE_LENGTH_UNITS(CANON_UNITS_INCHES)") != std::string::npos) mm_per_unit = 25.4;
        if (line.find("USE_LENGTH_UNITS(CANON_UNITS_MM)") != std::string::npos) mm_per_unit = 1.0;
        if (!std::regex_search(line, match, command_pattern)) continue;
        const std::string name = match[1];
        auto values = numbers(match[2]);
        if (name != "DWELL") {
            for (std::size_t k = 0; k < values.size(); ++k) {
                if (!(name == "ARC_FEED" && k == 4)) values[k] *= mm_per_unit;  // not the arc's turns
            }
        }
        if (name == "SET_FEED_RATE") {
            feed = values.at(0) / mm_per_unit;  // in the units in effect when the block moves
        } else if (name == "DWELL") {
            canonical.push_back({feedid::BlockKind::dwell, values, 0.0, line, 0.0});
        } else if (name == "ARC_FEED") {
            // ARC_FEED(first_end, second_end, first_axis, second_axis, rotation, axis_end_point, a, b, c)
            const auto kind = values.at(4) > 0 ? feedid::BlockKind::arc_ccw : feedid::BlockKind::arc_cw;
            canonical.push_back({kind, values, feed * mm_per_unit, line, printed * mm_per_unit});
        } else {
            canonical.push_back({name == "STRAIGHT_TRAVERSE" ? feedid::BlockKind::rapid : feedid::BlockKind::linear,
                                 values, feed * mm_per_unit, line, printed * mm_per_unit});
        }
    }
    return canonical;
}

void expect_same_moves(const std::filesystem::path& program) {
    const auto rs274 = feedid::testing::find_rs274();
    if (rs274.empty())
        GTEST_SKIP() << "LinuxCNC's rs274 interpreter not found (install Debian's linuxcnc-uspace: scripts/setup.sh "
                        "--extra); the comparison is skipped";
    const auto canonical = canonical_moves(rs274, program);
    const auto read = feedid::read_gcode_file(program);
    ASSERT_EQ(read.blocks.size(), canonical.size()) << program;
    for (std::size_t k = 0; k < canonical.size(); ++k) {
        const auto& c = canonical[k];
        const auto& b = read.blocks[k];
        const std::string where = program.filename().string() + ":" + std::to_string(b.line) + " vs " + c.line;
        ASSERT_EQ(b.kind, c.kind) << where;
        if (c.kind == feedid::BlockKind::dwell) {
            EXPECT_NEAR(b.dwell_s, c.values[0], 5e-5) << where;
            continue;
        }
        if (c.kind == feedid::BlockKind::arc_cw || c.kind == feedid::BlockKind::arc_ccw) {
            EXPECT_EQ(std::abs(c.values[4]), 1.0) << "one turn or less: " << where;
            EXPECT_NEAR(b.end[0] * 1e3, c.values[0], c.tolerance_mm) << where;
            EXPECT_NEAR(b.end[1] * 1e3, c.values[1], c.tolerance_mm) << where;
            EXPECT_NEAR(b.center[0] * 1e3, c.values[2], c.tolerance_mm) << where;
            EXPECT_NEAR(b.center[1] * 1e3, c.values[3], c.tolerance_mm) << where;
            EXPECT_NEAR(b.end[2] * 1e3, c.values[5], c.tolerance_mm) << where;
        } else {
            for (std::size_t axis = 0; axis < 3; ++axis) {
                EXPECT_NEAR(b.end[axis] * 1e3, c.values[axis], c.tolerance_mm) << where;
            }
        }
        if (c.kind != feedid::BlockKind::rapid) {
            EXPECT_NEAR(b.feed_m_per_s * 60000.0, c.feed_mm_per_min, 5e-4 * 25.4) << where;
        }
    }
}

TEST(GcodeReader, PocketMatchesLinuxCncMoveForMove) {
    expect_same_moves(programs / "pocket.ngc");
}
TEST(GcodeReader, ContourMatchesLinuxCncMoveForMove) {
    expect_same_moves(programs / "contour.ngc");
}
TEST(GcodeReader, DrillingMatchesLinuxCncMoveForMove) {
    expect_same_moves(programs / "drilling.ngc");
}

// The features the programs do not all use, against rs274 too: inches, incremental moves, a helix, modal motion.
TEST(GcodeReader, InchesIncrementalAndHelixMatchLinuxCnc) {
    const auto program = feedid::testing::suite_dir("gcode_reader") / "features.ngc";
    feedid::testing::write_text(program,
                                "%\n(features)\nN10 G17 G21 G90 G94 ; setup\nS1000 M3\nG0 X10 Y10 Z5\nG1 Z-1 "
                                "F200\nG2 X20 Y10 I5 J0 F500\nG3 X10 Y10 I-5 Z-2\nG91 G1 X5\nY-3\nG90 G4 P0.5\nG20 G1 "
                                "X1 F10\nG21 G0 Z3\nM5\nM2\n%\n");
    expect_same_moves(program);
}

TEST(GcodeReader, BlocksInSiWithSpindleAndLine) {
    const auto program = feedid::read_gcode(
        "%\nG21 G90\nS8000 M3\nG0 X10 Y0 Z1\nG1 Z-2 F120\nG2 X0 Y10 I-10 J0 "
        "F600\nM5\nG0 Z5\nM30\n%\n",
        "p.ngc");
    ASSERT_EQ(program.blocks.size(), 4u);
    const auto& plunge = program.blocks[1];
    EXPECT_EQ(plunge.kind, feedid::BlockKind::linear);
    EXPECT_NEAR(plunge.feed_m_per_s, 0.002, 1e-15);
    EXPECT_NEAR(plunge.end[2], -0.002, 1e-15);
    EXPECT_TRUE(plunge.spindle_on);
    EXPECT_EQ(plunge.spindle_rpm, 8000.0);
    EXPECT_EQ(plunge.line, 5);
    const auto& arc = program.blocks[2];
    EXPECT_EQ(arc.kind, feedid::BlockKind::arc_cw);
    EXPECT_NEAR(arc.center[0], 0.0, 1e-15);
    EXPECT_NEAR(arc.center[1], 0.0, 1e-15);
    EXPECT_FALSE(program.blocks[3].spindle_on);
}

void expect_input_error(const std::string& text, const std::string& wanted) {
    try {
        (void)feedid::read_gcode(text, "bad.ngc");
        ADD_FAILURE() << "no error for:\n" << text;
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find(wanted), std::string::npos) << e.what();
    }
}

TEST(GcodeReader, UnsupportedWordsNameTheLineAndWord) {
    expect_input_error("G21\nG33 X1 K1\nM2\n", "bad.ngc:2: G33");
    expect_input_error("G21\nG1 X1 F100\nG2 X2 Y0 I0.5 K1\nM2\n", "bad.ngc:3: K1");
    expect_input_error("G21\nG18\nM2\n", "bad.ngc:2: G18");
    expect_input_error("G21\nM98 P1\nM2\n", "bad.ngc:2: M98");
    expect_input_error("G21\nG1 X1\nM2\n", "bad.ngc:2: G1 without a feed rate");
    expect_input_error("G21\nG1 X1 F100\nG2 X3 Y0 I0.5\nM2\n", "bad.ngc:3: the arc's end is not on its circle");
    expect_input_error("G21\nG1 X1 F100\n", "the program ends without M2");
    expect_input_error("G21 (open\nM2\n", "bad.ngc:1: comment");
}

TEST(GcodeReader, ToolChangesAndCoolantAreNoted) {
    const auto program = feedid::read_gcode("G21\nT1 M6\nM8\nG0 X1\nM9\nM30\n", "p.ngc");
    ASSERT_EQ(program.blocks.size(), 1u);
    ASSERT_EQ(program.notes.size(), 4u);
    EXPECT_NE(program.notes[0].find("p.ngc:2: T1"), std::string::npos);
    EXPECT_NE(program.notes[1].find("M6"), std::string::npos);
}

}  // namespace
