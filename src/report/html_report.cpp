// The plots of an identify result and of a history, and the self-contained HTML pages that hold them.

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <span>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/report/history_report.hpp"
#include "feedid/report/result_report.hpp"
#include "html_page.hpp"

#include "feedid/model/friction.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/numeric/signal.hpp"
#include "feedid/core/version.hpp"

namespace feedid::report {
namespace {

constexpr const char* blue = "#1f77b4";
constexpr const char* orange = "#ff7f0e";
constexpr const char* green = "#2ca02c";
constexpr const char* red = "#d62728";
constexpr const char* grey = "#555555";

// Plots of RLS histories hold at most this many points: enough for the shape of a transient, small enough for a
// browser to draw dozens of plots at once.
constexpr std::size_t max_plot_points = 800;

// Plots of a long history are thinned to the runs where a value is smallest or largest within each stretch of runs,
// as simulate thins its errors, so that no outlier is lost; and the run where an alarm fired is kept. A series keeps
// at most 400 points (a plot is 760 px wide), and all the history plots of a page together about 12,000, at least 100
// per series: a report of 10,000 runs on a dozen axes stays a few MB.
constexpr std::size_t max_history_points = 400;
constexpr std::size_t min_history_points = 100;
constexpr std::size_t page_history_points = 12000;

/// The points each series of `plots` history plots may keep.
std::size_t history_points_per_series(std::size_t plots) {
    return std::clamp(page_history_points / std::max<std::size_t>(plots, 1), min_history_points, max_history_points);
}

/// Keeps the points `keep` (ascending) of a series: x, y, band and tooltips alike.
void keep_points(Series& series, const std::vector<std::size_t>& keep) {
    const auto pick = [&](auto& column) {
        if (column.size() != series.x.size() || column.empty()) return;
        std::remove_reference_t<decltype(column)> kept;
        kept.reserve(keep.size());
        for (const auto i : keep) kept.push_back(std::move(column[i]));
        column = std::move(kept);
    };
    pick(series.y);
    pick(series.band);
    pick(series.tooltips);
    pick(series.x);  // last: the others are checked against its length
}

/// Thins a history plot's series to `points` each by min/max per bucket of their y; series of one style drawn over the
/// same runs (the CUSUM's S+ and S-, the two alarm limits) are thinned together. The run where the alarm fired (the
/// first highlighted) stays; later highlights go with their runs.
void thin_history_plot(Plot& plot, std::size_t points) {
    const auto first_alarm = std::min_element(plot.highlights.begin(), plot.highlights.end(),
                                              [](const Highlight& a, const Highlight& b) { return a.x < b.x; });
    const std::optional<double> fired =
        first_alarm == plot.highlights.end() ? std::nullopt : std::optional<double>(first_alarm->x);
    std::set<double> kept_x;
    std::vector<bool> done(plot.series.size(), false);
    for (std::size_t s = 0; s < plot.series.size(); ++s) {
        if (done[s]) continue;
        std::vector<Series*> together;
        std::vector<std::span<const double>> columns;
        for (std::size_t t = s; t < plot.series.size(); ++t)
            if (!done[t] && plot.series[t].style == plot.series[s].style && plot.series[t].x == plot.series[s].x) {
                done[t] = true;
                together.push_back(&plot.series[t]);
                columns.emplace_back(plot.series[t].y);
            }
        const auto& x = plot.series[s].x;
        if (x.size() > points) {
            auto keep = extreme_preserving_indices(columns, x.size(), points - 1);
            if (const auto at = fired ? std::find(x.begin(), x.end(), *fired) : x.end(); at != x.end()) {
                keep.push_back(static_cast<std::size_t>(at - x.begin()));
                std::sort(keep.begin(), keep.end());
                keep.erase(std::unique(keep.begin(), keep.end()), keep.end());
            }
            for (auto* series : together) keep_points(*series, keep);
        }
        kept_x.insert(plot.series[s].x.begin(), plot.series[s].x.end());
    }
    std::erase_if(plot.highlights, [&](const Highlight& h) { return !kept_x.count(h.x) && h.x != fired; });
}

/// Whether a plot of the history is one of the per-run plots that thinning applies to.
bool per_run_plot(const Plot& plot) {
    return plot.id.starts_with("trend-") || plot.id.starts_with("cusum-");
}

std::string slug(const std::string& text) {
    std::string out;
    for (const char c : text) {
        if (std::isalnum(static_cast<unsigned char>(c)))
            out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        else if (!out.empty() && out.back() != '-')
            out += '-';
    }
    while (!out.empty() && out.back() == '-') out.pop_back();
    return out.empty() ? "plot" : out;
}

std::vector<double> numbers(const nlohmann::json& array) {
    std::vector<double> out;
    if (!array.is_array()) return out;
    out.reserve(array.size());
    for (const auto& value : array) out.push_back(value.is_number() ? value.get<double>() : std::nan(""));
    return out;
}

std::optional<double> number_at(const nlohmann::json& object, const char* key) {
    if (object.is_object() && object.contains(key) && object[key].is_number()) return object[key].get<double>();
    return std::nullopt;
}

/// object[key], or null when the object has no such key (or is not an object).
const nlohmann::json& member(const nlohmann::json& object, const char* key) {
    static const nlohmann::json none;
    return object.is_object() && object.contains(key) ? object[key] : none;
}

/// A document's "status" ("ok", "partial", "failed"); "ok" for documents of feedid versions that wrote none.
std::string document_status(const nlohmann::json& document) {
    const auto& status = member(document, "status");
    return status.is_string() ? status.get<std::string>() : std::string("ok");
}

std::string with_unit(const ParameterLabel& label) {
    return fmt::format("{} [{}]", label.name, label.unit);
}

std::string format_estimate(const std::optional<double>& value, const std::optional<double>& error,
                            const std::string& unit) {
    if (!value) return "—";
    if (!error) return fmt::format("{:.5g} {}", *value, unit);
    return fmt::format("{:.5g} ± {:.2g} {}", *value, *error, unit);
}

/// The fitted friction law of one direction from a result document's parameters (a symmetric model's keys serve both
/// directions), eq. (3); none when B or F_C is null. F_B and v_s give the Stribeck term when both are numbers.
std::optional<FrictionBranch> fitted_branch(const nlohmann::json& result, Direction direction) {
    if (!result.contains("parameters") || !result["parameters"].is_object()) return std::nullopt;
    std::map<Term, double> values;
    for (const auto& [key, entry] : result["parameters"].items()) {
        const auto meaning = parse_parameter_key(key);
        if (!meaning || (meaning->direction != Direction::both && meaning->direction != direction)) continue;
        if (const auto value = number_at(entry, "value"); value && std::isfinite(*value))
            values[meaning->term] = *value;
    }
    if (!values.count(Term::viscous) || !values.count(Term::coulomb)) return std::nullopt;
    FrictionBranch branch{values[Term::viscous], values[Term::coulomb], std::nullopt, std::nullopt};
    if (values.count(Term::breakaway) && values.count(Term::stribeck_velocity) &&
        values[Term::stribeck_velocity] > 0.0) {
        branch.breakaway = values[Term::breakaway];
        branch.stribeck_velocity = values[Term::stribeck_velocity];
    }
    return branch;
}

/// A model's friction, or any other parameter, differs between directions.
bool directional_friction(const nlohmann::json& result) {
    if (!result.contains("parameters") || !result["parameters"].is_object()) return false;
    for (const auto& [key, entry] : result["parameters"].items())
        if (const auto meaning = parse_parameter_key(key); meaning && meaning->direction != Direction::both)
            return true;
    return false;
}

/// The fitted model evaluated at 240 speeds spread evenly (in log speed on a log axis) from `low` to `high`: the
/// curve between the bins is the model's, not a straight line between its values at the bins.
Series model_curve(const FrictionBranch& branch, double low, double high, bool log_speed) {
    constexpr int points = 240;
    Series curve;
    const FrictionLaw law = branch.law();
    for (int i = 0; i < points; ++i) {
        const double fraction = static_cast<double>(i) / (points - 1);
        const double speed = log_speed ? low * std::pow(high / low, fraction) : low + (high - low) * fraction;
        curve.x.push_back(speed);
        curve.y.push_back(law.magnitude(speed));
    }
    return curve;
}

/// The friction curve of a result document, if it holds one: the measured bins per direction and the fitted model
/// from the result's parameters, over the measured speeds.
std::optional<Plot> friction_curve_plot(const nlohmann::json& result, const std::string& id, const std::string& title) {
    if (!result.is_object() || !result.contains("friction_curve") || !result["friction_curve"].is_object())
        return std::nullopt;
    const auto& curve = result["friction_curve"];
    const ParameterNaming naming{result.value("rotary", false)};
    Plot plot;
    plot.id = id;
    plot.title = title;
    plot.x_label = naming.rotary ? "speed |ω| [rad/s]" : "speed |v| [m/s]";
    plot.y_label = naming.rotary ? "friction torque [N·m]" : "friction force [N]";
    double low = std::numeric_limits<double>::infinity();
    double high = 0.0;
    const std::array<std::pair<const char*, const char*>, 2> directions{{{"forward", blue}, {"reverse", orange}}};
    for (const auto& [direction, colour] : directions) {
        if (!curve.contains(direction) || !curve[direction].is_object()) continue;
        const auto& branch = curve[direction];
        Series measured;
        measured.name = fmt::format("{}: measured (binned)", direction);
        measured.x = numbers(branch.value(naming.curve_velocity_key(), nlohmann::json::array()));
        measured.y = numbers(branch.value(naming.curve_force_key(), nlohmann::json::array()));
        measured.style = Series::Style::points;
        measured.colour = colour;
        for (std::size_t i = 0; i < measured.x.size() && i < measured.y.size(); ++i)
            if (std::isfinite(measured.x[i]) && measured.x[i] > 0.0 && std::isfinite(measured.y[i])) {
                low = std::min(low, measured.x[i]);
                high = std::max(high, measured.x[i]);
            }
        if (!measured.x.empty()) plot.series.push_back(std::move(measured));
    }
    if (plot.series.empty()) return std::nullopt;
    // The Stribeck region lives at low speed: a logarithmic speed axis when the data span more than a decade and a
    // half.
    plot.log_x = high > 0.0 && high / low > 30.0;
    if (!(high > low)) return plot;
    if (!directional_friction(result)) {
        if (const auto branch = fitted_branch(result, Direction::both)) {
            Series model = model_curve(*branch, low, high, plot.log_x);
            model.name = "fitted model (both directions)";
            model.colour = grey;
            plot.series.push_back(std::move(model));
        }
        return plot;
    }
    for (const auto& [direction, colour] : directions) {
        const auto branch =
            fitted_branch(result, direction == std::string("forward") ? Direction::forward : Direction::reverse);
        if (!branch) continue;
        Series model = model_curve(*branch, low, high, plot.log_x);
        model.name = fmt::format("{}: fitted model", direction);
        model.colour = colour;
        plot.series.push_back(std::move(model));
    }
    return plot;
}

/// The errors over time of a simulate document, checked; NaN where a document that did not succeed holds null.
struct SimulationSeries {
    bool rotary{false};
    std::string status;
    std::vector<double> time;
    std::vector<double> machine;
    std::vector<double> model;
    std::vector<double> modelling;
};

/// The suffix of a simulate document's summary keys: "_rad" on a rotary axis; "_m" on a linear one and in rotary
/// documents of feedid versions that wrote metre keys for both.
std::string summary_length_suffix(const nlohmann::json& simulation, bool rotary) {
    const std::string suffix = ParameterNaming{rotary}.length_key_suffix();
    return simulation.contains("tracking_error_mae" + suffix) ? suffix : std::string("_m");
}

/// The series have one value per time, and the times increase.
void check_simulation_times(const SimulationSeries& out, const std::string& unit, const std::string& source) {
    const std::array<std::pair<const char*, const std::vector<double>*>, 3> errors{
        {{"tracking_error_machine", &out.machine},
         {"tracking_error_model", &out.model},
         {"modelling_error", &out.modelling}}};
    for (const auto& [key, values] : errors)
        if (values->size() != out.time.size())
            throw InputError(fmt::format("{}: series.{}{} has {} values for {} times (series.time_s)", source, key,
                                         unit, values->size(), out.time.size()));
    for (std::size_t i = 0; i < out.time.size(); ++i) {
        if (!std::isfinite(out.time[i]))
            throw InputError(fmt::format("{}: series.time_s[{}] is not a number", source, i));
        if (i > 0 && !(out.time[i] > out.time[i - 1]))
            throw InputError(fmt::format("{}: series.time_s[{}] does not increase", source, i));
    }
}

/// A figure of a simulate document: a number, or null in a document whose status says it did not succeed (simulate
/// writes null, with a diagnostic, where a diverged simulation has no finite value).
bool figure_readable(const nlohmann::json& value, bool nulls_allowed) {
    return value.is_number() || (nulls_allowed && value.is_null());
}

SimulationSeries read_simulation_series(const nlohmann::json& simulation, const std::string& source) {
    const auto wrong_kind = [&](const std::string& why) {
        return InputError(fmt::format("{}: not a simulate document (feedid simulate --json): {}", source, why));
    };
    if (!simulation.is_object()) throw wrong_kind("not a JSON object");
    SimulationSeries out;
    if (simulation.contains("rotary")) {
        if (!simulation["rotary"].is_boolean())
            throw InputError(fmt::format("{}: 'rotary' is not true or false", source));
        out.rotary = simulation["rotary"].get<bool>();
    }
    out.status = document_status(simulation);
    const bool nulls_allowed = out.status != "ok";
    const std::string length = summary_length_suffix(simulation, out.rotary);
    const std::string mae = "tracking_error_mae" + length;
    if (!simulation.contains(mae) || !simulation[mae].is_object()) throw wrong_kind(fmt::format("it has no '{}'", mae));
    for (const char* key : {"model", "machine"})
        if (!figure_readable(member(simulation[mae], key), nulls_allowed))
            throw wrong_kind(fmt::format("'{}.{}' is not a number", mae, key));
    if (!figure_readable(member(simulation, ("modelling_error_mae" + length).c_str()), nulls_allowed))
        throw wrong_kind(fmt::format("'modelling_error_mae{}' is not a number", length));
    if (!simulation.contains("series") || !simulation["series"].is_object())
        throw InputError(
            fmt::format("{}: the simulate document has no 'series' of errors over time (written by an "
                        "older feedid; run feedid simulate --json again)",
                        source));
    const auto& series = simulation["series"];
    const auto column = [&](const std::string& key) {
        if (!series.contains(key) || !series[key].is_array())
            throw InputError(fmt::format("{}: series.{} is missing or not an array", source, key));
        std::vector<double> values;
        values.reserve(series[key].size());
        for (const auto& value : series[key]) {
            if (nulls_allowed && value.is_null()) {
                values.push_back(std::numeric_limits<double>::quiet_NaN());
                continue;
            }
            if (!value.is_number() || !std::isfinite(value.get<double>()))
                throw InputError(fmt::format("{}: series.{}[{}] is not a finite number", source, key, values.size()));
            values.push_back(value.get<double>());
        }
        return values;
    };
    const std::string unit = ParameterNaming{out.rotary}.length_key_suffix();
    out.time = column("time_s");
    out.machine = column("tracking_error_machine" + unit);
    out.model = column("tracking_error_model" + unit);
    out.modelling = column("modelling_error" + unit);
    check_simulation_times(out, unit, source);
    return out;
}

/// Lengths are shown in mm (mrad on a rotary axis): tracking errors of feed drives are fractions of a millimetre.
constexpr double display_scale = 1e3;
const char* display_unit(bool rotary) {
    return rotary ? "mrad" : "mm";
}

std::vector<double> scaled(const std::vector<double>& values) {
    std::vector<double> out(values.size());
    for (std::size_t i = 0; i < values.size(); ++i) out[i] = values[i] * display_scale;
    return out;
}

}  // namespace

namespace {

/// Where the simulated tracking error leaves the machine's scale for good: the first sample whose model error is not a
/// number or more than ten times the machine's largest; none when the simulation kept to it.
std::optional<std::size_t> divergence(const SimulationSeries& series) {
    double largest = 0.0;
    for (const double e : series.machine)
        if (std::isfinite(e)) largest = std::max(largest, std::abs(e));
    for (std::size_t i = 0; i < series.model.size(); ++i)
        if (!std::isfinite(series.model[i]) || (largest > 0.0 && std::abs(series.model[i]) > 10.0 * largest)) return i;
    return std::nullopt;
}

}  // namespace

std::vector<Plot> simulation_plots(const nlohmann::json& simulation, const std::string& source) {
    const auto series = read_simulation_series(simulation, source);
    const char* unit = display_unit(series.rotary);
    const std::string x = series.rotary ? "φ" : "x";
    Plot tracking;
    tracking.id = "fig6-tracking-error";
    tracking.title = "Tracking error of machine and model over time";
    tracking.x_label = "time [s]";
    tracking.y_label = fmt::format("tracking error {0}_ref − {0} [{1}]", x, unit);
    Series machine;
    machine.name = fmt::format("machine: {0}_ref − {0} (measured)", x);
    machine.x = series.time;
    machine.y = scaled(series.machine);
    machine.colour = blue;
    Series model;
    model.name = fmt::format("model: {0}_ref − {0}_sim (simulated)", x);
    model.x = series.time;
    model.y = scaled(series.model);
    model.colour = orange;
    model.dashed = true;

    Plot modelling;
    modelling.id = "fig6-modelling-error";
    modelling.title = "Modelling error over time";
    modelling.x_label = "time [s]";
    modelling.y_label = fmt::format("modelling error e_m = {0} − {0}_sim [{1}]", x, unit);
    Series error;
    error.name = fmt::format("e_m = {0}_machine − {0}_model", x);
    error.x = series.time;
    error.y = scaled(series.modelling);
    error.colour = green;
    modelling.horizontal.push_back({"", 0.0, grey, false});

    // Both on the record's time axis, also where a diverged simulation left no value.
    if (series.time.size() >= 2)
        tracking.x_limits = modelling.x_limits = std::pair{series.time.front(), series.time.back()};
    // A diverged model is drawn on the machine's scale: the axes are set by the measured error and by the
    // modelling error before the divergence, what lies beyond is clipped and marked.
    if (const auto diverged = divergence(series)) {
        model.sets_y_range = false;
        tracking.off_scale_label = modelling.off_scale_label = "diverged model beyond the axis";
        if (*diverged > 0) modelling.y_range_to_x = series.time[*diverged - 1];
        for (Plot* plot : {&tracking, &modelling})
            plot->vertical.push_back({"model diverges", series.time[*diverged], red});
    }
    tracking.series.push_back(std::move(machine));
    tracking.series.push_back(std::move(model));
    modelling.series.push_back(std::move(error));
    return {std::move(tracking), std::move(modelling)};
}

namespace {

// A figure of a fingerprint run (history::fingerprint_parameter_keys) in µm and N/µm (rotary: mdeg, N·m/mdeg).
std::optional<ParameterLabel> fingerprint_label(const std::string& key) {
    static const std::pair<const char*, const char*> names[] = {{"lost_motion", "Lost motion"},
                                                                {"backlash", "Backlash"},
                                                                {"stiffness", "Stiffness k"},
                                                                {"reversal_error", "Reversal error"}};
    constexpr double degree = 3.14159265358979323846 / 180.0;
    for (const auto& [stem, name] : names) {
        if (!key.starts_with(stem)) continue;
        std::string rest = key.substr(std::string_view(stem).size());
        std::string suffix;
        for (const auto& [side, shown] : {std::pair{"_forward", "+ (forward)"}, std::pair{"_reverse", "− (reverse)"}})
            if (rest.starts_with(side)) {
                suffix = shown;
                rest.erase(0, std::string_view(side).size());
            }
        if (rest == "_m") return ParameterLabel{name + suffix, "µm", 1e6};
        if (rest == "_rad") return ParameterLabel{name + suffix, "mdeg", 1e3 / degree};
        if (rest == "_N_per_m") return ParameterLabel{name + suffix, "N/µm", 1e-6};
        if (rest == "_Nm_per_rad") return ParameterLabel{name + suffix, "N·m/mdeg", degree / 1e3};
    }
    return std::nullopt;
}

}  // namespace

ParameterLabel parameter_label(const std::string& key) {
    if (auto fingerprint = fingerprint_label(key)) return *fingerprint;
    const auto parsed = parse_parameter_key(key);
    if (!parsed) return {key, "1"};
    const ParameterNaming naming{parsed->rotary};
    // the unit as written in the document ("N*m*s/rad", "kg*m^2"), typeset
    std::string unit;
    for (const char c : naming.unit(parsed->term)) unit += c == '*' ? std::string("·") : std::string(1, c);
    if (const auto square = unit.find("^2"); square != std::string::npos) unit.replace(square, 2, "²");
    static const std::map<Term, std::pair<const char*, const char*>> names{
        {Term::mass, {"Mass", "M"}},
        {Term::viscous, {"Viscous friction", "B"}},
        {Term::coulomb, {"Coulomb friction", "F_C"}},
        {Term::breakaway, {"Breakaway friction", "F_B"}},
        {Term::stribeck_velocity, {"Stribeck velocity", "v_s"}},
        {Term::offset, {"Offset", "F_0"}},
    };
    const auto& [word, symbol] = names.at(parsed->term);
    std::string name =
        parsed->rotary && parsed->term == Term::mass ? std::string("Inertia J") : fmt::format("{} {}", word, symbol);
    if (parsed->direction == Direction::forward) name += "+ (forward)";
    if (parsed->direction == Direction::reverse) name += "− (reverse)";
    return {name, unit};
}

namespace {

/// An estimate's value and the half-width of its ±2 band: the combined uncertainty when the document gives one
/// (statistical and preprocessing), else the standard error.
struct BandedValue {
    double value;
    std::optional<double> error;
    bool combined;
};

std::optional<BandedValue> banded_value(const nlohmann::json& estimate) {
    const auto value = number_at(estimate, "value");
    if (!value) return std::nullopt;
    if (const auto uncertainty = number_at(estimate, "uncertainty"); uncertainty && *uncertainty > 0.0)
        return BandedValue{*value, uncertainty, true};
    if (const auto error = number_at(estimate, "stderr"); error && *error > 0.0)
        return BandedValue{*value, error, false};
    return BandedValue{*value, std::nullopt, false};
}

/// One parameter's RLS estimate over time. The y axis is set by the settled part (after the transient; without the
/// first tenth of the record when the RLS did not settle) and the batch value with its band: the start-up transient,
/// often orders of magnitude larger, is clipped and marked where it leaves the plot.
Plot rls_plot(const nlohmann::json& result, const std::string& key, const std::vector<double>& time,
              const std::vector<double>& values) {
    const auto& rls = member(result, "rls");
    const auto label = parameter_label(key);
    Plot plot;
    plot.id = "rls-" + slug(key);
    plot.title = fmt::format("RLS estimate of {} over time", label.name);
    plot.x_label = "time [s]";
    plot.y_label = with_unit(label);
    plot.off_scale_label = "start-up transient beyond the axis";
    Series series;
    series.name = "RLS estimate";
    const std::size_t stride = std::max<std::size_t>(1, (time.size() + max_plot_points - 1) / max_plot_points);
    for (std::size_t i = 0; i < time.size() && i < values.size(); i += stride) {
        series.x.push_back(time[i]);
        series.y.push_back(values[i]);
    }
    plot.series.push_back(std::move(series));
    const auto transient_end = number_at(rls, "transient_end_s");
    const bool settled = member(rls, "settled").is_boolean() && member(rls, "settled").get<bool>();
    if (settled && transient_end) {
        plot.y_range_from_x = *transient_end;
    } else if (!time.empty() && std::isfinite(time.front()) && std::isfinite(time.back())) {
        plot.y_range_from_x = time.front() + 0.1 * (time.back() - time.front());
    }
    // The batch fit of the same samples (step 1), and the identified value when step 2 changed it.
    const auto batch = banded_value(member(member(member(result, "step1"), "batch"), key.c_str()));
    const auto identified = banded_value(member(member(result, "parameters"), key.c_str()));
    if (const auto& shown = batch ? batch : identified) {
        plot.horizontal.push_back({"batch least-squares value", shown->value, green, true});
        if (shown->error) {
            const std::string band = shown->combined ? "± 2 uncertainties" : "± 2 standard errors";
            plot.horizontal.push_back({band, shown->value + 2.0 * *shown->error, "#98df8a", true});
            plot.horizontal.push_back({"", shown->value - 2.0 * *shown->error, "#98df8a", true});
        }
    }
    if (batch && identified && std::abs(identified->value - batch->value) > 1e-9 * std::abs(batch->value))
        plot.horizontal.push_back({"identified value (after the friction-curve fit)", identified->value, grey, false});
    if (settled && transient_end) plot.vertical.push_back({"transient ends", *transient_end, red});
    return plot;
}

}  // namespace

std::vector<Plot> result_plots(const nlohmann::json& result, const std::string& source) {
    (void)history::run_from_result(result, source);  // InputError when it is not an identify result
    std::vector<Plot> plots;
    const auto& recorded = member(member(result, "rls"), "history");
    if (recorded.is_object()) {
        const auto time = numbers(recorded.value("time_s", nlohmann::json::array()));
        for (const auto& [key, values] : recorded.items())
            if (key != "time_s") plots.push_back(rls_plot(result, key, time, numbers(values)));
    }
    if (auto curve = friction_curve_plot(result, "friction-curve", "Friction against speed, measured and fitted"))
        plots.push_back(std::move(*curve));
    return plots;
}

namespace {

// One axis's runs as its history plots place them.
struct AxisRuns {
    std::vector<const history::RunRecord*> runs;  // in recording order
    std::map<std::int64_t, double> ordinal;       // run id -> x: its position in that order (from 1)
    std::string where;                            // "machine 'M' axis 'A'", for titles
    std::string prefix;                           // of the plots' element ids
    std::optional<double> baseline_end;           // x between the last baseline run and the next
};

// A run of the trend's series: its machine and axis, and its kind (a fingerprint run or an identification).
bool in_series(const history::RunRecord& run, const history::SeriesTrend& trend) {
    return run.machine == trend.machine && run.axis == trend.axis &&
           history::is_fingerprint_run(run) == (trend.kind == "fingerprint");
}

AxisRuns axis_runs(const std::vector<history::RunRecord>& runs, const history::SeriesTrend& trend) {
    AxisRuns axis;
    for (const auto& run : runs)
        if (in_series(run, trend)) axis.runs.push_back(&run);
    std::stable_sort(axis.runs.begin(), axis.runs.end(), [](const auto* a, const auto* b) {
        return a->recorded_at != b->recorded_at ? a->recorded_at < b->recorded_at : a->id < b->id;
    });
    for (std::size_t i = 0; i < axis.runs.size(); ++i) axis.ordinal[axis.runs[i]->id] = static_cast<double>(i + 1);
    const bool fingerprint = trend.kind == "fingerprint";
    axis.where = fmt::format("machine '{}' axis '{}'{}", trend.machine, trend.axis, fingerprint ? " (fingerprint)" : "");
    axis.prefix = slug(trend.machine + "-" + trend.axis) + (fingerprint ? "-fingerprint" : "");
    if (!trend.baseline_run_ids.empty() && axis.ordinal.count(trend.baseline_run_ids.back()))
        axis.baseline_end = axis.ordinal.at(trend.baseline_run_ids.back()) + 0.5;
    return axis;
}

// A parameter's value per run with its band of ± 2 standard errors, the baseline mean, and the one-run alarm limits.
Plot trend_plot(const history::ParameterTrend& parameter, const AxisRuns& axis, const history::TrendOptions& options) {
    const auto label = parameter_label(parameter.key);
    Plot values;
    values.id = fmt::format("trend-{}-{}", axis.prefix, slug(parameter.key));
    values.title = fmt::format("{} — {}", label.name, axis.where);
    values.x_label = "run (recording order)";
    values.y_label = with_unit(label);
    values.integer_x = true;
    // every parameter of the axis on the same run axis, also where a run left this one null
    values.x_limits = std::pair{1.0, static_cast<double>(std::max<std::size_t>(1, axis.runs.size()))};
    Series series;
    series.name = "value ± 2 standard errors";
    series.style = Series::Style::line_and_points;
    Series upper;
    upper.name = fmt::format("one-run alarm limit: baseline ± (h + k) σ = ± {:g} σ", options.cusum_h + options.cusum_k);
    upper.style = Series::Style::step;
    upper.colour = red;
    upper.dashed = true;
    Series lower = upper;
    lower.name.clear();
    for (const auto& point : parameter.points) {
        if (!point.value || !axis.ordinal.count(point.run_id)) continue;
        const double x = axis.ordinal.at(point.run_id);
        const double scale = label.scale;
        const auto scaled_error =
            point.standard_error ? std::optional<double>(*point.standard_error * std::abs(scale)) : std::nullopt;
        series.x.push_back(x);
        series.y.push_back(*point.value * scale);
        series.band.push_back(scaled_error ? 2.0 * *scaled_error : 0.0);
        series.tooltips.push_back(fmt::format("run #{} recorded {}: {}", point.run_id, point.recorded_at,
                                              format_estimate(*point.value * scale, scaled_error, label.unit)));
        if (point.role != history::RunRole::before_baseline && point.sigma && parameter.baseline_mean) {
            const double limit = (options.cusum_h + options.cusum_k) * *point.sigma;
            upper.x.push_back(x);
            upper.y.push_back((*parameter.baseline_mean + limit) * scale);
            lower.x.push_back(x);
            lower.y.push_back((*parameter.baseline_mean - limit) * scale);
        }
        if (point.alarm)
            values.highlights.push_back(
                {x, *point.value * scale, fmt::format("drift alarm at run #{} ({})", point.run_id, point.recorded_at)});
    }
    values.series.push_back(std::move(series));
    if (!upper.x.empty()) {
        values.series.push_back(std::move(upper));
        values.series.push_back(std::move(lower));
    }
    if (parameter.baseline_mean)
        values.horizontal.push_back({"baseline mean", *parameter.baseline_mean * label.scale, green, false});
    if (axis.baseline_end) values.vertical.push_back({"baseline ends", *axis.baseline_end, grey});
    return values;
}

// The two-sided CUSUM over the checked runs with the decision interval; none when no checked run has a change.
std::optional<Plot> cusum_plot(const history::ParameterTrend& parameter, const AxisRuns& axis,
                               const history::TrendOptions& options) {
    const auto label = parameter_label(parameter.key);
    Plot cusum;
    cusum.id = fmt::format("cusum-{}-{}", axis.prefix, slug(parameter.key));
    cusum.title = fmt::format("CUSUM of {} — {}", label.name, axis.where);
    cusum.x_label = "run (recording order)";
    cusum.y_label = "CUSUM [combined standard errors]";
    cusum.integer_x = true;
    Series up;
    up.name = "S+ (rise)";
    up.style = Series::Style::line_and_points;
    up.colour = red;
    Series down;
    down.name = "S− (fall)";
    down.style = Series::Style::line_and_points;
    down.colour = blue;
    for (const auto& point : parameter.points) {
        if (point.role != history::RunRole::checked || !point.z || !axis.ordinal.count(point.run_id)) continue;
        const double x = axis.ordinal.at(point.run_id);
        up.x.push_back(x);
        up.y.push_back(point.cusum_up);
        down.x.push_back(x);
        down.y.push_back(point.cusum_down);
        if (point.alarm)
            cusum.highlights.push_back(
                {x, std::max(point.cusum_up, point.cusum_down), fmt::format("drift alarm at run #{}", point.run_id)});
    }
    if (up.x.empty()) return std::nullopt;
    cusum.series.push_back(std::move(up));
    cusum.series.push_back(std::move(down));
    cusum.horizontal.push_back(
        {fmt::format("decision interval h = {:g}", options.cusum_h), options.cusum_h, red, true});
    return cusum;
}

// The friction curve of the latest run whose stored result holds one.
std::optional<Plot> latest_friction_plot(const AxisRuns& axis) {
    for (auto run = axis.runs.rbegin(); run != axis.runs.rend(); ++run) {
        auto curve = friction_curve_plot((*run)->result, fmt::format("friction-{}", axis.prefix),
                                         fmt::format("Friction against speed — {}, latest run #{} ({})", axis.where,
                                                     (*run)->id, (*run)->recorded_at));
        if (curve) return curve;
    }
    return std::nullopt;
}

}  // namespace

namespace {

std::vector<Plot> unthinned_history_plots(const std::vector<history::RunRecord>& runs,
                                          const std::vector<history::SeriesTrend>& trends,
                                          const history::TrendOptions& options) {
    std::vector<Plot> plots;
    for (const auto& trend : trends) {
        const AxisRuns axis = axis_runs(runs, trend);
        for (const auto& parameter : trend.parameters) {
            plots.push_back(trend_plot(parameter, axis, options));
            if (!parameter.note.empty() || !trend.baseline_complete) continue;
            if (auto cusum = cusum_plot(parameter, axis, options)) plots.push_back(std::move(*cusum));
        }
        if (auto curve = latest_friction_plot(axis)) plots.push_back(std::move(*curve));
    }
    return plots;
}

/// Thins the per-run plots among `plots` to the points a page of `page_plots` such plots allows each series.
void thin_history_plots(std::vector<Plot>& plots, std::size_t page_plots) {
    const std::size_t points = history_points_per_series(page_plots);
    for (auto& plot : plots)
        if (per_run_plot(plot)) thin_history_plot(plot, points);
}

}  // namespace

std::vector<Plot> history_plots(const std::vector<history::RunRecord>& runs,
                                const std::vector<history::SeriesTrend>& trends, const history::TrendOptions& options) {
    auto plots = unthinned_history_plots(runs, trends, options);
    thin_history_plots(plots, static_cast<std::size_t>(std::count_if(plots.begin(), plots.end(), per_run_plot)));
    return plots;
}

namespace {

constexpr const char* page_style = R"(
body { font-family: sans-serif; margin: 2em auto; max-width: 1000px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.25em; margin-top: 2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f3f3f3; } td.text, th.text { text-align: left; }
figure { margin: 1.5em 0; } figcaption { font-size: 0.85em; color: #555; }
.alarm { color: #b00; font-weight: bold; } .note { color: #555; }
.warning { border-left: 6px solid #b00; background: #fdecea; color: #5f0000; padding: 0.6em 1em; margin: 1em 0; }
.warning ul { margin: 0.3em 0; }
)";

std::string page(const std::string& title, const std::string& body) {
    return fmt::format(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n"
        "<style>{}</style>\n</head>\n<body>\n<h1>{}</h1>\n{}<p class=\"note\">Written by feedid {}.</p>\n"
        "</body>\n</html>\n",
        escape_xml(title), page_style, escape_xml(title), body, feedid::version);
}

std::string figure(const Plot& plot, const std::string& caption) {
    return fmt::format("<figure>\n{}<figcaption>{}</figcaption>\n</figure>\n", render_svg(plot), escape_xml(caption));
}

}  // namespace

std::string html_page(const std::string& title, const std::string& body) { return page(title, body); }
std::string html_figure(const Plot& plot, const std::string& caption) { return figure(plot, caption); }

namespace {

/// A warning box: a heading line and the document's diagnostics under it.
std::string warning(const std::string& heading, const nlohmann::json& diagnostics) {
    std::string box = fmt::format("<div class=\"warning\" role=\"alert\"><b>{}</b>", escape_xml(heading));
    if (diagnostics.is_array() && !diagnostics.empty()) {
        box += "<ul>";
        for (const auto& line : diagnostics)
            if (line.is_string()) box += fmt::format("<li>{}</li>", escape_xml(line.get<std::string>()));
        box += "</ul>";
    }
    return box + "</div>\n";
}

/// The warning a simulate document needs: none when it succeeded.
std::string simulation_warning(const SimulationDocument& simulation) {
    const std::string status = document_status(simulation.document);
    if (status == "ok") return "";
    return warning(fmt::format("The simulation {} has status \"{}\": its figures and plots are not a validation of "
                               "the identified axis.",
                               simulation.source, status),
                   member(simulation.document, "diagnostics"));
}

/// The warning a result document needs: none when its status is ok. A partial result names what it could not
/// identify.
std::string result_warning(const nlohmann::json& result) {
    const std::string status = document_status(result);
    if (status == "ok") return "";
    if (status == "failed")
        return warning(
            "The identification failed: no value on this page is an identified parameter (the diagnostics below "
            "say why).",
            nlohmann::json());
    std::string missing;
    for (const auto& [key, entry] : member(result, "parameters").items())
        if (!number_at(entry, "value")) missing += (missing.empty() ? "" : ", ") + parameter_label(key).name;
    const std::string what = missing.empty() ? std::string("some parameters") : missing;
    return warning(fmt::format("Partial result (status \"{}\"): {} could not be identified from this trace (the "
                               "diagnostics below say why).",
                               status, what),
                   nlohmann::json());
}

std::string cell(const std::optional<double>& value, double scale) {
    return value ? fmt::format("{:.4g}", *value * scale) : std::string("—");
}

/// The validation by simulation: its figures in two small tables and the Fig. 6 plots.
std::string validation_section(const SimulationDocument& simulation, const std::string& result_trace,
                               const std::vector<Plot>& plots) {
    const auto& document = simulation.document;
    const bool rotary = document.value("rotary", false);
    const std::string unit = display_unit(rotary);
    const auto object = [&](const char* key) {
        return document.contains(key) && document[key].is_object() ? document[key] : nlohmann::json::object();
    };
    std::string body =
        "<h2 id=\"validation\">Validation: the identified axis simulated on the recorded reference</h2>\n";
    body += simulation_warning(simulation);
    std::string simulated_trace;
    std::string samples;
    if (const auto trace = object("trace"); trace.contains("path") && trace["path"].is_string()) {
        simulated_trace = trace["path"].get<std::string>();
        if (const auto n = number_at(trace, "samples")) samples = fmt::format(", {:.0f} samples", *n);
    }
    const std::string of_trace =
        simulated_trace.empty() ? "" : fmt::format(" of trace <code>{}</code>", escape_xml(simulated_trace));
    body += fmt::format("<p>Simulation <code>{}</code>{}{}.</p>\n", escape_xml(simulation.source), of_trace, samples);
    if (!simulated_trace.empty() &&
        std::filesystem::path(simulated_trace).filename() != std::filesystem::path(result_trace).filename())
        body += fmt::format(
            "<p class=\"alarm\">The simulation ran on <code>{}</code>, the result was identified from "
            "<code>{}</code>.</p>\n",
            escape_xml(simulated_trace), escape_xml(result_trace));
    const std::string length = summary_length_suffix(document, rotary);
    const auto mae = object(("tracking_error_mae" + length).c_str());
    const auto largest = object(("tracking_error_max" + length).c_str());
    body += fmt::format(
        "<table>\n<tr><th class=\"text\">error</th><th>model</th><th>machine</th>"
        "<th class=\"text\">unit</th></tr>\n"
        "<tr><td class=\"text\">mean absolute tracking error</td><td>{}</td><td>{}</td>"
        "<td class=\"text\">{}</td></tr>\n"
        "<tr><td class=\"text\">largest tracking error</td><td>{}</td><td>{}</td>"
        "<td class=\"text\">{}</td></tr>\n"
        "<tr><td class=\"text\">mean absolute modelling error e_m</td><td colspan=\"2\">{}</td>"
        "<td class=\"text\">{}</td></tr>\n"
        "<tr><td class=\"text\">largest modelling error e_m</td><td colspan=\"2\">{}</td>"
        "<td class=\"text\">{}</td></tr>\n</table>\n",
        cell(number_at(mae, "model"), display_scale), cell(number_at(mae, "machine"), display_scale), unit,
        cell(number_at(largest, "model"), display_scale), cell(number_at(largest, "machine"), display_scale), unit,
        cell(number_at(document, ("modelling_error_mae" + length).c_str()), display_scale), unit,
        cell(number_at(document, ("modelling_error_max" + length).c_str()), display_scale), unit);
    const auto relative = object("relative_error_pct");
    body +=
        "<table>\n<tr><th class=\"text\">relative error 100·‖y − y_sim‖/‖y‖</th><th>position</th>"
        "<th>velocity</th><th>acceleration</th><th>force</th></tr>\n<tr><td class=\"text\">%</td>";
    for (const char* key : {"position", "velocity", "acceleration", "force"})
        body += fmt::format("<td>{}</td>", cell(number_at(relative, key), 1.0));
    body += "</tr>\n</table>\n";
    std::string thinned;
    if (const auto series = object("series"); number_at(series, "samples") && series.contains("time_s"))
        thinned = fmt::format(
            " The plots show {} of the {:.0f} samples: in each stretch of time the samples where an "
            "error is smallest or largest, so no peak is lost.",
            series["time_s"].size(), *number_at(series, "samples"));
    body += figure(plots.at(0),
                   "The tracking error of the machine (measured) and of the model (simulated in closed "
                   "loop with the identified gains) on the same reference." +
                       thinned);
    body += figure(plots.at(1), "The modelling error: measured minus simulated position." + thinned);
    return body;
}

}  // namespace

namespace {

/// The parameter table: value and standard error, and the systematic part and combined uncertainty where the
/// document gives them.
std::string parameter_table(const nlohmann::json& result) {
    const auto& parameters = member(result, "parameters");
    bool combined = false;
    for (const auto& [key, entry] : parameters.items())
        combined = combined || entry.contains("uncertainty") || entry.contains("systematic");
    std::string table = "<table>\n<tr><th class=\"text\">parameter</th><th>value</th><th>standard error</th>";
    if (combined) table += "<th>systematic</th><th>uncertainty</th>";
    table += "<th class=\"text\">unit</th></tr>\n";
    const auto shown = [](const std::optional<double>& v, const char* format) {
        return v ? fmt::format(fmt::runtime(format), *v) : std::string("—");
    };
    for (const auto& [key, entry] : parameters.items()) {
        const auto label = parameter_label(key);
        table += fmt::format("<tr><td class=\"text\">{}</td><td>{}</td><td>{}</td>", escape_xml(label.name),
                             shown(number_at(entry, "value"), "{:.6g}"), shown(number_at(entry, "stderr"), "{:.3g}"));
        if (combined)
            table += fmt::format("<td>{}</td><td>{}</td>", shown(number_at(entry, "systematic"), "{:.3g}"),
                                 shown(number_at(entry, "uncertainty"), "{:.3g}"));
        table += fmt::format("<td class=\"text\">{}</td></tr>\n", escape_xml(label.unit));
    }
    return table + "</table>\n";
}

// A production scan's windows: how many the trace gave, how many were pooled, why the others were not, and the
// information each parameter got from them ("" for an identify result).
std::string scan_windows_section(const nlohmann::json& result) {
    const auto& windows = member(result, "windows");
    if (member(result, "kind") != "scan" || !windows.is_object()) return {};
    static constexpr std::array<std::pair<const char*, const char*>, 9> reasons{{
        {"at_rest", "the axis stood still"},
        {"low_excitation", "too little excitation (one speed, hardly any acceleration)"},
        {"ill_conditioned", "mass and friction not separable within the window"},
        {"process_force", "the residual had outliers: a process (cutting) force, not the axis"},
        {"stick_slip", "stick-slip"},
        {"saturation", "the drive at its force limit"},
        {"gap", "a gap in the time stamps"},
        {"gated_out", "left out by --only-when"},
        {"inconsistent", "fitted the model on its own but not the pooled estimate"},
    }};
    const auto count = [](const nlohmann::json& object, const char* key) {
        const auto n = number_at(object, key);
        return n ? fmt::format("{:.0f}", *n) : std::string("—");
    };
    const auto window_s = number_at(member(result, "options"), "window_s");
    std::string html = "<h2>Windows</h2>\n";
    html += fmt::format(
        "<p>The trace was cut into {} windows{}; <b>{}</b> qualified and were pooled ({} rows, residual standard "
        "deviation {}). The others were left out:</p>\n",
        count(windows, "total"), window_s ? fmt::format(" of {:.3g} s", *window_s) : std::string(),
        count(windows, "qualified"), count(windows, "rows_used"),
        number_at(windows, "residual_std") ? fmt::format("{:.3g} {}", *number_at(windows, "residual_std"),
                                                         member(result, "rotary") == true ? "N·m" : "N")
                                           : "—");
    html += "<table>\n<tr><th class=\"text\">left out because</th><th>windows</th></tr>\n";
    const auto& rejected = member(windows, "rejected");
    for (const auto& [key, meaning] : reasons)
        if (const auto n = number_at(rejected, key); n && *n > 0)
            html += fmt::format("<tr><td class=\"text\">{}</td><td>{:.0f}</td></tr>\n", meaning, *n);
    html += "</table>\n";
    const auto& information = member(result, "information");
    if (!information.is_object()) return html;
    html +=
        "<p>The information each parameter got from the pooled windows (the inverse of its variance; the "
        "standard error it alone would give is 1/&radic;information):</p>\n<table>\n<tr><th "
        "class=\"text\">parameter</th><th>information</th><th>1/&radic;information</th><th "
        "class=\"text\">unit</th></tr>\n";
    for (const auto& [key, entry] : information.items()) {
        const auto inverse_variance = number_at(entry, "inverse_variance");
        if (!inverse_variance || *inverse_variance <= 0.0) continue;
        const auto label = parameter_label(key);
        html += fmt::format(
            "<tr><td class=\"text\">{}</td><td>{:.4g}</td><td>{:.3g}</td><td class=\"text\">{}</td></tr>\n",
            escape_xml(label.name), *inverse_variance, 1.0 / std::sqrt(*inverse_variance), escape_xml(label.unit));
    }
    return html + "</table>\n";
}

std::string plot_caption(const nlohmann::json& result, const Plot& plot) {
    if (plot.id.rfind("rls-", 0) != 0)
        return "Quasi-static friction binned by speed, per direction, with the fitted model (viscous, Coulomb and, "
               "where identified, Stribeck terms) evaluated from the identified parameters over the measured speeds.";
    const auto& settled = member(member(result, "rls"), "settled");
    const std::string range =
        settled.is_boolean() && settled.get<bool>()
            ? "The dashed red line marks where the RLS transient ends (estimates within 2 % or 3 standard errors of "
              "their final value); the y axis covers the estimate after it"
            : "The RLS did not settle; the y axis covers the estimate after the first tenth of the record";
    return range +
           " and the batch least-squares value of the same samples (green) with its band; the start-up transient "
           "beyond it is clipped, a triangle marks where it leaves the plot (its tooltip gives the farthest value). "
           "Where the friction-curve fit changed the value, the identified value is the grey line.";
}

}  // namespace

std::string result_report_html(const nlohmann::json& result, const std::string& source,
                               const std::optional<SimulationDocument>& simulation) {
    const auto plots = result_plots(result, source);
    // Both documents are checked before anything is written.
    const auto validation_plots =
        simulation ? simulation_plots(simulation->document, simulation->source) : std::vector<Plot>{};
    std::string body;
    std::string trace_path = source;
    if (const auto& path = member(member(result, "trace"), "path"); path.is_string())
        trace_path = path.get<std::string>();
    body += fmt::format("<p>Trace <code>{}</code>; model <b>{}</b>; status <b>{}</b>.</p>\n", escape_xml(trace_path),
                        escape_xml(result.value("model", std::string())),
                        escape_xml(result.value("status", std::string("—"))));
    body += result_warning(result);
    if (simulation && document_status(simulation->document) != "ok")
        body += warning(fmt::format("The validation by simulation did not succeed (status \"{}\"): see below.",
                                    document_status(simulation->document)),
                        nlohmann::json());
    body += parameter_table(result);
    if (const auto& fit = member(result, "fit"); fit.is_object()) {
        body += fmt::format(
            "<p>Step-1 batch least squares: relative error {} %, condition number {}, {} samples.</p>\n",
            number_at(fit, "relative_error_pct") ? fmt::format("{:.3g}", *number_at(fit, "relative_error_pct")) : "—",
            number_at(fit, "condition_number") ? fmt::format("{:.3g}", *number_at(fit, "condition_number")) : "—",
            number_at(fit, "samples_used") ? fmt::format("{:.0f}", *number_at(fit, "samples_used")) : "—");
    }
    body += scan_windows_section(result);
    if (const auto& diagnostics = member(result, "diagnostics"); diagnostics.is_array() && !diagnostics.empty()) {
        body += "<h2>Diagnostics</h2>\n<ul>\n";
        for (const auto& line : diagnostics)
            if (line.is_string()) body += fmt::format("<li>{}</li>\n", escape_xml(line.get<std::string>()));
        body += "</ul>\n";
    }
    body += "<h2>Plots</h2>\n";
    if (plots.empty())
        body += member(result, "kind") == "scan"
                    ? "<p class=\"note\">A scan pools windows and keeps neither an RLS history nor a friction curve: "
                      "those plots come from an identify run of a dedicated test (feedid plan).</p>\n"
                    : "<p class=\"note\">The result holds neither an RLS history nor a friction curve.</p>\n";
    for (const auto& plot : plots) body += figure(plot, plot_caption(result, plot));
    if (simulation)
        body += validation_section(*simulation, trace_path, validation_plots);
    else
        body +=
            "<p class=\"note\">Tracking-error plots (the paper's Fig. 6) need a simulation: give its document with "
            "--simulation (feedid simulate --json).</p>\n";
    const bool scan = member(result, "kind") == "scan";
    return page(fmt::format("feedid {} report: {}", scan ? "production-scan" : "identification",
                            std::filesystem::path(trace_path).filename().string()),
                body);
}

namespace {

// The table of runs lists every run of a short history; of a long one the baseline runs, the runs where an alarm
// fired and the latest runs, with a row saying how many are left out between them.
constexpr std::size_t table_latest_runs = 100;

std::vector<bool> listed_in_table(const history::SeriesTrend& trend,
                                  const std::vector<const history::RunRecord*>& series_runs) {
    const std::size_t n = series_runs.size();
    std::vector<bool> listed(n, n <= table_latest_runs + trend.baseline_run_ids.size());
    std::set<std::int64_t> named(trend.baseline_run_ids.begin(), trend.baseline_run_ids.end());
    for (const auto& alarm : trend.alarms) named.insert(alarm.run_id);
    for (std::size_t i = 0; i < n; ++i)
        if (i + table_latest_runs >= n || named.count(series_runs[i]->id)) listed[i] = true;
    return listed;
}

std::string runs_table(const history::SeriesTrend& trend, const std::vector<const history::RunRecord*>& series_runs,
                       const std::set<std::string>& keys) {
    std::map<std::string, std::set<std::int64_t>> in_alarm;
    for (const auto& parameter : trend.parameters)
        for (const auto& point : parameter.points)
            if (point.alarm) in_alarm[parameter.key].insert(point.run_id);
    const auto listed = listed_in_table(trend, series_runs);
    std::string body =
        "<table>\n<tr><th>run</th><th class=\"text\">recorded at</th><th class=\"text\">location</th>"
        "<th class=\"text\">status</th>";
    for (const auto& key : keys) body += fmt::format("<th>{}</th>", escape_xml(with_unit(parameter_label(key))));
    body += "</tr>\n";
    for (std::size_t i = 0; i < series_runs.size(); ++i) {
        if (!listed[i]) {
            std::size_t end = i;
            while (end < series_runs.size() && !listed[end]) ++end;
            body += fmt::format(
                "<tr><td class=\"text note\" colspan=\"{}\">… {} run(s) not listed here (feedid history DB --csv - "
                "lists every run)</td></tr>\n",
                keys.size() + 4, end - i);
            i = end - 1;
            continue;
        }
        const auto* run = series_runs[i];
        const bool ok = run->status.empty() || run->status == "ok";
        body += fmt::format(
            "<tr><td>#{}</td><td class=\"text\">{}</td><td class=\"text\">{}</td><td class=\"text{}\">{}</td>",
            run->id, escape_xml(run->recorded_at), escape_xml(run->location), ok ? "" : " alarm",
            escape_xml(run->status.empty() ? std::string("—") : run->status));
        for (const auto& key : keys) {
            const auto found = run->parameters.find(key);
            std::string cell = "—";
            const double scale = parameter_label(key).scale;
            if (found != run->parameters.end() && found->second.value)
                cell = found->second.standard_error
                           ? fmt::format("{:.5g} ± {:.2g}", *found->second.value * scale,
                                         *found->second.standard_error * std::abs(scale))
                           : fmt::format("{:.5g}", *found->second.value * scale);
            const bool alarm = in_alarm.count(key) && in_alarm.at(key).count(run->id);
            body += alarm ? fmt::format("<td class=\"alarm\">{} !</td>", escape_xml(cell))
                          : fmt::format("<td>{}</td>", escape_xml(cell));
        }
        body += "</tr>\n";
    }
    return body + "</table>\n";
}

}  // namespace

std::string history_report_html(const std::vector<history::RunRecord>& runs,
                                const std::vector<history::SeriesTrend>& trends, const history::TrendOptions& options,
                                const std::string& source) {
    std::string body;
    std::size_t alarm_count = 0;
    for (const auto& trend : trends) alarm_count += trend.alarms.size();
    std::set<std::pair<std::string, std::string>> axes;
    for (const auto& trend : trends) axes.emplace(trend.machine, trend.axis);
    body += fmt::format(
        "<p>History <code>{}</code>: {} run(s) of {} axis/axes. Baseline: the first {} runs of each "
        "axis (or from a pinned run), its fingerprint runs apart from its identifications; CUSUM allowance k = {:g}, "
        "decision interval h = {:g} (combined standard errors).</p>\n",
        escape_xml(source), runs.size(), axes.size(), options.baseline_runs, options.cusum_k, options.cusum_h);
    body += alarm_count == 0 ? std::string("<p>No drift alarm.</p>\n")
                             : fmt::format("<p class=\"alarm\">{} drift alarm(s).</p>\n", alarm_count);
    // Every axis's plots first: how many the page holds decides how far each is thinned.
    std::vector<std::vector<Plot>> axis_plots;
    std::size_t page_plots = 0;
    for (const auto& trend : trends) {
        axis_plots.push_back(unthinned_history_plots(runs, {trend}, options));
        page_plots +=
            static_cast<std::size_t>(std::count_if(axis_plots.back().begin(), axis_plots.back().end(), per_run_plot));
    }
    for (auto& plots : axis_plots) thin_history_plots(plots, page_plots);
    for (std::size_t t = 0; t < trends.size(); ++t) {
        const auto& trend = trends[t];
        body += fmt::format("<h2>Machine {} — axis {}{}</h2>\n", escape_xml(trend.machine), escape_xml(trend.axis),
                            trend.kind == "fingerprint" ? " — mechanical fingerprint" : "");
        if (!trend.alarms.empty()) {
            body += "<ul>\n";
            for (const auto& alarm : trend.alarms)
                body += fmt::format("<li class=\"alarm\">{}</li>\n", escape_xml(alarm.message()));
            body += "</ul>\n";
        }
        for (const auto& note : trend.notes) body += fmt::format("<p class=\"note\">{}</p>\n", escape_xml(note));
        // Table of runs.
        std::set<std::string> keys;
        std::vector<const history::RunRecord*> series_runs;
        for (const auto& run : runs)
            if (in_series(run, trend)) {
                series_runs.push_back(&run);
                for (const auto& [key, estimate] : run.parameters) keys.insert(key);
            }
        body += runs_table(trend, series_runs, keys);
        for (const auto& plot : axis_plots[t]) {
            std::string caption;
            if (plot.id.rfind("trend-", 0) == 0)
                caption =
                    "Each run's value with a band of ± 2 standard errors, the baseline mean, and the change that "
                    "raises the alarm in a single run; a red ring marks a run in alarm.";
            else if (plot.id.rfind("cusum-", 0) == 0)
                caption =
                    "Two-sided CUSUM of the change in combined standard errors over the runs after the baseline; "
                    "the alarm fires when it crosses h.";
            else
                caption =
                    "Quasi-static friction of the latest run with a stored friction curve, per direction, with "
                    "the fitted model.";
            body += figure(plot, caption);
        }
    }
    return page(fmt::format("feedid health report: {}", std::filesystem::path(source).filename().string()), body);
}

}  // namespace feedid::report
