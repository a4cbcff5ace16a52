#pragma once
// Production traces: what a 3-axis machining centre records while it runs an ordinary part program. The program
// (gcode_reader.hpp) becomes a reference (trajectory.hpp); the cutting forces of a simple milling model act on the
// axes during cutting moves; each axis, with its own drive, runs through synth.hpp's closed loop and sensors.
//
// The cutting-force model (the "process force" that identification must keep out). On a cutting sample (trajectory
// .cutting: a feed move, spindle on, tool below the stock top), with path velocity v (vector, from the reference),
// unit direction u = v/|v|, spindle speed n [rpm], z teeth:
//   chip load           h = |v| / (z n / 60)                                  [m per tooth]
//   tooth angle         phi(t) = 2 pi n t / 60
//   tangential force    F_t(t) = K h (1 + sum_m a_m cos(m z phi(t) + m) + sigma w(t)),  w white, unit variance
//   on the tool, per axis (the workpiece resists the feed, pushes sideways and pulls along the tool):
//     F_x = F_t (-u_x + rho u_y),   F_y = F_t (-u_y - rho u_x),   F_z = F_t (-u_z - alpha |u_xy|)
// with rho = radial_ratio, alpha = axial_ratio, a_m = harmonics (tooth-passing frequency z n / 60 and its multiples).
// K is set so that the largest |F_i| over the program (noise included) is `fraction` (default 30 %) of the axis'
// drive force on the one axis where that binds first, the others less: the drive force of an axis is the most its
// motion alone needs on this machine, F_drive = M a_max + max(F_B, F_C) + B v_max + |offset| (its limits).
// The spindle load [%] follows the cutting power: 100 K h v_c / P_rated with the cutting speed v_c = pi D n / 60
// (the mean force, as a spindle drive reports it), plus white noise, never below 0; 0 % plus noise when not cutting.

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/plan/gcode_reader.hpp"
#include "feedid/sim/synth.hpp"
#include "feedid/core/trace.hpp"
#include "feedid/plan/trajectory.hpp"

namespace feedid {

struct CuttingModel {
    int teeth{3};                              ///< z, cutting edges of the tool
    double tool_diameter_m{0.010};             ///< D [m]
    double radial_ratio{0.4};                  ///< rho = F_r / F_t
    double axial_ratio{0.2};                   ///< alpha = F_a / F_t
    std::vector<double> harmonics{0.6, 0.25};  ///< a_1, a_2, ...: tooth-passing harmonics relative to the mean
    double noise_fraction{0.1};                ///< sigma: broadband noise relative to the mean force
    double spindle_power_W{5500.0};            ///< P_rated: 100 % spindle load [W]
    double spindle_load_noise_pct{0.3};        ///< standard deviation of the spindle-load noise [%]

    [[nodiscard]] std::string validate() const;
};

/// A machine: its limits, a drive per axis (X, Y, Z; the synth drive with controller and sensors), the cutting.
struct MachineSpec {
    MachineLimits limits;
    std::array<SynthSpec, 3> drives;
    CuttingModel cutting;

    [[nodiscard]] std::string validate() const;
};

/// The default machine (README "Production traces"): limits as MachineLimits' defaults; drives
///   X: M 180 kg, B 150 N*s/m, F_C 210 N, F_B 273 N (1.3), v_s 3 mm/s
///   Y: M 320 kg, B 260 N*s/m, F_C 340 N, F_B 408 N (1.2), v_s 6 mm/s
///   Z: M  90 kg, B 120 N*s/m, F_C 160 N, F_B 232 N (1.45), v_s 4 mm/s, offset 35 N (the counterbalance's rest)
/// each with the demo's gains (K_v 2 (m/min)/mm, K_p 40000 N*s/m, T_n 20 ms), current-loop lag 0.5 ms, 1 kHz,
/// position quantum 0.1 um, the demo's current sensor; a 3-tooth 10 mm end mill and a 5.5 kW spindle.
MachineSpec default_machine();

/// Reads a machine file (JSON, or TOML when the name ends in .toml): sections `limits` (rapid_mm_per_min,
/// max_feed_mm_per_min, stock_top_mm, sample_time_ms, and per axis X/Y/Z: velocity_mm_per_min,
/// acceleration_m_per_s2, jerk_m_per_s3), `axes` (X/Y/Z: a synth drive file's sections, starting from the default
/// machine's drive) and `cutting` (teeth, tool_diameter_mm, radial_ratio, axial_ratio, harmonics, noise_fraction,
/// spindle_power_kW, spindle_load_noise_pct). Missing keys keep the defaults; unknown keys are an InputError.
MachineSpec machine_from_json(const nlohmann::json& document, const std::string& source);
MachineSpec read_machine(const std::filesystem::path& path);

/// The most force axis `axis` (0 X, 1 Y, 2 Z) needs for its motion alone at the machine's limits [N] (see above).
double drive_force_N(const MachineSpec& machine, std::size_t axis);

/// The process: per-sample cutting forces on each axis [N] (+ along the axis) and the spindle channels.
struct ProcessForces {
    std::array<std::vector<double>, 3> force_N;
    std::vector<double> spindle_load_pct;
    double scale{0.0};  ///< K [N per m of chip load]
};

/// The cutting forces along `trajectory` (zero off the cutting samples; all zero when fraction is 0). Deterministic
/// for a seed.
ProcessForces cutting_forces(const Trajectory& trajectory, const MachineSpec& machine, double fraction,
                             std::uint64_t seed);

struct ProductionOptions {
    double cutting_force_fraction{0.3};  ///< peak cutting force / drive force on the binding axis; 0 = no cutting
    std::uint64_t seed{1};               ///< drives the sensor noise of each axis and the cutting noise

    [[nodiscard]] std::string validate() const;
};

/// The cutting forces synthesize_production applies for these options (cutting_forces with the trace's cutting seed).
ProcessForces production_forces(const Trajectory& trajectory, const MachineSpec& machine,
                                const ProductionOptions& options);

/// The trace of the machine running `program`: t [s]; per axis A in X, Y, Z: A_x_ref, A_x [m], A_i [A]; spindle_load
/// [%], spindle_speed [rpm]. Constants: each axis' synth constants with its prefix (X_force_constant_N_per_A,
/// X_true_mass_kg, ...), X_drive_force_N ..., X_peak_cutting_force_N ..., cutting_force_fraction, seed.
Trace synthesize_production(const GcodeProgram& program, const MachineSpec& machine, const ProductionOptions& options);

}  // namespace feedid
