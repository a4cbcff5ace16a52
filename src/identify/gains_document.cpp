// The gains document (docs/documents.md): the identified gains with their standard errors, in SI, in
// the drive signal's units and in the NC's units, with the structure and the fit; and the controller read back from
// it for `feedid simulate --gains`.

#include <cmath>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/json_adapters.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/core/null_reasons.hpp"
#include "feedid/core/parameters.hpp"

namespace feedid {

namespace {

// The estimate in other units: value * factor, standard error * |factor|.
Estimate scaled(const Estimate& estimate, double factor) {
    Estimate out;
    if (estimate.value) out.value = *estimate.value * factor;
    if (estimate.standard_error) out.standard_error = *estimate.standard_error * std::abs(factor);
    return out;
}

bool starts_with(std::string_view text, std::string_view prefix) {
    return text.substr(0, prefix.size()) == prefix;
}

// Why a gains document holds a null at `path` (null_reasons.hpp).
std::string gains_null_reason(std::string_view path, const GainResult& result, const GainOptions& options,
                              const ParameterNaming& naming) {
    const bool failed = result.status == Status::failed;
    const bool integral = path.find("integral") != std::string_view::npos || starts_with(path, "nc_units.tn_ms");
    const bool feedforward = path.find("feedforward") != std::string_view::npos;
    const bool stderr_only = path.ends_with("stderr") && !failed;
    if (feedforward && result.method == "structure" && options.feedforward) {
        return "a velocity feed-forward is fitted only from a logged velocity command, which this trace lacks";
    }
    if (feedforward && !options.feedforward) return "no velocity feed-forward fitted (--feedforward not given)";
    if (integral && !failed && !result.velocity_integral_gain_N_per_m.value) {
        return options.velocity_loop == VelocityLoopStructure::p
                   ? "the velocity loop is fitted as P only (--velocity-loop p): no K_i, no T_n"
                   : "the velocity loop shows no integral action (see the diagnostic on it): no K_i, no T_n";
    }
    if (path == "structure.setpoint_delay_s.stderr" && !failed) {
        return "the residual does not curve in the setpoint delay about its best value, so it has no standard error";
    }
    if (stderr_only) return "the fit's variance of this gain is not a finite number >= 0, so it has no standard error";
    if (path == "fit.position_loop_relative_error_pct" && result.method != "velocity_command") {
        return "the position loop is fitted on its own only from a logged velocity command, which this trace lacks";
    }
    if (path == "structure." + naming.saturation_key()) return "no limit of the drive signal given (--saturation)";
    if (failed) return "the controller fit failed (the first diagnostic says why)";
    return {};
}

}  // namespace

nlohmann::json gains_document(const GainResult& result, const GainOptions& options, const Trace& trace) {
    const ParameterNaming naming{trace.rotary};
    nlohmann::json document;
    document["gains"] = {
        {"position_gain_per_s", result.position_gain_per_s},
        {naming.velocity_gain_key(), result.velocity_gain_N_s_per_m},
        {naming.velocity_integral_gain_key(), result.velocity_integral_gain_N_per_m},
        {"velocity_feedforward", result.velocity_feedforward},
    };
    if (options.force_per_signal != 0.0) {
        const double per = 1.0 / options.force_per_signal;
        document["gains"][naming.signal_velocity_gain_key()] = scaled(result.velocity_gain_N_s_per_m, per);
        document["gains"][naming.signal_integral_gain_key()] = scaled(result.velocity_integral_gain_N_per_m, per);
        document["signal"] = {{"unit", options.signal_unit}, {"force_per_signal", options.force_per_signal}};
    }
    const auto tn = scaled(result.reset_time_s, 1000.0);
    document["nc_units"] = {{"tn_ms", tn.value}, {"tn_ms_stderr", tn.standard_error}};
    if (!trace.rotary) {
        // K_v as NCs state it for a linear axis, (m/min)/mm; a rotary axis's K_v is in 1/s (position_gain_per_s).
        const auto kv = scaled(result.position_gain_per_s, m_per_min_per_mm_per_1_per_s);
        document["nc_units"]["kv_m_per_min_per_mm"] = kv.value;
        document["nc_units"]["kv_m_per_min_per_mm_stderr"] = kv.standard_error;
    }
    if (trace.rotary) document["rotary"] = true;  // without it a gains document is of a linear axis
    document["structure"] = {
        {"method", result.method},
        {"velocity_loop", result.velocity_integral_gain_N_per_m.value ? "PI" : "P"},
        {"velocity_difference_samples", result.velocity_difference_samples},
        {"reference_delay_samples", result.reference_delay_samples},
        {"setpoint_delay_s", result.setpoint_delay_s},
        {"current_lag_s", result.current_lag_s},
        {"drive_delay_samples", result.drive_delay_samples},
        {naming.saturation_key(), result.controller.saturation_N},
        {"sample_time_s", result.controller.velocity_cycle_s},
        {"servo_rate_hz", result.servo_rate_hz},
        {"fit", result.fit_kind},
        {"servo_rate_from", result.servo_rate_from},
    };
    // a position loop slower than the velocity loop (a position held over several samples): its own cycle
    if (result.controller.position_cycle_s > result.controller.velocity_cycle_s)
        document["structure"]["position_cycle_s"] = result.controller.position_cycle_s;
    document["status"] = to_string(result.status);
    document["fit"] = {{"relative_error_pct", result.relative_error_pct},
                       {"systematic_error_pct", result.systematic_error_pct},
                       {"injection_subtracted", result.injection_subtracted},
                       {"position_loop_relative_error_pct",
                        result.method == "velocity_command" ? nlohmann::json(result.position_loop_relative_error_pct)
                                                            : nlohmann::json()},
                       {"samples_used", result.samples_used}};
    if (result.effective_position_gain_per_s.value) {
        // the P-only fit of a loop with a feed-forward: named, never printed as the loop's gain
        document["gains"]["effective_position_gain_per_s"] = result.effective_position_gain_per_s;
    }
    if (!result.position_loop_models.empty()) {
        nlohmann::json models = nlohmann::json::array();
        for (const auto& model : result.position_loop_models) {
            models.push_back({{"model", model.name},
                              {"position_gain_per_s", model.position_gain_per_s},
                              {"relative_error_pct", model.relative_error_pct},
                              {"weight", model.weight}});
        }
        // position_gain_per_s.stderr takes in the choice between these; within the chosen one alone:
        document["position_loop"] = {
            {"model", result.velocity_feedforward.value ? "P+FF" : "P"},
            {"models", std::move(models)},
            {"position_gain_stderr_within_model", result.position_gain_within_model_stderr
                                                      ? nlohmann::json(*result.position_gain_within_model_stderr)
                                                      : nlohmann::json()}};
    }
    if (result.injection_subtracted) {
        // g: the drive signal holds the controller's output plus g times the injection as logged
        document["injection"] = {{"gain", result.injection_gain},
                                 {"gain_from", result.injection_gain.standard_error ? "fit" : "assumed"}};
    }
    document["diagnostics"] = result.diagnostics;
    document["trace"] = {{"path", trace.source_path}, {"samples", trace.samples()}};
    explain_nulls(document, [&](std::string_view path) { return gains_null_reason(path, result, options, naming); });
    return document;
}

bool gains_document_is_rotary(const nlohmann::json& document) {
    // A rotary axis's document carries the rotary keys (velocity_gain_Nms_per_rad, ...); "rotary" says which, and
    // without it the keys present do.
    if (!document.is_object()) return false;
    if (document.contains("rotary") && document["rotary"].is_boolean()) return document["rotary"].get<bool>();
    const auto found = document.find("gains");
    return found != document.end() && found->is_object() && found->contains(ParameterNaming{true}.velocity_gain_key());
}

ControllerModel controller_from_document(const nlohmann::json& document, const std::string& source) {
    // A number, or {"value": number}; absent or null is nothing, anything else is refused naming the key.
    const auto value_of = [&](const nlohmann::json& parent, const char* key) -> std::optional<double> {
        if (!parent.is_object() || !parent.contains(key)) return std::nullopt;
        const auto& entry = parent[key];
        const auto& value = entry.is_object() ? entry.value("value", nlohmann::json()) : entry;
        if (value.is_number()) return value.get<double>();
        if (!value.is_null()) throw InputError(fmt::format("{}: {}: must be a number or null", source, key));
        return std::nullopt;
    };
    if (!document.is_object() || !document.contains("gains")) {
        throw InputError(fmt::format("{}: not a gains document (no \"gains\" object)", source));
    }
    const auto& gains = document["gains"];
    if (document.contains("rotary") && !document["rotary"].is_boolean())
        throw InputError(fmt::format("{}: rotary: must be true or false", source));
    const ParameterNaming naming{gains_document_is_rotary(document)};
    ControllerModel model;
    const auto kv = value_of(gains, "position_gain_per_s");
    const auto kp = value_of(gains, naming.velocity_gain_key().c_str());
    if (!kv) throw InputError(fmt::format("{}: gains.position_gain_per_s.value is missing or null", source));
    if (!kp) throw InputError(fmt::format("{}: gains.{}.value is missing or null", source, naming.velocity_gain_key()));
    model.position_gain_per_s = *kv;
    model.velocity_gain_N_s_per_m = *kp;
    model.velocity_integral_gain_N_per_m = value_of(gains, naming.velocity_integral_gain_key().c_str()).value_or(0.0);
    model.velocity_feedforward = value_of(gains, "velocity_feedforward").value_or(0.0);
    if (document.contains("structure") && document["structure"].is_object()) {
        const auto& structure = document["structure"];
        if (const auto n = value_of(structure, "velocity_difference_samples")) {
            model.velocity_difference_samples = static_cast<int>(std::lround(*n));
        }
        model.current_lag_s = value_of(structure, "current_lag_s").value_or(0.0);
        model.setpoint_delay_s = value_of(structure, "setpoint_delay_s").value_or(0.0);
        model.saturation_N = value_of(structure, naming.saturation_key().c_str());
        model.velocity_cycle_s = value_of(structure, "sample_time_s").value_or(0.0);
        model.position_cycle_s = value_of(structure, "position_cycle_s").value_or(model.velocity_cycle_s);
    }
    if (document.contains("injection")) model.injection_gain = value_of(document["injection"], "gain").value_or(1.0);
    if (const auto problem = model.validate(); !problem.empty()) {
        throw InputError(fmt::format("{}: {}", source, problem));
    }
    return model;
}

}  // namespace feedid
