// Configuration files through the one reader: the same settings written in JSON and in TOML give the same tree and
// the same values, and the same refusals (unknown key, wrong type, out of range), each naming the file and the key
// path; TOML syntax errors name the line; the limits of JSON documents hold for TOML too.

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/config_file.hpp"
#include "testing.hpp"

namespace {

using feedid::ConfigSection;
using feedid::testing::write_text;

/// The message of the InputError `read` throws ("" when it throws none).
template <class Read>
std::string refusal(Read&& read) {
    try {
        read();
    } catch (const feedid::InputError& e) {
        return e.what();
    }
    return "";
}

const std::string settings_json = R"({
  "seed": 3,
  "controller": {"tn_ms": 15, "saturation_N": 900.5, "log": true, "unit": "mm"},
  "test": {"feedrates_mm_per_min": [1250, 9350.5]},
  "zones": [{"from_mm": 0}, {"from_mm": 10}]
})";

const std::string settings_toml = R"(seed = 3
[controller]
tn_ms = 15
saturation_N = 900.5
log = true
unit = "mm"
[test]
feedrates_mm_per_min = [1250, 9350.5]
[[zones]]
from_mm = 0
[[zones]]
from_mm = 10
)";

// What a reader of these settings takes from a file, through ConfigSection alone.
struct Settings {
    double seed{0.0};
    double tn_s{0.0};
    double saturation_N{0.0};
    bool log{false};
    std::string unit;
    std::vector<double> feedrates;
    std::vector<double> zones_from_mm;
};

Settings read_settings(const nlohmann::json& document, const std::string& source) {
    Settings out;
    ConfigSection top(document, source);
    top.read("seed", out.seed);
    if (auto controller = top.section("controller")) {
        controller->read("tn_ms", out.tn_s, 1e-3);
        out.saturation_N = controller->number("saturation_N", {0.0, 1e6, "N"}).value_or(0.0);
        out.log = controller->boolean("log").value_or(false);
        out.unit = controller->text("unit").value_or("");
        controller->reject_unknown();
    }
    if (auto test = top.section("test")) {
        out.feedrates = test->numbers("feedrates_mm_per_min").value_or(std::vector<double>{});
        test->reject_unknown();
    }
    for (auto& zone : top.sections("zones")) {
        out.zones_from_mm.push_back(zone.number("from_mm").value_or(-1.0));
        zone.reject_unknown();
    }
    top.reject_unknown();
    return out;
}

TEST(ConfigFile, JsonAndTomlGiveTheSameTreeAndTheSameValues) {
    const auto dir = feedid::testing::temp_dir();
    write_text(dir / "settings.json", settings_json);
    write_text(dir / "settings.toml", settings_toml);
    const auto json = feedid::read_config_file(dir / "settings.json");
    const auto toml = feedid::read_config_file(dir / "settings.toml");
    EXPECT_EQ(json, toml) << json.dump() << "\n" << toml.dump();
    for (const auto& document : {json, toml}) {
        const auto settings = read_settings(document, "settings");
        EXPECT_EQ(settings.seed, 3.0);
        EXPECT_DOUBLE_EQ(settings.tn_s, 0.015);
        EXPECT_EQ(settings.saturation_N, 900.5);
        EXPECT_TRUE(settings.log);
        EXPECT_EQ(settings.unit, "mm");
        EXPECT_EQ(settings.feedrates, (std::vector<double>{1250.0, 9350.5}));
        EXPECT_EQ(settings.zones_from_mm, (std::vector<double>{0.0, 10.0}));
    }
}

// The same mistake in either format: the same message but for the file's name.
TEST(ConfigFile, JsonAndTomlRefuseTheSameMistakesNamingFileAndKeyPath) {
    const auto dir = feedid::testing::temp_dir();
    struct Case {
        std::string json;
        std::string toml;
        std::string message;  // after "settings.EXT: "
    };
    const std::vector<Case> cases{
        {R"({"controller": {"tn_mz": 15}})", "[controller]\ntn_mz = 15\n", "unknown key 'controller.tn_mz'"},
        {R"({"sede": 3})", "sede = 3\n", "unknown key 'sede'"},
        {R"({"zones": [{"from_mm": 0}, {"to_mm": 1}]})", "[[zones]]\nfrom_mm = 0\n[[zones]]\nto_mm = 1\n",
         "unknown key 'zones[1].to_mm'"},
        {R"({"controller": {"tn_ms": "fast"}})", "[controller]\ntn_ms = \"fast\"\n",
         "controller.tn_ms: must be a finite number, not a string"},
        {R"({"controller": {"saturation_N": 2e6}})", "[controller]\nsaturation_N = 2e6\n",
         "controller.saturation_N: 2000000 is outside the allowed range 0 to 1e+06 N"},
        {R"({"controller": {"log": 1}})", "[controller]\nlog = 1\n",
         "controller.log: must be true or false, not a number"},
        {R"({"controller": 3})", "controller = 3\n", "controller: must be an object (a TOML table), not a number"},
        {R"({"test": {"feedrates_mm_per_min": [1, "2"]}})", "[test]\nfeedrates_mm_per_min = [1, \"2\"]\n",
         "test.feedrates_mm_per_min: must be a list of finite numbers, not a string at [1]"},
        {R"({"zones": {"from_mm": 0}})", "[zones]\nfrom_mm = 0\n", "zones: must be a list of objects, not an object"},
    };
    for (const auto& c : cases) {
        for (const std::string extension : {"json", "toml"}) {
            const auto path = dir / ("settings." + extension);
            write_text(path, extension == "json" ? c.json : c.toml);
            const std::string message =
                refusal([&] { (void)read_settings(feedid::read_config_file(path), path.string()); });
            EXPECT_EQ(message, path.string() + ": " + c.message) << extension;
        }
    }
}

TEST(ConfigFile, TomlOnlyValuesAreRefusedAsJsonCannotHoldThem) {
    // nan and infinities, and dates, which no setting takes
    const auto nan = feedid::parse_toml("[controller]\ntn_ms = nan\n", "s.toml");
    EXPECT_EQ(refusal([&] { (void)read_settings(nan, "s.toml"); }),
              "s.toml: controller.tn_ms: must be a finite number, not nan");
    const auto date = feedid::parse_toml("seed = 2024-05-01\n", "s.toml");
    EXPECT_EQ(refusal([&] { (void)read_settings(date, "s.toml"); }),
              "s.toml: seed: must be a finite number, not a string");
}

TEST(ConfigFile, TomlSyntaxErrorsNameTheLine) {
    const std::string message = refusal([] { (void)feedid::parse_toml("[axis]\nmass_kg = = 3\n", "bad.toml"); });
    EXPECT_EQ(message.rfind("bad.toml:2: not valid TOML: ", 0), 0u) << message;
}

TEST(ConfigFile, TheLimitsOfJsonDocumentsHoldForToml) {
    // nesting: the document is level 1, each table below it one more
    std::string deep;
    for (int level = 1; level < 64; ++level) deep += (level == 1 ? "[a" : ".a");
    const auto ok = feedid::parse_toml(deep + "]\nx = 1\n", "ok.toml");
    EXPECT_TRUE(ok.is_object());
    const std::string message = refusal([&] { (void)feedid::parse_toml(deep + ".a]\nx = 1\n", "deep.toml"); });
    EXPECT_NE(message.find("deep.toml: nested deeper than 64 levels at a.a.a.a"), std::string::npos) << message;
    // size
    feedid::JsonLimits small;
    small.max_bytes = 16;
    const std::string large = refusal([&] { (void)feedid::parse_toml("seed = 1\nother = 2\n", "big.toml", small); });
    EXPECT_NE(large.find("big.toml: larger than"), std::string::npos) << large;
    // and a JSON file keeps parse_json's limits
    const auto dir = feedid::testing::temp_dir();
    write_text(dir / "deep.json", std::string(100, '[') + std::string(100, ']'));
    const std::string json = refusal([&] { (void)feedid::read_config_file(dir / "deep.json"); });
    EXPECT_NE(json.find("nested deeper than 64 levels"), std::string::npos) << json;
}

TEST(ConfigFile, NullInJsonIsNotGivenAndCanBeAskedFor) {
    const auto document = nlohmann::json::parse(R"({"saturation_N": null})");
    ConfigSection top(document, "d.json");
    EXPECT_FALSE(top.has("saturation_N"));
    EXPECT_TRUE(top.is_null("saturation_N"));
    EXPECT_FALSE(top.number("saturation_N").has_value());
    top.reject_unknown();  // taken by the getter
}

TEST(ConfigFile, ValueRangeStatesTheRangeAsEveryFrontEndDoes) {
    const feedid::ValueRange range{0.1, 600.0, "s"};
    EXPECT_TRUE(range.contains(0.1));
    EXPECT_FALSE(range.contains(601.0));
    EXPECT_EQ(range.refusal("1000"), "1000 is outside the allowed range 0.1 to 600 s");
    EXPECT_EQ((feedid::ValueRange{1, 8, ""}).refusal("9"), "9 is outside the allowed range 1 to 8");
}

}  // namespace
