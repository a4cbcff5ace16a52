// brief_report(): the few lines a person reads of an identification (the trace, model, status and the parameter
// table), exactly as feedid identify prints them and as feedid scan prints its table.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "feedid/identify/brief_report.hpp"
#include "feedid/identify/result_document.hpp"
#include "testing.hpp"

namespace feedid {
namespace {

using testing::run_cli;

std::string quoted(const std::filesystem::path& path) {
    return "'" + path.string() + "'";
}

TEST(BriefReport, ShowsTraceModelStatusAndEveryParameterWithItsUncertainties) {
    IdentifyResult result;
    result.status = Status::partial;
    result.offset = true;
    result.trace = {"axis \x1b]0;X.csv", "csv", 24841, 1e-3, 24.84};
    result.parameters = model_parameters(FrictionModelKind::symmetric, true, false);
    result.parameters[0].estimate = Estimate::of(95.0137, 0.177);  // M
    result.parameters[0].estimate.uncertainty = 0.527;
    result.parameters[1].estimate = Estimate::of(203.786, 1.87);     // B, its combined uncertainty not assessed
    result.parameters[2].estimate.value = 20.3685;                   // F_C with no standard error
    result.parameters[3].estimate = Estimate::of(-3.17222, 0.0561);  // F_0
    result.parameters[3].estimate.uncertainty = 0.175;
    // F_B and v_s null

    const std::string expected =
        "axis \\x1b]0;X.csv (24841 samples, 24.84 s)\n"
        "model: symmetric with offset, status: partial\n"
        "\n"
        "                  value   std. error   uncertainty  unit      \n"
        "  M             95.0137 ± 0.177        0.527        kg        \n"
        "  B             203.786 ± 1.87         —            N*s/m     \n"
        "  F_C           20.3685 ± —            —            N         \n"
        "  F_0          -3.17222 ± 0.0561       0.175        N         \n"
        "  F_B                 —                             N         \n"
        "  v_s                 —                             m/s       \n";
    EXPECT_EQ(brief_report(result), expected);
    EXPECT_EQ(expected.substr(expected.find("  ")), parameter_table_text(result));
}

TEST(BriefReport, NamesAFailedResultAndARotaryAxisInItsUnits) {
    IdentifyResult result;
    result.status = Status::failed;
    result.model = FrictionModelKind::asymmetric;
    result.rotary = true;
    result.parameters = model_parameters(FrictionModelKind::asymmetric, false, true);
    const std::string text = brief_report(result);
    EXPECT_EQ(text.substr(0, text.find("\n\n")), "trace (0 samples, 0 s)\nmodel: asymmetric, status: failed");
    for (const auto& p : result.parameters) {
        EXPECT_NE(text.find(fmt::format("  {:<6} {:>14}", p.symbol, "—")), std::string::npos) << p.symbol;
        EXPECT_NE(text.find(p.unit), std::string::npos) << p.unit;
    }
}

TEST(BriefReport, IsWhatFeedidIdentifyPrintsFirst) {
    const auto work = std::filesystem::canonical(testing::temp_dir());
    ASSERT_EQ(run_cli("synth --out " + quoted(work / "demo.csv") + " --seed 1").exit_code, 0);
    const auto run = run_cli("identify " + quoted(work / "demo.csv") +
                             " --force-constant force_constant_N_per_A --json " + quoted(work / "demo.json"));
    ASSERT_EQ(run.exit_code, 0) << run.err;
    const auto result = nlohmann::json::parse(testing::read_text(work / "demo.json")).get<IdentifyResult>();
    const std::string brief = brief_report(result);
    EXPECT_EQ(run.out.substr(0, brief.size()), brief);
    EXPECT_NE(brief.find("status: ok"), std::string::npos) << brief;
    for (const auto& p : result.parameters) {
        ASSERT_TRUE(p.estimate.value && p.estimate.standard_error) << p.key;
        EXPECT_NE(brief.find(fmt::format("  {:<6} {:>14.6g} ± {:<12.3g}", p.symbol, *p.estimate.value,
                                         *p.estimate.standard_error)),
                  std::string::npos)
            << p.key << "\n"
            << brief;
    }
}

}  // namespace
}  // namespace feedid
