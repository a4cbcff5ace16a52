#include "feedid/sim/synth.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <span>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/io/config_file.hpp"
#include "feedid/io/import.hpp"
#include "feedid/io/json_input.hpp"
#include "feedid/core/units.hpp"

namespace feedid {

namespace {

// Bounds against typos, not physical limits: 1000 cycles of the default test run for about 13 hours (46 million
// samples); the synthesis time grows with the integration substeps per sample (default 8).
constexpr int max_cycles = 1000;
constexpr int max_substeps = 1000;
// NC servo traces sample every 0.1 to 10 ms; a sample time above 1 s is a unit mistake.
constexpr double max_sample_time_s = 1.0;
// Time stamps that jitter by less than half a sample stay in order.
constexpr double max_jitter_per_sample_time = 0.5;
// A sample rate that is a whole number of hertz up to the rounding of 1/T gets time stamps k/f_s.
constexpr double whole_rate_tolerance = 1e-12;

// A rotary axis' test and sensor lengths are in degrees where the drive file says mm: 1 "m" of them is 1000 deg.
constexpr double rotary_rad_per_length_unit = 1000.0 * std::numbers::pi / 180.0;

// SINUMERIK servo trace: 2 ms time base, position-loop signals every 4 ms.
constexpr double sinumerik_sample_time_s = 0.002;
constexpr double sinumerik_position_interval_s = 0.004;
constexpr double sinumerik_speed_controller_rate_hz = 8000.0;

// SI per unit of a recorded position or velocity ("deg" -> pi/180 rad); InputError for a unit that is not one of the
// role's quantity on this axis kind.
double recording_unit_scale(const std::string& unit, Role role, bool rotary) {
    const bool position = role == Role::position;
    const Quantity wanted = position ? (rotary ? Quantity::angle : Quantity::length)
                                     : (rotary ? Quantity::angular_velocity : Quantity::velocity);
    if (const auto conversion = parse_unit(unit); conversion && conversion->offset == 0.0) {
        if (conversion->quantity == wanted) return conversion->scale;
    } else if (rotary && !position) {
        // motor speed on a rotary axis: revolutions per minute of the axis itself
        for (const std::string_view rpm : {"rpm", "rev/min", "r/min", "1/min", "U/min"}) {
            if (unit == rpm) return 2.0 * std::numbers::pi / 60.0;
        }
    }
    throw InputError(fmt::format("recording: '{}' is not a unit of {} on a {} axis", unit,
                                 position ? "position" : "velocity", rotary ? "rotary" : "linear"));
}

}  // namespace

std::string RecordingModel::validate(bool rotary, double sample_time_s) const {
    for (const auto& [name, interval] : {std::pair{"position", position_interval_s},
                                         std::pair{"velocity", velocity_interval_s},
                                         std::pair{"drive", drive_interval_s}}) {
        if (!(interval >= 0.0 && std::isfinite(interval)))
            return fmt::format("the {} signal's interval must be a time >= 0", name);
        const double samples = interval / sample_time_s;
        if (interval > 0.0 && (samples < 1.0 - 1e-9 || std::abs(samples - std::round(samples)) > 1e-6))
            return fmt::format("the {} signal's interval ({:.6g} ms) must be a whole multiple of the sample time "
                               "({:.6g} ms)",
                               name, interval * 1e3, sample_time_s * 1e3);
    }
    for (const auto& [role, unit] : {std::pair{Role::position, &position_unit}, std::pair{Role::velocity, &velocity_unit}}) {
        if (unit->empty()) continue;
        try {
            (void)recording_unit_scale(*unit, role, rotary);
        } catch (const InputError& e) {
            return e.what();
        }
    }
    if (!(drive_delay_s >= 0.0 && drive_delay_s < 1.0))
        return "recording.drive_delay_ms must be a time from 0 to 1000 ms";
    return {};
}

std::string TestReference::validate() const {
    if (feedrates_mm_per_min.empty() && !(slow_passes && !slow_feedrates_mm_per_min.empty())) {
        return "the test needs at least one feedrate";
    }
    for (const double f : feedrates_mm_per_min) {
        if (!(f > 0.0 && std::isfinite(f))) return "every feedrate must be a positive number [mm/min]";
    }
    for (const double f : slow_feedrates_mm_per_min) {
        if (!(f > 0.0 && std::isfinite(f))) return "every slow-pass feedrate must be a positive number [mm/min]";
    }
    if (!(stroke_m > 0.0 && std::isfinite(stroke_m))) return "the stroke must be a positive length";
    if (cycles < 1 || cycles > max_cycles)
        return fmt::format("the cycles per feedrate must be between 1 and {}", max_cycles);
    if (!(slow_pass_duration_s > 0.0) || !(slow_stroke_min_m > 0.0))
        return "slow-pass duration and stroke must be positive";
    if (!(acceleration_m_per_s2 > 0.0 && std::isfinite(acceleration_m_per_s2)))
        return "the acceleration must be positive";
    if (!(dwell_s >= 0.0 && std::isfinite(dwell_s))) return "the dwell must be a time >= 0";
    if (!std::isfinite(start_m)) return "the start position must be a finite number";
    return {};
}

std::string SensorModel::validate() const {
    if (!(sample_time_s > 0.0 && sample_time_s <= max_sample_time_s))
        return fmt::format("the sample time must lie in (0, {}] s", max_sample_time_s);
    if (!(jitter_s >= 0.0 && jitter_s < max_jitter_per_sample_time * sample_time_s))
        return "the jitter must lie in [0, T/2)";
    if (!(position_resolution_m >= 0.0) || !(current_resolution_A >= 0.0) || !(current_noise_A >= 0.0)) {
        return "resolutions and noise must be >= 0";
    }
    if (substeps < 1 || substeps > max_substeps)
        return fmt::format("the substeps per sample must be between 1 and {}", max_substeps);
    return {};
}

std::string ProcessForceBursts::validate() const {
    if (!(rate_per_s > 0.0 && rate_per_s <= 100.0)) return "process_force.rate_per_s must lie in (0, 100]";
    if (!(min_duration_s > 0.0 && max_duration_s >= min_duration_s && max_duration_s <= 3600.0))
        return "process_force.duration_s must be [low, high] with 0 < low <= high <= 3600 s";
    if (!(min_fraction >= 0.0 && max_fraction >= min_fraction && max_fraction <= 100.0))
        return "process_force.amplitude_fraction must be [low, high] with 0 <= low <= high <= 100";
    if (!(ripple_hz >= 0.0 && ripple_hz <= 1e5) || !(ripple_fraction >= 0.0 && ripple_fraction <= 1.0))
        return "process_force.ripple_hz must lie in [0, 1e5] and ripple_fraction in [0, 1]";
    return {};
}

double SquareWaveInjection::at(double time_s) const {
    const double phase = time_s * frequency_Hz;
    return phase - std::floor(phase) < 0.5 ? amplitude_N : 0.0;
}

std::string SquareWaveInjection::validate(double sample_time_s) const {
    // A force (torque) of either sign from 1 uN to 10 MN: past any drive, short of nonsense.
    if (!(std::abs(amplitude_N) >= 1e-6 && std::abs(amplitude_N) <= 1e7))
        return "the injection's amplitude must be a number of either sign with a magnitude from 1e-06 to 1e+07 N";
    // At least four samples per half period, so that each half of the wave is seen as a level; at most a period of
    // 1000 s (a slower wave is a step).
    const double highest = 1.0 / (8.0 * sample_time_s);
    if (!(frequency_Hz >= 1e-3 && frequency_Hz <= highest)) {
        return fmt::format("the injection's frequency must lie from 0.001 to {:g} Hz (four samples per half period)",
                           highest);
    }
    return {};
}

double SynthSpec::force_constant_N_per_A() const {
    if (axis.rotary) return kt_Nm_per_A * gear_ratio;  // torque at the axis through the gear
    // eq. (2): F_d = K_t * i / R, R = l / 2*pi, times the gear ratio motor:screw
    return kt_Nm_per_A * gear_ratio * 2.0 * std::numbers::pi / lead_m;
}

std::string SynthSpec::validate() const {
    if (!(kt_Nm_per_A > 0.0) || !(lead_m > 0.0) || !(gear_ratio > 0.0))
        return "K_t, lead and gear ratio must be positive";
    if (!(axis.mass > 0.0)) return "the mass must be positive";
    if (auto problem = controller.validate(); !problem.empty()) return problem;
    if (auto problem = sensors.validate(); !problem.empty()) return problem;
    if (auto problem = recording.validate(axis.rotary, sensors.sample_time_s); !problem.empty()) return problem;
    if (auto problem = test.validate(); !problem.empty()) return problem;
    if (injection) {
        if (auto problem = injection->validate(sensors.sample_time_s); !problem.empty()) return problem;
    }
    if (process_force) {
        if (auto problem = process_force->validate(); !problem.empty()) return problem;
    }
    if (servo_rate_hz != 0.0) {
        const double per_sample = servo_rate_hz * sensors.sample_time_s;
        if (!(servo_rate_hz > 0.0 && std::isfinite(servo_rate_hz)) || per_sample < 1.0 - 1e-9 ||
            std::abs(per_sample - std::round(per_sample)) > 1e-6 * per_sample || per_sample > max_substeps)
            return fmt::format("controller.servo_rate_hz {:g} must be a whole multiple (1 to {}) of the sample rate {:g} Hz",
                               servo_rate_hz, max_substeps, 1.0 / sensors.sample_time_s);
    }
    SimulationOptions zones;
    zones.friction_zones = friction_zones;
    if (auto problem = zones.validate(); !problem.empty()) return problem;
    return {};
}

SynthSpec demo_spec(bool rotary) {
    const DemoDrive drive = demo_drive(rotary);
    SynthSpec spec;
    spec.axis = drive.axis;
    spec.controller = drive.controller;
    spec.kt_Nm_per_A = drive.kt_Nm_per_A;
    spec.lead_m = drive.lead_m;
    spec.gear_ratio = drive.gear_ratio;
    return spec;
}

SynthSpec rotary_demo_spec() {
    return demo_spec(true);
}

void apply_sinumerik_recording(SynthSpec& spec) {
    spec.sensors.sample_time_s = sinumerik_sample_time_s;
    spec.controller.position_cycle_s = sinumerik_position_interval_s;
    // the speed controller at its own 8 kHz (125 us, SINUMERIK's usual speed-controller cycle), measuring the
    // velocity from the encoder every cycle, faster than any trace records
    spec.servo_rate_hz = sinumerik_speed_controller_rate_hz;
    spec.controller.velocity_cycle_s = 1.0 / sinumerik_speed_controller_rate_hz;
    spec.controller.velocity_difference_samples = 1;
    auto& r = spec.recording;
    r.position_interval_s = sinumerik_position_interval_s;
    r.velocity_interval_s = sinumerik_position_interval_s;
    r.drive_interval_s = sinumerik_sample_time_s;
    r.log_velocity = true;
    r.log_torque = spec.axis.rotary;
    r.position_unit = spec.axis.rotary ? "deg" : "mm";
    r.velocity_unit = spec.axis.rotary ? "rpm" : "mm/min";
}

namespace {

// axis: the friction and mass keys axis_from_document reads, and no other.
void read_axis(ConfigSection& top, SynthSpec& spec) {
    auto axis = top.section("axis");
    if (!axis) return;
    const std::string where = top.path().empty() ? top.source() : fmt::format("{} ({})", top.source(), top.path());
    spec.axis = axis_from_document(axis->json(), where);
    // the parameter keys (core/parameters.hpp), and no other
    for (const auto& key : axis->keys()) {
        if (key == "rotary" || parse_parameter_key(key)) axis->accept(key);
    }
    axis->reject_unknown();
}

// controller: gains in SI or NC units (K_v in (m/min)/mm, T_n in ms), cycles and lags in ms; saturation_N null
// removes the limit.
void read_controller(ConfigSection& top, SynthSpec& spec) {
    auto c = top.section("controller");
    if (!c) return;
    ControllerModel& model = spec.controller;
    c->read("servo_rate_hz", spec.servo_rate_hz);
    c->read("position_gain_per_s", model.position_gain_per_s);
    if (const auto v = c->number("kv_m_per_min_per_mm")) model.position_gain_per_s = position_gain_from_kv(*v);
    c->read("velocity_gain_N_s_per_m", model.velocity_gain_N_s_per_m);
    c->read("velocity_integral_gain_N_per_m", model.velocity_integral_gain_N_per_m);
    if (const auto v = c->number("tn_ms")) {
        model.velocity_integral_gain_N_per_m = *v > 0.0 ? model.velocity_gain_N_s_per_m / (*v * 1e-3) : 0.0;
    }
    c->read("velocity_feedforward", model.velocity_feedforward);
    if (c->is_null("saturation_N"))
        model.saturation_N.reset();
    else if (const auto v = c->number("saturation_N"))
        model.saturation_N = *v;
    c->accept("saturation_N");
    c->read("current_lag_ms", model.current_lag_s, 1e-3);
    c->read("injection_gain", model.injection_gain);
    c->read("setpoint_delay_ms", model.setpoint_delay_s, 1e-3);
    c->read("position_cycle_ms", model.position_cycle_s, 1e-3);
    c->read("velocity_cycle_ms", model.velocity_cycle_s, 1e-3);
    if (const auto v = c->number("velocity_difference_samples"))
        model.velocity_difference_samples = static_cast<int>(std::lround(*v));
    c->reject_unknown();
}

void read_drive(ConfigSection& top, SynthSpec& spec) {
    auto d = top.section("drive");
    if (!d) return;
    d->read("kt_Nm_per_A", spec.kt_Nm_per_A);
    d->read("lead_mm", spec.lead_m, 1e-3);
    d->read("gear_ratio", spec.gear_ratio);
    d->reject_unknown();
}

void read_sensors(ConfigSection& top, SensorModel& sensors) {
    auto s = top.section("sensors");
    if (!s) return;
    s->read("sample_time_ms", sensors.sample_time_s, 1e-3);
    s->read("jitter_us", sensors.jitter_s, 1e-6);
    s->read("position_resolution_um", sensors.position_resolution_m, 1e-6);
    s->read("current_noise_A", sensors.current_noise_A);
    s->read("current_resolution_A", sensors.current_resolution_A);
    if (const auto v = s->number("substeps")) sensors.substeps = static_cast<int>(std::lround(*v));
    s->reject_unknown();
}

// recording: each signal group's interval in ms (0 = every sample), which signals are logged, the units written.
void read_recording(ConfigSection& top, RecordingModel& recording) {
    auto r = top.section("recording");
    if (!r) return;
    r->read("position_interval_ms", recording.position_interval_s, 1e-3);
    r->read("velocity_interval_ms", recording.velocity_interval_s, 1e-3);
    r->read("drive_interval_ms", recording.drive_interval_s, 1e-3);
    if (const auto v = r->boolean("log_velocity")) recording.log_velocity = *v;
    if (const auto v = r->boolean("log_torque")) recording.log_torque = *v;
    if (auto v = r->text("position_unit")) recording.position_unit = std::move(*v);
    if (auto v = r->text("velocity_unit")) recording.velocity_unit = std::move(*v);
    r->read("drive_delay_ms", recording.drive_delay_s, 1e-3);
    r->reject_unknown();
}

void read_test(ConfigSection& top, TestReference& test) {
    auto t = top.section("test");
    if (!t) return;
    if (auto v = t->numbers("feedrates_mm_per_min")) test.feedrates_mm_per_min = std::move(*v);
    t->read("stroke_mm", test.stroke_m, 1e-3);
    if (const auto v = t->number("cycles")) test.cycles = static_cast<int>(std::lround(*v));
    if (const auto v = t->boolean("slow_passes")) test.slow_passes = *v;
    if (auto v = t->numbers("slow_feedrates_mm_per_min")) test.slow_feedrates_mm_per_min = std::move(*v);
    t->read("slow_pass_duration_s", test.slow_pass_duration_s);
    t->read("slow_stroke_min_mm", test.slow_stroke_min_m, 1e-3);
    t->read("acceleration_m_per_s2", test.acceleration_m_per_s2);
    t->read("dwell_s", test.dwell_s);
    t->read("start_mm", test.start_m, 1e-3);
    if (const auto v = t->boolean("one_way")) test.one_way = *v;
    t->reject_unknown();
}

// process_force: bursts of a process force on the moves (rate_per_s, duration_s and amplitude_fraction as [low, high],
// ripple_hz, ripple_fraction); null or absent: none.
void read_process_force(ConfigSection& top, std::optional<ProcessForceBursts>& bursts) {
    if (top.is_null("process_force")) {
        bursts.reset();
        top.accept("process_force");
        return;
    }
    auto p = top.section("process_force");
    if (!p) return;
    ProcessForceBursts b = bursts.value_or(ProcessForceBursts{});
    p->read("rate_per_s", b.rate_per_s);
    const auto pair = [&](const char* key, double& low, double& high) {
        if (auto v = p->numbers(key)) {
            if (v->size() != 2) p->refuse(key, "must be [low, high]");
            low = (*v)[0];
            high = (*v)[1];
        }
    };
    pair("duration_s", b.min_duration_s, b.max_duration_s);
    pair("amplitude_fraction", b.min_fraction, b.max_fraction);
    p->read("ripple_hz", b.ripple_hz);
    p->read("ripple_fraction", b.ripple_fraction);
    p->reject_unknown();
    bursts = b;
}

// friction_zones: a list of {from_mm, to_mm, coulomb_factor}, each key required; replaces the demo's zones.
void read_friction_zones(ConfigSection& top, std::vector<FrictionZone>& zones) {
    if (!top.has("friction_zones")) {
        top.accept("friction_zones");
        return;
    }
    zones.clear();
    for (auto& z : top.sections("friction_zones")) {
        const auto from = z.number("from_mm");
        const auto to = z.number("to_mm");
        const auto factor = z.number("coulomb_factor");
        z.reject_unknown();
        if (!from || !to || !factor) z.refuse("", "needs from_mm, to_mm and coulomb_factor");
        zones.push_back({*from * 1e-3, *to * 1e-3, *factor});
    }
}

}  // namespace

SynthSpec spec_from_json(const nlohmann::json& document, const std::string& source) {
    return spec_from_json(document, source, demo_spec());
}

SynthSpec spec_from_json(const nlohmann::json& document, const std::string& source, const SynthSpec& base) {
    ConfigSection top(document, source);
    return spec_from_config(top, base);
}

SynthSpec spec_from_config(ConfigSection& top, const SynthSpec& base) {
    SynthSpec spec = base;
    read_axis(top, spec);
    read_controller(top, spec);
    read_process_force(top, spec.process_force);
    read_drive(top, spec);
    read_sensors(top, spec.sensors);
    read_recording(top, spec.recording);
    read_test(top, spec.test);
    read_friction_zones(top, spec.friction_zones);
    if (const auto v = top.boolean("slow_passes")) spec.test.slow_passes = *v;
    if (const auto v = top.number("seed")) {
        if (*v < 0.0) top.refuse("seed", "must be >= 0");
        spec.seed = static_cast<std::uint64_t>(*v);
    }
    top.accept("$schema");
    top.accept("description");
    top.reject_unknown();
    if (const auto problem = spec.validate(); !problem.empty()) {
        const std::string where = top.path().empty() ? top.source() : fmt::format("{} ({})", top.source(), top.path());
        throw InputError(fmt::format("{}: {}", where, problem));
    }
    return spec;
}

SynthSpec spec_from_toml(std::string_view text, const std::string& source) {
    return spec_from_json(parse_toml(text, source), source);
}

SynthSpec read_spec(const std::filesystem::path& path) {
    return spec_from_json(read_config_file(path), path.string());
}

namespace {

// The axis keys of a drive file: a linear axis' (mass_kg, ..._N) or a rotary one's (inertia_kgm2, ..._Nm).
nlohmann::json axis_to_json(const AxisModel& model) {
    const ParameterNaming naming{model.rotary};
    nlohmann::json axis;
    if (model.rotary) axis["rotary"] = true;
    axis[naming.key(Term::mass)] = model.mass;
    axis[naming.key(Term::offset)] = model.offset;
    for (const auto& [direction, branch] : {std::pair{Direction::forward, &model.friction.forward},
                                            std::pair{Direction::reverse, &model.friction.reverse}}) {
        axis[naming.key(Term::viscous, direction)] = branch->viscous;
        axis[naming.key(Term::coulomb, direction)] = branch->coulomb;
        axis[naming.key(Term::breakaway, direction)] =
            branch->has_stribeck() ? nlohmann::json(*branch->breakaway) : nlohmann::json();
        axis[naming.key(Term::stribeck_velocity, direction)] =
            branch->has_stribeck() ? nlohmann::json(*branch->stribeck_velocity) : nlohmann::json();
    }
    return axis;
}

}  // namespace

nlohmann::json spec_to_json(const SynthSpec& spec) {
    const nlohmann::json axis = axis_to_json(spec.axis);
    const auto& c = spec.controller;
    nlohmann::json controller{{"position_gain_per_s", c.position_gain_per_s},
                              {"velocity_gain_N_s_per_m", c.velocity_gain_N_s_per_m},
                              {"velocity_integral_gain_N_per_m", c.velocity_integral_gain_N_per_m},
                              {"velocity_feedforward", c.velocity_feedforward},
                              {"saturation_N", c.saturation_N ? nlohmann::json(*c.saturation_N) : nlohmann::json()},
                              {"current_lag_ms", c.current_lag_s * 1e3},
                              {"injection_gain", c.injection_gain},
                              {"setpoint_delay_ms", c.setpoint_delay_s * 1e3},
                              {"position_cycle_ms", c.position_cycle_s * 1e3},
                              {"velocity_cycle_ms", c.velocity_cycle_s * 1e3},
                              {"velocity_difference_samples", c.velocity_difference_samples},
                              {"servo_rate_hz", spec.servo_rate_hz}};
    const auto& s = spec.sensors;
    const auto& t = spec.test;
    const auto& r = spec.recording;
    nlohmann::json process_force = nullptr;
    if (const auto& b = spec.process_force) {
        process_force = {{"rate_per_s", b->rate_per_s},
                         {"duration_s", {b->min_duration_s, b->max_duration_s}},
                         {"amplitude_fraction", {b->min_fraction, b->max_fraction}},
                         {"ripple_hz", b->ripple_hz},
                         {"ripple_fraction", b->ripple_fraction}};
    }
    nlohmann::json zones = nlohmann::json::array();
    for (const auto& zone : spec.friction_zones) {
        zones.push_back(
            {{"from_mm", zone.from_m * 1e3}, {"to_mm", zone.to_m * 1e3}, {"coulomb_factor", zone.coulomb_factor}});
    }
    return {
        {"axis", axis},
        {"controller", controller},
        {"drive", {{"kt_Nm_per_A", spec.kt_Nm_per_A}, {"lead_mm", spec.lead_m * 1e3}, {"gear_ratio", spec.gear_ratio}}},
        {"sensors",
         {{"sample_time_ms", s.sample_time_s * 1e3},
          {"jitter_us", s.jitter_s * 1e6},
          {"position_resolution_um", s.position_resolution_m * 1e6},
          {"current_noise_A", s.current_noise_A},
          {"current_resolution_A", s.current_resolution_A},
          {"substeps", s.substeps}}},
        {"test",
         {{"feedrates_mm_per_min", t.feedrates_mm_per_min},
          {"stroke_mm", t.stroke_m * 1e3},
          {"cycles", t.cycles},
          {"slow_passes", t.slow_passes},
          {"slow_feedrates_mm_per_min", t.slow_feedrates_mm_per_min},
          {"slow_pass_duration_s", t.slow_pass_duration_s},
          {"slow_stroke_min_mm", t.slow_stroke_min_m * 1e3},
          {"acceleration_m_per_s2", t.acceleration_m_per_s2},
          {"dwell_s", t.dwell_s},
          {"start_mm", t.start_m * 1e3},
          {"one_way", t.one_way}}},
        {"recording",
         {{"position_interval_ms", r.position_interval_s * 1e3},
          {"velocity_interval_ms", r.velocity_interval_s * 1e3},
          {"drive_interval_ms", r.drive_interval_s * 1e3},
          {"log_velocity", r.log_velocity},
          {"log_torque", r.log_torque},
          {"position_unit", r.position_unit},
          {"velocity_unit", r.velocity_unit},
          {"drive_delay_ms", r.drive_delay_s * 1e3}}},
        {"friction_zones", zones},
        {"process_force", process_force},
        {"seed", spec.seed}};
}

std::vector<double> test_reference(const TestReference& test, double sample_time_s) {
    if (const auto problem = test.validate(); !problem.empty()) throw InputError("test: " + problem);
    if (!(sample_time_s > 0.0)) throw InputError("test: the sample time must be positive");
    // The test as a list of moves (target, speed) and dwells (speed 0).
    struct Move {
        double target;
        double speed;  // [m/s]; 0 = dwell at the current position for test.dwell_s
    };
    std::vector<Move> moves;
    const double start = test.start_m;
    moves.push_back({start, 0.0});
    double end = start;  // a one-way test's strokes follow one another
    const auto stroke = [&](double feedrate_mm_per_min, double length) {
        const double speed = feedrate_mm_per_min / 60000.0;
        for (int c = 0; c < test.cycles; ++c) {
            if (test.one_way) {
                end += length;
                moves.push_back({end, speed});
                moves.push_back({end, 0.0});
                continue;
            }
            moves.push_back({start + length, speed});
            moves.push_back({start + length, 0.0});
            moves.push_back({start, speed});
            moves.push_back({start, 0.0});
        }
    };
    for (const double f : test.feedrates_mm_per_min) stroke(f, test.stroke_m);
    if (test.slow_passes) {
        for (const double f : test.slow_feedrates_mm_per_min) {
            const double speed = f / 60000.0;
            stroke(f, std::clamp(speed * test.slow_pass_duration_s, test.slow_stroke_min_m, test.stroke_m));
        }
    }

    std::vector<double> reference;
    double position = start;
    double segment_start = 0.0;  // time at which the current move starts [s]
    std::size_t k = 0;
    const double a = test.acceleration_m_per_s2;
    for (const auto& move : moves) {
        double duration = 0.0;
        double peak = 0.0, accelerate = 0.0, cruise = 0.0;
        const double distance = std::abs(move.target - position);
        const double direction = move.target >= position ? 1.0 : -1.0;
        if (move.speed == 0.0 || distance == 0.0) {
            duration = move.speed == 0.0 ? test.dwell_s : 0.0;
        } else {
            // Trapezoidal velocity: accelerate to the feedrate (or a triangle when the move is too short).
            peak = std::min(move.speed, std::sqrt(distance * a));
            accelerate = peak / a;
            cruise = (distance - peak * accelerate) / peak;
            duration = 2.0 * accelerate + cruise;
        }
        const double end = segment_start + duration;
        for (; static_cast<double>(k) * sample_time_s < end; ++k) {
            const double tau = static_cast<double>(k) * sample_time_s - segment_start;
            double travelled = 0.0;
            if (peak > 0.0) {
                if (tau < accelerate)
                    travelled = 0.5 * a * tau * tau;
                else if (tau < accelerate + cruise)
                    travelled = 0.5 * peak * accelerate + peak * (tau - accelerate);
                else {
                    const double left = std::max(0.0, duration - tau);
                    travelled = distance - 0.5 * a * left * left;
                }
            }
            reference.push_back(position + direction * travelled);
        }
        position = move.target;
        segment_start = end;
    }
    reference.push_back(position);
    return reference;
}

namespace {

// Holds every factor-th sample (from the first) over the samples in between: a signal logged every `interval_s` on a
// time base of `dt`.
std::vector<double> held_every(std::vector<double> values, double interval_s, double dt) {
    const long factor = interval_s > 0.0 ? std::lround(interval_s / dt) : 1L;
    if (factor < 2) return values;
    const auto step = static_cast<std::size_t>(factor);
    for (std::size_t k = 0; k < values.size(); ++k) values[k] = values[k - k % step];
    return values;
}

// A channel as the recorder logs it: held over its interval, which it states.
void record(Trace& trace, std::string name, Role role, std::string unit, std::vector<double> values,
            double interval_s, double dt) {
    auto& channel = trace.set(std::move(name), role, std::move(unit), held_every(std::move(values), interval_s, dt));
    channel.source_unit = channel.unit;
    channel.native_interval_s = interval_s > 0.0 ? interval_s : dt;
    channel.interval_source = interval_s > 0.0 ? IntervalSource::format : IntervalSource::time_base;
}

struct SensorReadings {
    std::vector<double> time;   ///< [s]
    std::vector<double> drive;  ///< current [A], or the torque (force) from it [N*m or N]
};

// Time stamps k/f_s (k*T where the rate is not a whole number of hertz), jittered as the sensors say, and the drive
// force [N or N*m] as a current sensor (noise, quantum) reads it, or as the drive's torque (force) from that current.
SensorReadings read_sensors(const SynthSpec& spec, const std::vector<double>& force) {
    // a local generator, seeded, so that a trace is reproducible
    std::mt19937_64 generator(spec.seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    std::uniform_real_distribution<double> jitter(-1.0, 1.0);
    const double dt = spec.sensors.sample_time_s;
    const double per_ampere = spec.force_constant_N_per_A();
    const double quantum = spec.sensors.current_resolution_A;
    // k/f_s rather than k*T where the rate is a whole number of hertz: 0.009, not 0.009000000000000001.
    const double rate = std::round(1.0 / dt);
    const bool whole_rate = std::abs(rate * dt - 1.0) < whole_rate_tolerance;
    SensorReadings out{std::vector<double>(force.size()), std::vector<double>(force.size())};
    for (std::size_t k = 0; k < force.size(); ++k) {
        out.time[k] = (whole_rate ? static_cast<double>(k) / rate : static_cast<double>(k) * dt) +
                      (spec.sensors.jitter_s > 0.0 ? spec.sensors.jitter_s * jitter(generator) : 0.0);
        const double amperes = force[k] / per_ampere + (spec.sensors.current_noise_A > 0.0
                                                            ? spec.sensors.current_noise_A * noise(generator)
                                                            : 0.0);
        // + 0.0 turns -0 into 0 (a quantised zero prints as 0, not -0).
        const double current = (quantum > 0.0 ? quantum * std::nearbyint(amperes / quantum) : amperes) + 0.0;
        out.drive[k] = spec.recording.log_torque ? current * per_ampere : current;
    }
    return out;
}

// The drive constants and the true values, keyed with the axis kind's units.
void true_values(const SynthSpec& spec, const ControllerModel& controller, std::map<std::string, double>& constants) {
    const bool rotary = spec.axis.rotary;
    const ParameterNaming naming{rotary};
    const std::string length = naming.length_unit();
    constants["kt_Nm_per_A"] = spec.kt_Nm_per_A;
    constants["gear_ratio"] = spec.gear_ratio;
    if (rotary) {
        constants["torque_constant_Nm_per_A"] = spec.force_constant_N_per_A();
    } else {
        constants["lead_m"] = spec.lead_m;
        constants["force_constant_N_per_A"] = spec.force_constant_N_per_A();
    }
    constants["seed"] = static_cast<double>(spec.seed);
    // the true values under their result-document keys
    constants["true_" + naming.key(Term::mass)] = spec.axis.mass;
    constants["true_" + naming.key(Term::offset)] = spec.axis.offset;
    for (const auto& [direction, branch] : {std::pair{Direction::forward, &spec.axis.friction.forward},
                                            std::pair{Direction::reverse, &spec.axis.friction.reverse}}) {
        constants["true_" + naming.key(Term::viscous, direction)] = branch->viscous;
        constants["true_" + naming.key(Term::coulomb, direction)] = branch->coulomb;
        if (branch->has_stribeck()) {
            constants["true_" + naming.key(Term::breakaway, direction)] = *branch->breakaway;
            constants["true_" + naming.key(Term::stribeck_velocity, direction)] = *branch->stribeck_velocity;
        }
    }
    const double zone_scale = rotary ? rotary_rad_per_length_unit : 1.0;
    for (std::size_t z = 0; z < spec.friction_zones.size(); ++z) {
        const auto& zone = spec.friction_zones[z];
        constants[fmt::format("true_friction_zone{}_from_{}", z + 1, length)] = zone.from_m * zone_scale;
        constants[fmt::format("true_friction_zone{}_to_{}", z + 1, length)] = zone.to_m * zone_scale;
        constants[fmt::format("true_friction_zone{}_coulomb_factor", z + 1)] = zone.coulomb_factor;
    }
    constants["true_position_gain_per_s"] = controller.position_gain_per_s;
    constants["true_" + naming.velocity_gain_key()] = controller.velocity_gain_N_s_per_m;
    constants["true_" + naming.velocity_integral_gain_key()] = controller.velocity_integral_gain_N_per_m;
    constants["true_current_lag_s"] = controller.current_lag_s;
    if (controller.setpoint_delay_s > 0.0) constants["true_setpoint_delay_s"] = controller.setpoint_delay_s;
    if (controller.velocity_feedforward != 0.0) constants["true_velocity_feedforward"] = controller.velocity_feedforward;
    if (spec.servo_rate_hz > 0.0) constants["true_servo_rate_hz"] = spec.servo_rate_hz;
    if (spec.recording.drive_delay_s > 0.0) constants["true_drive_delay_s"] = spec.recording.drive_delay_s;
}

/// The integration steps per sample: the sensors', raised to a whole multiple of the servo's cycles per sample.
int integration_substeps(const SynthSpec& spec) {
    if (spec.servo_rate_hz <= 0.0) return spec.sensors.substeps;
    const auto per_sample = static_cast<int>(std::lround(spec.servo_rate_hz * spec.sensors.sample_time_s));
    return std::max(1, (spec.sensors.substeps + per_sample - 1) / per_sample) * per_sample;
}

/// The drive signal's delay in integration steps; InputError when it is not a whole number of them.
int delay_steps(const SynthSpec& spec, int substeps) {
    const double step = spec.sensors.sample_time_s / substeps;
    const double steps = spec.recording.drive_delay_s / step;
    if (std::abs(steps - std::round(steps)) > 1e-6 || steps > SimulationOptions::max_drive_signal_delay_steps) {
        throw InputError(fmt::format(
            "synth: recording.drive_delay_ms {:g} must be a whole number (at most {}) of integration steps of {:g} ms "
            "(the sample time over the substeps)",
            spec.recording.drive_delay_s * 1e3, SimulationOptions::max_drive_signal_delay_steps, step * 1e3));
    }
    return static_cast<int>(std::lround(steps));
}

/// Bursts of process force along the reference (ProcessForceBursts), as an external force in +x [N]; `count` the
/// bursts made. A generator of its own, so that the sensors' noise is the same with and without them.
std::vector<double> process_force_bursts(const SynthSpec& spec, const std::vector<double>& reference,
                                         std::size_t& count) {
    std::vector<double> force(reference.size(), 0.0);
    count = 0;
    if (!spec.process_force) return force;
    const ProcessForceBursts& b = *spec.process_force;
    std::mt19937_64 generator(spec.seed ^ 0x9e3779b97f4a7c15ULL);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const double dt = spec.sensors.sample_time_s;
    const double coulomb = 0.5 * (spec.axis.friction.forward.coulomb + spec.axis.friction.reverse.coulomb);
    std::size_t remaining = 0;
    double amplitude = 0.0, started = 0.0;
    for (std::size_t k = 1; k < reference.size(); ++k) {
        const double commanded = (reference[k] - reference[k - 1]) / dt;
        const bool moving = std::abs(commanded) > 1e-9;
        if (!moving) {
            remaining = 0;  // a cut ends where the move does
            continue;
        }
        if (remaining == 0 && unit(generator) < b.rate_per_s * dt) {
            remaining = static_cast<std::size_t>(
                std::lround((b.min_duration_s + unit(generator) * (b.max_duration_s - b.min_duration_s)) / dt));
            amplitude = (b.min_fraction + unit(generator) * (b.max_fraction - b.min_fraction)) * coulomb;
            started = static_cast<double>(k) * dt;
            ++count;
        }
        if (remaining == 0) continue;
        --remaining;
        const double t = static_cast<double>(k) * dt - started;
        const double ripple = 1.0 + b.ripple_fraction * std::sin(2.0 * std::numbers::pi * b.ripple_hz * t);
        force[k] = -(commanded > 0.0 ? 1.0 : -1.0) * amplitude * ripple;  // opposes the motion
    }
    return force;
}

// The closed loop simulated on the reference: lengths of a rotary axis' test, encoder and friction zones in radians.
SimulationOutput simulate_spec(const SynthSpec& spec, const ControllerModel& controller,
                               const std::vector<double>& reference, std::span<const double> injection,
                               std::span<const double> external_force) {
    const double scale = spec.axis.rotary ? rotary_rad_per_length_unit : 1.0;
    SimulationInput input;
    input.sample_time_s = spec.sensors.sample_time_s;
    input.reference = reference;
    input.injection = injection;
    input.external_force = external_force;
    SimulationOptions options;
    options.substeps = integration_substeps(spec);
    options.drive_signal_delay_steps = delay_steps(spec, options.substeps);
    if (spec.sensors.position_resolution_m > 0.0)
        options.position_resolution_m = spec.sensors.position_resolution_m * scale;
    options.friction_zones = spec.friction_zones;
    for (auto& zone : options.friction_zones) {
        zone.from_m *= scale;
        zone.to_m *= scale;
    }
    return simulate(spec.axis, controller, input, options);
}

// The injected signal u_inj(k*T) [N] (held over each sample), or empty when the spec has none.
std::vector<double> injected_signal(const SynthSpec& spec, std::size_t samples) {
    std::vector<double> signal;
    if (!spec.injection) return signal;
    signal.resize(samples);
    for (std::size_t k = 0; k < samples; ++k)
        signal[k] = spec.injection->at(static_cast<double>(k) * spec.sensors.sample_time_s);
    return signal;
}

// The injected signal as the controller logs it: its own channel, in the drive signal's units (A, as the current),
// exact (a setpoint, not a measurement); and its true values.
void log_injection(const SynthSpec& spec, std::span<const double> injection, Trace& trace) {
    if (!spec.injection) return;
    // As the drive signal: a current [A], or with log_torque the force (torque) itself.
    const bool as_force = spec.recording.log_torque;
    const double per_unit = as_force ? 1.0 : spec.force_constant_N_per_A();
    std::vector<double> values(injection.size());
    for (std::size_t k = 0; k < values.size(); ++k) values[k] = injection[k] / per_unit;
    const std::string unit = as_force ? (spec.axis.rotary ? "N*m" : "N") : "A";
    auto& channel = trace.set("injection", Role::injection, unit, std::move(values));
    channel.source_unit = unit;
    channel.native_interval_s = spec.sensors.sample_time_s;
    channel.interval_source = IntervalSource::time_base;
    trace.constants["true_injection_amplitude_N"] = spec.injection->amplitude_N;
    trace.constants["true_injection_frequency_Hz"] = spec.injection->frequency_Hz;
    trace.constants["true_injection_gain"] = spec.controller.injection_gain;
}

}  // namespace

Trace synthesize(const SynthSpec& spec, const std::optional<std::vector<double>>& reference_override,
                 std::span<const double> external_force) {
    if (const auto problem = spec.validate(); !problem.empty()) throw InputError("synth: " + problem);
    const double dt = spec.sensors.sample_time_s;
    std::vector<double> reference = reference_override ? *reference_override : test_reference(spec.test, dt);
    if (reference.size() < 2) throw InputError("synth: the reference needs at least two samples");
    if (!external_force.empty() && external_force.size() != reference.size())
        throw InputError(fmt::format("synth: the external force has {} samples where the reference has {}",
                                     external_force.size(), reference.size()));
    if (spec.axis.rotary && !reference_override) {
        for (double& r : reference) r *= rotary_rad_per_length_unit;  // the test's "mm" are degrees
    }

    ControllerModel controller = spec.controller;
    const double servo_cycle = spec.servo_rate_hz > 0.0 ? 1.0 / spec.servo_rate_hz : dt;
    if (controller.position_cycle_s == 0.0) controller.position_cycle_s = servo_cycle;
    if (controller.velocity_cycle_s == 0.0) {
        // the speed controller runs at the servo rate, never slower than the position loop
        controller.velocity_cycle_s =
            spec.servo_rate_hz > 0.0 ? std::min(servo_cycle, controller.position_cycle_s) : controller.position_cycle_s;
    }
    const std::vector<double> injection = injected_signal(spec, reference.size());
    std::size_t bursts = 0;
    std::vector<double> process = process_force_bursts(spec, reference, bursts);
    if (!external_force.empty()) {
        for (std::size_t k = 0; k < process.size(); ++k) process[k] += external_force[k];
    }
    const bool pushed = spec.process_force.has_value() || !external_force.empty();
    SimulationOutput simulated =
        simulate_spec(spec, controller, reference, injection, pushed ? std::span<const double>(process) : external_force);

    SensorReadings sensors = read_sensors(spec, simulated.force);

    const bool rotary = spec.axis.rotary;
    const std::string length = rotary ? "rad" : "m", speed = rotary ? "rad/s" : "m/s";
    const auto& r = spec.recording;
    Trace trace;
    trace.format = "synthetic";
    trace.rotary = rotary;
    record(trace, "t", Role::time, "s", std::move(sensors.time), 0.0, dt);
    record(trace, "x_ref", Role::reference_position, length, reference, r.position_interval_s, dt);
    record(trace, "x", Role::position, length, std::move(simulated.measured_position), r.position_interval_s, dt);
    record(trace, "v_cmd", Role::velocity_command, speed, std::move(simulated.velocity_command), r.position_interval_s,
           dt);
    if (r.log_velocity)
        record(trace, "v", Role::velocity, speed, std::move(simulated.velocity), r.velocity_interval_s, dt);
    if (r.log_torque)
        record(trace, "tau", Role::force, rotary ? "N*m" : "N", std::move(sensors.drive), r.drive_interval_s, dt);
    else
        record(trace, "i", Role::current, "A", std::move(sensors.drive), r.drive_interval_s, dt);
    true_values(spec, controller, trace.constants);
    if (spec.process_force) trace.constants["true_process_force_bursts"] = static_cast<double>(bursts);
    log_injection(spec, injection, trace);
    return trace;
}

Trace in_recording_units(const Trace& trace, const RecordingModel& recording) {
    Trace out = trace;
    for (auto& channel : out.channels) {
        const bool position = channel.role == Role::position || channel.role == Role::reference_position;
        const bool velocity = channel.role == Role::velocity || channel.role == Role::velocity_command;
        const std::string& unit = position ? recording.position_unit : velocity ? recording.velocity_unit : "";
        if (unit.empty() || (!position && !velocity)) continue;
        const double scale = recording_unit_scale(unit, position ? Role::position : Role::velocity, trace.rotary);
        for (double& value : channel.values) value /= scale;
        channel.unit = unit;
        channel.source_unit = unit;
    }
    return out;
}

}  // namespace feedid
