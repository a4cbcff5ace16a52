// The closed-loop simulation: EMPS reproduced (published model, identified gains), stick-slip through zero velocity,
// steady-state tracking, and reading the axis from a result document.
#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/model/controller.hpp"
#include "feedid/model/drive.hpp"
#include "feedid/core/error.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/io/import.hpp"
#include "feedid/numeric/signal.hpp"
#include "feedid/sim/simulate.hpp"
#include "feedid/sim/synth.hpp"
#include "testing.hpp"

namespace {

using feedid::testing::run_cli;
using feedid::testing::shared_data;

// The published IDIM-LS result on DATA_EMPS.mat, symmetric with offset (../shared/data/README.md).
nlohmann::json published_emps_result() {
    return nlohmann::json::parse(R"({
      "model": "symmetric",
      "parameters": {
        "mass_kg": {"value": 95.1089, "stderr": 0.1085},
        "viscous_Ns_per_m": {"value": 203.5034, "stderr": 1.1460},
        "coulomb_N": {"value": 20.3935, "stderr": 0.1012},
        "offset_N": {"value": -3.1648, "stderr": 0.0444},
        "breakaway_N": {"value": null, "stderr": null},
        "stribeck_velocity_m_per_s": {"value": null, "stderr": null}
      }})");
}

std::string emps_channels() {
    return "--channel position=qm --channel reference_position=qg --channel current=vir --force-constant gtau";
}

TEST(Simulate, EmpsPublishedModelWithIdentifiedGains) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    feedid::ImportOptions import;
    import.channels[feedid::Role::position] = "qm";
    import.channels[feedid::Role::reference_position] = "qg";
    import.channels[feedid::Role::current] = "vir";
    const auto trace = feedid::read_trace(shared_data() / "emps/DATA_EMPS.mat", import);
    feedid::DriveConstants drive;
    drive.force_constant_name = "gtau";
    const auto force = feedid::drive_force(trace, drive);
    const double gtau = trace.constants.at("gtau");

    feedid::GainOptions gain_options;
    gain_options.force_per_signal = gtau;
    gain_options.saturation_N = 10.0 * gtau;  // the EMPS controller saturates at 10 V
    const auto gains = feedid::identify_gains(trace, force, gain_options);
    const auto axis = feedid::axis_from_document(published_emps_result(), "published");

    feedid::SimulationInput input;
    input.sample_time_s = trace.time_base().sample_time_s;
    input.reference = trace.column(feedid::Role::reference_position);
    feedid::SimulationOptions options;
    options.initial_position_m = trace.column(feedid::Role::position)[0];
    const auto simulated = feedid::simulate(axis, gains.controller, input, options);
    const auto metrics = feedid::validate_simulation(trace, force, simulated);
    // Acceptance (published: 0.0138 % and 5.85 %).
    EXPECT_LE(metrics.position_relative_error_pct, 0.05);
    EXPECT_LE(metrics.force_relative_error_pct, 7.0);
    // The model tracks like the machine: modelling error far below the tracking error.
    EXPECT_LT(metrics.modelling_error_mae_m, 0.05 * metrics.tracking_error_mae_machine_m);
    EXPECT_NEAR(metrics.tracking_error_mae_model_m, metrics.tracking_error_mae_machine_m,
                0.05 * metrics.tracking_error_mae_machine_m);
}

TEST(Simulate, EmpsPublishedModelCommandLine) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto dir = feedid::testing::temp_dir();
    feedid::testing::write_text(dir / "result.json", published_emps_result().dump());
    const auto result =
        run_cli("simulate '" + (shared_data() / "emps/DATA_EMPS.mat").string() + "' " + emps_channels() +
                " --saturation 10 --result '" + (dir / "result.json").string() + "' --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    EXPECT_LE(document["relative_error_pct"]["position"].get<double>(), 0.05);
    EXPECT_LE(document["relative_error_pct"]["force"].get<double>(), 7.0);
    EXPECT_TRUE(document["tracking_error_mae_m"]["model"].is_number());
    EXPECT_TRUE(document["tracking_error_mae_m"]["machine"].is_number());
    EXPECT_TRUE(document["modelling_error_mae_m"].is_number());
}

// simulate --json carries the paper's Fig. 6 as series thinned for plotting. Checked against the full-rate errors
// rebuilt independently from the --out CSV (simulated x_ref, x) and the recording (measured qm): every point is a real
// sample, the thinning keeps each error's extremes exactly, and the summary MAE is the mean over all samples.
TEST(Simulate, EmpsSeriesOfErrorsKeepsTheExtremesWithinItsBound) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto dir = feedid::testing::temp_dir();
    feedid::testing::write_text(dir / "result.json", published_emps_result().dump());
    const auto mat = shared_data() / "emps/DATA_EMPS.mat";
    const auto result = run_cli("simulate '" + mat.string() + "' " + emps_channels() + " --saturation 10 --result '" +
                                (dir / "result.json").string() + "' --json '" + (dir / "sim.json").string() +
                                "' --out '" + (dir / "sim.csv").string() + "'");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(feedid::testing::read_text(dir / "sim.json"));

    feedid::ImportOptions import;
    import.channels[feedid::Role::position] = "qm";
    import.channels[feedid::Role::reference_position] = "qg";
    const auto machine = feedid::read_trace(mat, import);
    const auto simulated = feedid::read_trace(dir / "sim.csv");
    const auto measured = machine.column(feedid::Role::position);
    const auto t = simulated.column(feedid::Role::time);
    const auto reference = simulated.column(feedid::Role::reference_position);
    const auto x_sim = simulated.column(feedid::Role::position);
    const std::size_t n = measured.size();
    ASSERT_EQ(x_sim.size(), n);
    ASSERT_EQ(n, 24841u);
    const auto qg = machine.column(feedid::Role::reference_position);
    for (std::size_t k = 0; k < n; ++k) ASSERT_EQ(reference[k], qg[k]) << k;  // the simulation ran on qg

    std::vector<double> machine_error(n), model_error(n), modelling_error(n);
    double machine_sum = 0.0, model_sum = 0.0, modelling_sum = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        machine_error[k] = qg[k] - measured[k];
        model_error[k] = reference[k] - x_sim[k];
        modelling_error[k] = measured[k] - x_sim[k];
        machine_sum += std::abs(machine_error[k]);
        model_sum += std::abs(model_error[k]);
        modelling_sum += std::abs(modelling_error[k]);
    }
    const double count = static_cast<double>(n);
    EXPECT_NEAR(document["tracking_error_mae_m"]["machine"].get<double>(), machine_sum / count, 1e-12 * machine_sum);
    EXPECT_NEAR(document["tracking_error_mae_m"]["model"].get<double>(), model_sum / count, 1e-12 * model_sum);
    EXPECT_NEAR(document["modelling_error_mae_m"].get<double>(), modelling_sum / count, 1e-12 * modelling_sum);

    EXPECT_EQ(document["rotary"], false);
    const auto& series = document["series"];
    ASSERT_TRUE(series.is_object()) << document.dump().substr(0, 300);
    EXPECT_EQ(series["samples"].get<std::size_t>(), n);
    const auto time = series["time_s"].get<std::vector<double>>();
    const std::vector<std::pair<const char*, const std::vector<double>*>> errors{
        {"tracking_error_machine_m", &machine_error},
        {"tracking_error_model_m", &model_error},
        {"modelling_error_m", &modelling_error}};
    EXPECT_LE(time.size(), feedid::validation_series_points);
    EXPECT_GT(time.size(), feedid::validation_series_points / 3) << "thinned far more than needed";
    std::vector<std::size_t> index(time.size());
    for (std::size_t i = 0; i < time.size(); ++i) {
        index[i] = static_cast<std::size_t>(std::llround(time[i] / 0.001));
        ASSERT_LT(index[i], n);
        EXPECT_EQ(time[i], t[index[i]]) << "point " << i << " is not a sample instant";
        if (i > 0) {
            EXPECT_GT(index[i], index[i - 1]) << "point " << i;
        }
    }
    for (const auto& [key, full] : errors) {
        const auto values = series[key].get<std::vector<double>>();
        ASSERT_EQ(values.size(), time.size()) << key;
        for (std::size_t i = 0; i < values.size(); ++i)
            ASSERT_EQ(values[i], (*full)[index[i]]) << key << " at point " << i;
        // Min/max thinning keeps the extremes of the full-rate error exactly (the mean it does not keep).
        const auto [low, high] = std::minmax_element(values.begin(), values.end());
        const auto [full_low, full_high] = std::minmax_element(full->begin(), full->end());
        EXPECT_EQ(*high, *full_high) << key;
        EXPECT_EQ(*low, *full_low) << key;
    }
    double largest_model = 0.0;
    for (const double e : model_error) largest_model = std::max(largest_model, std::abs(e));
    EXPECT_EQ(document["tracking_error_max_m"]["model"].get<double>(), largest_model);
}

// The thinning keeps a one-sample spike in each signal and is the identity on short signals.
TEST(Simulate, ExtremePreservingThinningKeepsSpikes) {
    const std::size_t n = 100000;
    std::vector<double> smooth(n), spiky(n, 0.0);
    for (std::size_t k = 0; k < n; ++k) smooth[k] = std::sin(1e-4 * static_cast<double>(k));
    spiky[31337] = 5.0;
    spiky[31338] = -4.0;
    spiky[77777] = std::nan("");
    const std::array<std::span<const double>, 2> signals{smooth, spiky};
    const auto kept = feedid::extreme_preserving_indices(signals, n, 400);
    EXPECT_LE(kept.size(), 400u);
    EXPECT_TRUE(std::is_sorted(kept.begin(), kept.end()));
    EXPECT_EQ(std::adjacent_find(kept.begin(), kept.end()), kept.end()) << "an index kept twice";
    EXPECT_NE(std::find(kept.begin(), kept.end(), 31337u), kept.end());
    EXPECT_NE(std::find(kept.begin(), kept.end(), 31338u), kept.end());
    EXPECT_EQ(std::find(kept.begin(), kept.end(), 77777u), kept.end()) << "a NaN kept over numbers";
    const auto largest = std::max_element(smooth.begin(), smooth.end()) - smooth.begin();
    EXPECT_NE(std::find(kept.begin(), kept.end(), static_cast<std::size_t>(largest)), kept.end());
    const auto all = feedid::extreme_preserving_indices(signals, 300, 400);
    ASSERT_EQ(all.size(), 300u);
    for (std::size_t k = 0; k < all.size(); ++k) EXPECT_EQ(all[k], k);
}

// The whole pipeline, as a user runs it: identify (symmetric with offset), gains, simulate.
TEST(Simulate, EmpsIdentifyGainsSimulatePipeline) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto dir = feedid::testing::temp_dir();
    const std::string file = "'" + (shared_data() / "emps/DATA_EMPS.mat").string() + "' ";
    const auto identified = run_cli("identify " + file +
                                    "--channel position=qm --channel current=vir --force-constant gtau --offset "
                                    "--json '" +
                                    (dir / "result.json").string() + "'");
    ASSERT_EQ(identified.exit_code, 0) << identified.err;
    const auto gains =
        run_cli("gains " + file + emps_channels() + " --saturation 10 --json '" + (dir / "gains.json").string() + "'");
    ASSERT_EQ(gains.exit_code, 0) << gains.err;
    const auto result = run_cli("simulate " + file + emps_channels() + " --result '" + (dir / "result.json").string() +
                                "' --gains '" + (dir / "gains.json").string() + "' --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    EXPECT_LE(document["relative_error_pct"]["position"].get<double>(), 0.05);
    EXPECT_LE(document["relative_error_pct"]["force"].get<double>(), 7.0);
    EXPECT_EQ(document["controller"]["saturation_N"].get<double>(), 10.0 * 35.15065188248547);
}

feedid::AxisModel stick_slip_axis(double offset) {
    feedid::FrictionBranch branch;
    branch.viscous = 50.0;
    branch.coulomb = 100.0;
    branch.breakaway = 150.0;
    branch.stribeck_velocity = 0.002;
    feedid::AxisModel axis;
    axis.mass = 20.0;
    axis.friction = feedid::Friction::symmetric(branch);
    axis.offset = offset;
    return axis;
}

// A P-P loop whose drive force grows with a slowly rising reference while the axis sticks:
// F_d = K_p*K_v*(x_ref - x) - K_p*v. The axis must not move at all until F_d - F_0 exceeds F_B.
void expect_breakaway_at_the_breakaway_force(double offset) {
    const auto axis = stick_slip_axis(offset);
    feedid::ControllerModel controller;
    controller.position_gain_per_s = 20.0;
    controller.velocity_gain_N_s_per_m = 2000.0;  // K_p*K_v = 40 N/mm
    const double dt = 1e-3;
    std::vector<double> reference(8000);
    for (std::size_t k = 0; k < reference.size(); ++k) reference[k] = 1e-6 * static_cast<double>(k);  // 1 mm/s
    feedid::SimulationInput input;
    input.sample_time_s = dt;
    input.reference = reference;
    const auto out = feedid::simulate(axis, controller, input);
    const auto first_moving = static_cast<std::size_t>(
        std::find_if(out.velocity.begin(), out.velocity.end(), [](double v) { return v != 0.0; }) -
        out.velocity.begin());
    ASSERT_LT(first_moving, out.velocity.size()) << "the axis never broke away";
    ASSERT_GT(first_moving, 1u);
    for (std::size_t k = 0; k < first_moving; ++k) {
        ASSERT_EQ(out.position[k], reference[0]) << "crept at sample " << k;
        ASSERT_EQ(out.velocity[k], 0.0);
    }
    // While stuck, the drive force stayed within the breakaway force; in the interval where it started, the drive
    // force exceeded it (F_d rises by 0.04 N per sample).
    for (std::size_t k = 0; k + 1 < first_moving; ++k) {
        ASSERT_LE(out.force[k] - offset, 150.0 + 1e-9) << "stuck above breakaway at sample " << k;
    }
    EXPECT_GT(out.force[first_moving - 1] - offset, 150.0);
    EXPECT_LT(out.force[first_moving - 1] - offset, 150.0 + 0.05);
    // Upwards, in the direction of the net force.
    EXPECT_GT(out.velocity[first_moving], 0.0);
}

TEST(Simulate, StaysAtRestBelowBreakawayAndStartsAboveIt) {
    expect_breakaway_at_the_breakaway_force(0.0);
}

TEST(Simulate, VerticalAxisHeldByStaticFrictionStartsAtBreakawayPlusWeight) {
    // The weight (offset 80 N) is below F_B: static friction holds the axis; it moves up once F_d > F_0 + F_B.
    expect_breakaway_at_the_breakaway_force(80.0);
}

TEST(Simulate, FrictionZoneRaisesTheBreakawayForceWhereTheAxisStands) {
    // The same ramp of drive force, the axis standing in a stretch with 1.3 times the Coulomb and breakaway friction:
    // it breaks away at 1.3 * F_B = 195 N, not at 150 N; outside the stretch the axis model's friction holds.
    const auto axis = stick_slip_axis(0.0);
    feedid::ControllerModel controller;
    controller.position_gain_per_s = 20.0;
    controller.velocity_gain_N_s_per_m = 2000.0;
    std::vector<double> reference(8000);
    for (std::size_t k = 0; k < reference.size(); ++k) reference[k] = 1e-6 * static_cast<double>(k);
    feedid::SimulationInput input;
    input.sample_time_s = 1e-3;
    input.reference = reference;
    for (const auto& [from, to, breakaway] : {std::tuple{-0.01, 0.01, 195.0}, std::tuple{0.02, 0.03, 150.0}}) {
        feedid::SimulationOptions options;
        options.friction_zones = {{from, to, 1.3}};
        const auto out = feedid::simulate(axis, controller, input, options);
        const auto first_moving = static_cast<std::size_t>(
            std::find_if(out.velocity.begin(), out.velocity.end(), [](double v) { return v != 0.0; }) -
            out.velocity.begin());
        ASSERT_LT(first_moving, out.velocity.size()) << "the axis never broke away";
        for (std::size_t k = 0; k + 1 < first_moving; ++k) ASSERT_LE(out.force[k], breakaway + 1e-9) << k;
        EXPECT_GT(out.force[first_moving - 1], breakaway);
        EXPECT_LT(out.force[first_moving - 1], breakaway + 0.05);
    }
    feedid::SimulationOptions reversed;
    reversed.friction_zones = {{0.01, -0.01, 1.3}};
    EXPECT_THROW((void)feedid::simulate(axis, controller, input, reversed), feedid::InputError);
}

TEST(Simulate, ReusedOutputHoldsTheSameRunAsAFreshOne) {
    const auto axis = stick_slip_axis(0.0);
    feedid::ControllerModel controller;
    controller.position_gain_per_s = 30.0;
    controller.velocity_gain_N_s_per_m = 3000.0;
    std::vector<double> reference(3000);
    for (std::size_t k = 0; k < reference.size(); ++k) reference[k] = 0.02 * std::sin(1e-3 * static_cast<double>(k));
    feedid::SimulationInput input;
    input.sample_time_s = 1e-3;
    input.reference = reference;
    feedid::SimulationOutput reused;
    feedid::simulate(axis, controller, input, {}, reused);  // a longer run first ...
    input.reference = std::span<const double>(reference).first(1000);
    feedid::simulate(axis, controller, input, {}, reused);  // ... then a shorter one into the same output
    const auto fresh = feedid::simulate(axis, controller, input);
    EXPECT_EQ(reused.position, fresh.position);
    EXPECT_EQ(reused.force, fresh.force);
    EXPECT_EQ(reused.time.size(), 1000u);
    EXPECT_EQ(reused.stick_transitions, fresh.stick_transitions);
}

TEST(Simulate, NoChatteringAtRestAfterAStop) {
    // Move, then hold still: after the stop the axis rests (velocity exactly 0) without chattering about zero.
    const auto axis = stick_slip_axis(0.0);
    feedid::ControllerModel controller;
    controller.position_gain_per_s = 30.0;
    controller.velocity_gain_N_s_per_m = 3000.0;
    controller.velocity_integral_gain_N_per_m = 3000.0 / 0.02;
    std::vector<double> reference(6000, 0.0);
    for (std::size_t k = 0; k < 1000; ++k) reference[k] = 0.01 * static_cast<double>(k) / 1000.0;
    std::fill(reference.begin() + 1000, reference.end(), 0.01);
    feedid::SimulationInput input;
    input.sample_time_s = 1e-3;
    input.reference = reference;
    const auto out = feedid::simulate(axis, controller, input);
    // Integral action against Stribeck friction hunts after the stop (the classic stick-slip limit cycle: the
    // integrator winds up while the axis sticks, breaks it loose, it overshoots and sticks again), but the axis rests
    // for long stretches rather than crossing zero velocity every step, and at rest it does not creep.
    const std::size_t tail = 2000;
    std::size_t at_rest = 0;
    for (std::size_t k = out.velocity.size() - tail; k < out.velocity.size(); ++k) at_rest += out.velocity[k] == 0.0;
    EXPECT_GT(at_rest, tail * 9 / 10);
    EXPECT_LT(out.stick_transitions, 20u);
    for (std::size_t k = 1000; k + 1 < out.velocity.size(); ++k) {
        if (out.velocity[k] == 0.0 && out.velocity[k + 1] == 0.0 && std::abs(out.force[k]) < 150.0) {
            ASSERT_EQ(out.position[k + 1], out.position[k]) << "crept at rest at sample " << k;
        }
    }
    for (std::size_t k = 1500; k < out.position.size(); ++k) ASSERT_NEAR(out.position[k], 0.01, 2e-4);
}

TEST(Simulate, FrictionlessRampHasTheFollowingErrorOfAPPositionLoop) {
    // A P position loop following a ramp of speed v lags by v / K_v in steady state.
    feedid::AxisModel axis;
    axis.mass = 50.0;
    feedid::ControllerModel controller;
    controller.position_gain_per_s = 25.0;
    controller.velocity_gain_N_s_per_m = 10000.0;
    controller.velocity_integral_gain_N_per_m = 10000.0 / 0.01;
    const double speed = 0.05;
    std::vector<double> reference(4000);
    for (std::size_t k = 0; k < reference.size(); ++k) reference[k] = speed * 1e-3 * static_cast<double>(k);
    feedid::SimulationInput input;
    input.sample_time_s = 1e-3;
    input.reference = reference;
    const auto out = feedid::simulate(axis, controller, input);
    EXPECT_NEAR(out.tracking_error.back(), speed / 25.0, 1e-3 * speed / 25.0 + 1e-6);
    EXPECT_NEAR(out.velocity.back(), speed, 1e-6);
    // With full velocity feed-forward the steady following error vanishes.
    controller.velocity_feedforward = 1.0;
    const auto fed = feedid::simulate(axis, controller, input);
    EXPECT_LT(std::abs(fed.tracking_error.back()), 1e-6);
}

TEST(Simulate, ExternalForcePushesAPLoopOffByForceOverStiffness) {
    // P-P cascade on a frictionless axis, held at a fixed reference against a constant external force F: at rest
    // K_p*K_v*(x_ref - x) = -F, so the axis settles F/(K_p*K_v) away from the reference, in the direction of F.
    feedid::AxisModel axis;
    axis.mass = 40.0;
    feedid::ControllerModel controller;
    controller.position_gain_per_s = 20.0;
    controller.velocity_gain_N_s_per_m = 2000.0;
    const std::vector<double> reference(4000, 0.1);
    const std::vector<double> external(reference.size(), 100.0);
    feedid::SimulationInput input;
    input.sample_time_s = 1e-3;
    input.reference = reference;
    input.external_force = external;
    const auto out = feedid::simulate(axis, controller, input);
    EXPECT_NEAR(out.tracking_error.back(), -100.0 / (20.0 * 2000.0), 1e-7);
    EXPECT_NEAR(out.force.back(), -100.0, 1e-3);
    const std::vector<double> short_force(10, 1.0);
    input.external_force = short_force;
    EXPECT_THROW((void)feedid::simulate(axis, controller, input), feedid::InputError);
}

TEST(Simulate, CommandLineWritesTheSimulatedSignals) {
    // feedid simulate --out: the simulated signals as CSV, read back with their roles and units; with the true drive
    // as the "identified" one the simulated position follows the synthetic machine's.
    const auto dir = feedid::testing::temp_dir();
    const std::string trace = "'" + (dir / "synth.csv").string() + "'";
    ASSERT_EQ(run_cli("synth --no-slow-passes --out " + trace).exit_code, 0);
    feedid::testing::write_text(dir / "result.json", R"({"parameters": {
        "mass_kg": {"value": 69.1}, "viscous_Ns_per_m": {"value": 54.2}, "coulomb_N": {"value": 742.8},
        "breakaway_N": {"value": 946.2}, "stribeck_velocity_m_per_s": {"value": 0.005}}})");
    const auto result = run_cli("simulate " + trace + " --force-constant force_constant_N_per_A --result '" +
                                (dir / "result.json").string() + "' --out '" + (dir / "sim.csv").string() + "'");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto simulated = feedid::read_trace(dir / "sim.csv");
    const auto machine = feedid::read_trace(dir / "synth.csv");
    ASSERT_EQ(simulated.samples(), machine.samples());
    for (const auto role : {feedid::Role::time, feedid::Role::reference_position, feedid::Role::position,
                            feedid::Role::velocity, feedid::Role::velocity_command, feedid::Role::force}) {
        EXPECT_TRUE(simulated.has(role)) << static_cast<int>(role);
    }
    const auto x = simulated.column(feedid::Role::position);
    const auto x_machine = machine.column(feedid::Role::position);
    double largest = 0.0;
    for (std::size_t k = 0; k < x.size(); ++k) largest = std::max(largest, std::abs(x[k] - x_machine[k]));
    EXPECT_LT(largest, 1e-4) << "the true model tracks the synthetic machine";
    EXPECT_EQ(simulated.find(feedid::Role::position)->unit, "m");
}

TEST(Simulate, FasterVelocityLoopThanThePositionLoop) {
    // Position loop every 2 ms, velocity loop every 125 us, on a 1 kHz reference: still tracks a ramp.
    feedid::AxisModel axis;
    axis.mass = 50.0;
    axis.friction = feedid::Friction::symmetric({100.0, 200.0, std::nullopt, std::nullopt});
    feedid::ControllerModel controller;
    controller.position_gain_per_s = 30.0;
    controller.velocity_gain_N_s_per_m = 20000.0;
    controller.velocity_integral_gain_N_per_m = 20000.0 / 0.01;
    controller.position_cycle_s = 2e-3;
    controller.velocity_cycle_s = 125e-6;
    controller.current_lag_s = 0.2e-3;
    std::vector<double> reference(3000);
    for (std::size_t k = 0; k < reference.size(); ++k) reference[k] = 0.03 * 1e-3 * static_cast<double>(k);
    feedid::SimulationInput input;
    input.sample_time_s = 1e-3;
    input.reference = reference;
    const auto out = feedid::simulate(axis, controller, input);
    EXPECT_NEAR(out.velocity.back(), 0.03, 1e-4);
    EXPECT_NEAR(out.tracking_error.back(), 0.03 / 30.0, 0.1 * 0.03 / 30.0);
}

TEST(Simulate, AxisFromSymmetricAndAsymmetricDocuments) {
    const auto symmetric = feedid::axis_from_document(published_emps_result(), "r");
    EXPECT_DOUBLE_EQ(symmetric.mass, 95.1089);
    EXPECT_DOUBLE_EQ(symmetric.offset, -3.1648);
    EXPECT_DOUBLE_EQ(symmetric.friction.reverse.coulomb, 20.3935);
    EXPECT_FALSE(symmetric.friction.forward.has_stribeck());

    const auto asymmetric = feedid::axis_from_document(nlohmann::json::parse(R"({"parameters": {
        "mass_kg": {"value": 95.154},
        "viscous_forward_Ns_per_m": {"value": 166.7061}, "viscous_reverse_Ns_per_m": {"value": 240.4236},
        "coulomb_forward_N": {"value": 20.144}, "coulomb_reverse_N": {"value": 20.6277},
        "breakaway_forward_N": {"value": 25.0}, "breakaway_reverse_N": {"value": null},
        "stribeck_velocity_forward_m_per_s": {"value": 0.004}, "stribeck_velocity_reverse_m_per_s": {"value": null}
      }})"),
                                                       "r");
    EXPECT_DOUBLE_EQ(asymmetric.friction.forward.viscous, 166.7061);
    EXPECT_DOUBLE_EQ(asymmetric.friction.reverse.viscous, 240.4236);
    EXPECT_DOUBLE_EQ(asymmetric.friction.reverse.coulomb, 20.6277);
    EXPECT_TRUE(asymmetric.friction.forward.has_stribeck());
    EXPECT_FALSE(asymmetric.friction.reverse.has_stribeck());
    EXPECT_DOUBLE_EQ(asymmetric.friction.breakaway_force(true), 25.0);
    EXPECT_DOUBLE_EQ(asymmetric.friction.breakaway_force(false), 20.6277);
}

TEST(Simulate, ResultWithoutMassIsBadInput) {
    EXPECT_THROW(feedid::axis_from_document(nlohmann::json::parse(R"({"parameters": {"mass_kg": {"value": null},
        "coulomb_N": {"value": 1}}})"),
                                            "r.json"),
                 feedid::InputError);
    EXPECT_THROW(feedid::axis_from_document(nlohmann::json::parse("[1, 2]"), "r.json"), feedid::InputError);
    try {
        feedid::axis_from_document(nlohmann::json::parse(R"({"parameters": {"mass_kg": {"value": 3}}})"), "r.json");
        FAIL() << "expected an InputError";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("r.json"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("coulomb"), std::string::npos) << e.what();
    }
}

TEST(Simulate, MissingResultFileIsExitCode2) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto result =
        run_cli("simulate '" + (shared_data() / "emps/DATA_EMPS.mat").string() + "' " + emps_channels() +
                " --unit time=s --unit position=m --unit reference_position=m --unit current=V "
                "--result /nonexistent/result.json");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_EQ(feedid::testing::count_lines(result.err), 1) << result.err;
}

// A trace of 100 samples at 1 ms: enough for documented_twin_controller to read the sample time from.
feedid::Trace millisecond_trace() {
    feedid::Trace trace;
    std::vector<double> time(100);
    for (std::size_t k = 0; k < time.size(); ++k) time[k] = 1e-3 * static_cast<double>(k);
    trace.set("t", feedid::Role::time, "s", time);
    return trace;
}

TEST(Simulate, TwinControllerFromAGainsDocumentTakesTheOptionsDriveSettings) {
    const auto document = nlohmann::json::parse(R"({"gains": {
        "position_gain_per_s": {"value": 30.0, "stderr": 0.1}, "velocity_gain_N_s_per_m": {"value": 1000.0},
        "velocity_integral_gain_N_per_m": {"value": 5e4}},
        "structure": {"velocity_difference_samples": 1, "current_lag_s": 1e-4, "saturation_N": 80}})");
    const auto trace = millisecond_trace();
    const auto as_documented = feedid::documented_twin_controller(document, "gains.json", {}, trace);
    EXPECT_EQ(as_documented.model.position_gain_per_s, 30.0);
    EXPECT_EQ(as_documented.model.velocity_integral_gain_N_per_m, 5e4);
    EXPECT_EQ(as_documented.model.saturation_N, 80.0);
    EXPECT_EQ(as_documented.model.current_lag_s, 1e-4);
    EXPECT_TRUE(as_documented.notes.empty());
    // The document has no sample time: both loops run at the trace's.
    EXPECT_NEAR(as_documented.model.position_cycle_s, 1e-3, 1e-12);
    EXPECT_EQ(as_documented.model.velocity_cycle_s, as_documented.model.position_cycle_s);

    feedid::GainOptions options;
    options.saturation_N = 50.0;
    options.current_lag_s = 2e-4;
    options.velocity_difference_samples = 2;
    const auto overridden = feedid::documented_twin_controller(document, "gains.json", options, trace);
    EXPECT_EQ(overridden.model.saturation_N, 50.0);
    EXPECT_EQ(overridden.model.current_lag_s, 2e-4);
    EXPECT_EQ(overridden.model.velocity_difference_samples, 2);
    EXPECT_EQ(overridden.model.velocity_gain_N_s_per_m, 1000.0);

    try {
        (void)feedid::documented_twin_controller(nlohmann::json::parse(R"({"gains": {}})"), "gains.json", {}, trace);
        FAIL() << "expected an InputError";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("gains.json"), std::string::npos) << e.what();
    }
}

// The demo drive's synthetic trace, its drive force, and its true axis and controller.
struct SyntheticRecording {
    feedid::SynthSpec spec = feedid::demo_spec();
    feedid::Trace trace;
    std::vector<double> force;
    SyntheticRecording() {
        spec.test.feedrates_mm_per_min = {1250, 4000};
        spec.test.slow_passes = false;
        trace = feedid::synthesize(spec);
        feedid::DriveConstants drive;
        drive.force_constant_name = "force_constant_N_per_A";
        force = feedid::drive_force(trace, drive);
    }
};

TEST(Simulate, TwinControllerWithoutADocumentIsIdentifiedFromTheTrace) {
    const SyntheticRecording recording;
    const auto controller = feedid::identified_twin_controller(recording.trace, recording.force, {});
    const auto identified = feedid::identify_gains(recording.trace, recording.force).controller;
    EXPECT_EQ(controller.model.position_gain_per_s, identified.position_gain_per_s);
    EXPECT_EQ(controller.model.velocity_gain_N_s_per_m, identified.velocity_gain_N_s_per_m);
    EXPECT_EQ(controller.model.velocity_integral_gain_N_per_m, identified.velocity_integral_gain_N_per_m);
    EXPECT_NEAR(controller.model.velocity_gain_N_s_per_m, recording.spec.controller.velocity_gain_N_s_per_m,
                0.03 * recording.spec.controller.velocity_gain_N_s_per_m);
    ASSERT_EQ(controller.notes.size(), 1u);
    EXPECT_EQ(controller.notes[0].rfind("gains identified from the trace: K_v ", 0), 0u) << controller.notes[0];
}

TEST(Simulate, TraceSimulationStartsWhereTheMachineStartedAndItsDocumentSaysWhatRan) {
    const SyntheticRecording recording;
    const feedid::TwinController controller{recording.spec.controller, {"a note"}};
    const auto simulation =
        feedid::simulate_trace(recording.trace, recording.force, recording.spec.axis, controller.model);

    // The same as simulate() on the trace's reference, from the trace's first position.
    feedid::SimulationInput input;
    input.sample_time_s = recording.trace.time_base().sample_time_s;
    input.reference = recording.trace.column(feedid::Role::reference_position);
    feedid::SimulationOptions options;
    options.initial_position_m = recording.trace.column(feedid::Role::position)[0];
    const auto direct = feedid::simulate(recording.spec.axis, controller.model, input, options);
    EXPECT_EQ(simulation.output.position, direct.position);
    EXPECT_EQ(simulation.output.force, direct.force);
    // The true axis and controller reproduce the machine.
    EXPECT_LT(simulation.metrics.modelling_error_mae_m, 0.02 * simulation.metrics.tracking_error_mae_machine_m);

    const auto document = feedid::simulation_document(recording.trace, controller, simulation);
    EXPECT_EQ(document["relative_error_pct"], feedid::validation_document(simulation.metrics)["relative_error_pct"]);
    EXPECT_EQ(document["trace"]["samples"].get<std::size_t>(), recording.trace.samples());
    EXPECT_EQ(document["trace"]["sample_time_s"].get<double>(), input.sample_time_s);
    EXPECT_EQ(document["controller"]["velocity_gain_N_s_per_m"].get<double>(),
              controller.model.velocity_gain_N_s_per_m);
    ASSERT_TRUE(controller.model.saturation_N);
    EXPECT_EQ(document["controller"]["saturation_N"].get<double>(), *controller.model.saturation_N);
    EXPECT_FALSE(document["rotary"].get<bool>());
    EXPECT_TRUE(document["series"].contains("tracking_error_machine_m"));
    EXPECT_EQ(document["diagnostics"], nlohmann::json::array({"a note"}));
}

}  // namespace
