#include "feedid/synth.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <set>
#include <span>

#include <fmt/core.h>
#include <toml++/toml.h>

#include "feedid/error.hpp"
#include "feedid/io/import.hpp"

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

// The demo controller (feedid synth --help): K_v 2 (m/min)/mm, T_n 20 ms, current lag 0.3 ms, and K_p high enough
// that sliding is stable down to about 100 mm/min against the Stribeck slope (F_B - F_C)/v_s = 40 kN*s/m; below
// that the axis stick-slips, as real axes do. The force limit is twice the demo motor's rated 18 A.
constexpr double demo_kv_m_per_min_per_mm = 2.0;
constexpr double demo_velocity_gain_N_s_per_m = 40000.0;
constexpr double demo_integral_time_s = 0.020;
constexpr double demo_current_lag_s = 0.3e-3;
constexpr double demo_saturation_A = 36.0;

}  // namespace

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

double SquareWaveInjection::at(double time_s) const {
    const double phase = time_s * frequency_Hz;
    return phase - std::floor(phase) < 0.5 ? amplitude_N : 0.0;
}

std::string SquareWaveInjection::validate(double sample_time_s) const {
    if (!(std::isfinite(amplitude_N) && amplitude_N != 0.0))
        return "the injection's amplitude must be a number != 0 [N]";
    // At least four samples per half period, so that each half of the wave is seen as a level.
    const double highest = 1.0 / (8.0 * sample_time_s);
    if (!(frequency_Hz > 0.0 && frequency_Hz <= highest)) {
        return fmt::format("the injection's frequency must lie in (0, {:g}] Hz (four samples per half period)",
                           highest);
    }
    return {};
}

double SynthSpec::force_constant_N_per_A() const {
    // eq. (2): F_d = K_t * i / R, R = l / 2*pi, times the gear ratio motor:screw
    return kt_Nm_per_A * gear_ratio * 2.0 * std::numbers::pi / lead_m;
}

std::string SynthSpec::validate() const {
    if (!(kt_Nm_per_A > 0.0) || !(lead_m > 0.0) || !(gear_ratio > 0.0))
        return "K_t, lead and gear ratio must be positive";
    if (!(axis.mass > 0.0)) return "the mass must be positive";
    // The test is given in mm and mm/min and the drive acts through a ball screw: a rotary table would come out as a
    // linear axis with the wrong units. Refuse it rather than write such a trace.
    if (axis.rotary)
        return "rotary axes are not synthesised (the test is in mm and mm/min, the drive a ball screw); "
               "give a linear axis";
    if (auto problem = controller.validate(); !problem.empty()) return problem;
    if (auto problem = sensors.validate(); !problem.empty()) return problem;
    if (auto problem = test.validate(); !problem.empty()) return problem;
    if (injection) {
        if (auto problem = injection->validate(sensors.sample_time_s); !problem.empty()) return problem;
    }
    SimulationOptions zones;
    zones.friction_zones = friction_zones;
    if (auto problem = zones.validate(); !problem.empty()) return problem;
    return {};
}

SynthSpec demo_spec() {
    SynthSpec spec;
    FrictionBranch branch;
    branch.viscous = 54.2;
    branch.coulomb = 742.8;
    branch.breakaway = 946.2;
    branch.stribeck_velocity = 0.005;
    spec.axis.mass = 69.1;
    spec.axis.friction = Friction::symmetric(branch);
    spec.controller.position_gain_per_s = position_gain_from_kv(demo_kv_m_per_min_per_mm);
    spec.controller.velocity_gain_N_s_per_m = demo_velocity_gain_N_s_per_m;
    spec.controller.velocity_integral_gain_N_per_m = demo_velocity_gain_N_s_per_m / demo_integral_time_s;
    spec.controller.current_lag_s = demo_current_lag_s;
    spec.controller.saturation_N = demo_saturation_A * spec.force_constant_N_per_A();
    return spec;
}

namespace {

// Walks a JSON object, taking known keys and rejecting unknown ones (a typo must not pass silently).
class Section {
public:
    Section(const nlohmann::json& object, std::string path, std::string source)
        : object_(object), path_(std::move(path)), source_(std::move(source)) {
        if (!object_.is_object()) throw InputError(fmt::format("{}: '{}' must be an object", source_, path_));
    }
    ~Section() = default;
    Section(const Section&) = delete;
    Section& operator=(const Section&) = delete;

    bool has(const std::string& key) const { return object_.contains(key) && !object_[key].is_null(); }

    std::optional<double> number(const std::string& key) {
        known_.insert(key);
        if (!has(key)) return std::nullopt;
        const auto& value = object_[key];
        if (!value.is_number() || !std::isfinite(value.get<double>())) {
            throw InputError(fmt::format("{}: {}.{} must be a number", source_, path_, key));
        }
        return value.get<double>();
    }
    std::optional<bool> boolean(const std::string& key) {
        known_.insert(key);
        if (!has(key)) return std::nullopt;
        if (!object_[key].is_boolean())
            throw InputError(fmt::format("{}: {}.{} must be true or false", source_, path_, key));
        return object_[key].get<bool>();
    }
    std::optional<std::vector<double>> numbers(const std::string& key) {
        known_.insert(key);
        if (!has(key)) return std::nullopt;
        const auto& value = object_[key];
        if (!value.is_array())
            throw InputError(fmt::format("{}: {}.{} must be a list of numbers", source_, path_, key));
        std::vector<double> out;
        for (const auto& item : value) {
            if (!item.is_number())
                throw InputError(fmt::format("{}: {}.{} must be a list of numbers", source_, path_, key));
            out.push_back(item.get<double>());
        }
        return out;
    }
    void accept(const std::string& key) { known_.insert(key); }
    void reject_unknown() const {
        for (const auto& [key, value] : object_.items()) {
            if (!known_.contains(key)) {
                throw InputError(
                    fmt::format("{}: unknown key '{}{}{}'", source_, path_, path_.empty() ? "" : ".", key));
            }
        }
    }

private:
    const nlohmann::json& object_;
    std::string path_;
    std::string source_;
    std::set<std::string> known_;
};

// axis: the friction and mass keys axis_from_document reads, and no other.
void read_axis(const nlohmann::json& axis, const std::string& source, SynthSpec& spec) {
    spec.axis = axis_from_document(axis, source);
    for (const auto& [key, value] : axis.items()) {
        static const std::set<std::string> keys{"mass_kg", "inertia_kgm2", "offset_N", "offset_Nm", "rotary"};
        const bool friction_key = key.starts_with("viscous_") || key.starts_with("coulomb_") ||
                                  key.starts_with("breakaway_") || key.starts_with("stribeck_velocity_");
        if (!keys.contains(key) && !friction_key)
            throw InputError(fmt::format("{}: unknown key 'axis.{}'", source, key));
    }
}

// controller: gains in SI or NC units (K_v in (m/min)/mm, T_n in ms), cycles and lags in ms; saturation_N null
// removes the limit.
void read_controller(const nlohmann::json& object, const std::string& source, ControllerModel& model) {
    Section c(object, "controller", source);
    if (const auto v = c.number("position_gain_per_s")) model.position_gain_per_s = *v;
    if (const auto v = c.number("kv_m_per_min_per_mm")) model.position_gain_per_s = position_gain_from_kv(*v);
    if (const auto v = c.number("velocity_gain_N_s_per_m")) model.velocity_gain_N_s_per_m = *v;
    if (const auto v = c.number("velocity_integral_gain_N_per_m")) model.velocity_integral_gain_N_per_m = *v;
    if (const auto v = c.number("tn_ms")) {
        model.velocity_integral_gain_N_per_m = *v > 0.0 ? model.velocity_gain_N_s_per_m / (*v * 1e-3) : 0.0;
    }
    if (const auto v = c.number("velocity_feedforward")) model.velocity_feedforward = *v;
    if (c.has("saturation_N"))
        model.saturation_N = c.number("saturation_N");
    else if (object.contains("saturation_N"))
        model.saturation_N.reset();
    c.accept("saturation_N");
    if (const auto v = c.number("current_lag_ms")) model.current_lag_s = *v * 1e-3;
    if (const auto v = c.number("position_cycle_ms")) model.position_cycle_s = *v * 1e-3;
    if (const auto v = c.number("velocity_cycle_ms")) model.velocity_cycle_s = *v * 1e-3;
    if (const auto v = c.number("velocity_difference_samples"))
        model.velocity_difference_samples = static_cast<int>(std::lround(*v));
    c.reject_unknown();
}

void read_drive(const nlohmann::json& object, const std::string& source, SynthSpec& spec) {
    Section d(object, "drive", source);
    if (const auto v = d.number("kt_Nm_per_A")) spec.kt_Nm_per_A = *v;
    if (const auto v = d.number("lead_mm")) spec.lead_m = *v * 1e-3;
    if (const auto v = d.number("gear_ratio")) spec.gear_ratio = *v;
    d.reject_unknown();
}

void read_sensors(const nlohmann::json& object, const std::string& source, SensorModel& sensors) {
    Section s(object, "sensors", source);
    if (const auto v = s.number("sample_time_ms")) sensors.sample_time_s = *v * 1e-3;
    if (const auto v = s.number("jitter_us")) sensors.jitter_s = *v * 1e-6;
    if (const auto v = s.number("position_resolution_um")) sensors.position_resolution_m = *v * 1e-6;
    if (const auto v = s.number("current_noise_A")) sensors.current_noise_A = *v;
    if (const auto v = s.number("current_resolution_A")) sensors.current_resolution_A = *v;
    if (const auto v = s.number("substeps")) sensors.substeps = static_cast<int>(std::lround(*v));
    s.reject_unknown();
}

void read_test(const nlohmann::json& object, const std::string& source, TestReference& test) {
    Section t(object, "test", source);
    if (auto v = t.numbers("feedrates_mm_per_min")) test.feedrates_mm_per_min = std::move(*v);
    if (const auto v = t.number("stroke_mm")) test.stroke_m = *v * 1e-3;
    if (const auto v = t.number("cycles")) test.cycles = static_cast<int>(std::lround(*v));
    if (const auto v = t.boolean("slow_passes")) test.slow_passes = *v;
    if (auto v = t.numbers("slow_feedrates_mm_per_min")) test.slow_feedrates_mm_per_min = std::move(*v);
    if (const auto v = t.number("slow_pass_duration_s")) test.slow_pass_duration_s = *v;
    if (const auto v = t.number("slow_stroke_min_mm")) test.slow_stroke_min_m = *v * 1e-3;
    if (const auto v = t.number("acceleration_m_per_s2")) test.acceleration_m_per_s2 = *v;
    if (const auto v = t.number("dwell_s")) test.dwell_s = *v;
    if (const auto v = t.number("start_mm")) test.start_m = *v * 1e-3;
    t.reject_unknown();
}

// friction_zones: a list of {from_mm, to_mm, coulomb_factor}, each key required; replaces the demo's zones.
std::vector<FrictionZone> read_friction_zones(const nlohmann::json& list, const std::string& source) {
    if (!list.is_array()) throw InputError(fmt::format("{}: friction_zones must be a list of objects", source));
    std::vector<FrictionZone> zones;
    for (std::size_t k = 0; k < list.size(); ++k) {
        Section z(list[k], fmt::format("friction_zones[{}]", k), source);
        const auto from = z.number("from_mm");
        const auto to = z.number("to_mm");
        const auto factor = z.number("coulomb_factor");
        z.reject_unknown();
        if (!from || !to || !factor) {
            throw InputError(fmt::format("{}: friction_zones[{}] needs from_mm, to_mm and coulomb_factor", source, k));
        }
        zones.push_back({*from * 1e-3, *to * 1e-3, *factor});
    }
    return zones;
}

}  // namespace

SynthSpec spec_from_json(const nlohmann::json& document, const std::string& source) {
    SynthSpec spec = demo_spec();
    Section top(document, "", source);
    if (top.has("axis")) read_axis(document["axis"], source, spec);
    top.accept("axis");
    if (top.has("controller")) read_controller(document["controller"], source, spec.controller);
    top.accept("controller");
    if (top.has("drive")) read_drive(document["drive"], source, spec);
    top.accept("drive");
    if (top.has("sensors")) read_sensors(document["sensors"], source, spec.sensors);
    top.accept("sensors");
    if (top.has("test")) read_test(document["test"], source, spec.test);
    top.accept("test");
    if (top.has("friction_zones")) spec.friction_zones = read_friction_zones(document["friction_zones"], source);
    top.accept("friction_zones");
    if (const auto v = top.boolean("slow_passes")) spec.test.slow_passes = *v;
    if (const auto v = top.number("seed")) {
        if (*v < 0.0) throw InputError(fmt::format("{}: seed must be >= 0", source));
        spec.seed = static_cast<std::uint64_t>(*v);
    }
    top.accept("$schema");
    top.accept("description");
    top.reject_unknown();
    if (const auto problem = spec.validate(); !problem.empty())
        throw InputError(fmt::format("{}: {}", source, problem));
    return spec;
}

namespace {

// TOML values as JSON, so that one reader (spec_from_json) checks the keys of both formats.
nlohmann::json to_json(const toml::node& node) {
    if (const auto* table = node.as_table()) {
        nlohmann::json object = nlohmann::json::object();
        for (const auto& [key, value] : *table) object[std::string(key.str())] = to_json(value);
        return object;
    }
    if (const auto* array = node.as_array()) {
        nlohmann::json list = nlohmann::json::array();
        for (const auto& item : *array) list.push_back(to_json(item));
        return list;
    }
    if (const auto* integer = node.as_integer()) return integer->get();
    if (const auto* floating = node.as_floating_point()) return floating->get();
    if (const auto* boolean = node.as_boolean()) return boolean->get();
    if (const auto* text = node.as_string()) return text->get();
    return nullptr;  // dates and times: no drive key takes one, so the key check reports it
}

}  // namespace

SynthSpec spec_from_toml(std::string_view text, const std::string& source) {
    try {
        const toml::table table = toml::parse(text, source);
        return spec_from_json(to_json(table), source);
    } catch (const toml::parse_error& e) {
        throw InputError(fmt::format("{}:{}: not valid TOML: {}", source, e.source().begin.line, e.description()));
    }
}

SynthSpec read_spec(const std::filesystem::path& path) {
    const std::string text = read_file_bytes(path);
    if (path.extension() == ".toml") return spec_from_toml(text, path.string());
    try {
        return spec_from_json(nlohmann::json::parse(text), path.string());
    } catch (const nlohmann::json::parse_error& e) {
        throw InputError(fmt::format("{}: not a JSON document (byte {})", path.string(), e.byte));
    }
}

nlohmann::json spec_to_json(const SynthSpec& spec) {
    nlohmann::json axis;
    axis["mass_kg"] = spec.axis.mass;
    axis["offset_N"] = spec.axis.offset;
    for (const auto& [direction, branch] : {std::pair{std::string("forward"), &spec.axis.friction.forward},
                                            std::pair{std::string("reverse"), &spec.axis.friction.reverse}}) {
        axis["viscous_" + direction + "_Ns_per_m"] = branch->viscous;
        axis["coulomb_" + direction + "_N"] = branch->coulomb;
        axis["breakaway_" + direction + "_N"] =
            branch->has_stribeck() ? nlohmann::json(*branch->breakaway) : nlohmann::json();
        axis["stribeck_velocity_" + direction + "_m_per_s"] =
            branch->has_stribeck() ? nlohmann::json(*branch->stribeck_velocity) : nlohmann::json();
    }
    const auto& c = spec.controller;
    nlohmann::json controller{{"position_gain_per_s", c.position_gain_per_s},
                              {"velocity_gain_N_s_per_m", c.velocity_gain_N_s_per_m},
                              {"velocity_integral_gain_N_per_m", c.velocity_integral_gain_N_per_m},
                              {"velocity_feedforward", c.velocity_feedforward},
                              {"saturation_N", c.saturation_N ? nlohmann::json(*c.saturation_N) : nlohmann::json()},
                              {"current_lag_ms", c.current_lag_s * 1e3},
                              {"position_cycle_ms", c.position_cycle_s * 1e3},
                              {"velocity_cycle_ms", c.velocity_cycle_s * 1e3},
                              {"velocity_difference_samples", c.velocity_difference_samples}};
    const auto& s = spec.sensors;
    const auto& t = spec.test;
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
          {"start_mm", t.start_m * 1e3}}},
        {"friction_zones", zones},
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
    const auto stroke = [&](double feedrate_mm_per_min, double length) {
        const double speed = feedrate_mm_per_min / 60000.0;
        for (int c = 0; c < test.cycles; ++c) {
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
    const double per_ampere = spec.force_constant_N_per_A();
    std::vector<double> amperes(injection.size());
    for (std::size_t k = 0; k < amperes.size(); ++k) amperes[k] = injection[k] / per_ampere;
    trace.set("injection", Role::injection, "A", std::move(amperes)).source_unit = "A";
    trace.constants["true_injection_amplitude_N"] = spec.injection->amplitude_N;
    trace.constants["true_injection_frequency_Hz"] = spec.injection->frequency_Hz;
}

}  // namespace

Trace synthesize(const SynthSpec& spec, const std::optional<std::vector<double>>& reference_override) {
    if (const auto problem = spec.validate(); !problem.empty()) throw InputError("synth: " + problem);
    const double dt = spec.sensors.sample_time_s;
    const std::vector<double> reference = reference_override ? *reference_override : test_reference(spec.test, dt);
    if (reference.size() < 2) throw InputError("synth: the reference needs at least two samples");

    ControllerModel controller = spec.controller;
    if (controller.position_cycle_s == 0.0) controller.position_cycle_s = dt;
    if (controller.velocity_cycle_s == 0.0) controller.velocity_cycle_s = controller.position_cycle_s;
    const std::vector<double> injection = injected_signal(spec, reference.size());
    const SimulationInput input{dt, reference, {}, injection};
    SimulationOptions options;
    options.substeps = spec.sensors.substeps;
    if (spec.sensors.position_resolution_m > 0.0) options.position_resolution_m = spec.sensors.position_resolution_m;
    options.friction_zones = spec.friction_zones;
    const SimulationOutput simulated = simulate(spec.axis, controller, input, options);

    // Sensors: a local generator, seeded, so that a trace is reproducible.
    std::mt19937_64 generator(spec.seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    std::uniform_real_distribution<double> jitter(-1.0, 1.0);
    const std::size_t n = reference.size();
    const double force_per_ampere = spec.force_constant_N_per_A();
    const auto quantise = [](double value, double quantum) {
        // + 0.0 turns -0 into 0 (a quantised zero prints as 0, not -0).
        return (quantum > 0.0 ? quantum * std::nearbyint(value / quantum) : value) + 0.0;
    };
    std::vector<double> time(n), current(n);
    // k/f_s rather than k*T where the rate is a whole number of hertz: 0.009, not 0.009000000000000001.
    const double rate = std::round(1.0 / dt);
    const bool whole_rate = std::abs(rate * dt - 1.0) < whole_rate_tolerance;
    for (std::size_t k = 0; k < n; ++k) {
        time[k] = (whole_rate ? static_cast<double>(k) / rate : static_cast<double>(k) * dt) +
                  (spec.sensors.jitter_s > 0.0 ? spec.sensors.jitter_s * jitter(generator) : 0.0);
        const double amperes =
            simulated.force[k] / force_per_ampere +
            (spec.sensors.current_noise_A > 0.0 ? spec.sensors.current_noise_A * noise(generator) : 0.0);
        current[k] = quantise(amperes, spec.sensors.current_resolution_A);
    }

    Trace trace;
    trace.format = "synthetic";
    trace.rotary = spec.axis.rotary;
    trace.set("t", Role::time, "s", std::move(time));
    trace.set("x_ref", Role::reference_position, "m", reference);
    trace.set("x", Role::position, "m", simulated.measured_position);
    trace.set("v_cmd", Role::velocity_command, "m/s", simulated.velocity_command);
    trace.set("i", Role::current, "A", std::move(current));
    for (auto& channel : trace.channels) channel.source_unit = channel.unit;

    auto& constants = trace.constants;
    constants["kt_Nm_per_A"] = spec.kt_Nm_per_A;
    constants["lead_m"] = spec.lead_m;
    constants["gear_ratio"] = spec.gear_ratio;
    constants["force_constant_N_per_A"] = force_per_ampere;
    constants["seed"] = static_cast<double>(spec.seed);
    constants["true_mass_kg"] = spec.axis.mass;
    constants["true_offset_N"] = spec.axis.offset;
    for (const auto& [direction, branch] : {std::pair{std::string("forward"), &spec.axis.friction.forward},
                                            std::pair{std::string("reverse"), &spec.axis.friction.reverse}}) {
        constants["true_viscous_" + direction + "_Ns_per_m"] = branch->viscous;
        constants["true_coulomb_" + direction + "_N"] = branch->coulomb;
        if (branch->has_stribeck()) {
            constants["true_breakaway_" + direction + "_N"] = *branch->breakaway;
            constants["true_stribeck_velocity_" + direction + "_m_per_s"] = *branch->stribeck_velocity;
        }
    }
    for (std::size_t z = 0; z < spec.friction_zones.size(); ++z) {
        const auto& zone = spec.friction_zones[z];
        constants[fmt::format("true_friction_zone{}_from_m", z + 1)] = zone.from_m;
        constants[fmt::format("true_friction_zone{}_to_m", z + 1)] = zone.to_m;
        constants[fmt::format("true_friction_zone{}_coulomb_factor", z + 1)] = zone.coulomb_factor;
    }
    constants["true_position_gain_per_s"] = controller.position_gain_per_s;
    constants["true_velocity_gain_N_s_per_m"] = controller.velocity_gain_N_s_per_m;
    constants["true_velocity_integral_gain_N_per_m"] = controller.velocity_integral_gain_N_per_m;
    constants["true_current_lag_s"] = controller.current_lag_s;
    log_injection(spec, injection, trace);
    return trace;
}

}  // namespace feedid
