#pragma once
// Synthetic traces: what an NC records for a known drive (mass, per-direction friction with breakaway and Stribeck,
// offset), its P-PI controller and a reference, through the closed-loop simulator and sensor models (position
// quantisation, current noise and quantisation, current-loop lag, sample time and time-stamp jitter). The ground
// truth for tests, the demo and `feedid synth`.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/controller.hpp"
#include "feedid/friction.hpp"
#include "feedid/simulate.hpp"
#include "feedid/trace.hpp"

namespace feedid {

/// The constant-velocity back-and-forth test of METHOD.md: strokes at stepwise increasing feedrates, plus optional
/// slow passes (short strokes at log-spaced low feedrates) so that breakaway friction and Stribeck velocity are
/// identifiable.
struct TestReference {
    std::vector<double> feedrates_mm_per_min{1250, 2150, 3050, 3950, 4850, 5750, 6650, 7550, 8450, 9350};
    double stroke_m{0.030};  ///< length of each stroke [m]
    int cycles{1};           ///< back-and-forth cycles per feedrate
    bool slow_passes{true};
    std::vector<double> slow_feedrates_mm_per_min{10, 17.8, 31.6, 56.2, 100, 178, 316, 562, 1000};
    double slow_pass_duration_s{1.5};   ///< each slow stroke lasts about this long ...
    double slow_stroke_min_m{0.0002};   ///< ... but is at least this long [m]
    double acceleration_m_per_s2{2.0};  ///< the NC's acceleration limit [m/s^2]
    double dwell_s{0.2};                ///< pause at each reversal and at the start and end [s]
    double start_m{0.0};                ///< where the strokes start [m]

    [[nodiscard]] std::string validate() const;
};

/// The sensors and the recording.
struct SensorModel {
    double sample_time_s{1e-3};          ///< the trace's sample time (and the controller's cycle) [s]
    double jitter_s{0.0};                ///< time stamps jitter uniformly within +-jitter [s] (< T/2)
    double position_resolution_m{1e-8};  ///< encoder quantum [m]; 0 = exact
    double current_noise_A{0.02};        ///< standard deviation of white current-sensor noise [A]
    double current_resolution_A{0.005};  ///< current quantum [A]; 0 = exact
    int substeps{8};                     ///< integration steps per sample

    [[nodiscard]] std::string validate() const;
};

/// A test signal added to the controller's force command before the current loop, as a disturbance-injection
/// experiment adds it (EMPS's validation pulses, SINUMERIK's additive torque setpoint, a drive's function
/// generator): a square wave at `amplitude_N` for the first half of each period and 0 for the second, from t = 0.
struct SquareWaveInjection {
    double amplitude_N{300.0};  ///< the wave's high level [N] (negative: a wave below zero)
    double frequency_Hz{1.0};   ///< [Hz]

    /// u_inj(t) [N].
    [[nodiscard]] double at(double time_s) const;
    /// What is wrong with it for a trace sampled every `sample_time_s` ("" when nothing).
    [[nodiscard]] std::string validate(double sample_time_s) const;
};

/// Everything `feedid synth` needs: the drive, its controller, the sensors, the test, the seed.
struct SynthSpec {
    AxisModel axis;
    ControllerModel controller;
    double kt_Nm_per_A{1.444};  ///< motor torque constant [N*m/A] (the paper's 26.0 N*m at 18.0 A)
    double lead_m{0.020};       ///< ball-screw lead [m]
    double gear_ratio{1.0};     ///< motor revolutions per screw revolution
    SensorModel sensors;
    TestReference test;
    /// Friction along the axis: stretches with scaled Coulomb and breakaway friction (a worn part of the screw).
    std::vector<FrictionZone> friction_zones;
    /// A test signal injected at the controller's output, logged as its own channel; none = no injection.
    std::optional<SquareWaveInjection> injection;
    std::uint64_t seed{1};

    /// Force per ampere [N/A] = K_t * g * 2*pi / lead (eq. 2).
    [[nodiscard]] double force_constant_N_per_A() const;
    [[nodiscard]] std::string validate() const;
};

/// The demo drive: the paper's M 69.1 kg, B 54.2 N*s/m, F_C 742.8 N, F_B 946.2 N with a ball-screw-typical
/// v_s = 5 mm/s, K_v = 2 (m/min)/mm, K_p = 40000 N*s/m, T_n = 20 ms, 1 kHz, with slow passes.
SynthSpec demo_spec();

/// Reads a drive file (JSON; see `feedid synth --help` and the README for the keys); unspecified fields keep the
/// demo values. InputError naming `source` and the key on a bad value.
SynthSpec spec_from_json(const nlohmann::json& document, const std::string& source);
/// The same from TOML text (the same keys; tables for the sections). InputError with the line on a syntax error.
SynthSpec spec_from_toml(std::string_view text, const std::string& source);
/// Reads a drive file: TOML when the name ends in .toml, JSON otherwise.
SynthSpec read_spec(const std::filesystem::path& path);
/// The drive file of a spec (every key, with its value), e.g. to start a new drive file from the demo.
nlohmann::json spec_to_json(const SynthSpec& spec);

/// The reference position of the test sampled every `sample_time_s` [s]; trapezoidal velocity (acceleration
/// limited) between dwells.
std::vector<double> test_reference(const TestReference& test, double sample_time_s);

/// Generates the trace: channels t [s], x_ref [m], x [m], v_cmd [m/s], i [A] (and F_ext [N] when an external force
/// is given; `injection` [A], the injected signal in the current's units, role injection, when the spec has one: the
/// current i contains it); constants kt_Nm_per_A, lead_m, gear_ratio, force_constant_N_per_A and the true values
/// (true_mass_kg, ...). `reference` overrides the test (sampled every sensors.sample_time_s). Deterministic for a
/// given seed.
Trace synthesize(const SynthSpec& spec, const std::optional<std::vector<double>>& reference = std::nullopt);

}  // namespace feedid
