// Baselines, changes in units of the combined standard error, and the two-sided CUSUM (see trend.hpp for the
// equations and the choice of defaults).

#include "feedid/history/trend.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <fmt/core.h>

namespace feedid::history {
namespace {

// z of the 25 % quantile of the standard normal distribution: the chi-square quantile below uses it to give a 75 %
// upper confidence bound of a standard deviation.
constexpr double z_25_percent = -0.6744897501960817;

/// sqrt(nu / chi2_{0.25}(nu)) with Wilson and Hilferty's (1931) cube-root approximation
/// chi2_p(nu) ~ nu * (1 - 2/(9 nu) + z_p sqrt(2/(9 nu)))^3, accurate to a few per cent even for nu = 1.
double scatter_upper_factor(int nu) {
    if (nu < 1) return 1.0;
    const double a = 2.0 / (9.0 * nu);
    const double cube = 1.0 - a + z_25_percent * std::sqrt(a);
    const double quantile = nu * cube * cube * cube;
    return std::sqrt(nu / quantile);
}

nlohmann::json optional_json(const std::optional<double>& value) {
    return value && std::isfinite(*value) ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

const char* role_name(RunRole role) {
    switch (role) {
        case RunRole::before_baseline: return "before_baseline";
        case RunRole::baseline: return "baseline";
        case RunRole::checked: return "checked";
    }
    return "checked";
}

// The runs of the baseline, [start, end) in recording order.
struct BaselineWindow {
    std::size_t start{0};
    std::size_t end{0};

    [[nodiscard]] RunRole role_of(std::size_t i) const {
        if (i < start) return RunRole::before_baseline;
        if (i < end) return RunRole::baseline;
        return RunRole::checked;
    }
};

// Where the baseline starts: the first run, or the pinned one.
std::size_t baseline_start(const SeriesRuns& runs, const TrendOptions& options, SeriesTrend& series) {
    if (!options.pinned_run) return 0;
    const auto pinned = std::find(runs.run_ids.begin(), runs.run_ids.end(), *options.pinned_run);
    if (pinned == runs.run_ids.end()) {
        series.notes.push_back(
            fmt::format("pinned run #{} is not among this axis's runs; the baseline starts at "
                        "the first run",
                        *options.pinned_run));
        series.pinned_run.reset();
        return 0;
    }
    return static_cast<std::size_t>(pinned - runs.run_ids.begin());
}

BaselineWindow baseline_window(const SeriesRuns& runs, const TrendOptions& options, SeriesTrend& series) {
    BaselineWindow window;
    window.start = baseline_start(runs, options, series);
    window.end = std::min(runs.size(), window.start + static_cast<std::size_t>(options.baseline_runs));
    for (std::size_t i = window.start; i < window.end; ++i) series.baseline_run_ids.push_back(runs.run_ids[i]);
    series.baseline_complete = window.end - window.start == static_cast<std::size_t>(options.baseline_runs);
    if (!series.baseline_complete)
        series.notes.push_back(fmt::format("the baseline is still forming ({} of {} runs); nothing is checked yet",
                                           window.end - window.start, options.baseline_runs));
    return window;
}

// Options differing between runs make values incomparable; say so rather than guess.
void note_differing_options(const SeriesRuns& runs, std::size_t start, SeriesTrend& series) {
    for (std::size_t i = start + 1; i < runs.size(); ++i) {
        if (runs.options_groups[i] != runs.options_groups[start]) {
            series.notes.push_back(
                "the runs were identified with different options; their values may not be comparable");
            return;
        }
    }
}

// What a change of one parameter is measured against (see trend.hpp).
struct Baseline {
    double mean{0.0};           // mu_0
    double stderr_rms{0.0};     // rms of the reported standard errors
    double scatter_bound{0.0};  // c * s_b
    double sigma_mean{0.0};     // sigma_mu
};

// The baseline of the parameter `trend.key` (its estimates per run), kept in `trend` too; a note there when no change
// can be judged.
Baseline baseline_of(const std::vector<StoredEstimate>& estimates, const BaselineWindow& window,
                     ParameterTrend& trend) {
    std::vector<double> values;
    std::vector<double> errors;
    for (std::size_t i = window.start; i < window.end; ++i) {
        if (!estimates[i].value) continue;
        values.push_back(*estimates[i].value);
        if (estimates[i].standard_error) errors.push_back(*estimates[i].standard_error);
    }
    const std::size_t n = values.size();
    Baseline baseline;
    double scatter = 0.0;
    if (n > 0) {
        for (const double v : values) baseline.mean += v;
        baseline.mean /= static_cast<double>(n);
        trend.baseline_mean = baseline.mean;
    }
    if (n > 1) {
        for (const double v : values) scatter += (v - baseline.mean) * (v - baseline.mean);
        scatter = std::sqrt(scatter / static_cast<double>(n - 1));
        trend.baseline_scatter = scatter;
        trend.scatter_factor = scatter_upper_factor(static_cast<int>(n) - 1);
    }
    if (!errors.empty()) {
        for (const double e : errors) baseline.stderr_rms += e * e;
        baseline.stderr_rms = std::sqrt(baseline.stderr_rms / static_cast<double>(errors.size()));
        trend.baseline_stderr_rms = baseline.stderr_rms;
    }
    baseline.scatter_bound = trend.scatter_factor * scatter;
    const double sigma = std::max(baseline.stderr_rms, baseline.scatter_bound);
    baseline.sigma_mean = n > 0 ? sigma / std::sqrt(static_cast<double>(n)) : 0.0;
    if (n == 0)
        trend.note = "no baseline run has this parameter";
    else if (sigma <= 0.0)
        trend.note = "neither a standard error nor a run-to-run scatter is known; no change can be judged";
    return baseline;
}

// Run i's value with its change from the baseline in combined standard errors (when a change can be judged).
TrendPoint point_of(const SeriesRuns& runs, std::size_t i, const StoredEstimate& estimate, RunRole role,
                    const ParameterTrend& trend, const Baseline& baseline) {
    TrendPoint point;
    point.run_id = runs.run_ids[i];
    point.recorded_at = runs.recorded_at[i];
    point.role = role;
    point.value = estimate.value;
    point.standard_error = estimate.standard_error;
    if (trend.note.empty()) {
        const double reported = estimate.standard_error.value_or(baseline.stderr_rms);
        const double sigma_run = std::max(reported, baseline.scatter_bound);
        const double sigma = std::sqrt(sigma_run * sigma_run + baseline.sigma_mean * baseline.sigma_mean);
        point.change = *point.value - baseline.mean;
        point.sigma = sigma;
        if (sigma > 0.0) point.z = *point.change / sigma;
    }
    return point;
}

// The two-sided CUSUM of one parameter along its checked runs.
struct Cusum {
    double up{0.0};
    double down{0.0};
    bool in_alarm{false};
};

// Advances the CUSUM by the point's z; true when the alarm fires here (the first crossing of h). Once fired, a
// parameter stays in alarm until a new baseline is pinned: drift from wear does not heal by itself, and a nightly
// check must keep saying so.
bool advance(Cusum& cusum, TrendPoint& point, const TrendOptions& options) {
    cusum.up = std::max(0.0, cusum.up + *point.z - options.cusum_k);
    cusum.down = std::max(0.0, cusum.down - *point.z - options.cusum_k);
    point.cusum_up = cusum.up;
    point.cusum_down = cusum.down;
    const bool alarm = cusum.up > options.cusum_h || cusum.down > options.cusum_h;
    const bool fires = alarm && !cusum.in_alarm;
    cusum.in_alarm = cusum.in_alarm || alarm;
    point.alarm = cusum.in_alarm;
    return fires;
}

Alarm alarm_at(const SeriesTrend& series, const std::string& key, const TrendPoint& point, const Cusum& cusum,
               double mean, const TrendOptions& options) {
    Alarm fired;
    fired.machine = series.machine;
    fired.axis = series.axis;
    fired.parameter = key;
    fired.run_id = point.run_id;
    fired.recorded_at = point.recorded_at;
    fired.direction = cusum.up > options.cusum_h ? "up" : "down";
    fired.cusum = std::max(cusum.up, cusum.down);
    fired.change = *point.change;
    fired.change_pct = mean != 0.0 ? 100.0 * *point.change / std::abs(mean) : 0.0;
    fired.z = *point.z;
    fired.sigma = point.sigma.value_or(0.0);
    fired.baseline_runs = series.baseline_run_ids;
    return fired;
}

// One parameter (keys[k]) over the runs: its baseline, a point per run that has it (when kept), and the alarms (into
// `series`) of the runs checked after a complete baseline.
ParameterTrend parameter_trend(std::size_t k, const SeriesRuns& runs, const BaselineWindow& window,
                               const TrendOptions& options, SeriesTrend& series, std::vector<char>& checked) {
    ParameterTrend trend;
    trend.key = runs.keys[k];
    const auto& estimates = runs.estimates[k];
    const Baseline baseline = baseline_of(estimates, window, trend);
    Cusum cusum;
    for (std::size_t i = 0; i < runs.size(); ++i) {
        if (!estimates[i].value) continue;
        TrendPoint point = point_of(runs, i, estimates[i], window.role_of(i), trend, baseline);
        const bool compared = point.role == RunRole::checked && series.baseline_complete && point.z;
        if (compared) checked[i] = 1;
        if (compared && advance(cusum, point, options)) {
            series.alarms.push_back(alarm_at(series, trend.key, point, cusum, baseline.mean, options));
        }
        if (options.keep_points) trend.points.push_back(std::move(point));
    }
    return trend;
}

}  // namespace

std::string TrendOptions::validate() const {
    if (baseline_runs < 1) return fmt::format("--baseline-runs must be at least 1 (got {})", baseline_runs);
    if (!(cusum_k >= 0.0) || !std::isfinite(cusum_k))
        return fmt::format("--cusum-k must be a finite number >= 0 (got {})", cusum_k);
    if (!(cusum_h > 0.0) || !std::isfinite(cusum_h))
        return fmt::format("--cusum-h must be a finite number > 0 (got {})", cusum_h);
    return {};
}

std::string Alarm::message() const {
    const std::string baseline =
        baseline_runs.empty() ? std::string()
                              : fmt::format(" from the baseline of runs #{}..#{}", baseline_runs.front(), baseline_runs.back());
    return fmt::format(
        "drift alarm: machine '{}' axis '{}' parameter {} at run #{} (recorded {}): {} by {:+.4g} ± {:.2g}{} "
        "({:+.1f} %, {:+.1f} combined standard errors), CUSUM {:.1f}",
        machine, axis, parameter, run_id, recorded_at, direction == "up" ? "rose" : "fell", change, sigma, baseline,
        change_pct, z, cusum);
}

SeriesTrend analyse_series(const SeriesRuns& runs, const TrendOptions& options) {
    SeriesTrend series;
    series.machine = runs.machine;
    series.axis = runs.axis;
    series.pinned_run = options.pinned_run;
    const BaselineWindow window = baseline_window(runs, options, series);
    note_differing_options(runs, window.start, series);
    std::vector<char> checked(runs.size(), 0);
    for (std::size_t k = 0; k < runs.keys.size(); ++k) {
        const auto& estimates = runs.estimates[k];
        const bool any = std::any_of(estimates.begin(), estimates.end(), [](const auto& e) { return e.value; });
        if (any) series.parameters.push_back(parameter_trend(k, runs, window, options, series, checked));
    }
    series.checked_runs = static_cast<std::size_t>(std::count(checked.begin(), checked.end(), 1));
    std::stable_sort(series.alarms.begin(), series.alarms.end(),
                     [&](const Alarm& a, const Alarm& b) { return a.run_id < b.run_id; });
    return series;
}

namespace {

// The runs of one kind of a series (fingerprint or not), in their order.
SeriesRuns runs_of_kind(const SeriesRuns& runs, bool fingerprint) {
    SeriesRuns part;
    part.machine = runs.machine;
    part.axis = runs.axis;
    std::vector<std::size_t> members;
    for (std::size_t i = 0; i < runs.size(); ++i)
        if ((runs.fingerprint.size() == runs.size() && runs.fingerprint[i] != 0) == fingerprint) members.push_back(i);
    for (const auto i : members) {
        part.run_ids.push_back(runs.run_ids[i]);
        part.recorded_at.push_back(runs.recorded_at[i]);
        part.options_groups.push_back(runs.options_groups[i]);
        if (fingerprint) part.fingerprint.push_back(1);
    }
    for (std::size_t k = 0; k < runs.keys.size(); ++k) {
        std::vector<StoredEstimate> estimates;
        for (const auto i : members) estimates.push_back(runs.estimates[k][i]);
        if (std::any_of(estimates.begin(), estimates.end(), [](const auto& e) { return e.value; })) {
            part.keys.push_back(runs.keys[k]);
            part.estimates.push_back(std::move(estimates));
        }
    }
    return part;
}

// The pinned run as the part sees it: the pin itself, or the part's first run from the pin on (in recording order).
std::int64_t pin_in_part(const SeriesRuns& runs, const SeriesRuns& part, std::int64_t pin) {
    const auto pinned = std::find(runs.run_ids.begin(), runs.run_ids.end(), pin);
    if (pinned == runs.run_ids.end()) return pin;  // analyse_series says it is not among the axis's runs
    for (auto i = static_cast<std::size_t>(pinned - runs.run_ids.begin()); i < runs.size(); ++i)
        if (std::find(part.run_ids.begin(), part.run_ids.end(), runs.run_ids[i]) != part.run_ids.end())
            return runs.run_ids[i];
    return pin;  // no run of this kind since the pin: analyse_series says the baseline starts at its first
}

}  // namespace

std::vector<SeriesTrend> analyse_trends(const std::vector<SeriesRuns>& series, const std::vector<BaselinePin>& pins,
                                        const TrendOptions& options) {
    std::vector<SeriesTrend> result;
    for (const auto& all : series) {
        // an explicit pin applies to the axis holding it only; a stored one to its axis
        bool pinned = false;
        std::int64_t pin = 0;
        if (options.pinned_run) {
            pin = *options.pinned_run;
            pinned = std::find(all.run_ids.begin(), all.run_ids.end(), pin) != all.run_ids.end();
        } else {
            for (const auto& stored : pins)
                if (stored.machine == all.machine && stored.axis == all.axis) {
                    pinned = true;
                    pin = stored.run_id;
                }
        }
        const bool mixed = std::count(all.fingerprint.begin(), all.fingerprint.end(), 1) > 0;
        for (const bool fingerprint : {false, true}) {
            if (fingerprint && !mixed) break;
            const SeriesRuns part = mixed ? runs_of_kind(all, fingerprint) : SeriesRuns{};
            const SeriesRuns& runs = mixed ? part : all;
            if (runs.size() == 0) continue;
            TrendOptions series_options = options;
            series_options.pinned_run.reset();
            if (pinned) series_options.pinned_run = pin_in_part(all, runs, pin);
            result.push_back(analyse_series(runs, series_options));
            if (fingerprint) result.back().kind = "fingerprint";
        }
    }
    return result;
}

std::vector<SeriesRuns> series_of(const std::vector<RunRecord>& runs) {
    std::map<std::pair<std::string, std::string>, std::vector<const RunRecord*>> groups;
    for (const auto& run : runs) groups[{run.machine, run.axis}].push_back(&run);
    std::map<std::string, std::int64_t> options_texts;  // for records without an options group
    std::vector<SeriesRuns> result;
    for (auto& [name, members] : groups) {
        std::stable_sort(members.begin(), members.end(), [](const RunRecord* a, const RunRecord* b) {
            return a->recorded_at != b->recorded_at ? a->recorded_at < b->recorded_at : a->id < b->id;
        });
        SeriesRuns series;
        series.machine = name.first;
        series.axis = name.second;
        std::set<std::string> keys;
        for (const auto* run : members)
            for (const auto& [key, estimate] : run->parameters) keys.insert(key);
        series.keys.assign(keys.begin(), keys.end());
        series.estimates.assign(keys.size(), std::vector<StoredEstimate>(members.size()));
        for (std::size_t i = 0; i < members.size(); ++i) {
            const RunRecord& run = *members[i];
            series.run_ids.push_back(run.id);
            series.recorded_at.push_back(run.recorded_at);
            if (run.options_group != 0) {
                series.options_groups.push_back(run.options_group);
            } else {
                const auto text = options_texts.emplace(run.options.dump(), -1 - std::ssize(options_texts)).first;
                series.options_groups.push_back(text->second);
            }
            for (std::size_t k = 0; k < series.keys.size(); ++k)
                if (const auto found = run.parameters.find(series.keys[k]); found != run.parameters.end())
                    series.estimates[k][i] = found->second;
            if (is_fingerprint_run(run)) {
                series.fingerprint.resize(members.size(), 0);
                series.fingerprint[i] = 1;
            }
        }
        result.push_back(std::move(series));
    }
    return result;
}

std::vector<SeriesTrend> analyse_trends(const std::vector<RunRecord>& runs, const std::vector<BaselinePin>& pins,
                                        const TrendOptions& options) {
    return analyse_trends(series_of(runs), pins, options);
}

nlohmann::json alarm_document(const Alarm& alarm) {
    return {{"machine", alarm.machine},
            {"axis", alarm.axis},
            {"parameter", alarm.parameter},
            {"run", alarm.run_id},
            {"recorded_at", alarm.recorded_at},
            {"direction", alarm.direction},
            {"cusum", alarm.cusum},
            {"change", alarm.change},
            {"change_pct", alarm.change_pct},
            {"z", alarm.z},
            {"sigma", alarm.sigma},
            {"baseline_runs", alarm.baseline_runs},
            {"message", alarm.message()}};
}

nlohmann::json to_json(const SeriesTrend& trend) {
    nlohmann::json parameters = nlohmann::json::object();
    for (const auto& parameter : trend.parameters) {
        nlohmann::json points = nlohmann::json::array();
        for (const auto& point : parameter.points) {
            points.push_back({{"run", point.run_id},
                              {"recorded_at", point.recorded_at},
                              {"role", role_name(point.role)},
                              {"value", optional_json(point.value)},
                              {"stderr", optional_json(point.standard_error)},
                              {"change", optional_json(point.change)},
                              {"sigma", optional_json(point.sigma)},
                              {"z", optional_json(point.z)},
                              {"cusum_up", point.cusum_up},
                              {"cusum_down", point.cusum_down},
                              {"alarm", point.alarm}});
        }
        parameters[parameter.key] = {{"baseline_mean", optional_json(parameter.baseline_mean)},
                                     {"baseline_scatter", optional_json(parameter.baseline_scatter)},
                                     {"baseline_stderr_rms", optional_json(parameter.baseline_stderr_rms)},
                                     {"scatter_factor", parameter.scatter_factor},
                                     {"note", parameter.note},
                                     {"points", points}};
    }
    nlohmann::json alarms = nlohmann::json::array();
    for (const auto& alarm : trend.alarms) alarms.push_back(alarm_document(alarm));
    return {{"machine", trend.machine},
            {"axis", trend.axis},
            {"kind", trend.kind},
            {"baseline_runs", trend.baseline_run_ids},
            {"baseline_complete", trend.baseline_complete},
            {"pinned_run", trend.pinned_run ? nlohmann::json(*trend.pinned_run) : nlohmann::json(nullptr)},
            {"parameters", parameters},
            {"alarms", alarms},
            {"notes", trend.notes}};
}

}  // namespace feedid::history
