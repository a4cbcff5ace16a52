#include "feedid/sim/production_synth.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include <fmt/core.h>

#include "feedid/model/controller.hpp"
#include "feedid/core/error.hpp"
#include "feedid/io/config_file.hpp"
#include "feedid/io/import.hpp"

namespace feedid {

namespace {

constexpr std::array<const char*, 3> axis_names{"X", "Y", "Z"};

// The default machine's drives (production_synth.hpp): mass, viscous, Coulomb, breakaway / Coulomb, Stribeck velocity,
// offset.
struct DriveDefaults {
    double mass_kg, viscous_Ns_per_m, coulomb_N, breakaway_ratio, stribeck_velocity_m_per_s, offset_N;
};
constexpr std::array<DriveDefaults, 3> default_drives{{{180.0, 150.0, 210.0, 1.3, 0.003, 0.0},
                                                       {320.0, 260.0, 340.0, 1.2, 0.006, 0.0},
                                                       {90.0, 120.0, 160.0, 1.45, 0.004, 35.0}}};
constexpr double default_current_lag_s = 0.5e-3;
constexpr double default_position_quantum_m = 1e-7;

// Below this path speed the feed direction is undefined and the chip load 0 [m/s].
constexpr double standstill_m_per_s = 1e-9;
// Seeds of one production trace: the cutting noise and each axis' sensors draw from distinct streams.
constexpr std::uint64_t seeds_per_trace = 4;

}  // namespace

std::string CuttingModel::validate() const {
    if (teeth < 1 || teeth > 20) return "cutting.teeth must be between 1 and 20";
    if (!(tool_diameter_m > 0.0 && tool_diameter_m < 1.0)) return "cutting.tool_diameter_mm must be in (0, 1000)";
    for (const double value : {radial_ratio, axial_ratio, noise_fraction, spindle_load_noise_pct}) {
        if (!(value >= 0.0 && std::isfinite(value)))
            return "cutting: radial_ratio, axial_ratio, noise_fraction, spindle_load_noise_pct must be >= 0";
    }
    for (const double a : harmonics) {
        if (!(std::abs(a) <= 1.0)) return "cutting.harmonics must each be within -1..1 (relative to the mean force)";
    }
    if (!(spindle_power_W > 0.0 && std::isfinite(spindle_power_W))) return "cutting.spindle_power_kW must be positive";
    return {};
}

std::string MachineSpec::validate() const {
    if (auto problem = limits.validate(); !problem.empty()) return "limits: " + problem;
    for (std::size_t i = 0; i < 3; ++i) {
        if (drives[i].axis.rotary) return fmt::format("axes.{}: a production axis is linear", axis_names[i]);
        if (auto problem = drives[i].validate(); !problem.empty())
            return fmt::format("axes.{}: {}", axis_names[i], problem);
        if (std::abs(drives[i].sensors.sample_time_s - limits.sample_time_s) > 1e-12)
            return fmt::format("axes.{}: the sensors' sample time must be the machine's ({} ms)", axis_names[i],
                               limits.sample_time_s * 1e3);
    }
    return cutting.validate();
}

std::string ProductionOptions::validate() const {
    if (!(cutting_force_fraction >= 0.0 && cutting_force_fraction <= 1.0))
        return "the cutting force fraction must be within 0..1";
    return {};
}

MachineSpec default_machine() {
    MachineSpec machine;
    for (std::size_t i = 0; i < 3; ++i) {
        const auto& d = default_drives[i];
        SynthSpec spec = demo_spec();  // the demo's gains, motor and current sensor
        FrictionBranch branch;
        branch.viscous = d.viscous_Ns_per_m;
        branch.coulomb = d.coulomb_N;
        branch.breakaway = d.coulomb_N * d.breakaway_ratio;
        branch.stribeck_velocity = d.stribeck_velocity_m_per_s;
        spec.axis.mass = d.mass_kg;
        spec.axis.friction = Friction::symmetric(branch);
        spec.axis.offset = d.offset_N;
        spec.controller.current_lag_s = default_current_lag_s;
        spec.sensors.position_resolution_m = default_position_quantum_m;
        spec.sensors.sample_time_s = machine.limits.sample_time_s;
        machine.drives[i] = spec;
    }
    return machine;
}

double drive_force_N(const MachineSpec& machine, std::size_t axis) {
    const auto& spec = machine.drives[axis];
    const auto& limits = machine.limits.axes[axis];
    const auto& branch = spec.axis.friction.forward;
    const double friction = std::max(branch.coulomb, branch.breakaway.value_or(branch.coulomb));
    return spec.axis.mass * limits.acceleration_m_per_s2 + friction + branch.viscous * limits.velocity_m_per_s +
           std::abs(spec.axis.offset);
}

namespace {

// Unscaled (K = 1) cutting forces on the cutting samples, noise included, and the mean tangential force K h.
struct UnitForces {
    std::array<std::vector<double>, 3> force;
    std::vector<double> mean;
};

UnitForces unit_forces(const Trajectory& trajectory, const CuttingModel& model, std::uint64_t seed) {
    const std::size_t n = trajectory.samples();
    const double dt = trajectory.sample_time_s;
    UnitForces out{{std::vector<double>(n), std::vector<double>(n), std::vector<double>(n)}, std::vector<double>(n)};
    std::mt19937_64 generator(seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    const auto& p = trajectory.position;
    for (std::size_t k = 1; k + 1 < n; ++k) {
        const double white = noise(generator);  // drawn on every sample: the stream does not depend on the program
        if (!trajectory.cutting[k] || trajectory.spindle_rpm[k] <= 0.0) continue;
        std::array<double, 3> v{};
        for (std::size_t i = 0; i < 3; ++i) v[i] = (p[i][k + 1] - p[i][k - 1]) / (2.0 * dt);
        const double speed = std::hypot(v[0], v[1], v[2]);
        if (speed < standstill_m_per_s) continue;
        const double tooth_rate = model.teeth * trajectory.spindle_rpm[k] / 60.0;                // teeth per second
        const double chip = speed / tooth_rate;                                                  // h [m per tooth]
        const double angle = 2.0 * std::numbers::pi * tooth_rate * static_cast<double>(k) * dt;  // z * phi
        double pulsation = 1.0 + model.noise_fraction * white;
        for (std::size_t m = 0; m < model.harmonics.size(); ++m) {
            const double order = static_cast<double>(m + 1);
            pulsation += model.harmonics[m] * std::cos(order * angle + order);
        }
        const double tangential = chip * pulsation;
        const double ux = v[0] / speed, uy = v[1] / speed, uz = v[2] / speed;
        out.force[0][k] = tangential * (-ux + model.radial_ratio * uy);
        out.force[1][k] = tangential * (-uy - model.radial_ratio * ux);
        out.force[2][k] = tangential * (-uz - model.axial_ratio * std::hypot(ux, uy));
        out.mean[k] = chip;
    }
    return out;
}

}  // namespace

ProcessForces cutting_forces(const Trajectory& trajectory, const MachineSpec& machine, double fraction,
                             std::uint64_t seed) {
    const std::size_t n = trajectory.samples();
    const auto& model = machine.cutting;
    UnitForces unit = unit_forces(trajectory, model, seed);
    ProcessForces out;
    // K: the binding axis' largest |F| reaches `fraction` of its drive force.
    double scale = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < 3; ++i) {
        double peak = 0.0;
        for (const double f : unit.force[i]) peak = std::max(peak, std::abs(f));
        if (peak > 0.0) scale = std::min(scale, fraction * drive_force_N(machine, i) / peak);
    }
    if (!std::isfinite(scale)) scale = 0.0;
    out.scale = scale;
    for (std::size_t i = 0; i < 3; ++i) {
        out.force_N[i] = std::move(unit.force[i]);
        for (double& f : out.force_N[i]) f *= scale;
    }
    // The spindle drive reports the power of the mean cutting force, with its own noise.
    std::mt19937_64 generator(seed + 1);
    std::normal_distribution<double> noise(0.0, model.spindle_load_noise_pct);
    out.spindle_load_pct.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
        const double cutting_speed = std::numbers::pi * model.tool_diameter_m * trajectory.spindle_rpm[k] / 60.0;
        const double power = scale * unit.mean[k] * cutting_speed;
        out.spindle_load_pct[k] = std::max(0.0, 100.0 * power / model.spindle_power_W + noise(generator));
    }
    return out;
}

namespace {

// Each axis' trace channels under its prefix, and its constants.
void add_axis(Trace& out, Trace&& axis, std::size_t i) {
    const std::string prefix = std::string(axis_names[i]) + "_";
    for (const char* name : {"x_ref", "x", "i"}) {
        Channel* channel = axis.find(std::string_view(name));
        Channel& added = out.set(prefix + name, Role::other, channel->unit, std::move(channel->values));
        added.source_unit = channel->source_unit;
        added.native_interval_s = channel->native_interval_s;
        added.interval_source = channel->interval_source;
    }
    for (const auto& [name, value] : axis.constants) out.constants[prefix + name] = value;
}

void add_spindle(Trace& out, std::vector<double> load, const Trajectory& trajectory, double dt) {
    for (auto [name, unit, values] : {std::tuple{"spindle_load", "%", std::move(load)},
                                      std::tuple{"spindle_speed", "rpm", trajectory.spindle_rpm}}) {
        Channel& channel = out.set(name, Role::other, unit, std::move(values));
        channel.source_unit = unit;
        channel.native_interval_s = dt;
    }
}

}  // namespace

ProcessForces production_forces(const Trajectory& trajectory, const MachineSpec& machine,
                                const ProductionOptions& options) {
    return cutting_forces(trajectory, machine, options.cutting_force_fraction, options.seed * seeds_per_trace);
}

Trace synthesize_production(const GcodeProgram& program, const MachineSpec& machine, const ProductionOptions& options) {
    if (auto problem = machine.validate(); !problem.empty()) throw InputError("machine: " + problem);
    if (auto problem = options.validate(); !problem.empty()) throw InputError("production: " + problem);
    const Trajectory trajectory = plan_trajectory(program, machine.limits);
    const std::uint64_t base_seed = options.seed * seeds_per_trace;
    ProcessForces process = production_forces(trajectory, machine, options);
    Trace out;
    out.format = "synthetic";
    for (std::size_t i = 0; i < 3; ++i) {
        SynthSpec spec = machine.drives[i];
        spec.seed = base_seed + i + 1;
        Trace axis = synthesize(spec, trajectory.position[i], process.force_N[i]);
        if (i == 0) {
            Channel* time = axis.find(Role::time);
            Channel& t = out.set("t", Role::time, "s", std::move(time->values));
            t.source_unit = "s";
            t.native_interval_s = time->native_interval_s;
        }
        add_axis(out, std::move(axis), i);
        double peak = 0.0;
        for (const double f : process.force_N[i]) peak = std::max(peak, std::abs(f));
        out.constants[fmt::format("{}_drive_force_N", axis_names[i])] = drive_force_N(machine, i);
        out.constants[fmt::format("{}_peak_cutting_force_N", axis_names[i])] = peak;
    }
    add_spindle(out, std::move(process.spindle_load_pct), trajectory, machine.limits.sample_time_s);
    out.constants["seed"] = static_cast<double>(options.seed);
    out.constants["cutting_force_fraction"] = options.cutting_force_fraction;
    out.constants["cutting_force_scale_N_per_m"] = process.scale;
    return out;
}

namespace {

void read_limits(ConfigSection& top, MachineLimits& limits) {
    auto section = top.section("limits");
    if (!section) return;
    section->read("rapid_mm_per_min", limits.rapid_m_per_s, 1.0 / 60000.0);
    section->read("max_feed_mm_per_min", limits.max_feed_m_per_s, 1.0 / 60000.0);
    section->read("stock_top_mm", limits.stock_top_m, 1e-3);
    section->read("sample_time_ms", limits.sample_time_s, 1e-3);
    for (std::size_t i = 0; i < 3; ++i) {
        auto axis = section->section(axis_names[i]);
        if (!axis) continue;
        auto& a = limits.axes[i];
        axis->read("velocity_mm_per_min", a.velocity_m_per_s, 1.0 / 60000.0);
        axis->read("acceleration_m_per_s2", a.acceleration_m_per_s2);
        axis->read("jerk_m_per_s3", a.jerk_m_per_s3);
        axis->reject_unknown();
    }
    section->reject_unknown();
}

void read_cutting(ConfigSection& top, CuttingModel& cutting) {
    auto section = top.section("cutting");
    if (!section) return;
    if (const auto teeth = section->number("teeth")) cutting.teeth = static_cast<int>(std::lround(*teeth));
    section->read("tool_diameter_mm", cutting.tool_diameter_m, 1e-3);
    section->read("radial_ratio", cutting.radial_ratio);
    section->read("axial_ratio", cutting.axial_ratio);
    section->read("noise_fraction", cutting.noise_fraction);
    section->read("spindle_power_kW", cutting.spindle_power_W, 1e3);
    section->read("spindle_load_noise_pct", cutting.spindle_load_noise_pct);
    if (auto harmonics = section->numbers("harmonics")) cutting.harmonics = std::move(*harmonics);
    section->reject_unknown();
}

}  // namespace

MachineSpec machine_from_json(const nlohmann::json& document, const std::string& source) {
    MachineSpec machine = default_machine();
    ConfigSection top(document, source);
    read_limits(top, machine.limits);
    for (auto& drive : machine.drives) drive.sensors.sample_time_s = machine.limits.sample_time_s;
    if (auto axes = top.section("axes")) {
        for (std::size_t i = 0; i < 3; ++i) {
            if (auto axis = axes->section(axis_names[i]))
                machine.drives[i] = spec_from_config(*axis, machine.drives[i]);
        }
        axes->reject_unknown();
    }
    read_cutting(top, machine.cutting);
    top.accept("description");
    top.accept("$schema");
    top.reject_unknown();
    if (auto problem = machine.validate(); !problem.empty()) throw InputError(fmt::format("{}: {}", source, problem));
    return machine;
}

MachineSpec read_machine(const std::filesystem::path& path) {
    return machine_from_json(read_config_file(path), path.string());
}

}  // namespace feedid
