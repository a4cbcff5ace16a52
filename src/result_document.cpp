#include "feedid/result_document.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <fmt/core.h>

#include "feedid/error.hpp"

namespace feedid {

using Json = nlohmann::json;

// ---- the records, each with its keys

void to_json(Json& j, const TraceSummary& t) {
    j = Json{{"path", t.path},
             {"format", t.format},
             {"samples", t.samples},
             {"sample_time_s", t.sample_time_s},
             {"duration_s", t.duration_s}};
}

void to_json(Json& j, const PreprocessReport& p) {
    j = Json{{"differentiation", p.differentiation},
             {"filter_order", p.filter_order},
             {"cutoff_hz", p.cutoff_hz},
             {"decimation", p.decimation},
             {"edge_samples", p.edge_samples},
             {"velocity_source", p.velocity_source}};
    if (p.differentiation == "savitzky-golay") {
        j["savitzky_golay_window"] = p.savitzky_golay_window;
        j["savitzky_golay_order"] = p.savitzky_golay_order;
    }
}

void to_json(Json& j, const SelectionReport& s) {
    j = Json{{"total", s.total},
             {"window", s.window},
             {"moving", s.moving},
             {"step1", s.step1},
             {"step2", s.step2},
             {"moving_threshold", s.moving_threshold},
             {"split_velocity", s.split_velocity},
             {"initial_split_velocity", s.initial_split},
             {"passes", s.passes},
             {"stick_slip_passes", s.stick_slip_passes},
             {"stick_slip_samples", s.stick_slip_samples},
             {"clipped", s.clipped},
             {"near_rest", s.near_rest},
             {"notes", s.notes}};
}

void to_json(Json& j, const LogLinearStribeck& l) {
    j = Json{{"breakaway", l.breakaway},
             {"stribeck_velocity", l.stribeck_velocity},
             {"samples_used", l.used},
             {"excluded_wrong_sign", l.wrong_sign},
             {"excluded_below_noise", l.below_noise}};
}

void to_json(Json& j, const NonlinearFitReport& n) {
    j = Json{{"method", n.method},
             {"converged", n.converged},
             {"relative_error_pct", n.relative_error_pct},
             {"residual_std", n.residual_std},
             {"samples_used", n.samples_used},
             {"function_evaluations", n.function_evaluations}};
}

namespace {

constexpr std::array<const char*, 2> kDirections{"forward", "reverse"};

/// A number that may have been written as null (NaN and infinities are).
double number(const Json& j, const char* key) {
    if (!j.contains(key)) return std::numeric_limits<double>::quiet_NaN();
    return j.at(key).get<std::optional<double>>().value_or(std::numeric_limits<double>::quiet_NaN());
}

template <class T>
Json keyed(const std::vector<std::string>& keys, const std::vector<T>& values) {
    Json out = Json::object();
    for (std::size_t c = 0; c < keys.size() && c < values.size(); ++c) out[keys[c]] = values[c];
    return out;
}

Json step1_fit_json(const Step1Report& s) {
    Json out{{"relative_error_pct", s.relative_error_pct},
             {"condition_number", s.condition_number},
             {"samples_used", s.samples_used},
             {"residual_std", s.residual_std},
             {"r_diagonal", s.r_diagonal}};
    if (s.correlation.size() == s.keys.size() && !s.keys.empty()) {
        // correlations of the estimates, by key pair: correlations[a][b]
        Json correlations = Json::object();
        for (std::size_t i = 0; i < s.keys.size(); ++i) {
            for (std::size_t j = 0; j < s.keys.size(); ++j) {
                if (i != j) correlations[s.keys[i]][s.keys[j]] = s.correlation[i][j];
            }
        }
        out["correlations"] = correlations;
    }
    return out;
}

Json systematic_json(const SystematicReport& report) {
    Json variants = Json::array();
    for (const auto& v : report.variants) {
        variants.push_back({{"preprocessing", v.label}, {"status", v.status}, {"parameters", keyed(v.keys, v.values)}});
    }
    return Json{{"variants", variants}};
}

Json rls_json(const RlsReport& r) {
    Json history = Json::object();
    if (!r.history_time.empty()) {
        history["time_s"] = r.history_time;
        for (std::size_t c = 0; c < r.keys.size(); ++c) history[r.keys[c]] = r.history[c];
    }
    Json out{{"variant", r.options.variant == RlsVariant::exponential ? "exponential" : "directional"},
             {"forgetting_factor", r.options.forgetting_factor},
             {"initial_covariance", r.options.initial_covariance},
             {"final", keyed(r.keys, r.final_estimate)},
             {"averaged", keyed(r.keys, r.averaged)},
             {"settled", r.settled},
             {"transient_end_s", r.transient_end_s}};
    if (!history.empty()) out["history"] = history;  // absent in the history store's copies
    return out;
}

Json stribeck_json(const StribeckReport& s) {
    Json out = Json::object();
    for (std::size_t g = 0; g < 2; ++g) {
        if (s.log_linear[g]) out[kDirections[g]]["log_linear"] = *s.log_linear[g];
    }
    if (s.nonlinear) out["nonlinear"] = *s.nonlinear;
    return out;
}

Json friction_curve_json(const FrictionCurveReport& c, const ParameterNaming& naming) {
    Json out = Json::object();
    const std::array<const std::optional<FrictionCurvePoints>*, 2> sides{&c.forward, &c.reverse};
    for (std::size_t g = 0; g < 2; ++g) {
        if (!*sides[g]) continue;
        const auto& points = **sides[g];
        out[kDirections[g]] = {{naming.curve_velocity_key(), points.speed},
                               {naming.curve_force_key(), points.force},
                               {"fitted_" + naming.curve_force_key(), points.fitted}};
    }
    return out;
}

}  // namespace

void to_json(Json& document, const IdentifyResult& result) {
    const ParameterNaming naming{result.rotary};
    document = Json::object();
    document["feedid_version"] = result.feedid_version;
    document["trace"] = result.trace;
    document["model"] = result.model_name();
    document["rotary"] = result.rotary;
    Json parameters = Json::object();
    for (const auto& p : result.parameters) parameters[p.key] = p.estimate;
    document["parameters"] = parameters;
    document["status"] = result.status;
    document["diagnostics"] = result.diagnostics;
    if (result.preprocessing) document["preprocessing"] = *result.preprocessing;
    if (result.selection) document["selection"] = *result.selection;
    if (result.step1) {
        document["fit"] = step1_fit_json(*result.step1);
        document["step1"] = {{"batch", keyed(result.step1->keys, result.step1->batch)}};
        if (!result.step1->white_noise_standard_error.empty()) {
            document["step1"]["white_noise_stderr"] =
                keyed(result.step1->keys, result.step1->white_noise_standard_error);
        }
    }
    if (result.rls) document["rls"] = rls_json(*result.rls);
    if (result.stribeck) document["stribeck"] = stribeck_json(*result.stribeck);
    if (result.friction_curve) document["friction_curve"] = friction_curve_json(*result.friction_curve, naming);
    if (result.systematic) document["systematic"] = systematic_json(*result.systematic);
    if (result.friction_only) {
        document["friction_only"] = {{"reason", result.friction_only->reason},
                                     {"samples_used", result.friction_only->samples_used},
                                     {"relative_error_pct", result.friction_only->relative_error_pct},
                                     {"residual_std", result.friction_only->residual_std}};
    }
    if (!result.options.is_null()) document["options"] = result.options;
}

// ---- reading a document back

void from_json(const Json& j, TraceSummary& t) {
    t.path = j.value("path", std::string());
    t.format = j.value("format", std::string());
    t.samples = j.value("samples", std::size_t{0});
    t.sample_time_s = number(j, "sample_time_s");
    t.duration_s = number(j, "duration_s");
}

void from_json(const Json& j, PreprocessReport& p) {
    p.differentiation = j.at("differentiation").get<std::string>();
    p.filter_order = j.at("filter_order").get<int>();
    p.cutoff_hz = number(j, "cutoff_hz");
    p.decimation = j.at("decimation").get<int>();
    p.edge_samples = j.at("edge_samples").get<std::size_t>();
    p.velocity_source = j.value("velocity_source", std::string("position"));  // documents before it existed
    p.savitzky_golay_window = j.value("savitzky_golay_window", 0);
    p.savitzky_golay_order = j.value("savitzky_golay_order", 0);
}

void from_json(const Json& j, SelectionReport& s) {
    s.total = j.at("total").get<std::size_t>();
    s.window = j.at("window").get<std::size_t>();
    s.moving = j.at("moving").get<std::size_t>();
    s.step1 = j.at("step1").get<std::size_t>();
    s.step2 = j.at("step2").get<std::size_t>();
    s.moving_threshold = number(j, "moving_threshold");
    s.split_velocity = number(j, "split_velocity");
    s.initial_split = j.contains("initial_split_velocity") ? number(j, "initial_split_velocity") : s.split_velocity;
    // documents before stick-slip detection and clip detection hold none of these
    s.passes = j.value("passes", std::size_t{0});
    s.stick_slip_passes = j.value("stick_slip_passes", std::size_t{0});
    s.stick_slip_samples = j.value("stick_slip_samples", std::size_t{0});
    s.clipped = j.value("clipped", std::size_t{0});
    s.near_rest = j.value("near_rest", std::size_t{0});
    s.notes = j.at("notes").get<std::vector<std::string>>();
}

void from_json(const Json& j, LogLinearStribeck& l) {
    l.breakaway = j.at("breakaway").get<std::optional<double>>();
    l.stribeck_velocity = j.at("stribeck_velocity").get<std::optional<double>>();
    l.used = j.at("samples_used").get<std::size_t>();
    l.wrong_sign = j.at("excluded_wrong_sign").get<std::size_t>();
    l.below_noise = j.at("excluded_below_noise").get<std::size_t>();
}

void from_json(const Json& j, NonlinearFitReport& n) {
    n.method = j.at("method").get<std::string>();
    n.converged = j.at("converged").get<bool>();
    n.relative_error_pct = number(j, "relative_error_pct");
    n.residual_std = number(j, "residual_std");
    n.samples_used = j.at("samples_used").get<std::size_t>();
    n.function_evaluations = j.at("function_evaluations").get<int>();
}

namespace {

/// The parameters of the document, in feedid's order, with the model they imply.
void read_parameters(const Json& j, IdentifyResult& r) {
    const Json& parameters = j.at("parameters");
    bool asymmetric = j.value("model", std::string()) == "asymmetric", offset = false, rotary_keys = false;
    for (const auto& [key, entry] : parameters.items()) {
        const auto meaning = parse_parameter_key(key);
        if (!meaning) throw InputError(fmt::format("parameter \"{}\" is not one of feedid's model", key));
        asymmetric = asymmetric || (meaning->direction != Direction::both && meaning->term != Term::mass);
        offset = offset || meaning->term == Term::offset;
        rotary_keys = rotary_keys || meaning->rotary;
    }
    r.rotary = j.contains("rotary") ? j.at("rotary").get<bool>() : rotary_keys;
    r.model = asymmetric ? FrictionModelKind::asymmetric : FrictionModelKind::symmetric;
    r.offset = offset;
    r.parameters = model_parameters(r.model, r.offset, r.rotary);
    for (const auto& [key, entry] : parameters.items()) {
        auto it =
            std::find_if(r.parameters.begin(), r.parameters.end(), [&](const Parameter& p) { return p.key == key; });
        if (it == r.parameters.end()) {
            throw InputError(fmt::format("parameter \"{}\" does not belong to a {} {} model", key, r.model_name(),
                                         r.rotary ? "rotary" : "linear"));
        }
        it->estimate = entry.get<Estimate>();
    }
    r.axis = axis_from_parameters(r.parameters, r.model, r.rotary);
}

Step1Report read_step1(const Json& fit, const Json& step1) {
    Step1Report s;
    s.relative_error_pct = number(fit, "relative_error_pct");
    s.condition_number = number(fit, "condition_number");
    s.samples_used = fit.at("samples_used").get<std::size_t>();
    s.residual_std = number(fit, "residual_std");
    for (const auto& value : fit.at("r_diagonal"))
        s.r_diagonal.push_back(value.get<std::optional<double>>().value_or(NAN));
    for (const auto& [key, entry] : step1.at("batch").items()) {
        s.keys.push_back(key);
        s.batch.push_back(entry.get<Estimate>());
        if (step1.contains("white_noise_stderr"))
            s.white_noise_standard_error.push_back(number(step1.at("white_noise_stderr"), key.c_str()));
    }
    if (fit.contains("correlations")) {
        const Json& correlations = fit.at("correlations");
        s.correlation.assign(s.keys.size(), std::vector<double>(s.keys.size(), 1.0));
        for (std::size_t i = 0; i < s.keys.size(); ++i) {
            for (std::size_t j = 0; j < s.keys.size(); ++j) {
                if (i != j) s.correlation[i][j] = number(correlations.at(s.keys[i]), s.keys[j].c_str());
            }
        }
    }
    return s;
}

SystematicReport read_systematic(const Json& j) {
    SystematicReport report;
    for (const auto& v : j.at("variants")) {
        SystematicVariant variant{v.at("preprocessing").get<std::string>(), v.at("status").get<Status>(), {}, {}};
        for (const auto& [key, value] : v.at("parameters").items()) {
            variant.keys.push_back(key);
            variant.values.push_back(value.get<std::optional<double>>());
        }
        report.variants.push_back(std::move(variant));
    }
    return report;
}

RlsReport read_rls(const Json& j) {
    RlsReport r;
    r.options.variant =
        j.at("variant").get<std::string>() == "exponential" ? RlsVariant::exponential : RlsVariant::directional;
    r.options.forgetting_factor = number(j, "forgetting_factor");
    r.options.initial_covariance = number(j, "initial_covariance");
    r.settled = j.at("settled").get<bool>();
    r.transient_end_s = number(j, "transient_end_s");
    // the history store keeps results without the RLS history (it is bulky): then it reads back empty
    const Json history = j.value("history", Json::object());
    r.history_time = history.value("time_s", std::vector<double>{});
    for (const auto& [key, value] : j.at("final").items()) {
        r.keys.push_back(key);
        r.final_estimate.push_back(value.get<std::optional<double>>().value_or(NAN));
        r.averaged.push_back(number(j.at("averaged"), key.c_str()));
        std::vector<double> series;
        if (history.contains(key)) {
            for (const auto& v : history.at(key)) series.push_back(v.get<std::optional<double>>().value_or(NAN));
        }
        r.history.push_back(std::move(series));
    }
    return r;
}

StribeckReport read_stribeck(const Json& j) {
    StribeckReport s;
    for (std::size_t g = 0; g < 2; ++g) {
        if (j.contains(kDirections[g]))
            s.log_linear[g] = j.at(kDirections[g]).at("log_linear").get<LogLinearStribeck>();
    }
    if (j.contains("nonlinear")) s.nonlinear = j.at("nonlinear").get<NonlinearFitReport>();
    return s;
}

FrictionCurveReport read_friction_curve(const Json& j, const ParameterNaming& naming) {
    FrictionCurveReport c;
    const std::array<std::optional<FrictionCurvePoints>*, 2> sides{&c.forward, &c.reverse};
    for (std::size_t g = 0; g < 2; ++g) {
        if (!j.contains(kDirections[g])) continue;
        const Json& side = j.at(kDirections[g]);
        *sides[g] = FrictionCurvePoints{side.at(naming.curve_velocity_key()).get<std::vector<double>>(),
                                        side.at(naming.curve_force_key()).get<std::vector<double>>(),
                                        side.at("fitted_" + naming.curve_force_key()).get<std::vector<double>>()};
    }
    return c;
}

void read_records(const Json& j, IdentifyResult& r) {
    if (j.contains("preprocessing")) r.preprocessing = j.at("preprocessing").get<PreprocessReport>();
    if (j.contains("selection")) r.selection = j.at("selection").get<SelectionReport>();
    if (j.contains("fit") && j.contains("step1")) r.step1 = read_step1(j.at("fit"), j.at("step1"));
    if (j.contains("rls")) r.rls = read_rls(j.at("rls"));
    if (j.contains("stribeck")) r.stribeck = read_stribeck(j.at("stribeck"));
    if (j.contains("friction_only")) {
        const Json& f = j.at("friction_only");
        r.friction_only = FrictionOnlyReport{f.at("reason").get<std::string>(), f.at("samples_used").get<std::size_t>(),
                                             number(f, "relative_error_pct"), number(f, "residual_std")};
    }
    if (j.contains("friction_curve"))
        r.friction_curve = read_friction_curve(j.at("friction_curve"), ParameterNaming{r.rotary});
    if (j.contains("systematic")) r.systematic = read_systematic(j.at("systematic"));
}

}  // namespace

void from_json(const Json& document, IdentifyResult& result) {
    if (!document.is_object() || !document.contains("parameters") || !document.at("parameters").is_object()) {
        throw InputError("not an identify result (no \"parameters\" object)");
    }
    IdentifyResult r;
    try {
        read_parameters(document, r);
        r.feedid_version = document.value("feedid_version", std::string());
        if (document.contains("trace")) r.trace = document.at("trace").get<TraceSummary>();
        r.diagnostics = document.value("diagnostics", std::vector<std::string>{});
        if (document.contains("status")) {
            r.status = document.at("status").get<Status>();
        } else {
            const bool any_null = std::any_of(r.parameters.begin(), r.parameters.end(),
                                              [](const Parameter& p) { return !p.estimate.value; });
            r.status = any_null ? Status::partial : Status::ok;
        }
        read_records(document, r);
        if (document.contains("options")) r.options = document.at("options");
    } catch (const Json::exception& e) {
        throw InputError(fmt::format("not a readable identify result: {}", e.what()));
    }
    result = std::move(r);
}

nlohmann::json identify_options_document(const IdentifyOptions& o, const nlohmann::json& command_line) {
    const auto& p = o.preprocess;
    const char* differentiation = p.differentiation == Differentiation::central          ? "central"
                                  : p.differentiation == Differentiation::savitzky_golay ? "savitzky-golay"
                                                                                         : "butterworth";
    Json document{{"model", o.model == FrictionModelKind::asymmetric ? "asymmetric" : "symmetric"},
                  {"offset", o.offset},
                  {"stribeck", o.stribeck},
                  {"differentiation", differentiation},
                  {"velocity_source", p.velocity_source == VelocitySource::position ? "position"
                                      : p.velocity_source == VelocitySource::logged ? "velocity"
                                                                                    : "auto"},
                  {"filter_order", p.filter_order},
                  {"cutoff_hz", p.cutoff_hz},
                  {"savitzky_golay_window", p.savitzky_golay_window},
                  {"savitzky_golay_order", p.savitzky_golay_order},
                  {"decimation", p.decimation},
                  {"edge_samples", p.edge_samples},
                  {"from_s", p.from_s},
                  {"to_s", p.to_s},
                  {"split_velocity", o.selection.split_velocity},
                  {"moving_threshold", o.selection.moving_threshold},
                  {"systematic", o.systematic},
                  {"rls",
                   {{"variant", o.step1.rls.variant == RlsVariant::exponential ? "paper" : "directional"},
                    {"forgetting_factor", o.step1.rls.forgetting_factor},
                    {"initial_covariance", o.step1.rls.initial_covariance}}}};
    for (const auto& [key, value] : command_line.items()) document[key] = value;
    return document;
}

}  // namespace feedid
