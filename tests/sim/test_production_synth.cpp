// Production traces (issue 15's test data): each example program synthesizes into one multi-axis trace that feedid's
// import reads per axis; the cutting force is in the drive signal (with and without cutting, the difference is the
// model's force as the closed loop passes it to the drive); the spindle load follows the cutting; the machine file.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <numeric>

#include "feedid/core/error.hpp"
#include "feedid/plan/gcode_reader.hpp"
#include "feedid/io/csv.hpp"
#include "feedid/io/import.hpp"
#include "feedid/sim/production_synth.hpp"
#include "testing.hpp"

namespace {

const std::filesystem::path programs = std::filesystem::path(FEEDID_TEST_SOURCE_DIR) / ".." / "examples" / "programs";

std::vector<double> moving_average(const std::vector<double>& x, std::size_t half_width) {
    std::vector<double> sums(x.size() + 1, 0.0);
    for (std::size_t k = 0; k < x.size(); ++k) sums[k + 1] = sums[k] + x[k];
    std::vector<double> out(x.size(), 0.0);
    for (std::size_t k = half_width; k + half_width < x.size(); ++k)
        out[k] = (sums[k + half_width + 1] - sums[k - half_width]) / static_cast<double>(2 * half_width + 1);
    return out;
}

class ProductionProgram : public ::testing::TestWithParam<std::string> {};

TEST_P(ProductionProgram, SynthesizesATraceImportReadsPerAxis) {
    const auto program = feedid::read_gcode_file(programs / GetParam());
    const auto machine = feedid::default_machine();
    feedid::ProductionOptions options;
    options.seed = 3;
    const auto start = std::chrono::steady_clock::now();
    const auto trace = feedid::synthesize_production(program, machine, options);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << GetParam() << ": synthesize_production " << seconds << " s for " << trace.samples() << " samples\n";

    std::vector<std::string> names;
    for (const auto& channel : trace.channels) names.push_back(channel.name);
    const std::vector<std::string> expected{"t",   "X_x_ref", "X_x", "X_i", "Y_x_ref",      "Y_x",
                                            "Y_i", "Z_x_ref", "Z_x", "Z_i", "spindle_load", "spindle_speed"};
    EXPECT_EQ(names, expected);
    for (std::size_t i = 0; i < 3; ++i) {
        const std::string a(1, "XYZ"[i]);
        EXPECT_EQ(trace.constants.at(a + "_true_mass_kg"), machine.drives[i].axis.mass);
        EXPECT_EQ(trace.constants.at(a + "_true_coulomb_forward_N"), machine.drives[i].axis.friction.forward.coulomb);
        EXPECT_EQ(trace.constants.at(a + "_force_constant_N_per_A"), machine.drives[i].force_constant_N_per_A());
        EXPECT_LE(trace.constants.at(a + "_peak_cutting_force_N"),
                  0.3 * trace.constants.at(a + "_drive_force_N") * (1 + 1e-12));
    }

    // Written and read back as `feedid identify FILE --axis Y` does: the Y channels get their roles.
    const auto path = feedid::testing::temp_dir() / "production.csv";
    feedid::testing::write_text(path, feedid::write_csv(trace));
    feedid::ImportOptions import;
    import.axis = "Y";
    const auto read = feedid::read_trace(path, import);
    ASSERT_NE(read.find(feedid::Role::position), nullptr);
    EXPECT_EQ(read.find(feedid::Role::position)->name, "Y_x");
    EXPECT_EQ(read.find(feedid::Role::reference_position)->name, "Y_x_ref");
    EXPECT_EQ(read.find(feedid::Role::current)->name, "Y_i");
    EXPECT_EQ(read.samples(), trace.samples());
    EXPECT_EQ(read.constants.at("Y_true_mass_kg"), 320.0);
}

INSTANTIATE_TEST_SUITE_P(Examples, ProductionProgram, ::testing::Values("pocket.ngc", "contour.ngc", "drilling.ngc"));

// With and without cutting (same seed: the same sensor noise), the drive force differs by the cutting force the
// closed loop passes to the drive: below its bandwidth (K_p/M = 220 rad/s on X) the loop holds the axis on its path, so
// the drive pushes against the whole force, M a and friction unchanged. Compared over 51 ms moving means, which take
// out the tooth-passing harmonics (400 Hz: 20.4 periods) that the loop cannot follow, where the axis slides (its
// reference above 5 mm/s for the last 100 ms and the next 25): at rest static friction takes up to F_B of the force
// and the controller's integrator keeps what it wound up, so there the drive force is not a function of the force.
bool sliding(const std::vector<double>& reference, std::size_t k, double dt) {
    if (k < 101 || k + 26 >= reference.size()) return false;
    for (std::size_t j = k - 100; j <= k + 25; ++j) {
        if (std::abs(reference[j] - reference[j - 1]) / dt < 0.005) return false;
    }
    return true;
}

TEST(Production, DriveCurrentCarriesTheCuttingForce) {
    const auto program = feedid::read_gcode_file(programs / "pocket.ngc");
    const auto machine = feedid::default_machine();
    feedid::ProductionOptions cut;
    cut.seed = 5;
    feedid::ProductionOptions clean = cut;
    clean.cutting_force_fraction = 0.0;
    const auto with = feedid::synthesize_production(program, machine, cut);
    const auto without = feedid::synthesize_production(program, machine, clean);
    const auto trajectory = feedid::plan_trajectory(program, machine.limits);
    const auto process = feedid::production_forces(trajectory, machine, cut);
    for (std::size_t i = 0; i < 2; ++i) {
        const std::string a(1, "XY"[i]);
        const double per_ampere = machine.drives[i].force_constant_N_per_A();
        const auto& i_with = with.find(a + "_i")->values;
        const auto& i_without = without.find(a + "_i")->values;
        std::vector<double> difference(i_with.size()), expected(i_with.size());
        for (std::size_t k = 0; k < difference.size(); ++k) {
            difference[k] = (i_with[k] - i_without[k]) * per_ampere;
            expected[k] = -process.force_N[i][k];  // the drive pushes against the force on the tool
        }
        const auto d = moving_average(difference, 25);
        const auto e = moving_average(expected, 25);
        double error = 0.0, norm = 0.0;
        std::size_t used = 0;
        for (std::size_t k = 0; k < d.size(); ++k) {
            if (!trajectory.cutting[k] || !sliding(trajectory.position[i], k, trajectory.sample_time_s)) continue;
            error += (d[k] - e[k]) * (d[k] - e[k]);
            norm += e[k] * e[k];
            ++used;
        }
        ASSERT_GT(used, 10000u);
        const double relative = std::sqrt(error / norm);
        std::cout << a << ": rms of the cutting force (51 ms means) " << std::sqrt(norm / used) << " N, of its "
                  << "difference from the drive force's change " << std::sqrt(error / used) << " N (" << 100 * relative
                  << " %)\n";
        EXPECT_LT(relative, 0.05) << a;
        // and the cutting force is large: its peak is 30 % of the drive force on X, the binding axis
        const double peak = *std::max_element(process.force_N[i].begin(), process.force_N[i].end(),
                                              [](double x, double y) { return std::abs(x) < std::abs(y); });
        if (i == 0) {
            EXPECT_NEAR(std::abs(peak), 0.3 * feedid::drive_force_N(machine, 0), 1e-9);
        }
    }
    // The spindle load follows the cutting: a few % on cutting moves, the noise's ~0 elsewhere.
    const auto& load = with.find("spindle_load")->values;
    double cutting_load = 0.0, idle_load = 0.0;
    std::size_t cutting = 0, idle = 0;
    for (std::size_t k = 0; k < load.size(); ++k) {
        (trajectory.cutting[k] ? cutting_load : idle_load) += load[k];
        ++(trajectory.cutting[k] ? cutting : idle);
    }
    // idle: white noise of sigma 0.3 % clipped at 0, mean sigma / sqrt(2 pi) = 0.12 %
    const double idle_mean = machine.cutting.spindle_load_noise_pct / std::sqrt(2 * M_PI);
    EXPECT_NEAR(idle_load / static_cast<double>(idle), idle_mean, 0.01);
    EXPECT_GT(cutting_load / static_cast<double>(cutting), 10 * idle_mean);
    std::cout << "spindle load: " << cutting_load / static_cast<double>(cutting) << " % cutting, "
              << idle_load / static_cast<double>(idle) << " % idle\n";
    EXPECT_EQ(without.find("spindle_speed")->values, with.find("spindle_speed")->values);
}

TEST(Production, MachineFileSetsLimitsDrivesAndCutting) {
    const auto dir = feedid::testing::temp_dir();
    feedid::testing::write_text(dir / "machine.toml", R"(
[limits]
rapid_mm_per_min = 24000
[limits.X]
acceleration_m_per_s2 = 2.0
[axes.X.axis]
mass_kg = 250.0
viscous_Ns_per_m = 100.0
coulomb_N = 200.0
offset_N = 0.0
[cutting]
teeth = 4
spindle_power_kW = 7.5
)");
    const auto machine = feedid::read_machine(dir / "machine.toml");
    EXPECT_DOUBLE_EQ(machine.limits.rapid_m_per_s, 0.4);
    EXPECT_DOUBLE_EQ(machine.limits.axes[0].acceleration_m_per_s2, 2.0);
    EXPECT_DOUBLE_EQ(machine.limits.axes[1].acceleration_m_per_s2, 3.0);
    EXPECT_DOUBLE_EQ(machine.drives[0].axis.mass, 250.0);
    EXPECT_DOUBLE_EQ(machine.drives[1].axis.mass, 320.0);                     // the default machine's Y
    EXPECT_DOUBLE_EQ(machine.drives[0].sensors.position_resolution_m, 1e-7);  // X's other sections kept
    EXPECT_EQ(machine.cutting.teeth, 4);
    EXPECT_DOUBLE_EQ(machine.cutting.spindle_power_W, 7500.0);

    feedid::testing::write_text(dir / "typo.json", R"({"limits": {"X": {"jerk_m_per_s": 40}}})");
    try {
        (void)feedid::read_machine(dir / "typo.json");
        ADD_FAILURE() << "no error for an unknown key";
    } catch (const feedid::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("limits.X.jerk_m_per_s"), std::string::npos) << e.what();
    }
}

TEST(Production, CliWritesTheTraceIdentifyReadsIt) {
    const auto dir = feedid::testing::temp_dir();
    const auto out = dir / "drilling.csv";
    const auto synth = feedid::testing::run_cli("synth --program '" + (programs / "drilling.ngc").string() +
                                                "' --seed 2 --cutting-force 0.2 --out '" + out.string() + "'");
    ASSERT_EQ(synth.exit_code, 0) << synth.err;
    const auto identify =
        feedid::testing::run_cli("identify '" + out.string() + "' --axis X --force-constant X_force_constant_N_per_A");
    EXPECT_NE(identify.exit_code, 2) << identify.err;  // it reads; what it finds is the scan's business
    // a program with an unsupported word: exit 2 naming the line
    feedid::testing::write_text(dir / "bad.ngc", "G21\nG1 X1 F100\nG33 X2 K1\nM2\n");
    const auto bad = feedid::testing::run_cli("synth --program '" + (dir / "bad.ngc").string() + "' --out '" +
                                              (dir / "bad.csv").string() + "'");
    EXPECT_EQ(bad.exit_code, 2);
    EXPECT_NE(bad.err.find("bad.ngc:3: G33"), std::string::npos) << bad.err;
}

}  // namespace
