// run_twin: the one orchestration of a recorded trace's twin that `feedid simulate` and Python's feedid.simulate both
// call. It simulates what the pieces simulate, refuses a result that is not of this axis (axis kind, units, sign) and
// gains of the other axis kind with the command line's messages, and says why a twin failed.
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/model/drive.hpp"
#include "feedid/sim/synth.hpp"
#include "feedid/sim/twin.hpp"

namespace {

using feedid::Term;

// The demo drive's synthetic recording (two feedrates, no slow passes), named as a file would name it.
struct Recording {
    feedid::SynthSpec spec = feedid::demo_spec();
    feedid::Trace trace;
    nlohmann::json drive_file;  // the drive file of the true axis: a result document run_twin accepts
    Recording() {
        spec.test.feedrates_mm_per_min = {1250, 4000};
        spec.test.slow_passes = false;
        trace = feedid::synthesize(spec);
        trace.source_path = "demo.csv";
        drive_file = feedid::spec_to_json(spec);
    }
    static feedid::TwinOptions options() {
        feedid::TwinOptions options;
        options.drive.force_constant_name = "force_constant_N_per_A";
        return options;
    }
};

const Recording& recording() {
    static const Recording made;
    return made;
}

std::string input_error(const feedid::Trace& trace, const nlohmann::json& result,
                        const std::optional<nlohmann::json>& gains, const feedid::TwinOptions& options) {
    try {
        (void)feedid::run_twin(trace, {result, "result.json"},
                               gains ? std::optional<feedid::TwinDocument>({*gains, "gains.json"}) : std::nullopt,
                               options);
    } catch (const feedid::InputError& e) {
        return e.what();
    }
    return "no InputError";
}

bool starts_with(const std::string& text, const std::string& prefix) {
    return text.rfind(prefix, 0) == 0;
}

TEST(Twin, SimulatesWhatItsPiecesSimulateWithTheGainsIdentifiedFromTheTrace) {
    const auto& r = recording();
    auto options = Recording::options();
    options.simulation.substeps = 4;
    const feedid::Twin twin = feedid::run_twin(r.trace, {r.drive_file, "drive.json"}, std::nullopt, options);
    EXPECT_EQ(twin.status, feedid::Status::ok);
    EXPECT_EQ(twin.failure, "");
    EXPECT_EQ(twin.axis.mass, r.spec.axis.mass);

    const auto force = feedid::drive_force(r.trace, options.drive);
    feedid::GainOptions gain_options;
    feedid::set_drive_signal(gain_options, r.trace, options.drive, std::nullopt);
    const auto controller = feedid::identified_twin_controller(r.trace, force, gain_options);
    EXPECT_EQ(twin.controller.model.velocity_gain_N_s_per_m, controller.model.velocity_gain_N_s_per_m);
    EXPECT_EQ(twin.controller.notes, controller.notes);
    const auto direct = feedid::simulate_trace(r.trace, force, feedid::axis_from_document(r.drive_file, "drive.json"),
                                               controller.model, options.simulation);
    EXPECT_EQ(twin.simulation.output.position, direct.output.position);
    EXPECT_EQ(twin.simulation.output.force, direct.output.force);
    // The true axis in closed loop with the identified gains follows the machine.
    EXPECT_LT(twin.simulation.metrics.modelling_error_mae_m,
              0.1 * twin.simulation.metrics.tracking_error_mae_machine_m);

    EXPECT_EQ(feedid::twin_document(r.trace, twin),
              feedid::simulation_document(r.trace, twin.controller, twin.simulation));
    std::vector<std::string> diagnostics = twin.controller.notes;
    diagnostics.insert(diagnostics.end(), twin.simulation.diagnostics.begin(), twin.simulation.diagnostics.end());
    EXPECT_EQ(twin.diagnostics(), diagnostics);
}

TEST(Twin, TheGainsDocumentsControllerTakesTheSaturationInDriveSignalUnits) {
    const auto& r = recording();
    auto options = Recording::options();
    const auto force = feedid::drive_force(r.trace, options.drive);
    const auto gains = feedid::identify_gains(r.trace, force);
    const auto document = feedid::gains_document(gains, {}, r.trace);
    options.saturation = 10.0;  // in A, the trace's drive signal
    const feedid::Twin twin =
        feedid::run_twin(r.trace, {r.drive_file, "drive.json"}, feedid::TwinDocument{document, "gains.json"}, options);
    EXPECT_EQ(twin.status, feedid::Status::ok) << twin.failure;
    ASSERT_TRUE(twin.controller.model.saturation_N);
    EXPECT_DOUBLE_EQ(*twin.controller.model.saturation_N, 10.0 * r.trace.constants.at("force_constant_N_per_A"));
    EXPECT_TRUE(twin.controller.notes.empty());
}

// The model does not fit: a result in other units (mass and friction 1000 times too large, as mm or mN would give)
// or a drive signal of the opposite sign. Refused as bad input with the command line's message, before any
// simulation.
TEST(Twin, RefusesAResultThatDoesNotFitTheTrace) {
    const auto& r = recording();
    nlohmann::json scaled = r.drive_file;
    for (auto& [key, value] : scaled["axis"].items()) {
        const auto parameter = feedid::parse_parameter_key(key);
        if (parameter && parameter->term != Term::stribeck_velocity && value.is_number())
            value = value.get<double>() * 1000.0;
    }
    std::string error = input_error(r.trace, scaled, std::nullopt, Recording::options());
    EXPECT_TRUE(starts_with(error, "result.json: the result does not fit the trace demo.csv: ")) << error;
    EXPECT_NE(error.find("0.001"), std::string::npos) << error;

    auto flipped = Recording::options();
    flipped.drive.force_constant_name.clear();
    flipped.drive.force_constant = -r.trace.constants.at("force_constant_N_per_A");
    error = input_error(r.trace, r.drive_file, std::nullopt, flipped);
    EXPECT_TRUE(starts_with(error, "result.json: the result does not fit the trace demo.csv: ")) << error;
    EXPECT_NE(error.find("opposite"), std::string::npos) << error;
}

TEST(Twin, RefusesAResultOrGainsOfTheOtherAxisKind) {
    const auto& r = recording();
    const nlohmann::json rotary = feedid::spec_to_json(feedid::rotary_demo_spec());
    EXPECT_EQ(input_error(r.trace, rotary, std::nullopt, Recording::options()),
              "result.json: the result is of a rotary axis, the trace demo.csv of a linear axis");
    const auto gains = nlohmann::json::parse(R"({"rotary": true, "gains": {"position_gain_per_s": {"value": 33.3},
        "velocity_gain_Nms_per_rad": {"value": 5.0}}, "structure": {"sample_time_s": 0.001}})");
    EXPECT_EQ(input_error(r.trace, r.drive_file, std::optional<nlohmann::json>(gains), Recording::options()),
              "gains.json: the gains are of a rotary axis, the trace demo.csv of a linear axis");
}

TEST(Twin, RefusesBadOptionsAndAResultWithoutItsMass) {
    const auto& r = recording();
    auto options = Recording::options();
    options.gains.velocity_difference_samples = 9;
    EXPECT_EQ(input_error(r.trace, r.drive_file, std::nullopt, options),
              "--velocity-difference must be between 1 and 8 samples");
    nlohmann::json massless = r.drive_file;
    massless["axis"].erase(feedid::ParameterNaming{}.key(Term::mass));
    EXPECT_TRUE(starts_with(input_error(r.trace, massless, std::nullopt, Recording::options()), "result.json: "));
}

// Gains 200 times too high for the mass: the loop diverges. Not an exception: the twin failed, and says why first.
TEST(Twin, ADivergingTwinFailsWithTheSimulationsReasonFirst) {
    const auto& r = recording();
    const auto options = Recording::options();
    const auto force = feedid::drive_force(r.trace, options.drive);
    auto document = feedid::gains_document(feedid::identify_gains(r.trace, force), {}, r.trace);
    auto& velocity_gain = document["gains"][feedid::ParameterNaming{}.velocity_gain_key()]["value"];
    velocity_gain = velocity_gain.get<double>() * 200.0;
    const feedid::Twin twin =
        feedid::run_twin(r.trace, {r.drive_file, "drive.json"}, feedid::TwinDocument{document, "gains.json"}, options);
    EXPECT_EQ(twin.status, feedid::Status::failed);
    EXPECT_EQ(twin.simulation.status, feedid::Status::failed);
    ASSERT_FALSE(twin.simulation.diagnostics.empty());
    EXPECT_EQ(twin.failure, twin.simulation.diagnostics.front());
    EXPECT_EQ(feedid::twin_document(r.trace, twin)["status"], "failed");
}

}  // namespace
