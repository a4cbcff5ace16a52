// Text from inputs shown on a terminal: control characters, bidirectional overrides and bytes that are not UTF-8
// escaped; every other character as it is.

#include <gtest/gtest.h>

#include "feedid/core/terminal_text.hpp"

namespace {

using feedid::terminal_message;
using feedid::terminal_text;

TEST(TerminalText, ControlCharactersAreEscaped) {
    EXPECT_EQ(terminal_text("M\x1b]0;T\a\x1b[2J"), R"(M\x1b]0;T\x07\x1b[2J)");
    EXPECT_EQ(terminal_text("a\tb\nc\rd\x7f"), R"(a\x09b\x0ac\x0dd\x7f)");
    EXPECT_EQ(terminal_text(std::string("nul\0here", 8)), R"(nul\x00here)");
    // C1 controls (U+0080..U+009F, e.g. the CSI U+009B) and bidirectional overrides are characters, escaped as such
    EXPECT_EQ(terminal_text("x\xc2\x9b"
                            "2J"),
              R"(x\u009b2J)");
    EXPECT_EQ(terminal_text("evil\xe2\x80\xaetxt.exe"), R"(evil\u202etxt.exe)");
}

TEST(TerminalText, ValidUtf8PassesAndInvalidBytesAreEscaped) {
    EXPECT_EQ(terminal_text("742.8 ± 0.8 N·m, 5 µm, Δ, 日本, 😀"), "742.8 ± 0.8 N·m, 5 µm, Δ, 日本, 😀");
    EXPECT_EQ(terminal_text("m\xffm"), R"(m\xffm)");
    EXPECT_EQ(terminal_text("\x80"), R"(\x80)");                          // a stray continuation byte
    EXPECT_EQ(terminal_text("\xc3"), R"(\xc3)");                          // a truncated sequence
    EXPECT_EQ(terminal_text("\xc0\xaf"), R"(\xc0\xaf)");                  // an overlong '/'
    EXPECT_EQ(terminal_text("\xed\xa0\x80"), R"(\xed\xa0\x80)");          // a surrogate
    EXPECT_EQ(terminal_text("\xf4\x90\x80\x80"), R"(\xf4\x90\x80\x80)");  // beyond U+10FFFF
}

TEST(TerminalText, MessagesKeepTheirLines) {
    EXPECT_EQ(terminal_message("line one\nline \x1b[31mtwo\n"), "line one\nline \\x1b[31mtwo\n");
}

// Names from outside (MQTT topics and payloads, the command line): what both history backends store and a terminal
// shows unharmed, or a reason.
TEST(TerminalText, NamesAreUtf8WithoutControlsWithinALength) {
    using feedid::name_problem;
    EXPECT_EQ(name_problem("M1", 64), "");
    EXPECT_EQ(name_problem("Fräse Nr. 3 日本", 64), "");
    EXPECT_EQ(name_problem("", 64), "empty");
    EXPECT_EQ(name_problem(std::string(65, 'x'), 64), "longer than 64 bytes");
    EXPECT_EQ(name_problem("M\xff", 64), "not UTF-8");
    EXPECT_EQ(name_problem("\xed\xa0\x80", 64), "not UTF-8");
    EXPECT_EQ(name_problem(std::string("M\0X", 3), 64), "a control character");
    EXPECT_EQ(name_problem("M\nX", 64), "a control character");
    EXPECT_EQ(name_problem("x\xc2\x9b", 64), "a control character");
    EXPECT_EQ(name_problem("evil\xe2\x80\xaeX", 64), "a bidirectional override");
    EXPECT_TRUE(feedid::is_storable_text("M\ttab, 日本"));
    EXPECT_FALSE(feedid::is_storable_text(std::string("M\0X", 3)));
    EXPECT_FALSE(feedid::is_storable_text("M\xc3"));
}

}  // namespace
