// The gains document (`feedid gains --json`, DESIGN.md): the identified gains with their standard errors, in SI, in
// the drive signal's units and in the NC's units, with the structure and the fit; and the controller read back from
// it for `feedid simulate --gains`.

#include <cmath>

#include <fmt/core.h>

#include "feedid/error.hpp"
#include "feedid/gains.hpp"

namespace feedid {

namespace {

// The estimate in other units: value * factor, standard error * |factor|.
Estimate scaled(const Estimate& estimate, double factor) {
    Estimate out;
    if (estimate.value) out.value = *estimate.value * factor;
    if (estimate.standard_error) out.standard_error = *estimate.standard_error * std::abs(factor);
    return out;
}

}  // namespace

nlohmann::json gains_document(const GainResult& result, const GainOptions& options, const Trace& trace) {
    nlohmann::json document;
    document["gains"] = {
        {"position_gain_per_s", result.position_gain_per_s},
        {"velocity_gain_N_s_per_m", result.velocity_gain_N_s_per_m},
        {"velocity_integral_gain_N_per_m", result.velocity_integral_gain_N_per_m},
        {"velocity_feedforward", result.velocity_feedforward},
    };
    if (options.force_per_signal != 0.0) {
        const double per = 1.0 / options.force_per_signal;
        document["gains"]["velocity_gain_signal_per_m_per_s"] = scaled(result.velocity_gain_N_s_per_m, per);
        document["gains"]["velocity_integral_gain_signal_per_m"] = scaled(result.velocity_integral_gain_N_per_m, per);
        document["signal"] = {{"unit", options.signal_unit}, {"force_per_signal", options.force_per_signal}};
    }
    const auto kv = scaled(result.position_gain_per_s, m_per_min_per_mm_per_1_per_s);
    const auto tn = scaled(result.reset_time_s, 1000.0);
    document["nc_units"] = {
        {"kv_m_per_min_per_mm", kv.value},
        {"kv_m_per_min_per_mm_stderr", kv.standard_error},
        {"tn_ms", tn.value},
        {"tn_ms_stderr", tn.standard_error},
    };
    document["structure"] = {
        {"method", result.method},
        {"velocity_loop", result.velocity_integral_gain_N_per_m.value ? "PI" : "P"},
        {"velocity_difference_samples", result.velocity_difference_samples},
        {"reference_delay_samples", result.reference_delay_samples},
        {"current_lag_s", result.current_lag_s},
        {"drive_delay_samples", result.drive_delay_samples},
        {"saturation_N", result.controller.saturation_N},
        {"sample_time_s", result.controller.velocity_cycle_s},
    };
    document["status"] = to_string(result.status);
    document["fit"] = {{"relative_error_pct", result.relative_error_pct},
                       {"systematic_error_pct", result.systematic_error_pct},
                       {"injection_subtracted", result.injection_subtracted},
                       {"position_loop_relative_error_pct",
                        result.method == "velocity_command" ? nlohmann::json(result.position_loop_relative_error_pct)
                                                            : nlohmann::json()},
                       {"samples_used", result.samples_used}};
    document["diagnostics"] = result.diagnostics;
    document["trace"] = {{"path", trace.source_path}, {"samples", trace.samples()}};
    return document;
}

ControllerModel controller_from_document(const nlohmann::json& document, const std::string& source) {
    const auto value_of = [&](const nlohmann::json& parent, const char* key) -> std::optional<double> {
        if (!parent.is_object() || !parent.contains(key)) return std::nullopt;
        const auto& entry = parent[key];
        const auto& value = entry.is_object() ? entry.value("value", nlohmann::json()) : entry;
        if (value.is_number()) return value.get<double>();
        return std::nullopt;
    };
    if (!document.is_object() || !document.contains("gains")) {
        throw InputError(fmt::format("{}: not a gains document (no \"gains\" object)", source));
    }
    const auto& gains = document["gains"];
    ControllerModel model;
    const auto kv = value_of(gains, "position_gain_per_s");
    const auto kp = value_of(gains, "velocity_gain_N_s_per_m");
    if (!kv) throw InputError(fmt::format("{}: gains.position_gain_per_s.value is missing or null", source));
    if (!kp) throw InputError(fmt::format("{}: gains.velocity_gain_N_s_per_m.value is missing or null", source));
    model.position_gain_per_s = *kv;
    model.velocity_gain_N_s_per_m = *kp;
    model.velocity_integral_gain_N_per_m = value_of(gains, "velocity_integral_gain_N_per_m").value_or(0.0);
    model.velocity_feedforward = value_of(gains, "velocity_feedforward").value_or(0.0);
    if (document.contains("structure") && document["structure"].is_object()) {
        const auto& structure = document["structure"];
        if (const auto n = value_of(structure, "velocity_difference_samples")) {
            model.velocity_difference_samples = static_cast<int>(std::lround(*n));
        }
        model.current_lag_s = value_of(structure, "current_lag_s").value_or(0.0);
        model.saturation_N = value_of(structure, "saturation_N");
        model.position_cycle_s = value_of(structure, "sample_time_s").value_or(0.0);
        model.velocity_cycle_s = model.position_cycle_s;
    }
    if (const auto problem = model.validate(); !problem.empty()) {
        throw InputError(fmt::format("{}: {}", source, problem));
    }
    return model;
}

}  // namespace feedid
