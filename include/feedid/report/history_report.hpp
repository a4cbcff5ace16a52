#pragma once
// The report of a history: one self-contained HTML file (no script, no font, no stylesheet from the network) with,
// per axis and parameter, the values of every run with their uncertainty band (value +- 2 standard errors), the
// baseline mean, the one-run alarm limits and the runs in alarm, and the CUSUM with its decision interval; plus the
// latest run's friction curve when the stored result holds one. The plots are svg_plot.hpp's.

#include <string>
#include <vector>

#include "feedid/history/store.hpp"
#include "feedid/history/trend.hpp"
#include "feedid/report/svg_plot.hpp"

namespace feedid::report {

/// Plots of a history: for each axis and parameter with a trend, the values with their band, baseline, one-run alarm
/// limits and alarms, and the CUSUM; the latest run's friction curve of each axis when stored.
std::vector<Plot> history_plots(const std::vector<history::RunRecord>& runs,
                                const std::vector<history::SeriesTrend>& trends, const history::TrendOptions& options);

/// The whole HTML page of a history (per axis: runs, alarms, trend and CUSUM plots, latest friction curve).
std::string history_report_html(const std::vector<history::RunRecord>& runs,
                                const std::vector<history::SeriesTrend>& trends, const history::TrendOptions& options,
                                const std::string& source);

}  // namespace feedid::report
