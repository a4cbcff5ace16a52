#include "feedid/identify/result_document.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/json_adapters.hpp"
#include "feedid/io/json_input.hpp"

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

/// The name of a chosen model: "symmetric", "symmetric with offset", "per direction".
std::string model_selected(const ModelChoice& choice) {
    if (choice.model == FrictionModelKind::asymmetric) return "per direction";
    return choice.offset ? "symmetric with offset" : "symmetric";
}

/// The unit of a candidate's tested term.
std::string candidate_unit(const ModelCandidate& candidate, const ParameterNaming& naming) {
    if (candidate.tested == "tau") return "s";
    if (candidate.tested == "F_0") return naming.unit(Term::offset);
    if (candidate.tested == "B+ - B-") return naming.unit(Term::viscous);
    if (candidate.tested == "Stribeck friction forward - reverse") return naming.force_unit();
    return "";
}

/// The lack-of-fit checks: per grouping, the chi-square deviate of the residual's group means and the largest
/// significant structure (in the force unit and as a fraction of the typical drive force).
Json fit_checks_json(const std::vector<FitCheck>& checks, const ParameterNaming& naming) {
    Json out = Json::array();
    for (const auto& c : checks) {
        out.push_back({{"grouping", c.name},
                       {"groups", c.groups},
                       {"statistic", c.statistic},
                       {"threshold", c.threshold},
                       {"largest_" + naming.curve_force_key(), c.largest},
                       {"stderr_" + naming.curve_force_key(), c.largest_standard_error},
                       {"where", c.where},
                       {"fraction", c.relative},
                       {"material_fraction", c.material_fraction},
                       {"passed", c.passed}});
    }
    return out;
}

Json model_selection_json(const ModelChoice& choice, const ParameterNaming& naming) {
    Json candidates = Json::array();
    for (const auto& c : choice.candidates) {
        candidates.push_back({{"name", c.name},
                              {"tested", c.tested},
                              {"unit", candidate_unit(c, naming)},
                              {"estimate", c.estimate},
                              {"stderr", c.standard_error},
                              {"statistic", c.statistic},
                              {"threshold", c.threshold},
                              {"taken", c.taken},
                              {"verdict", c.verdict}});
    }
    Json out{{"automatic", choice.automatic},
             {"selected", model_selected(choice)},
             {"one_way", choice.one_way},
             {"candidates", candidates}};
    if (!choice.aliased_friction.empty()) out["aliased"] = choice.aliased_friction;
    out["residual_autocorrelation_samples"] = choice.residual_autocorrelation_samples;
    if (choice.correlation_block_samples > 0) out["correlation_block_samples"] = choice.correlation_block_samples;
    if (!choice.fit_checks.empty()) out["fit_checks"] = fit_checks_json(choice.fit_checks, naming);
    if (choice.rest) {
        out["rest_level"] = {{"samples", choice.rest->samples},
                             {"mean_" + naming.curve_force_key(), choice.rest->mean},
                             {"stderr_" + naming.curve_force_key(), choice.rest->standard_error}};
    }
    return out;
}

Json timing_json(const ModelChoice& choice) {
    return Json{{"delay_s", Estimate{choice.delay_s, choice.delay_standard_error}},
                {"applied", choice.delay_applied},
                {"source", choice.delay_source.empty() ? Json(nullptr) : Json(choice.delay_source)}};
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
    if (result.model_choice) {
        document["model_selection"] = model_selection_json(*result.model_choice, naming);
        document["timing"] = timing_json(*result.model_choice);
    }
    if (result.friction_only) {
        document["friction_only"] = {{"reason", result.friction_only->reason},
                                     {"samples_used", result.friction_only->samples_used},
                                     {"relative_error_pct", result.friction_only->relative_error_pct},
                                     {"residual_std", result.friction_only->residual_std},
                                     {"rejected_samples", result.friction_only->rejected_samples}};
    }
    if (!result.options.is_null()) document["options"] = result.options;
}

// ---- reading a document back: every value's type checked (JsonField), an error naming the key

namespace {

/// A member that may be absent: NaN then, as for null (non-finite numbers are written as null).
double number_or_nan(const JsonField& record, const char* key) {
    const auto member = record.find(key);
    return member ? member->number() : std::numeric_limits<double>::quiet_NaN();
}

/// {"value": v|null, "stderr": s|null}; "stderr", "systematic" and "uncertainty" may be absent. Every one present
/// must be a number or null; other keys are left for later versions.
Estimate read_estimate(const JsonField& entry) {
    entry.object();
    Estimate estimate;
    estimate.value = entry.at("value").optional_number();
    if (const auto error = entry.find("stderr")) estimate.standard_error = error->optional_number();
    if (const auto member = entry.find("systematic")) estimate.systematic = member->optional_number();
    if (const auto member = entry.find("uncertainty")) estimate.uncertainty = member->optional_number();
    return estimate;
}

TraceSummary read_trace_summary(const JsonField& j) {
    j.object();
    TraceSummary t;
    if (const auto v = j.find("path")) t.path = v->text();
    if (const auto v = j.find("format")) t.format = v->text();
    if (const auto v = j.find("samples")) t.samples = v->count();
    t.sample_time_s = number_or_nan(j, "sample_time_s");
    t.duration_s = number_or_nan(j, "duration_s");
    return t;
}

PreprocessReport read_preprocess(const JsonField& j) {
    PreprocessReport p;
    p.differentiation = j.at("differentiation").text();
    p.filter_order = j.at("filter_order").integer();
    p.cutoff_hz = number_or_nan(j, "cutoff_hz");
    p.decimation = j.at("decimation").integer();
    p.edge_samples = j.at("edge_samples").count();
    // documents before it existed
    p.velocity_source = j.has("velocity_source") ? j.at("velocity_source").text() : std::string("position");
    if (const auto v = j.find("savitzky_golay_window")) p.savitzky_golay_window = v->integer();
    if (const auto v = j.find("savitzky_golay_order")) p.savitzky_golay_order = v->integer();
    return p;
}

SelectionReport read_selection(const JsonField& j) {
    SelectionReport s;
    s.total = j.at("total").count();
    s.window = j.at("window").count();
    s.moving = j.at("moving").count();
    s.step1 = j.at("step1").count();
    s.step2 = j.at("step2").count();
    s.moving_threshold = number_or_nan(j, "moving_threshold");
    s.split_velocity = number_or_nan(j, "split_velocity");
    s.initial_split = j.has("initial_split_velocity") ? number_or_nan(j, "initial_split_velocity") : s.split_velocity;
    // documents before stick-slip and clip detection hold none of these
    const auto count = [&](const char* key) { return j.has(key) ? j.at(key).count() : std::size_t{0}; };
    s.passes = count("passes");
    s.stick_slip_passes = count("stick_slip_passes");
    s.stick_slip_samples = count("stick_slip_samples");
    s.clipped = count("clipped");
    s.near_rest = count("near_rest");
    s.notes = j.at("notes").texts();
    return s;
}

LogLinearStribeck read_log_linear(const JsonField& j) {
    LogLinearStribeck l;
    l.breakaway = j.at("breakaway").optional_number();
    l.stribeck_velocity = j.at("stribeck_velocity").optional_number();
    l.used = j.at("samples_used").count();
    l.wrong_sign = j.at("excluded_wrong_sign").count();
    l.below_noise = j.at("excluded_below_noise").count();
    return l;
}

NonlinearFitReport read_nonlinear(const JsonField& j) {
    NonlinearFitReport n;
    n.method = j.at("method").text();
    n.converged = j.at("converged").boolean();
    n.relative_error_pct = number_or_nan(j, "relative_error_pct");
    n.residual_std = number_or_nan(j, "residual_std");
    n.samples_used = j.at("samples_used").count();
    n.function_evaluations = j.at("function_evaluations").integer();
    return n;
}

/// "ok", "partial" or "failed" (or a status a later version of the enum adds): the text must read back as itself.
Status read_status(const JsonField& j) {
    const std::string text = j.text();
    const Status status = nlohmann::json(text).get<Status>();
    if (text != to_string(status))
        throw InputError(fmt::format("{}: must be \"ok\", \"partial\" or \"failed\", not \"{}\"", j.path(), text));
    return status;
}

/// The parameters of the document, in feedid's order, with the model they imply.
void read_parameters(const JsonField& j, IdentifyResult& r) {
    const JsonField parameters = j.at("parameters").object();
    bool asymmetric = j.has("model") && j.at("model").text() == "asymmetric";
    bool offset = false;
    bool rotary_keys = false;
    for (const auto& [key, entry] : parameters.members()) {
        const auto meaning = parse_parameter_key(key);
        if (!meaning) throw InputError(fmt::format("parameter \"{}\" is not one of feedid's model", key));
        asymmetric = asymmetric || (meaning->direction != Direction::both && meaning->term != Term::mass);
        offset = offset || meaning->term == Term::offset;
        rotary_keys = rotary_keys || meaning->rotary;
    }
    r.rotary = j.has("rotary") ? j.at("rotary").boolean() : rotary_keys;
    r.model = asymmetric ? FrictionModelKind::asymmetric : FrictionModelKind::symmetric;
    r.offset = offset;
    r.parameters = model_parameters(r.model, r.offset, r.rotary);
    for (const auto& [key, entry] : parameters.members()) {
        auto it = std::find_if(r.parameters.begin(), r.parameters.end(),
                               [&name = key](const Parameter& p) { return p.key == name; });
        if (it == r.parameters.end()) {
            throw InputError(fmt::format("parameter \"{}\" does not belong to a {} {} model", key, r.model_name(),
                                         r.rotary ? "rotary" : "linear"));
        }
        it->estimate = read_estimate(entry);
    }
    r.axis = axis_from_parameters(r.parameters, r.model, r.rotary);
}

Step1Report read_step1(const JsonField& fit, const JsonField& step1) {
    Step1Report s;
    s.relative_error_pct = number_or_nan(fit, "relative_error_pct");
    s.condition_number = number_or_nan(fit, "condition_number");
    s.samples_used = fit.at("samples_used").count();
    s.residual_std = number_or_nan(fit, "residual_std");
    s.r_diagonal = fit.at("r_diagonal").numbers();
    const auto white = step1.find("white_noise_stderr");
    for (const auto& [key, entry] : step1.at("batch").members()) {
        s.keys.push_back(key);
        s.batch.push_back(read_estimate(entry));
        if (white) s.white_noise_standard_error.push_back(number_or_nan(white->object(), key.c_str()));
    }
    if (const auto correlations = fit.find("correlations")) {
        correlations->object();
        s.correlation.assign(s.keys.size(), std::vector<double>(s.keys.size(), 1.0));
        for (std::size_t i = 0; i < s.keys.size(); ++i) {
            const JsonField row = correlations->at(s.keys[i]).object();
            for (std::size_t k = 0; k < s.keys.size(); ++k) {
                if (i != k) s.correlation[i][k] = number_or_nan(row, s.keys[k].c_str());
            }
        }
    }
    return s;
}

SystematicReport read_systematic(const JsonField& j) {
    SystematicReport report;
    for (const auto& v : j.object().at("variants").elements()) {
        SystematicVariant variant{v.at("preprocessing").text(), read_status(v.at("status")), {}, {}};
        for (const auto& [key, value] : v.at("parameters").object().members()) {
            variant.keys.push_back(key);
            variant.values.push_back(value.optional_number());
        }
        report.variants.push_back(std::move(variant));
    }
    return report;
}

RlsReport read_rls(const JsonField& j) {
    RlsReport r;
    const std::string variant = j.at("variant").text();
    if (variant != "exponential" && variant != "directional")
        throw InputError(fmt::format("{}.variant: \"{}\" is not exponential or directional", j.path(), variant));
    r.options.variant = variant == "exponential" ? RlsVariant::exponential : RlsVariant::directional;
    r.options.forgetting_factor = number_or_nan(j, "forgetting_factor");
    r.options.initial_covariance = number_or_nan(j, "initial_covariance");
    r.settled = j.at("settled").boolean();
    r.transient_end_s = number_or_nan(j, "transient_end_s");
    // the history store keeps results without the RLS history (it is bulky): then it reads back empty
    const auto history = j.find("history");
    if (history) {
        history->object();
        if (const auto time = history->find("time_s")) r.history_time = time->numbers();
    }
    const JsonField averaged = j.at("averaged").object();
    for (const auto& [key, value] : j.at("final").members()) {
        r.keys.push_back(key);
        r.final_estimate.push_back(value.number());
        r.averaged.push_back(number_or_nan(averaged, key.c_str()));
        const auto series = history ? history->find(key) : std::nullopt;
        r.history.push_back(series ? series->numbers() : std::vector<double>{});
    }
    return r;
}

StribeckReport read_stribeck(const JsonField& j) {
    StribeckReport s;
    for (std::size_t g = 0; g < 2; ++g) {
        if (const auto side = j.object().find(kDirections[g]))
            s.log_linear[g] = read_log_linear(side->at("log_linear"));
    }
    if (const auto nonlinear = j.find("nonlinear")) s.nonlinear = read_nonlinear(*nonlinear);
    return s;
}

FrictionCurveReport read_friction_curve(const JsonField& j, const ParameterNaming& naming) {
    FrictionCurveReport c;
    const std::array<std::optional<FrictionCurvePoints>*, 2> sides{&c.forward, &c.reverse};
    for (std::size_t g = 0; g < 2; ++g) {
        const auto side = j.object().find(kDirections[g]);
        if (!side) continue;
        *sides[g] = FrictionCurvePoints{side->at(naming.curve_velocity_key()).numbers(),
                                        side->at(naming.curve_force_key()).numbers(),
                                        side->at("fitted_" + naming.curve_force_key()).numbers()};
    }
    return c;
}

ModelCandidate read_candidate(const JsonField& j) {
    j.object();
    ModelCandidate c;
    c.name = j.at("name").text();
    c.tested = j.at("tested").text();
    c.estimate = j.at("estimate").optional_number();
    c.standard_error = j.at("stderr").optional_number();
    c.statistic = j.at("statistic").optional_number();
    c.threshold = number_or_nan(j, "threshold");
    c.taken = j.at("taken").boolean();
    c.verdict = j.at("verdict").text();
    return c;
}

/// model_selection and timing (documents before the model-adequacy stage hold neither).
std::optional<ModelChoice> read_model_choice(const JsonField& j, const IdentifyResult& r) {
    const auto selection = j.find("model_selection");
    if (!selection) return std::nullopt;
    selection->object();
    const ParameterNaming naming{r.rotary};
    ModelChoice choice;
    choice.model = r.model;
    choice.offset = r.offset;
    choice.automatic = selection->at("automatic").boolean();
    choice.one_way = selection->at("one_way").boolean();
    for (const auto& c : selection->at("candidates").elements()) choice.candidates.push_back(read_candidate(c));
    if (const auto aliased = selection->find("aliased")) choice.aliased_friction = aliased->text();
    if (selection->has("residual_autocorrelation_samples"))
        choice.residual_autocorrelation_samples = number_or_nan(*selection, "residual_autocorrelation_samples");
    if (const auto block = selection->find("correlation_block_samples")) choice.correlation_block_samples = block->count();
    if (const auto checks = selection->find("fit_checks")) {
        for (const auto& c : checks->elements()) {
            FitCheck check;
            check.name = c.at("grouping").text();
            check.groups = c.at("groups").count();
            if (!c.at("statistic").json().is_null()) check.statistic = number_or_nan(c, "statistic");
            check.threshold = number_or_nan(c, "threshold");
            check.largest = number_or_nan(c, ("largest_" + naming.curve_force_key()).c_str());
            check.largest_standard_error = number_or_nan(c, ("stderr_" + naming.curve_force_key()).c_str());
            check.where = c.at("where").text();
            check.relative = number_or_nan(c, "fraction");
            check.material_fraction = number_or_nan(c, "material_fraction");
            check.passed = c.at("passed").boolean();
            choice.fit_checks.push_back(std::move(check));
        }
    }
    if (const auto rest = selection->find("rest_level")) {
        rest->object();
        choice.rest = RestLevel{rest->at("samples").count(),
                                number_or_nan(*rest, ("mean_" + naming.curve_force_key()).c_str()),
                                number_or_nan(*rest, ("stderr_" + naming.curve_force_key()).c_str())};
    }
    if (const auto timing = j.find("timing")) {
        timing->object();
        const Estimate delay = read_estimate(timing->at("delay_s"));
        choice.delay_s = delay.value;
        choice.delay_standard_error = delay.standard_error;
        choice.delay_applied = timing->at("applied").boolean();
        const JsonField source = timing->at("source");
        choice.delay_source = source.json().is_null() ? std::string() : source.text();
    }
    return choice;
}

void read_records(const JsonField& j, IdentifyResult& r) {
    if (const auto v = j.find("preprocessing")) r.preprocessing = read_preprocess(v->object());
    if (const auto v = j.find("selection")) r.selection = read_selection(v->object());
    if (j.has("fit") && j.has("step1")) r.step1 = read_step1(j.at("fit").object(), j.at("step1").object());
    if (const auto v = j.find("rls")) r.rls = read_rls(v->object());
    if (const auto v = j.find("stribeck")) r.stribeck = read_stribeck(*v);
    if (const auto v = j.find("friction_only")) {
        v->object();
        r.friction_only =
            FrictionOnlyReport{v->at("reason").text(), v->at("samples_used").count(),
                               number_or_nan(*v, "relative_error_pct"), number_or_nan(*v, "residual_std"),
                               v->has("rejected_samples") ? v->at("rejected_samples").count() : 0};
    }
    if (const auto v = j.find("friction_curve")) r.friction_curve = read_friction_curve(*v, ParameterNaming{r.rotary});
    if (const auto v = j.find("systematic")) r.systematic = read_systematic(*v);
    r.model_choice = read_model_choice(j, r);
}

}  // namespace

void from_json(const Json& document, IdentifyResult& result) {
    if (!document.is_object() || !document.contains("parameters") || !document.at("parameters").is_object()) {
        throw InputError("not an identify result (no \"parameters\" object)");
    }
    const JsonField j(document, "");
    IdentifyResult r;
    read_parameters(j, r);
    if (const auto v = j.find("feedid_version")) r.feedid_version = v->text();
    if (const auto v = j.find("trace")) r.trace = read_trace_summary(*v);
    if (const auto v = j.find("diagnostics")) r.diagnostics = v->texts();
    if (const auto v = j.find("status")) {
        r.status = read_status(*v);
    } else {
        const bool any_null =
            std::any_of(r.parameters.begin(), r.parameters.end(), [](const Parameter& p) { return !p.estimate.value; });
        r.status = any_null ? Status::partial : Status::ok;
    }
    read_records(j, r);
    if (const auto v = j.find("options")) r.options = v->object().json();
    result = std::move(r);
}

nlohmann::json identify_options_document(const IdentifyOptions& o, const nlohmann::json& command_line) {
    const auto& p = o.preprocess;
    const char* differentiation = p.differentiation == Differentiation::central          ? "central"
                                  : p.differentiation == Differentiation::savitzky_golay ? "savitzky-golay"
                                                                                         : "butterworth";
    const auto& m = o.model_selection;
    Json document{{"model", o.model == FrictionModelKind::asymmetric ? "asymmetric" : "symmetric"},
                  {"offset", o.offset},
                  {"model_selection", m.automatic ? "automatic" : "forced"},
                  {"delay", m.known_delay_s                                           ? Json(*m.known_delay_s)
                            : m.delay == ModelSelectionOptions::Delay::none     ? Json("none")
                            : m.delay == ModelSelectionOptions::Delay::estimate ? Json("estimate")
                                                                                : Json("auto")},
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
