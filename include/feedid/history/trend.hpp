#pragma once
// Trends and drift alarms over the history of one axis.
//
// Baseline: the first `baseline_runs` runs of the axis (default 8), or that many runs starting at a pinned run (pin a
// new baseline after maintenance). For each parameter:
//   mu_0 = mean of the baseline values, s_b = their sample standard deviation (the run-to-run scatter),
//   c    = sqrt(nu / chi2_{0.25}(nu)), nu = n_b - 1: the 75 % upper confidence factor of s_b (Wilson-Hilferty's
//          approximation of the chi-square quantile), because a scatter estimated from a handful of runs is often
//          too small and would make the alarm fire on noise;
//   sigma_i = max(stderr_i, c * s_b): the larger of the reported standard error and the baseline scatter. The
//          standard errors of identify come from the residuals of one trace and are optimistic for run-to-run scatter
//          (coloured residuals, re-clamping, temperature); the scatter of real repeated runs is what an alarm must
//          not fire on;
//   sigma_mu = max(rms stderr of the baseline, c * s_b) / sqrt(n_b): the uncertainty of mu_0 itself;
//   z_i  = (x_i - mu_0) / sqrt(sigma_i^2 + sigma_mu^2): the change in units of the combined standard error.
// Detector: a two-sided tabular CUSUM (Page 1954; Montgomery, Introduction to Statistical Quality Control, ch. 9)
// on z over the runs after the baseline:
//   S+_i = max(0, S+_{i-1} + z_i - k),  S-_i = max(0, S-_{i-1} - z_i - k),  alarm when S+ or S- exceeds h,
// with k = 1 (tuned to a sustained shift of 2 combined standard errors) and h = 6 by default. In a Monte Carlo study
// (8 baseline runs, 12 runs checked, 6 parameters, reported standard errors three times too optimistic) these
// defaults raised a false alarm in about 5 % of series and caught a drift of one scatter unit per run within six
// runs in about 90 % (two units per run: always). A parameter stays in alarm until a new baseline is pinned.
//
// The fingerprint runs of an axis (feedid fingerprint --record: lost motion, backlash, stiffness, reversal error)
// form a series of their own beside its identifications, with its own baseline of as many fingerprint runs; a pinned
// run starts the baseline of both, the other kind's at its first run recorded from the pinned one on.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/history/store.hpp"

namespace feedid::history {

struct TrendOptions {
    int baseline_runs{8};                    ///< runs in the baseline (from the first run, or from the pinned run)
    double cusum_k{1.0};                     ///< CUSUM allowance [combined standard errors]
    double cusum_h{6.0};                     ///< CUSUM decision interval [combined standard errors]
    std::optional<std::int64_t> pinned_run;  ///< overrides a pin stored in the history
    /// Keep every run's point in ParameterTrend::points (plots, listings); without, only the alarms are found and the
    /// memory stays that of the runs (history --check on a large history).
    bool keep_points{true};

    /// What is wrong ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

enum class RunRole { before_baseline, baseline, checked };

struct TrendPoint {
    std::int64_t run_id{0};
    std::string recorded_at;
    RunRole role{RunRole::checked};
    std::optional<double> value;           ///< the parameter (SI, as keyed)
    std::optional<double> standard_error;  ///< as reported
    std::optional<double> change;          ///< value - mu_0
    std::optional<double> sigma;           ///< combined standard error of the change
    std::optional<double> z;               ///< change / sigma
    double cusum_up{0.0};
    double cusum_down{0.0};
    bool alarm{false};  ///< the CUSUM is above h at this run
};

struct ParameterTrend {
    std::string key;
    std::optional<double> baseline_mean;        ///< mu_0
    std::optional<double> baseline_scatter;     ///< s_b (absent with fewer than two baseline values)
    std::optional<double> baseline_stderr_rms;  ///< rms of the reported standard errors in the baseline
    double scatter_factor{1.0};                 ///< c
    std::vector<TrendPoint> points;             ///< one per run that has this parameter, in order
    std::string note;                           ///< why there is no trend ("" when there is one)
};

/// An alarm: the CUSUM of a parameter crossed h at a run.
struct Alarm {
    std::string machine;
    std::string axis;
    std::string parameter;
    std::int64_t run_id{0};
    std::string recorded_at;
    std::string direction;  ///< "up" or "down"
    double cusum{0.0};
    double change{0.0};      ///< value - mu_0 at that run
    double change_pct{0.0};  ///< 100 * change / |mu_0| (0 when mu_0 is 0)
    double z{0.0};
    double sigma{0.0};                      ///< the combined standard error of the change (change / z)
    std::vector<std::int64_t> baseline_runs;  ///< the runs of the baseline the change is measured from

    /// One line for people: machine, axis, parameter, run, by how much (with its combined standard error) and
    /// against which baseline runs.
    [[nodiscard]] std::string message() const;
};

struct SeriesTrend {
    std::string machine;
    std::string axis;
    std::string kind{"identification"};  ///< "identification" or "fingerprint" (the runs of fingerprint_model)
    std::vector<std::int64_t> baseline_run_ids;
    bool baseline_complete{false};  ///< as many baseline runs as asked for
    /// Runs compared with the complete baseline (a change and its z for at least one parameter), as the listing
    /// marks them; counted with or without keep_points.
    std::size_t checked_runs{0};
    std::optional<std::int64_t> pinned_run;
    std::vector<ParameterTrend> parameters;
    std::vector<Alarm> alarms;
    std::vector<std::string> notes;
};

/// The trend of one axis; `runs` are that axis's runs in recording order.
SeriesTrend analyse_series(const SeriesRuns& runs, const TrendOptions& options);

/// Applies stored pins (unless options.pinned_run is set, which applies to every series holding that run) and
/// analyses each series, in the order given (HistoryStore::series orders them by machine, then axis); a series that
/// holds fingerprint runs gives two trends, its identifications' and then its fingerprints'.
std::vector<SeriesTrend> analyse_trends(const std::vector<SeriesRuns>& series, const std::vector<BaselinePin>& pins,
                                        const TrendOptions& options);

/// Run records as the trend reads them: grouped by (machine, axis), ordered by machine, then axis, each in
/// recording order (time, then id).
std::vector<SeriesRuns> series_of(const std::vector<RunRecord>& runs);

/// analyse_trends(series_of(runs), pins, options).
std::vector<SeriesTrend> analyse_trends(const std::vector<RunRecord>& runs, const std::vector<BaselinePin>& pins,
                                        const TrendOptions& options);

/// The alarm document, the one spelling of an alarm: an element of the "alarms" of `feedid history --json`'s trends
/// and the payload `feedid watch` publishes on <prefix>/feedid/alarm (machine, axis, parameter, run, recorded_at,
/// direction, cusum, change, change_pct, z, sigma, baseline_runs, message).
nlohmann::json alarm_document(const Alarm& alarm);

/// The `feedid history --json` "trends" element of one series (its kind, its alarms as alarm_document() writes them).
nlohmann::json to_json(const SeriesTrend& trend);

}  // namespace feedid::history
