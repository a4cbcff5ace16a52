// A hint printed for a role guessed from a channel's name works when pasted as printed: `feedid info FILE` plus the
// printed `--channel ROLE=NAME` (quoted for a shell where the name needs it) reads, and that role is then set, not
// guessed. On a synthetic two-encoder trace, the SINUMERIK reversal trace and one axis of the UMich mill's log.

#include <gtest/gtest.h>

#include <regex>
#include <string>
#include <vector>

#include "testing.hpp"

using namespace feedid::testing;

namespace {

struct Hint {
    std::string role;
    std::string option;  // as printed
};

std::vector<Hint> guess_hints(const std::string& text) {
    static const std::regex pattern(R"(taken as (\w+) \(guessed from [^;]*; set it with (--channel (?:'[^']*'|\S+))\))");
    std::vector<Hint> hints;
    for (auto it = std::sregex_iterator(text.begin(), text.end(), pattern); it != std::sregex_iterator(); ++it)
        hints.push_back({(*it)[1].str(), (*it)[2].str()});
    return hints;
}

void expect_hints_work(const std::string& arguments) {
    const auto guessed = run_cli("info " + arguments);
    ASSERT_EQ(guessed.exit_code, 0) << guessed.err;
    const auto hints = guess_hints(guessed.out + guessed.err);
    ASSERT_FALSE(hints.empty()) << guessed.out;
    for (const auto& hint : hints) {
        EXPECT_EQ(hint.option.find("NAME"), std::string::npos) << hint.option;
        const auto pasted = run_cli("info " + arguments + " " + hint.option);
        EXPECT_EQ(pasted.exit_code, 0) << hint.option << ": " << pasted.err;
        EXPECT_EQ((pasted.out + pasted.err).find("taken as " + hint.role + " (guessed"), std::string::npos)
            << hint.option << " did not set " << hint.role;
    }
}

}  // namespace

TEST(PrintedHints, GuessedRolesNameTheirChannelAndWorkWhenPasted) {
    const auto dir = temp_dir();
    const auto trace = (dir / "two-encoders.csv").string();
    ASSERT_EQ(run_cli("synth --backlash 8 --stiffness 150 --out '" + trace + "'").exit_code, 0);
    expect_hints_work("'" + trace + "'");
    expect_hints_work("'" + (shared_data() / "sinumerik-trace" / "X_BK300_1.xml").string() + "'");
    expect_hints_work("'" + (shared_data() / "umich-cnc-mill" / "experiment_01.csv").string() + "' --axis X1");
}
