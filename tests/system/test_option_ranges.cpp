// Options and file constants checked at parse time (issue 13): a value that is not a finite number, or one no unit
// could make sense of, exits 2 before anything is read, with one line naming the option (or the file's constant) and
// its allowed range. Before, --from nan was accepted and the window ignored, --cutoff 1e-300 printed "|v| <= nan",
// --force-constant 1e308 printed "-nan kg", a file's force_constant = nan, inf or 0 was blamed on the data, and
// --sg-window 5 --sg-order 5 was exit 1 "internal error".

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "feedid/model/drive.hpp"
#include "feedid/core/error.hpp"
#include "history_testing.hpp"
#include "testing.hpp"

namespace {

using feedid::testing::quoted;
using feedid::testing::read_text;
using feedid::testing::run_cli;
using feedid::testing::write_text;

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// A demo trace (15 s, the paper's ladder) in the test's folder.
std::filesystem::path demo_trace(const std::filesystem::path& dir) {
    const auto trace = dir / "synth.csv";
    const auto made = run_cli("synth --no-slow-passes --out " + quoted(trace));
    EXPECT_EQ(made.exit_code, 0) << made.err;
    return trace;
}

// The options `feedid SUBCOMMAND --help` lists with a numeric type (FLOAT, INT, UINT), as "--name".
std::vector<std::string> numeric_options(const std::string& subcommand) {
    const auto help = run_cli(subcommand + " --help");
    EXPECT_EQ(help.exit_code, 0) << help.err;
    std::vector<std::string> options;
    const std::regex line(R"(^\s+(?:-\w,)?(--[a-z0-9-]+) (FLOAT|INT|UINT)\b)");
    std::istringstream in(help.out);
    std::string text;
    std::smatch match;
    while (std::getline(in, text)) {
        if (std::regex_search(text, match, line)) options.push_back(match[1]);
    }
    return options;
}

TEST(OptionRanges, EveryNumericOptionOfEverySubcommandRefusesNanInfinityAndAbsurdValues) {
    // Every numeric option the help lists, with what each subcommand requires besides; the paths need not exist, for
    // the value is refused while the command line is parsed, before any file is opened.
    const std::map<std::string, std::string> required{
        {"info", "t.csv"},   {"identify", "t.csv"},
        {"gains", "t.csv"},  {"simulate", "t.csv --result r.json"},
        {"synth", ""},       {"plan", "--travel=-400:400 --centers=0"},
        {"history", "h.db"}, {"report", "r.json -o r.html"},
    };
    // at least as many numeric options as each subcommand has today (a help the pattern no longer reads fails here)
    const std::map<std::string, std::size_t> at_least{{"info", 5},  {"identify", 19}, {"gains", 10},  {"simulate", 11},
                                                      {"synth", 1}, {"plan", 18},     {"history", 5}, {"report", 3}};
    struct Case {
        std::string command;
        std::string option;
    };
    std::vector<Case> cases;
    for (const auto& [subcommand, arguments] : required) {
        const auto options = numeric_options(subcommand);
        EXPECT_GE(options.size(), at_least.at(subcommand)) << subcommand;
        for (const auto& option : options) {
            for (const std::string value : {"nan", "1e300", "-1e300"}) {
                cases.push_back({subcommand + " " + arguments + " " + option + "=" + value, option});
            }
        }
    }
    EXPECT_GE(cases.size(), 3u * 72u);
    // two at a time: each is a process that parses its command line and stops
    const auto scratch = feedid::testing::temp_dir();
    std::vector<feedid::testing::CliResult> results(cases.size());
    std::vector<std::thread> workers;
    for (std::size_t worker = 0; worker < 2; ++worker) {
        workers.emplace_back([&, worker] {
            for (std::size_t i = worker; i < cases.size(); i += 2)
                results[i] = feedid::testing::run_shell(feedid::testing::cli() + " " + cases[i].command, scratch);
        });
    }
    for (auto& thread : workers) thread.join();
    for (std::size_t i = 0; i < cases.size(); ++i) {
        const auto& result = results[i];
        EXPECT_EQ(result.exit_code, 2) << cases[i].command << ": " << result.err;
        EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << cases[i].command << ": " << result.err;
        EXPECT_TRUE(contains(result.err, cases[i].option)) << cases[i].command << ": " << result.err;
    }
}

TEST(OptionRanges, TheMessageNamesTheOptionAndItsAllowedRange) {
    const auto dir = feedid::testing::temp_dir();
    const auto trace = demo_trace(dir);
    const std::string identify = "identify " + quoted(trace) + " --force-constant force_constant_N_per_A ";
    const std::vector<std::pair<std::string, std::string>> cases{
        {"--from nan", "feedid: --from: nan is not a finite number (allowed: -1e+12 to 1e+12 s)\n"},
        {"--to nan", "feedid: --to: nan is not a finite number (allowed: -1e+12 to 1e+12 s)\n"},
        {"--cutoff 1e-300", "feedid: --cutoff: 1e-300 is outside the allowed range 0.001 to 1e+06 Hz\n"},
        {"--sg-window 4 --differentiation savitzky-golay",
         "feedid: --sg-window: 4 is outside the allowed range 5 to 1e+06 samples\n"},
        {"--lambda 0", "feedid: --lambda: 0 is outside the allowed range 1e-06 to 1\n"},
        {"--gear-ratio 0",
         "feedid: --gear-ratio: 0 is outside the allowed range 1e-05 to 1e+06 motor turns per "
         "screw turn\n"},
    };
    for (const auto& [options, message] : cases) {
        const auto result = run_cli(identify + options);
        EXPECT_EQ(result.exit_code, 2) << options;
        EXPECT_EQ(result.err, message) << options;
        EXPECT_TRUE(result.out.empty()) << options << ": nothing identified\n" << result.out;
    }
}

TEST(OptionRanges, AForceConstantOf1e308IsRefusedBeforeItMakesNan) {
    const auto dir = feedid::testing::temp_dir();
    const auto trace = demo_trace(dir);
    for (const std::string subcommand : {"identify", "gains"}) {
        for (const std::string value : {"1e308", "-1e308", "0", "nan", "1e-300"}) {
            const auto result = run_cli(subcommand + " " + quoted(trace) + " --force-constant " + value);
            EXPECT_EQ(result.exit_code, 2) << subcommand << " " << value;
            EXPECT_EQ(result.err, "feedid: --force-constant: " + value +
                                      " is not allowed: a force constant is a finite number of either sign with a "
                                      "magnitude from 1e-09 to 1e+09 N (N*m on a rotary axis) per unit of the drive "
                                      "signal\n")
                << subcommand << " " << value;
            EXPECT_FALSE(contains(result.out, "nan")) << result.out;
        }
    }
    // a negative constant (a drive signal of the other sign) within the range is a constant
    const auto negative = run_cli("gains " + quoted(trace) + " --force-constant -453.6");
    EXPECT_FALSE(contains(negative.err, "is not allowed")) << negative.err;
}

TEST(OptionRanges, SavitzkyGolayOrderAtTheWindowIsBadUsageNotAnInternalError) {
    const auto dir = feedid::testing::temp_dir();
    const auto trace = demo_trace(dir);
    const auto result = run_cli("identify " + quoted(trace) +
                                " --force-constant force_constant_N_per_A --differentiation savitzky-golay "
                                "--sg-window 5 --sg-order 5");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_EQ(result.err,
              "feedid: --sg-order 5 must be below --sg-window 5 (a polynomial of that order needs more samples)\n");
}

TEST(OptionRanges, AFileConstantThatIsNoForceConstantIsTheFilesFaultNotTheData) {
    const auto dir = feedid::testing::temp_dir();
    const std::string text = read_text(demo_trace(dir));
    const std::regex constant(R"(# force_constant_N_per_A = [^\n]*)");
    ASSERT_TRUE(std::regex_search(text, constant));
    for (const std::string value : {"nan", "inf", "0", "1e308"}) {
        const auto trace = dir / ("constant_" + value + ".csv");
        write_text(trace, std::regex_replace(text, constant, "# force_constant_N_per_A = " + value));
        for (const std::string subcommand : {"identify", "gains"}) {
            const auto result = run_cli(subcommand + " " + quoted(trace) + " --force-constant force_constant_N_per_A");
            EXPECT_EQ(result.exit_code, 2) << subcommand << " " << value << ": " << result.err;
            // one line (after the import's notes) that names the constant; never the data's fault
            const std::string last = result.err.substr(result.err.rfind("feedid: "));
            EXPECT_TRUE(contains(last, "force_constant_N_per_A")) << last;
            EXPECT_FALSE(contains(result.err, "mass")) << result.err;
            EXPECT_FALSE(contains(result.out, "nan")) << result.out;
            if (value != "1e308") {  // a reader may refuse a constant that is no finite number itself
                EXPECT_TRUE(contains(last, "the file's constant 'force_constant_N_per_A' is " + value) ||
                            contains(last, "not a finite number"))
                    << last;
            }
        }
    }
}

TEST(OptionRanges, DriveConstantsOutsideTheirRangesAreNamedWithTheRange) {
    const auto problem = [](auto set) {
        feedid::DriveConstants constants;
        set(constants);
        return constants.validate();
    };
    EXPECT_EQ(problem([](auto& c) { c.torque_constant_Nm_per_A = NAN; }),
              "--kt nan is outside the allowed range 1e-05 to 500000 N*m/A");
    EXPECT_EQ(problem([](auto& c) { c.lead_m = 1e300; }),
              "--lead 1e+303 mm is outside the allowed range 0.0005 to "
              "100000 mm");
    EXPECT_EQ(problem([](auto& c) { c.gear_ratio = INFINITY; }),
              "--gear-ratio inf is outside the allowed range 1e-05 to 1e+06");
    EXPECT_NE(problem([](auto& c) { c.force_constant = 1e308; }).find("--force-constant 1e+308 is not allowed"),
              std::string::npos);
    EXPECT_EQ(problem([](auto& c) { c.force_constant = -35.15; }), "");
    EXPECT_EQ(problem([](auto& c) {
                  c.torque_constant_Nm_per_A = 1.4;
                  c.lead_m = 0.01;
              }),
              "");
    // a file's constant is checked when it is resolved
    feedid::Trace trace;
    trace.source_path = "t.csv";
    trace.constants["gtau"] = 0.0;
    feedid::DriveConstants named;
    named.force_constant_name = "gtau";
    try {
        (void)named.force_per_signal(trace);
        ADD_FAILURE() << "a force constant of 0 was taken";
    } catch (const feedid::InputError& e) {
        EXPECT_TRUE(contains(e.what(), "the file's constant 'gtau' is 0")) << e.what();
    }
    trace.constants["gtau"] = 35.15;
    EXPECT_EQ(named.force_per_signal(trace).value_or(0.0), 35.15);
}

TEST(OptionRanges, CompoundOptionsRefuseAbsurdNumbersToo) {
    const auto dir = feedid::testing::temp_dir();
    // synth's injection AMPLITUDE@FREQUENCY, info's --rated VALUE+UNIT
    const auto injection = run_cli("synth --injection 1e300N@1Hz --out " + quoted(dir / "never.csv"));
    EXPECT_EQ(injection.exit_code, 2);
    EXPECT_TRUE(contains(injection.err,
                         "amplitude must be a number of either sign with a magnitude from 1e-06 to "
                         "1e+07 N"))
        << injection.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "never.csv"));
    const auto slow = run_cli("synth --injection 300N@1e-300Hz --out " + quoted(dir / "never.csv"));
    EXPECT_EQ(slow.exit_code, 2);
    EXPECT_TRUE(contains(slow.err, "frequency must lie from 0.001 to")) << slow.err;
    // plan's lists of numbers, item by item
    for (const auto& [option, message] :
         {std::pair{"--centers=0,nan",
                    "feedid: --centers: nan is not a finite number (allowed: -1e+06 to 1e+06 mm or deg)\n"},
          std::pair{"--feeds=1000,1e300",
                    "feedid: --feeds: 1e300 is outside the allowed range 0.001 to 1e+06 mm/min or deg/min\n"},
          std::pair{"--slow-feeds=10:1000:1e12",
                    "feedid: --slow-feeds: '10:1000:1e12' needs 0.001 <= LO <= HI <= "
                    "1e+06 mm/min and a whole N from 1 to 100.\n"}}) {
        const auto plan = run_cli(std::string("plan --travel=-400:400 --centers=0 -o /dev/null ") + option);
        EXPECT_EQ(plan.exit_code, 2) << option;
        EXPECT_EQ(plan.err, message) << option;
    }
    const auto rated = run_cli("info " + quoted(demo_trace(dir)) + " --rated 1e300A");
    EXPECT_EQ(rated.exit_code, 2);
    EXPECT_TRUE(contains(rated.err, "--rated 1e300A: the rated value must be a positive number from 1e-06 to 1e+07"))
        << rated.err;
}

}  // namespace
