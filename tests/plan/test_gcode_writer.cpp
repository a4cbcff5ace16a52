// Part-program emitters: the ISO and SINUMERIK (and LinuxCNC) programs, read back by a small G-code parser, hold the
// plan's move list block for block: targets [mm, or deg on a rotary axis], feedrates [mm/min or deg/min], dwells [s].
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "feedid/core/error.hpp"
#include "feedid/plan/gcode_writer.hpp"
#include "feedid/plan/test_plan.hpp"
#include "feedid/core/version.hpp"

namespace {

using feedid::Dialect;
using feedid::MoveKind;

struct ParsedMove {
    MoveKind kind{MoveKind::feed};
    double target{0.0};        // [mm or deg]
    double feed_per_min{0.0};  // [mm/min or deg/min]
    double dwell_s{0.0};
};

struct ParsedProgram {
    std::vector<ParsedMove> moves;
    std::vector<std::string> comments;
    std::vector<std::string> modal_words;  // G and other words of blocks without motion (G21, G90, SOFT, ...)
    bool ended{false};                     // M30 / M2 seen
};

// Words of a block: an address (letters) and a value, "X-300.0", "X1=-300.0", "G4", "F10.0"; bare words ("SOFT").
struct Word {
    std::string address;
    std::string value;
};

std::vector<Word> split_words(const std::string& block) {
    std::vector<Word> words;
    std::istringstream in(block);
    std::string token;
    while (in >> token) {
        Word word;
        if (const auto equals = token.find('='); equals != std::string::npos) {
            word.address = token.substr(0, equals);
            word.value = token.substr(equals + 1);
        } else {
            std::size_t k = 0;
            while (k < token.size() && std::isalpha(static_cast<unsigned char>(token[k]))) ++k;
            word.address = token.substr(0, k);
            word.value = token.substr(k);
        }
        words.push_back(word);
    }
    return words;
}

// A deliberately strict reader: every word must be one the emitters are allowed to write.
ParsedProgram parse_program(const std::string& text, Dialect dialect, const std::string& axis) {
    ParsedProgram program;
    std::istringstream lines(text);
    std::string line;
    double feed = 0.0;
    while (std::getline(lines, line)) {
        std::string block;
        if (dialect == Dialect::sinumerik) {
            const auto semicolon = line.find(';');
            if (semicolon != std::string::npos) program.comments.push_back(line.substr(semicolon + 1));
            block = line.substr(0, semicolon);
        } else {
            // ( ... ) comments; no nesting allowed.
            bool inside = false;
            std::string comment;
            for (const char c : line) {
                if (c == '(') {
                    EXPECT_FALSE(inside) << "nested parenthesis in: " << line;
                    inside = true;
                    comment.clear();
                } else if (c == ')') {
                    EXPECT_TRUE(inside) << "unbalanced parenthesis in: " << line;
                    inside = false;
                    program.comments.push_back(comment);
                } else if (inside) {
                    comment += c;
                } else {
                    block += c;
                }
            }
            EXPECT_FALSE(inside) << "unclosed comment: " << line;
        }
        if (block.find_first_not_of(" \t\r") == std::string::npos) continue;
        if (dialect == Dialect::iso && (block == "%" || block.rfind("O", 0) == 0)) continue;
        const auto words = split_words(block);
        bool motion = false;
        bool dwell = false;
        std::optional<double> target;
        std::optional<double> block_feed;
        std::optional<double> dwell_time;
        for (const auto& word : words) {
            if (word.address == "G" && (word.value == "1" || word.value == "01")) {
                motion = true;
            } else if (word.address == "G" && (word.value == "4" || word.value == "04")) {
                dwell = true;
            } else if (word.address == axis && !dwell) {
                target = std::stod(word.value);
            } else if (dwell && ((dialect == Dialect::iso && word.address == "X") ||
                                 (dialect == Dialect::sinumerik && word.address == "F") ||
                                 (dialect == Dialect::linuxcnc && word.address == "P"))) {
                dwell_time = std::stod(word.value);
            } else if (word.address == "F") {
                block_feed = std::stod(word.value);
            } else if (word.address == "M" && (word.value == "30" || word.value == "2")) {
                program.ended = true;
            } else {
                program.modal_words.push_back(word.address + word.value);
            }
        }
        if (block_feed) feed = *block_feed;
        if (dwell) {
            EXPECT_TRUE(dwell_time.has_value()) << "dwell without time: " << line;
            program.moves.push_back({MoveKind::dwell, 0.0, 0.0, dwell_time.value_or(-1.0)});
        } else if (motion) {
            EXPECT_TRUE(target.has_value()) << "G1 without the axis: " << line;
            EXPECT_GT(feed, 0.0) << "feed move before any feedrate: " << line;
            program.moves.push_back({MoveKind::feed, target.value_or(NAN), feed, 0.0});
        } else {
            EXPECT_FALSE(target.has_value()) << "axis word outside a G1 block: " << line;
        }
    }
    return program;
}

feedid::TestPlanOptions multi_center_options() {
    feedid::TestPlanOptions options;
    options.axis = "X";
    options.travel_min = -0.5;
    options.travel_max = 0.2;
    options.centers = {-0.3, -0.1, 0.1};
    options.slow_feeds = feedid::log_spaced_feeds(10.0 / 60000.0, 1000.0 / 60000.0, 4);
    options.cycles = 2;
    options.dwell = 0.25;
    return options;
}

void expect_same_moves(const feedid::TestPlan& plan, const ParsedProgram& program) {
    const feedid::PlanUnits units = plan.options.units();
    ASSERT_EQ(program.moves.size(), plan.moves.size());
    for (std::size_t k = 0; k < plan.moves.size(); ++k) {
        const auto& expected = plan.moves[k];
        const auto& parsed = program.moves[k];
        ASSERT_EQ(static_cast<int>(parsed.kind), static_cast<int>(expected.kind)) << "block " << k + 1;
        if (expected.kind == MoveKind::feed) {
            EXPECT_NEAR(parsed.target, expected.target / units.length(), 5e-5)
                << "block " << k + 1 << ": " << expected.description;
            EXPECT_NEAR(parsed.feed_per_min, expected.feed / units.feed(), 5e-4) << "block " << k + 1;
        } else {
            EXPECT_NEAR(parsed.dwell_s, expected.dwell, 5e-4) << "block " << k + 1;
        }
    }
}

bool contains(const std::vector<std::string>& words, const std::string& word) {
    return std::find(words.begin(), words.end(), word) != words.end();
}

TEST(Gcode, IsoHoldsThePlanMoveForMove) {
    const auto plan = feedid::make_test_plan(multi_center_options());
    const auto text = feedid::emit_part_program(plan, Dialect::iso);
    const auto program = parse_program(text, Dialect::iso, "X");
    expect_same_moves(plan, program);
    EXPECT_TRUE(program.ended);
    EXPECT_TRUE(contains(program.modal_words, "G21"));
    EXPECT_TRUE(contains(program.modal_words, "G90"));
    EXPECT_TRUE(contains(program.modal_words, "G94"));
    EXPECT_TRUE(contains(program.modal_words, "G61"));
    EXPECT_NE(text.find(std::string("feedid ") + feedid::version), std::string::npos);
    EXPECT_EQ(text.rfind("%\n", 0), 0u) << "ISO tape start";
    // Every position carries a decimal point (no decimal-point programming = increments).
    for (std::size_t at = text.find("G1 X"); at != std::string::npos; at = text.find("G1 X", at + 1)) {
        const auto end = text.find_first_of(" \n", at + 4);
        EXPECT_NE(text.substr(at, end - at).find('.'), std::string::npos);
    }
}

TEST(Gcode, SinumerikHoldsThePlanMoveForMoveWithTraceAndJerk) {
    auto options = multi_center_options();
    options.axis = "X1";
    options.jerk = 50.0;
    const auto plan = feedid::make_test_plan(options);
    const auto text = feedid::emit_part_program(plan, Dialect::sinumerik);
    const auto program = parse_program(text, Dialect::sinumerik, "X1");
    expect_same_moves(plan, program);
    EXPECT_TRUE(program.ended);
    for (const auto* word : {"G71", "G90", "G94", "G60", "SOFT"})
        EXPECT_TRUE(contains(program.modal_words, word)) << word;
    // Servo trace start and stop, commented out for the user to enable, around the moves.
    const auto start = text.find(";R99=1");
    const auto stop = text.find(";R99=0");
    ASSERT_NE(start, std::string::npos);
    ASSERT_NE(stop, std::string::npos);
    EXPECT_LT(start, text.find("G1 X1="));
    EXPECT_GT(stop, text.rfind("G1 X1="));
    EXPECT_NE(text.find(std::string("feedid ") + feedid::version), std::string::npos);

    options.jerk.reset();
    const auto brisk = feedid::emit_part_program(feedid::make_test_plan(options), Dialect::sinumerik);
    EXPECT_TRUE(contains(parse_program(brisk, Dialect::sinumerik, "X1").modal_words, "BRISK"));
}

TEST(Gcode, LinuxcncHoldsThePlanMoveForMove) {
    const auto plan = feedid::make_test_plan(multi_center_options());
    const auto text = feedid::emit_part_program(plan, Dialect::linuxcnc);
    const auto program = parse_program(text, Dialect::linuxcnc, "X");
    expect_same_moves(plan, program);
    EXPECT_TRUE(program.ended);
    EXPECT_NE(text.find("\nM2\n"), std::string::npos);
}

TEST(Gcode, HeaderRecordsThePlanParameters) {
    const auto plan = feedid::make_test_plan(multi_center_options());
    const auto text = feedid::emit_part_program(plan, Dialect::linuxcnc);
    for (const auto* fragment : {"axis X", "travel -500.0 .. 200.0 mm", "centres -300.0, -100.0, 100.0 mm",
                                 "stroke 30.0 mm", "1250.0, 2600.0, 3950.0, 5300.0, 6650.0, 8000.0, 9350.0 mm/min",
                                 "slow feeds 10.0, 46.0, 220.0, 1000.0 mm/min", "cycles per feedrate 2",
                                 "dwell at reversals 0.25 s", "acceleration 1.0 m/s^2", "trace sample time 1.0 ms"}) {
        EXPECT_NE(text.find(fragment), std::string::npos) << fragment;
    }
}

// A rotary table: positions in degrees, feeds in deg/min, in all three dialects.
TEST(Gcode, ARotaryAxisIsProgrammedInDegreesAndDegreesPerMinute) {
    constexpr double deg = M_PI / 180.0;
    for (const auto& [dialect, axis] :
         {std::pair{Dialect::iso, "B"}, std::pair{Dialect::linuxcnc, "A"}, std::pair{Dialect::sinumerik, "C1"}}) {
        auto options = feedid::default_plan_options(axis);
        options.travel_min = -200.0 * deg;
        options.travel_max = 200.0 * deg;
        options.centers = {-90.0 * deg, 45.0 * deg};
        options.slow_feeds = feedid::log_spaced_feeds(10.0 * deg / 60.0, 1000.0 * deg / 60.0, 3, options.units());
        const auto plan = feedid::make_test_plan(options);
        const auto text = feedid::emit_part_program(plan, dialect);
        const auto program = parse_program(text, dialect, axis);
        expect_same_moves(plan, program);
        EXPECT_TRUE(program.ended);
        for (const auto* fragment : {"for rotary axis", "centres -90.0, 45.0 deg", "stroke 30.0 deg",
                                     "1250.0, 2600.0, 3950.0, 5300.0, 6650.0, 8000.0, 9350.0 deg/min",
                                     "slow feeds 10.0, 100.0, 1000.0 deg/min", "acceleration 1000.0 deg/s^2"})
            EXPECT_NE(text.find(fragment), std::string::npos) << fragment << " in\n" << text.substr(0, 800);
        EXPECT_EQ(text.find(" mm"), std::string::npos) << "no millimetres on a rotary axis";
    }
}

TEST(Gcode, AxisNamesAreCheckedPerDialect) {
    auto options = multi_center_options();
    options.axis = "X1";
    const auto plan = feedid::make_test_plan(options);
    EXPECT_THROW((void)feedid::emit_part_program(plan, Dialect::linuxcnc), feedid::InputError);
    EXPECT_THROW((void)feedid::emit_part_program(plan, Dialect::iso), feedid::InputError);
    EXPECT_NO_THROW((void)feedid::emit_part_program(plan, Dialect::sinumerik));
}

}  // namespace
