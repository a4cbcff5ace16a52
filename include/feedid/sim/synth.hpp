#pragma once
// Synthetic traces: what an NC records for a known drive (mass, per-direction friction with breakaway and Stribeck,
// offset), its P-PI controller and a reference, through the closed-loop simulator and sensor models (position
// quantisation, current noise and quantisation, current-loop lag, sample time and time-stamp jitter). The ground
// truth for tests, the demo and `feedid synth`.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/io/config_file.hpp"
#include "feedid/model/controller.hpp"
#include "feedid/model/demo_drives.hpp"
#include "feedid/model/friction.hpp"
#include "feedid/sim/simulate.hpp"
#include "feedid/core/trace.hpp"

namespace feedid {

/// The constant-velocity back-and-forth test (docs/method.md): strokes at stepwise increasing feedrates, plus optional
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
    /// Every stroke forward, one after the other (the axis never reverses): a move in one direction, as a rack
    /// rig or a vertical axis that only lifts records it.
    bool one_way{false};

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

/// How the recorder logs the signals (an NC's trace): each signal group's own interval, held (forward-filled) on the
/// trace's time base as a SINUMERIK servo trace does, the units it writes, and which signals it logs.
struct RecordingModel {
    /// Position, reference position and velocity command are logged every this [s] (the position loop's cycle) and
    /// held in between; 0 = every sample.
    double position_interval_s{0.0};
    double velocity_interval_s{0.0};  ///< the actual velocity's interval [s]; 0 = every sample
    double drive_interval_s{0.0};     ///< the current's (or torque's) interval [s]; 0 = every sample
    bool log_velocity{false};         ///< log the actual velocity too (channel `v`)
    bool log_torque{false};           ///< log the drive torque (force) `tau` [N*m or N] instead of the current `i` [A]
    std::string position_unit;        ///< the unit `feedid synth` writes positions in ("deg", "mm"); "" = SI
    std::string velocity_unit;        ///< ... velocities ("rpm", "deg/min", "mm/min"); "" = SI
    /// The drive signal is logged this much late: sample k holds the drive force of t_k - drive_delay_s (another
    /// instant of the servo cycle, a current-loop filter, two clocks) [s]; a whole number of integration steps
    /// (sample time / substeps), at most 256 of them.
    double drive_delay_s{0.0};

    /// What is wrong, given the axis kind and the trace's sample time ("" when nothing).
    [[nodiscard]] std::string validate(bool rotary, double sample_time_s) const;
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

/// Bursts of a process force (cutting, a load the drive's model has no term for) on the moves of the test: each
/// starts with probability rate_per_s per second of commanded motion, lasts a time uniform in [min_duration_s,
/// max_duration_s], opposes the commanded motion with an amplitude uniform in [min_fraction, max_fraction] of the
/// axis's Coulomb friction, and carries a tooth-passing ripple of ripple_fraction of it at ripple_hz.
struct ProcessForceBursts {
    double rate_per_s{0.3};
    double min_duration_s{0.2};
    double max_duration_s{1.5};
    double min_fraction{0.1};
    double max_fraction{0.5};
    double ripple_hz{80.0};
    double ripple_fraction{0.3};

    /// What is wrong ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// Everything `feedid synth` needs: the drive, its controller, the sensors, the test, the seed.
/// A rotary axis (axis.rotary) is SI of its kind inside: rad, rad/s, kg*m^2, N*m; its test and sensor lengths are read
/// in degrees where the keys say mm, as an NC does for a rotary axis (stroke 30 mm is 30 deg, 9350 mm/min is
/// 9350 deg/min, a 1 um encoder quantum 0.001 deg), and its drive has no lead: torque = K_t * gear ratio * i.
struct SynthSpec {
    AxisModel axis;
    ControllerModel controller;
    double kt_Nm_per_A{1.444};  ///< motor torque constant [N*m/A] (the paper's 26.0 N*m at 18.0 A)
    double lead_m{0.020};       ///< ball-screw lead [m]
    double gear_ratio{1.0};     ///< motor revolutions per screw revolution
    SensorModel sensors;
    RecordingModel recording;
    TestReference test;
    /// Friction along the axis: stretches with scaled Coulomb and breakaway friction (a worn part of the screw).
    std::vector<FrictionZone> friction_zones;
    /// A test signal injected at the controller's output, logged as its own channel; none = no injection.
    std::optional<SquareWaveInjection> injection;
    /// The servo (position and velocity loops) runs at this rate while the recorder logs at the sample rate, as
    /// NCs do (an 8 kHz speed controller logged at 1 kHz) [Hz]; 0 = the loops' own cycles (default: the sample
    /// time). A whole multiple of the sample rate; the integration steps follow it.
    double servo_rate_hz{0.0};
    /// Process forces on the moves (a test trace with cutting in it); none = no process force.
    std::optional<ProcessForceBursts> process_force;
    std::uint64_t seed{1};

    /// Force per ampere [N/A] = K_t * g * 2*pi / lead (eq. 2); on a rotary axis torque per ampere [N*m/A] = K_t * g.
    [[nodiscard]] double force_constant_N_per_A() const;
    [[nodiscard]] std::string validate() const;
};

/// The demo drive of model/demo_drives.hpp (linear, or the rotary table) with the default sensors (1 kHz) and test
/// (with slow passes).
SynthSpec demo_spec(bool rotary = false);

/// demo_spec(true).
SynthSpec rotary_demo_spec();

/// Records `spec` as a SINUMERIK servo trace does: 2 ms time base, the position loop (and so position, reference and
/// velocity command, and the actual velocity) every 4 ms, the torque every 2 ms, while the speed controller runs at
/// 8 kHz (servo_rate_hz), faster than the trace, measuring the velocity over each of its 125 us cycles; positions
/// written in deg (rotary) or mm, velocities in rpm or mm/min, the torque in N*m (rotary) or the current in A.
void apply_sinumerik_recording(SynthSpec& spec);

/// The trace in the units the recording states (positions, velocities), for writing: values converted from SI and
/// the channels' units set to them. Throws InputError for a unit that does not fit the axis kind.
Trace in_recording_units(const Trace& trace, const RecordingModel& recording);

/// Reads a drive file (JSON; see `feedid synth --help` and the README for the keys); unspecified fields keep the
/// demo values. InputError naming `source` and the key on a bad value.
SynthSpec spec_from_json(const nlohmann::json& document, const std::string& source);
/// The same starting from `base` instead of the demo (a machine file's axis over the machine's default drive).
SynthSpec spec_from_json(const nlohmann::json& document, const std::string& source, const SynthSpec& base);
/// The same from a section of a configuration file (a machine file's axes.X), which names the keys in messages.
SynthSpec spec_from_config(ConfigSection& section, const SynthSpec& base);
/// The same from TOML text (the same keys; tables for the sections). InputError with the line on a syntax error.
SynthSpec spec_from_toml(std::string_view text, const std::string& source);
/// Reads a drive file: TOML when the name ends in .toml, JSON otherwise.
SynthSpec read_spec(const std::filesystem::path& path);
/// The drive file of a spec (every key, with its value), e.g. to start a new drive file from the demo.
nlohmann::json spec_to_json(const SynthSpec& spec);

/// The reference position of the test sampled every `sample_time_s` [s]; trapezoidal velocity (acceleration
/// limited) between dwells.
std::vector<double> test_reference(const TestReference& test, double sample_time_s);

/// Generates the trace: channels t [s], x_ref [m], x [m], v_cmd [m/s], i [A] (or tau [N] with recording.log_torque;
/// v [m/s] with recording.log_velocity; `injection`, the injected signal in the drive signal's units (A, or N or N*m
/// with log_torque), role injection, when the spec has one: the drive signal contains it); on a rotary axis rad,
/// rad/s, N*m. Each channel's native interval is the
/// recording's (format source), its values held over it. Constants kt_Nm_per_A, gear_ratio, lead_m and
/// force_constant_N_per_A (linear) or torque_constant_Nm_per_A (rotary), and the true values (true_mass_kg or
/// true_inertia_kgm2, ...). `reference` overrides the test (sampled every sensors.sample_time_s). Deterministic for a
/// given seed. `external_force` [N, or N*m on a rotary axis], one value per reference sample acting in +x (a process
/// force such as cutting), is felt by the axis and not logged; empty = none.
Trace synthesize(const SynthSpec& spec, const std::optional<std::vector<double>>& reference = std::nullopt,
                 std::span<const double> external_force = {});

}  // namespace feedid
