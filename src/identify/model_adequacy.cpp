#include "feedid/identify/model_adequacy.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <cmath>
#include <iterator>
#include <limits>
#include <optional>
#include <span>
#include <thread>

#include <Eigen/Cholesky>

#include <fmt/core.h>

#include "feedid/core/parameters.hpp"
#include "feedid/numeric/least_squares.hpp"
#include "feedid/numeric/signal.hpp"

namespace feedid {

std::string ModelSelectionOptions::validate() const {
    if (!(test_level > 0.0 && test_level < 0.5)) return "the model test level must lie in (0, 0.5)";
    if (!(max_delay_s > 0.0 && std::isfinite(max_delay_s))) return "the largest delay must be a positive time [s]";
    if (known_delay_s && !(std::isfinite(*known_delay_s) && std::abs(*known_delay_s) <= 1.0))
        return "--delay must be a time within +-1 s";
    if (!(one_way_fraction >= 0.0 && one_way_fraction < 0.5)) return "the one-way fraction must lie in [0, 0.5)";
    if (!(collinearity_limit > 0.0 && collinearity_limit < 1.0)) return "the collinearity limit must lie in (0, 1)";
    if (!(lack_of_fit_fraction >= 0.0 && std::isfinite(lack_of_fit_fraction)))
        return "the lack-of-fit fraction must be a finite fraction >= 0";
    return {};
}

namespace {

/// The two-sided standard normal quantile at `level` (z such that P(|Z| > z) = level), by bisection on erfc.
double normal_quantile(double level) {
    double low = 0.0, high = 40.0;
    for (int i = 0; i < 200; ++i) {
        const double middle = 0.5 * (low + high);
        (std::erfc(middle / std::sqrt(2.0)) > level ? low : high) = middle;
    }
    return 0.5 * (low + high);
}

/// Least squares of `output` on `columns` over `rows`, with standard errors that allow for residuals correlated over
/// `block` samples.
LeastSquaresResult fit_columns(const std::vector<std::span<const double>>& columns, std::span<const double> output,
                               std::span<const SampleIndex> rows, std::size_t block) {
    const auto p = static_cast<Eigen::Index>(columns.size());
    const auto row = [&](std::size_t i, double* phi) {
        const std::size_t k = rows[i];
        for (std::size_t c = 0; c < columns.size(); ++c) phi[c] = columns[c][k];
        return output[k];
    };
    return solve_least_squares_rows(rows.size(), p, row, [&](std::size_t i) { return rows[i]; }, block);
}

/// The regressor's columns, plus `extra` when given.
std::vector<std::span<const double>> columns_of(const Regressors& regressors, std::span<const double> extra = {}) {
    std::vector<std::span<const double>> columns(regressors.values.begin(), regressors.values.end());
    if (!extra.empty()) columns.push_back(extra);
    return columns;
}

/// Index of the column (term, direction) in a regressor; -1 when absent.
Eigen::Index column_index(const std::vector<RegressorColumn>& columns, Term term, Direction direction) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
        if (columns[c].term == term && columns[c].direction == direction)
            return static_cast<Eigen::Index>(c);
    }
    return -1;
}

/// A candidate from a linear combination c^T theta of a fit (its Wald statistic against the threshold).
ModelCandidate test_combination(std::string name, std::string tested, const LeastSquaresResult& fit,
                                const Eigen::VectorXd& combination, double threshold) {
    ModelCandidate candidate;
    candidate.name = std::move(name);
    candidate.tested = std::move(tested);
    candidate.threshold = threshold;
    if (fit.rank_deficient || fit.estimate.size() != combination.size() || fit.covariance.rows() != combination.size())
        return candidate;
    const double value = combination.dot(fit.estimate);
    const double variance = combination.dot(fit.covariance * combination);
    if (!std::isfinite(value) || !(variance > 0.0) || !std::isfinite(variance)) return candidate;
    candidate.estimate = value;
    candidate.standard_error = std::sqrt(variance);
    candidate.statistic = std::abs(value) / *candidate.standard_error;
    candidate.taken = *candidate.statistic > threshold;
    return candidate;
}

/// A list of rows (ascending sample indices) and the samples their central differences reach: the model-adequacy
/// stage holds its regressor columns there only (step 1's rows are about a quarter of the trace), not on every sample.
class RowSupport {
public:
    /// With `neighbours`, each row's neighbours within its stretch are held too (for slope()).
    RowSupport(const Derivatives& d, std::span<const SampleIndex> rows, bool neighbours) : d_(d), rows_(rows) {
        const std::size_t n = d.size();
        std::size_t s = 0;
        std::vector<std::array<SampleIndex, 2>> reach;  // each row's central difference's ends (sample indices)
        reach.reserve(rows.size());
        for (const std::size_t k : rows) {
            while (s + 1 < d.segment_starts.size() && d.segment_starts[s + 1] <= k) ++s;
            const std::size_t begin = d.segment_starts[s];
            const std::size_t end = s + 1 < d.segment_starts.size() ? d.segment_starts[s + 1] : n;
            // central differences within the stretch, none in a stretch under 3 samples (its slope is 0)
            const bool differenced = neighbours && end - begin >= 3;
            const std::size_t before = differenced && k > begin ? k - 1 : k;
            const std::size_t after = differenced && k + 1 < end ? k + 1 : k;
            for (const std::size_t m : {before, k, after})
                if (samples_.empty() || m > samples_.back()) samples_.push_back(static_cast<SampleIndex>(m));
            reach.push_back({static_cast<SampleIndex>(before), static_cast<SampleIndex>(after)});
        }
        const auto at = [&](std::size_t m) {
            return static_cast<std::uint32_t>(std::lower_bound(samples_.begin(), samples_.end(), m) - samples_.begin());
        };
        position_.resize(rows.size());
        ends_.resize(rows.size());
        for (std::size_t i = 0; i < rows.size(); ++i) {
            position_[i] = at(rows[i]);
            ends_[i] = {at(reach[i][0]), at(reach[i][1])};
        }
    }
    [[nodiscard]] std::span<const SampleIndex> rows() const { return rows_; }
    [[nodiscard]] std::size_t size() const { return rows_.size(); }
    /// Where row i's value lies in a column held on the support.
    [[nodiscard]] std::size_t at(std::size_t i) const { return position_[i]; }
    /// A whole-trace column on the support.
    [[nodiscard]] std::vector<double> gather(std::span<const double> full) const {
        std::vector<double> out(samples_.size());
        for (std::size_t j = 0; j < samples_.size(); ++j) out[j] = full[samples_[j]];
        return out;
    }
    /// The time derivative at row i of a column held on the support (central differences within the stretch; 0 in
    /// a stretch under 3 samples).
    [[nodiscard]] double slope(const std::vector<double>& held, std::size_t i) const {
        const std::size_t before = ends_[i][0], after = ends_[i][1];
        const double dt = d_.time[samples_[after]] - d_.time[samples_[before]];
        return dt > 0.0 ? (held[after] - held[before]) / dt : 0.0;
    }
    /// The same of a whole-trace column.
    [[nodiscard]] double slope_of_whole(std::span<const double> full, std::size_t i) const {
        const std::size_t before = samples_[ends_[i][0]], after = samples_[ends_[i][1]];
        const double dt = d_.time[after] - d_.time[before];
        return dt > 0.0 ? (full[after] - full[before]) / dt : 0.0;
    }
    /// The column -F'(t) (delay_column) at row i.
    [[nodiscard]] double negated_force_slope(std::size_t i) const {
        const std::size_t before = samples_[ends_[i][0]], after = samples_[ends_[i][1]];
        const double dt = d_.time[after] - d_.time[before];
        return dt > 0.0 ? -(d_.force[after] - d_.force[before]) / dt : 0.0;
    }

private:
    const Derivatives& d_;
    std::span<const SampleIndex> rows_;
    SampleIndices samples_;                                // the support's sample indices, ascending
    std::vector<std::uint32_t> position_;                  // row i's place in samples_
    std::vector<std::array<std::uint32_t, 2>> ends_;       // the places of its central difference's ends
};

/// One column of a RowRegressors: held on the support (gathered from a whole-trace column the stage formed), a view of
/// a whole-trace column held anyway (the Derivatives' x'' and x': not copied), or the constant 1 (the offset of an
/// undecimated trace: not formed).
struct RowColumn {
    std::shared_ptr<const std::vector<double>> held;
    std::span<const double> whole;
    /// At support place j, sample k (the same row).
    [[nodiscard]] double at(std::size_t j, std::size_t k) const {
        return held ? (*held)[j] : whole.empty() ? 1.0 : whole[k];
    }
};

/// A regressor on the rows of a RowSupport: values[c] column c.
struct RowRegressors {
    const RowSupport* support{nullptr};
    std::vector<RegressorColumn> columns;
    std::vector<RowColumn> values;
    [[nodiscard]] std::size_t parameters() const { return columns.size(); }
    /// Row i of Phi into phi.
    void row(std::size_t i, double* phi) const {
        const std::size_t j = support->at(i), k = support->rows()[i];
        for (std::size_t c = 0; c < values.size(); ++c) phi[c] = values[c].at(j, k);
    }
    /// The time derivative of column c at row i (RowSupport::slope).
    [[nodiscard]] double slope(std::size_t c, std::size_t i) const {
        const RowColumn& column = values[c];
        if (column.held) return support->slope(*column.held, i);
        return column.whole.empty() ? 0.0 : support->slope_of_whole(column.whole, i);
    }
};

/// The columns of the models the stage fits, on a RowSupport: each formed on the whole trace (or taken from the
/// caller's cache), gathered and released, so that only one whole-trace column exists at a time; the Derivatives' own
/// columns are viewed and the constant is not formed.
class RowColumns {
public:
    RowColumns(const Derivatives& d, const RowSupport& support, const RegressorColumnCache* full)
        : d_(d), support_(support), full_(full) {}
    RowRegressors regressors(FrictionModelKind model, bool offset) {
        RowRegressors r;
        r.support = &support_;
        r.columns = linear_columns(model, offset);
        for (const auto& column : r.columns) r.values.push_back(held(column));
        return r;
    }

private:
    RowColumn held(const RegressorColumn& column) {
        if (column.term == Term::offset && d_.used.decimation <= 1) return {};  // 1 on every sample
        for (const auto& [key, values] : held_)
            if (key.term == column.term && key.direction == column.direction) return values;
        RegressorValues formed = regressor_values(d_, column, full_);
        if (!formed.owned) return {nullptr, formed.values};  // the Derivatives' own column
        RowColumn values{std::make_shared<const std::vector<double>>(support_.gather(formed.values)), {}};
        held_.emplace_back(column, values);
        return values;
    }
    const Derivatives& d_;
    const RowSupport& support_;
    const RegressorColumnCache* full_;
    std::vector<std::pair<RegressorColumn, RowColumn>> held_;
};

/// A whole-trace column at the rows.
std::vector<double> at_rows(std::span<const double> full, std::span<const SampleIndex> rows) {
    std::vector<double> out(rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) out[i] = full[rows[i]];
    return out;
}

/// Least squares of `output` (one value per row) on the regressor's columns, and `extra` (one value per row) when
/// given, with standard errors that allow for residuals correlated over `block` samples.
LeastSquaresResult fit_rows(const RowRegressors& r, std::span<const double> extra, std::span<const double> output,
                            std::size_t block) {
    const auto rows = r.support->rows();
    const std::size_t p = r.parameters();
    const auto row = [&](std::size_t i, double* phi) {
        r.row(i, phi);
        if (!extra.empty()) phi[p] = extra[i];
        return output[i];
    };
    return solve_least_squares_rows(rows.size(), static_cast<Eigen::Index>(p + (extra.empty() ? 0 : 1)), row,
                                    [&](std::size_t i) { return rows[i]; }, block);
}

/// Step 1's samples per direction.
std::pair<std::size_t, std::size_t> direction_counts(const Derivatives& d, std::span<const SampleIndex> rows) {
    std::size_t forward = 0;
    for (const auto k : rows) forward += d.velocity[k] > 0.0 ? 1 : 0;
    return {forward, rows.size() - forward};
}

/// The typical magnitude of the drive force on step 1's samples (its median |F|) [N].
double typical_force(const Derivatives& d, std::span<const SampleIndex> rows) {
    std::vector<double> magnitudes;
    const std::size_t stride = std::max<std::size_t>(1, rows.size() / 20000);
    for (std::size_t i = 0; i < rows.size(); i += stride) magnitudes.push_back(std::abs(d.force[rows[i]]));
    return magnitudes.empty() ? 0.0 : percentile_in_place(magnitudes, 0.5);
}

}  // namespace

std::optional<RestLevel> rest_level(std::span<const double> force, std::size_t samples) {
    samples = std::min(samples, force.size());
    if (samples < 10) return std::nullopt;
    double sum = 0.0;
    for (std::size_t k = 0; k < samples; ++k) sum += force[k];
    const double mean = sum / static_cast<double>(samples);
    double squares = 0.0, lagged = 0.0;
    for (std::size_t k = 0; k < samples; ++k) {
        squares += (force[k] - mean) * (force[k] - mean);
        if (k > 0) lagged += (force[k] - mean) * (force[k - 1] - mean);
    }
    // neighbours that move together count as fewer independent samples: n (1 - rho) / (1 + rho)
    const double rho = squares > 0.0 ? std::clamp(lagged / squares, 0.0, 0.95) : 0.0;
    const double independent = std::max(1.0, static_cast<double>(samples) * (1.0 - rho) / (1.0 + rho));
    RestLevel rest;
    rest.samples = samples;
    rest.mean = mean;
    rest.standard_error = std::sqrt(squares / static_cast<double>(samples - 1) / independent);
    return rest;
}

std::vector<double> delay_column(const Derivatives& d) {
    const std::size_t n = d.size();
    std::vector<double> column(n, 0.0);
    for (std::size_t s = 0; s < d.segment_starts.size(); ++s) {
        const std::size_t begin = d.segment_starts[s];
        const std::size_t end = s + 1 < d.segment_starts.size() ? d.segment_starts[s + 1] : n;
        if (end - begin < 3) continue;
        for (std::size_t k = begin; k < end; ++k) {
            const std::size_t before = k > begin ? k - 1 : k, after = k + 1 < end ? k + 1 : k;
            const double dt = d.time[after] - d.time[before];
            column[k] = dt > 0.0 ? -(d.force[after] - d.force[before]) / dt : 0.0;
        }
    }
    return column;
}

void shift_drive_force(Derivatives& d, double delay_s) {
    const std::size_t n = d.size();
    std::vector<double> shifted(n);
    for (std::size_t s = 0; s < d.segment_starts.size(); ++s) {
        const std::size_t begin = d.segment_starts[s];
        const std::size_t end = s + 1 < d.segment_starts.size() ? d.segment_starts[s + 1] : n;
        if (end - begin < 4) {
            std::copy(d.force.begin() + static_cast<std::ptrdiff_t>(begin),
                      d.force.begin() + static_cast<std::ptrdiff_t>(end),
                      shifted.begin() + static_cast<std::ptrdiff_t>(begin));
            continue;
        }
        const double step = (d.time[end - 1] - d.time[begin]) / static_cast<double>(end - begin - 1);
        const double offset = delay_s / step;  // in samples
        const auto at = [&](std::ptrdiff_t i) {
            const auto clamped =
                std::clamp<std::ptrdiff_t>(i, static_cast<std::ptrdiff_t>(begin), static_cast<std::ptrdiff_t>(end) - 1);
            return d.force[static_cast<std::size_t>(clamped)];
        };
        for (std::size_t k = begin; k < end; ++k) {
            // Catmull-Rom between the samples around k + offset (the filtered force is smooth on the sample grid)
            const double position = static_cast<double>(k) + offset;
            const double floor = std::floor(position);
            const double f = position - floor;
            const auto i = static_cast<std::ptrdiff_t>(floor);
            const double p0 = at(i - 1), p1 = at(i), p2 = at(i + 1), p3 = at(i + 2);
            shifted[k] = p1 + 0.5 * f *
                                  (p2 - p0 + f * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + f * (3.0 * (p1 - p2) + p3 - p0)));
        }
    }
    // into the same buffer: regressors view it (Regressors::output)
    std::copy(shifted.begin(), shifted.end(), d.force.begin());
}

namespace {

/// The regressors of the three nested candidates on the (aligned) force.
struct DelayFit {
    double delay{0.0};
    double standard_error{0.0};
    double largest_correlation{0.0};  // of the delay with a parameter of the model
    double plain_standard_error{0.0};  // as if the residuals were uncorrelated
    bool valid{false};
};

/// A run of consecutive step-1 rows (rows [first, last) of the row list) within one stretch of the Derivatives:
/// the stretch's samples [begin, end) and its sample step [s].
struct RowRun {
    std::size_t first, last, begin, end;
    double step;
};

std::vector<RowRun> row_runs(const Derivatives& d, std::span<const SampleIndex> rows) {
    std::vector<RowRun> runs;
    std::size_t s = 0;
    const std::size_t n = d.size();
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const std::size_t k = rows[i];
        while (s + 1 < d.segment_starts.size() && d.segment_starts[s + 1] <= k) ++s;
        const std::size_t begin = d.segment_starts[s];
        if (!runs.empty() && runs.back().begin == begin) {
            runs.back().last = i + 1;
            continue;
        }
        const std::size_t end = s + 1 < d.segment_starts.size() ? d.segment_starts[s + 1] : n;
        const double step = end - begin > 1 ? (d.time[end - 1] - d.time[begin]) / static_cast<double>(end - begin - 1)
                                            : d.sample_time_s;
        runs.push_back(RowRun{i, i + 1, begin, end, step});
    }
    return runs;
}

/// The filtered force at `position` (in samples, fractional) within [begin, end), Catmull-Rom, held at the ends.
double force_at(const std::vector<double>& force, double position, std::size_t begin, std::size_t end) {
    const double floor = std::floor(position);
    const double f = position - floor;
    const auto i = static_cast<std::ptrdiff_t>(floor);
    const auto at = [&](std::ptrdiff_t j) {
        return force[static_cast<std::size_t>(
            std::clamp<std::ptrdiff_t>(j, static_cast<std::ptrdiff_t>(begin), static_cast<std::ptrdiff_t>(end) - 1))];
    };
    const double p0 = at(i - 1), p1 = at(i), p2 = at(i + 1), p3 = at(i + 2);
    return p1 + 0.5 * f * (p2 - p0 + f * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + f * (3.0 * (p1 - p2) + p3 - p0)));
}

/// A shift of `offset` samples that is a whole number of them up to the rounding of the stretch's mean interval
/// (the delay profile's grid: m sample times over a stretch whose time stamps end a few ulps off m intervals), as
/// that number; else no_whole_shift. Read at the sample itself, such a shift is exact where the spline of force_at
/// would interpolate a fraction of 1e-9 of a sample that the time stamps' rounding made.
constexpr std::ptrdiff_t no_whole_shift = std::numeric_limits<std::ptrdiff_t>::min();
std::ptrdiff_t whole_shift(double offset) {
    const double nearest = std::round(offset);
    return std::abs(offset - nearest) < 1e-6 ? static_cast<std::ptrdiff_t>(nearest) : no_whole_shift;
}

/// The profile of the residual over the delay: min over theta of ||F_log(t + tau) - Phi theta||^2 on step 1's rows,
/// from the normal equations of Phi (fixed) and one pass over the rows per tau.
class DelayProfile {
public:
    static constexpr Eigen::Index max_parameters = 8;
    using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, max_parameters, 1>;

    /// On rows [first, last) of the regressor's rows.
    DelayProfile(const Derivatives& d, const RowRegressors& regressors, std::size_t first, std::size_t last)
        : d_(d), regressors_(regressors), first_(first), rows_(regressors.support->rows().subspan(first, last - first)),
          runs_(row_runs(d, rows_)) {
        const auto p = static_cast<Eigen::Index>(regressors.parameters());
        if (p > max_parameters) return;
        Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(p, p);
        Eigen::VectorXd phi(p);
        for (std::size_t i = first; i < last; ++i) {
            regressors.row(i, phi.data());
            add_outer_product_lower(gram, phi.data());
        }
        gram = gram.selfadjointView<Eigen::Lower>();
        solver_.compute(gram);
        valid_ = solver_.info() == Eigen::Success;
    }
    [[nodiscard]] bool valid() const { return valid_; }

    /// The profile at several delays (at most max_delays) in one pass over the rows: each row's regressors read once
    /// for all of them, each delay's sums formed in the same order as on its own.
    static constexpr std::size_t max_delays = 24;
    void residuals(std::span<const double> delays, std::span<double> out) const {
        switch (regressors_.parameters()) {
            case 1: return residuals_of<1>(delays, out);
            case 2: return residuals_of<2>(delays, out);
            case 3: return residuals_of<3>(delays, out);
            case 4: return residuals_of<4>(delays, out);
            case 5: return residuals_of<5>(delays, out);
            case 6: return residuals_of<6>(delays, out);
            case 7: return residuals_of<7>(delays, out);
            default: return residuals_of<max_parameters>(delays, out);  // valid() with at most max_parameters
        }
    }

private:
    /// residuals() with the parameters' count known to the compiler: the sums of each row unrolled.
    template <int P>
    void residuals_of(std::span<const double> delays, std::span<double> out) const {
        const std::size_t m = delays.size();
        std::array<std::array<double, P>, max_delays> cross{};
        std::array<double, max_delays> squares{}, offset{};
        std::array<std::ptrdiff_t, max_delays> whole{};  // the shift in samples where it is one, else no_whole_shift
        std::array<double, P> phi{};
        for (const RowRun& run : runs_) {
            for (std::size_t j = 0; j < m; ++j) {
                offset[j] = delays[j] / run.step;  // in samples, for the stretch
                whole[j] = whole_shift(offset[j]);
            }
            const auto first = static_cast<std::ptrdiff_t>(run.begin), last = static_cast<std::ptrdiff_t>(run.end) - 1;
            for (std::size_t i = run.first; i < run.last; ++i) {
                const std::size_t k = rows_[i];
                regressors_.row(first_ + i, phi.data());
                for (std::size_t j = 0; j < m; ++j) {
                    const double y =
                        whole[j] != no_whole_shift
                            ? d_.force[static_cast<std::size_t>(
                                  std::clamp(static_cast<std::ptrdiff_t>(k) + whole[j], first, last))]
                            : force_at(d_.force, static_cast<double>(k) + offset[j], run.begin, run.end);
                    for (int c = 0; c < P; ++c) cross[j][c] += phi[c] * y;
                    squares[j] += y * y;
                }
            }
        }
        for (std::size_t j = 0; j < m; ++j) {
            const Vector sums = Eigen::Map<const Vector>(cross[j].data(), P);
            out[j] = squares[j] - sums.dot(solver_.solve(Eigen::VectorXd(sums)));
        }
    }

    const Derivatives& d_;
    const RowRegressors& regressors_;
    std::size_t first_;
    std::span<const SampleIndex> rows_;
    std::vector<RowRun> runs_;
    Eigen::LDLT<Eigen::MatrixXd> solver_;
    bool valid_{false};
};

/// The profile at whole-sample shifts m * sample_time, evaluated on every core (independent passes over the rows).
std::vector<double> profile_at(const DelayProfile& profile, const std::vector<long>& shifts, double sample_time) {
    std::vector<double> values(shifts.size());
    std::vector<double> delays(shifts.size());
    for (std::size_t i = 0; i < shifts.size(); ++i) delays[i] = static_cast<double>(shifts[i]) * sample_time;
    const std::size_t cores = std::min<std::size_t>(std::max(1u, std::thread::hardware_concurrency()), 4);
    // batches of delays, one pass over the rows each, as many batches as cores at least
    const std::size_t batch = std::clamp<std::size_t>((shifts.size() + cores - 1) / cores, 1, DelayProfile::max_delays);
    const std::size_t batches = (shifts.size() + batch - 1) / batch;
    std::atomic<std::size_t> next{0};
    const auto work = [&] {
        for (std::size_t b = next++; b < batches; b = next++) {
            const std::size_t from = b * batch, count = std::min(batch, shifts.size() - from);
            profile.residuals(std::span<const double>(delays).subspan(from, count),
                              std::span<double>(values).subspan(from, count));
        }
    };
    std::vector<std::thread> helpers(std::min(cores, batches) - 1);
    for (auto& helper : helpers) helper = std::thread(work);
    work();
    for (auto& helper : helpers) helper.join();
    return values;
}

/// The shift of `shifts` with the smallest profile (the first of equals).
long best_shift(const DelayProfile& profile, const std::vector<long>& shifts, double sample_time) {
    const std::vector<double> values = profile_at(profile, shifts, sample_time);
    return shifts[static_cast<std::size_t>(std::min_element(values.begin(), values.end()) - values.begin())];
}

/// The delay minimising the profile within +-limit. Searched on whole samples only: a shift by a fraction of a sample
/// interpolates the force, which smooths it, and the smoothing alone lowers the residual (by 0.06 % at half a sample on
/// the benchmark trace); on a profile the data leave nearly flat a search over fractional shifts finds that ripple's
/// minimum, not the delay (4.5 ms on a trace built with 0.5). The best whole sample (on a grid of at most about 40
/// points, then its neighbours) is refined by the parabola through it and its two neighbours, whose fractions are
/// equal.
double minimise_profile(const DelayProfile& profile, double limit, double sample_time) {
    const auto reach = static_cast<long>(std::floor(limit / sample_time + 1e-9));
    const long stride = std::max(1L, reach / 20);
    std::vector<long> shifts;
    for (long m = -(reach / stride) * stride; m <= reach; m += stride) shifts.push_back(m);
    long best = best_shift(profile, shifts, sample_time);
    if (stride > 1) {
        shifts.clear();
        for (long m = best - stride + 1; m < best + stride; ++m) shifts.push_back(m);
        best = best_shift(profile, shifts, sample_time);
    }
    const std::vector<double> around = profile_at(profile, {best - 1, best, best + 1}, sample_time);
    const double curvature = around[0] - 2.0 * around[1] + around[2];
    const double vertex = curvature > 0.0 ? std::clamp(0.5 * (around[0] - around[2]) / curvature, -1.0, 1.0) : 0.0;
    return (static_cast<double>(best) + vertex) * sample_time;
}

/// The filtered force read `delay` later (shift_drive_force) at the rows.
std::vector<double> shifted_force_at_rows(const Derivatives& d, std::span<const SampleIndex> rows, double delay) {
    std::vector<double> out(rows.size());
    for (const RowRun& run : row_runs(d, rows)) {
        const double offset = delay / run.step;  // in samples
        for (std::size_t i = run.first; i < run.last; ++i) {
            const std::size_t k = rows[i];
            // a stretch under 4 samples is not shifted (shift_drive_force)
            out[i] = run.end - run.begin < 4 ? d.force[k]
                                             : force_at(d.force, static_cast<double>(k) + offset, run.begin, run.end);
        }
    }
    return out;
}

/// -d(Phi theta)/dt at the rows, of the model fitted to `output` on them (the linearised delay's column), or empty
/// where it has no fit.
std::vector<double> negated_model_derivative(const RowRegressors& regressors, std::span<const double> output,
                                             std::size_t block) {
    const LeastSquaresResult base = fit_rows(regressors, {}, output, block);
    if (base.rank_deficient) return {};
    const RowSupport& support = *regressors.support;
    std::vector<double> column(support.size(), 0.0);
    for (std::size_t c = 0; c < regressors.values.size(); ++c) {
        const double theta = base.estimate(static_cast<Eigen::Index>(c));
        for (std::size_t i = 0; i < support.size(); ++i) column[i] -= theta * regressors.slope(c, i);
    }
    return column;
}

/// What rows [first, last) tell of a shift along `column` (one value per row) beyond the regressor's own columns:
/// the Schur complement c'c - c'Phi (Phi'Phi)^-1 Phi'c of the Gram matrix of [Phi, c] (the delay's information up to
/// the noise variance).
double delay_information(const RowRegressors& regressors, std::span<const double> column, std::size_t first,
                         std::size_t last) {
    const auto p = static_cast<Eigen::Index>(regressors.parameters());
    Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(p + 1, p + 1);
    Eigen::VectorXd phi(p + 1);
    for (std::size_t i = first; i < last; ++i) {
        regressors.row(i, phi.data());
        phi(p) = column[i];
        add_outer_product_lower(gram, phi.data());
    }
    gram = gram.selfadjointView<Eigen::Lower>();
    const Eigen::LDLT<Eigen::MatrixXd> solver(gram.topLeftCorner(p, p));
    if (solver.info() != Eigen::Success) return 0.0;
    const Eigen::VectorXd cross = gram.col(p).head(p);
    return std::max(0.0, gram(p, p) - cross.dot(solver.solve(cross)));
}

/// The delay's standard error at the (aligned) force `output` (one value per row): the Gauss-Newton linearisation
/// F_log = Phi theta - tau d(Phi theta)/dt, with the model's own derivative (from the position, not the noisy force:
/// no attenuation), and standard errors that allow for correlated residuals. Its estimate is the residual delay
/// (about 0 at the optimum).
DelayFit linearised_delay(const RowRegressors& regressors, std::span<const double> output, std::size_t block) {
    DelayFit out;
    const std::vector<double> column = negated_model_derivative(regressors, output, block);
    if (column.empty()) return out;
    const LeastSquaresResult fit = fit_rows(regressors, column, output, block);
    if (fit.rank_deficient) return out;
    const auto last = fit.estimate.size() - 1;
    out.delay = fit.estimate(last);
    out.standard_error = fit.standard_error(last);
    const LeastSquaresResult plain = fit_rows(regressors, column, output, 1);
    out.plain_standard_error = plain.rank_deficient ? 0.0 : plain.standard_error(last);
    for (Eigen::Index j = 0; j < last; ++j) {
        const double scale = std::sqrt(fit.covariance(last, last) * fit.covariance(j, j));
        if (scale > 0.0) out.largest_correlation = std::max(out.largest_correlation, std::abs(fit.covariance(last, j)) / scale);
    }
    // and with all of them at once (the multiple correlation, 1 - 1/(C_tt (C^-1)_tt)): on a sinusoidal motion a shift
    // is a change of M and B together, M x''(t + tau) + B x'(t + tau) = (M + B tau) x'' + (B - M w^2 tau) x', while
    // its correlation with each alone stays moderate
    const Eigen::LDLT<Eigen::MatrixXd> covariance(fit.covariance);
    if (covariance.info() == Eigen::Success) {
        const Eigen::VectorXd unit = Eigen::VectorXd::Unit(fit.covariance.rows(), last);
        const double information = unit.dot(covariance.solve(unit));
        const double shared = 1.0 - 1.0 / (fit.covariance(last, last) * information);
        if (std::isfinite(shared)) out.largest_correlation = std::max(out.largest_correlation, std::sqrt(std::max(0.0, shared)));
    }
    out.valid = std::isfinite(out.delay) && std::isfinite(out.standard_error) && out.standard_error > 0.0;
    return out;
}

/// The delay's standard error from the profile's own curvature at its minimum where that is the wider: the
/// linearisation's column is the model's time derivative, which on a quantised position carries noise of its own (a
/// third derivative of the position) that looks like information; on a motion where a shift is a change of the
/// parameters (one sinusoid: M x''(t + tau) + B x'(t + tau) is (M + B tau) x'' + (B - M w^2 tau) x') the profile is
/// flat however sharp the column makes it look. Correlated residuals widen both alike. A profile that does not curve
/// up at all leaves the delay as wide as the search.
void widen_to_profile(const DelayProfile& profile, double delay, double sample_time, double search, std::size_t rows,
                      std::size_t parameters, DelayFit& fit) {
    if (!fit.valid || rows <= parameters) return;
    // a whole sample either side: the interpolated force's smoothing changes with the shift's fraction of a sample
    // (a ripple of one sample's period on the profile), which points a whole sample apart share
    const double h = sample_time;
    const std::array<double, 3> delays{delay - h, delay, delay + h};
    std::array<double, 3> values{};
    profile.residuals(delays, values);  // one pass for the three
    const double at = values[1];
    const double curvature = (values[2] - 2.0 * at + values[0]) / (h * h);
    const double variance = at / static_cast<double>(rows - parameters);
    const double inflation =
        fit.plain_standard_error > 0.0 ? std::max(1.0, fit.standard_error / fit.plain_standard_error) : 1.0;
    const double from_profile = curvature > 0.0 ? std::sqrt(2.0 * variance / curvature) * inflation : search;
    if (std::isfinite(from_profile)) fit.standard_error = std::max(fit.standard_error, from_profile);
}

/// Student's t quantile with `dof` degrees of freedom at the two-sided `level`, from the normal one by the
/// Cornish-Fisher expansion (Abramowitz & Stegun 26.7.5; within 0.1 % of the exact value from 10 degrees of freedom).
double student_quantile(double level, double dof) {
    const double z = normal_quantile(level), z2 = z * z;
    const double g1 = (z2 + 1.0) * z / 4.0;
    const double g2 = ((5.0 * z2 + 16.0) * z2 + 3.0) * z / 96.0;
    const double g3 = (((3.0 * z2 + 19.0) * z2 + 17.0) * z2 - 15.0) * z / 384.0;
    const double g4 = ((((79.0 * z2 + 776.0) * z2 + 1482.0) * z2 - 1920.0) * z2 - 945.0) * z / 92160.0;
    return z + g1 / dof + g2 / (dof * dof) + g3 / (dof * dof * dof) + g4 / (dof * dof * dof * dof);
}

/// The delay's standard error from its scatter over consecutive blocks of the rows: each block's own profile minimum,
/// weighted by what the block tells of a shift (delay_information: a block of constant-speed passes tells nothing
/// and its minimum lies anywhere), SE^2 = sum w_b (tau_b - tau_w)^2 / ((B - 1) sum w_b) (batch means), scaled by t/z
/// for the blocks' few degrees of freedom so that the normal test at `level` is the t test; 0 where the rows are too
/// few for blocks. Where a shift is nearly a change of the parameters, the profile's minimum on the whole trace sits
/// wherever the noise and the model's small misfits (a quantised position's third derivative, the last of a Stribeck
/// rise) put it, and its local curvature measures their ripple, not the information: on sinusoidal strokes of one
/// frequency built with 0.5 ms it lay at 4.1 ms with a curvature that said +-0.3 ms. The blocks' minima scatter by
/// milliseconds there, and agree to their own error where the data carry the delay.
double block_standard_error(const Derivatives& d, const RowRegressors& largest, const ModelSelectionOptions& options,
                            std::size_t block) {
    const std::size_t n = largest.support->size();
    const double search = 2.0 * options.max_delay_s, level = options.test_level;
    const std::size_t least = 20 * largest.parameters();
    std::size_t blocks = 16;
    while (blocks >= 8 && n / blocks < least) blocks /= 2;
    if (blocks < 8) return 0.0;
    const std::vector<double> column =
        negated_model_derivative(largest, at_rows(d.force, largest.support->rows()), block);
    if (column.empty()) return 0.0;
    std::vector<double> minima, weights;
    for (std::size_t b = 0; b < blocks; ++b) {
        const std::size_t first = b * n / blocks, last = (b + 1) * n / blocks;
        const DelayProfile profile(d, largest, first, last);
        const double information = delay_information(largest, column, first, last);
        if (!profile.valid() || !(information > 0.0)) continue;
        minima.push_back(minimise_profile(profile, search, d.sample_time_s));
        weights.push_back(information);
    }
    if (minima.size() < 8) return 0.0;
    double total = 0.0, mean = 0.0, squares = 0.0;
    for (std::size_t b = 0; b < minima.size(); ++b) total += weights[b];
    for (std::size_t b = 0; b < minima.size(); ++b) mean += weights[b] * minima[b] / total;
    for (std::size_t b = 0; b < minima.size(); ++b) squares += weights[b] * (minima[b] - mean) * (minima[b] - mean);
    const double count = static_cast<double>(minima.size());
    const double spread = std::sqrt(squares / ((count - 1.0) * total));
    return spread * student_quantile(level, count - 1.0) / normal_quantile(level);
}

/// The delay: the profile's minimum in the largest model the data can take, tested against its standard error,
/// applied where significant; or the known one applied.
void apply_known_delay(Derivatives& d, double delay_s, ModelChoice& choice) {
    shift_drive_force(d, delay_s);
    choice.delay_s = delay_s;
    choice.delay_applied = true;
    choice.delay_source = "given";
}

void choose_delay(Derivatives& d, bool one_way, const ModelSelectionOptions& options, double threshold,
                  std::size_t block, RowColumns& columns, ModelChoice& choice) {
    if (options.known_delay_s) return apply_known_delay(d, *options.known_delay_s, choice);
    if (options.delay == ModelSelectionOptions::Delay::none) return;
    const bool apply = options.automatic || options.delay == ModelSelectionOptions::Delay::estimate;
    const RowRegressors largest =
        columns.regressors(one_way ? FrictionModelKind::symmetric : FrictionModelKind::asymmetric, false);
    const std::size_t rows = largest.support->size();
    ModelCandidate candidate;
    candidate.name = "delay";
    candidate.tested = "tau";
    candidate.threshold = threshold;
    const DelayProfile profile(d, largest, 0, rows);
    // the search reaches a little beyond the plausible range, so that a clock offset shows as one
    const double delay = profile.valid() ? minimise_profile(profile, 2.0 * options.max_delay_s, d.sample_time_s) : 0.0;
    DelayFit fit;
    if (profile.valid()) {
        fit = linearised_delay(largest, shifted_force_at_rows(d, largest.support->rows(), delay), block);
        widen_to_profile(profile, delay, d.sample_time_s, 2.0 * options.max_delay_s, rows, largest.parameters(), fit);
    }
    if (fit.valid) fit.standard_error = std::max(fit.standard_error, block_standard_error(d, largest, options, block));
    if (!fit.valid) {
        candidate.verdict = "not estimable from these samples";
        choice.candidates.push_back(candidate);
        return;
    }
    candidate.estimate = delay;
    candidate.standard_error = fit.standard_error;
    candidate.statistic = std::abs(delay) / fit.standard_error;
    const bool significant = *candidate.statistic > threshold;
    choice.delay_uncertain = !significant;
    const bool plausible = std::abs(delay) <= options.max_delay_s;
    choice.delay_s = delay;
    choice.delay_standard_error = fit.standard_error;
    if (significant && fit.largest_correlation > options.collinearity_limit) {
        // on a motion whose jerk is a combination of its speed and a constant (one smooth stroke), a shift of the
        // force in time is a change of B and F_C: the data cannot say which
        candidate.verdict = fmt::format(
            "not separable from the model's parameters on these samples (correlated {:.4f} with them)",
            fit.largest_correlation);
        choice.findings.push_back(fmt::format(
            "the drive signal's timing cannot be told from the friction on these samples (a shift of {:.3g} ms would "
            "fit as well as the model's parameters, correlated {:.4f}): no delay applied; a test with constant-speed "
            "passes at several feedrates separates them (--delay TIME applies a known one)",
            delay * 1e3, fit.largest_correlation));
    } else if (significant && plausible && apply) {
        shift_drive_force(d, delay);
        choice.delay_applied = true;
        choice.delay_source = "estimated";
        candidate.taken = true;
        candidate.verdict = "taken: the drive signal is read this much later";
    } else if (significant && !plausible) {
        candidate.verdict = fmt::format("{:.3g} ms is beyond +-{:g} ms: not a timing offset within the servo cycle",
                                        delay * 1e3, options.max_delay_s * 1e3);
        choice.findings.push_back(fmt::format(
            "the drive signal and the position look {:.3g} ms apart (+/- {:.2g} ms), more than a servo cycle: two "
            "recorders' clocks? (--join FILE@SHIFT)",
            delay * 1e3, fit.standard_error * 1e3));
    } else if (significant) {
        candidate.verdict = "the forced model leaves it out";
        choice.findings.push_back(fmt::format(
            "the data show the drive signal {:.3g} ms {} the position (+/- {:.2g} ms, {:.1f} standard errors), which "
            "the forced model leaves out (--delay auto estimates it, --delay {:.3g}ms applies it)",
            std::abs(delay) * 1e3, delay > 0.0 ? "behind" : "ahead of", fit.standard_error * 1e3,
            *candidate.statistic, delay * 1e3));
    } else {
        candidate.verdict = "not significant";
    }
    choice.candidates.push_back(candidate);
}

/// Tukey's biweight of a residual scaled by its limit.
double biweight(double residual, double limit) {
    const double u = residual / limit;
    return std::abs(u) >= 1.0 ? 0.0 : (1.0 - u * u) * (1.0 - u * u);
}

/// The median of |x| times 1.4826: a robust standard deviation.
double robust_deviation(std::span<const double> values) {
    return values.empty() ? 0.0 : 1.4826 * absolute_percentile(values, 0.5);
}

/// Step 1's model fitted robustly (iteratively reweighted least squares with Tukey's biweight, from the least-squares
/// fit, in the residuals' robust scale): what the samples that follow the model say, whatever a minority of them
/// carries besides.
Eigen::VectorXd robust_fit(const RowRegressors& regressors, std::span<const double> output, double tukey_constant) {
    const auto p = static_cast<Eigen::Index>(regressors.parameters());
    const std::size_t n = regressors.support->size();
    Eigen::VectorXd theta = Eigen::VectorXd::Zero(p), phi(p);
    std::vector<double> weights(n, 1.0), residuals(n);
    for (int iteration = 0; iteration < 12; ++iteration) {
        Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(p, p);
        Eigen::VectorXd cross = Eigen::VectorXd::Zero(p);
        for (std::size_t i = 0; i < n; ++i) {
            if (weights[i] == 0.0) continue;
            regressors.row(i, phi.data());
            const double y = output[i];
            add_outer_product_lower(gram, phi.data(), weights[i]);
            add_scaled(cross.data(), phi.data(), weights[i] * y, p);
        }
        gram = gram.selfadjointView<Eigen::Lower>();
        const Eigen::LDLT<Eigen::MatrixXd> solver(gram);
        if (solver.info() != Eigen::Success) break;
        const Eigen::VectorXd next = solver.solve(cross);
        const bool settled = iteration > 0 && (next - theta).cwiseAbs().maxCoeff() <=
                                                  1e-6 * std::max(1.0, next.cwiseAbs().maxCoeff());
        theta = next;
        if (settled) break;
        for (std::size_t i = 0; i < n; ++i) {
            regressors.row(i, phi.data());
            residuals[i] = output[i] - phi.dot(theta);
        }
        const double scale = robust_deviation(residuals);
        if (!(scale > 0.0)) break;
        for (std::size_t i = 0; i < n; ++i) weights[i] = biweight(residuals[i], tukey_constant * scale);
    }
    return theta;
}

/// A stretch of samples whose residual stays far on one side.
struct Burst {
    double start_s{0.0}, end_s{0.0};
    double peak{0.0};  ///< the largest residual in it [N]
};

/// Runs of consecutive samples (indices `index`, ascending; a gap of more than `gap` samples ends a run) whose
/// residual lies beyond `limit` on one side, at least `minimum` samples long.
void find_bursts(const Derivatives& d, std::span<const SampleIndex> index, const std::vector<double>& residual,
                 double limit, std::size_t minimum, std::size_t gap, std::vector<Burst>& out) {
    std::size_t run = 0;
    int side = 0;
    Burst current;
    std::size_t last = 0;
    const auto close = [&] {
        if (run >= minimum) out.push_back(current);
        run = 0;
        side = 0;
    };
    for (std::size_t i = 0; i < index.size(); ++i) {
        const std::size_t k = index[i];
        const int s = residual[i] > limit ? 1 : residual[i] < -limit ? -1 : 0;
        if (run > 0 && (s != side || k > last + gap)) close();
        if (s == 0) continue;
        if (run == 0) {
            current = Burst{d.time[k], d.time[k], residual[i]};
            side = s;
        }
        ++run;
        last = k;
        current.end_s = d.time[k];
        if (std::abs(residual[i]) > std::abs(current.peak)) current.peak = residual[i];
    }
    close();
}

/// The quasi-static samples of every steady pass (at least 20 of them) and their force less M x'' against the pass's
/// median: each pass's friction is one level, so a burst shows against it.
void steady_pass_levels(const Derivatives& d, const Selection& selection, double mass, SampleIndices& slow_index,
                        std::vector<double>& slow) {
    const auto slow_member = [&](std::size_t k) { return selection.steady(k) && !selection.near_rest(k); };
    std::size_t slow_count = 0;  // counted first: the columns below are allocated once, at their size
    for (const auto& pass : selection.stick_slip.passes) {
        if (pass.stick_slip) continue;
        std::size_t members = 0;
        for (std::size_t k = pass.first; k < pass.last && k < d.size(); ++k) members += slow_member(k) ? 1 : 0;
        if (members >= 20) slow_count += members;
    }
    slow_index.reserve(slow_count);
    slow.reserve(slow_count);
    for (const auto& pass : selection.stick_slip.passes) {
        if (pass.stick_slip) continue;
        std::vector<double> level;
        SampleIndices members;
        for (std::size_t k = pass.first; k < pass.last && k < d.size(); ++k) {
            if (!slow_member(k)) continue;
            members.push_back(static_cast<SampleIndex>(k));
            level.push_back(d.force[k] - mass * d.acceleration[k]);
        }
        if (members.size() < 20) continue;
        std::vector<double> copy = level;
        const double median = percentile_in_place(copy, 0.5);
        for (std::size_t m = 0; m < members.size(); ++m) {
            slow_index.push_back(members[m]);
            slow.push_back(level[m] - median);
        }
    }
}

/// Bursts of force the model does not explain: on step 1's samples against a robust fit of the largest model; on
/// the quasi-static samples of every steady pass (whose friction is one level) against the pass's median force less
/// M x''. Said in `choice.process_forces` when there is one.
void detect_process_forces(const Derivatives& d, const Selection& selection, bool one_way,
                           const ModelSelectionOptions& options, RowColumns& columns, ModelChoice& choice) {
    const auto& rows = selection.step1;
    RowRegressors largest =
        columns.regressors(one_way ? FrictionModelKind::symmetric : FrictionModelKind::asymmetric, false);
    // with the timing term: a drive signal out of step with the position leaves one-sided stretches wherever the
    // force changes, which are not a process force (the column is not a friction term: Term::offset marks it)
    {
        const RowSupport& support = *largest.support;
        std::vector<double> timing(support.size() == 0 ? 0 : support.at(support.size() - 1) + 1, 0.0);
        for (std::size_t i = 0; i < support.size(); ++i) timing[support.at(i)] = support.negated_force_slope(i);
        largest.values.push_back({std::make_shared<const std::vector<double>>(std::move(timing)), {}});
        largest.columns.push_back(RegressorColumn{Term::offset, Direction::both});
    }
    // the force at step 1's rows becomes the fit's residual in place, and is released before the steady passes'
    // levels are formed: one column of step 1's length at a time besides the robust scale's copy (identify's peak)
    std::vector<double> fast = at_rows(d.force, rows);
    const Eigen::VectorXd theta = robust_fit(largest, fast, options.tukey_constant);
    const double mass = theta(0);
    Eigen::VectorXd phi(static_cast<Eigen::Index>(largest.parameters()));
    for (std::size_t i = 0; i < rows.size(); ++i) {
        largest.row(i, phi.data());
        fast[i] -= phi.dot(theta);
    }
    const std::size_t correlation = std::max<std::size_t>(1, d.correlation_samples);
    const auto minimum = static_cast<std::size_t>(std::max(
        options.burst_correlation_lengths * static_cast<double>(correlation), options.burst_min_s / d.sample_time_s));
    // a process force is a material fraction of the friction it adds to: on a trace with almost no noise, the
    // model's own small misfit in the transients (a current loop's lag) stands far out of the scatter
    double coulomb = 0.0;
    int sign_columns = 0;
    for (std::size_t c = 0; c < largest.columns.size(); ++c) {
        if (largest.columns[c].term != Term::coulomb) continue;
        coulomb += std::abs(theta(static_cast<Eigen::Index>(c)));
        ++sign_columns;
    }
    const double floor = sign_columns > 0 ? options.burst_friction_fraction * coulomb / sign_columns : 0.0;
    std::vector<Burst> bursts;
    const double fast_scale = robust_deviation(fast);
    if (fast_scale > 0.0)
        find_bursts(d, rows, fast, std::max(options.burst_deviations * fast_scale, floor), minimum, correlation,
                    bursts);
    std::vector<double>().swap(fast);
    SampleIndices slow_index;
    std::vector<double> slow;
    steady_pass_levels(d, selection, mass, slow_index, slow);
    const double slow_scale = robust_deviation(slow);
    if (slow_scale > 0.0)
        find_bursts(d, slow_index, slow, std::max(options.burst_deviations * slow_scale, floor), minimum, correlation,
                    bursts);
    if (bursts.empty()) return;
    double duration = 0.0, peak = 0.0;
    for (const auto& b : bursts) {
        duration += b.end_s - b.start_s;
        if (std::abs(b.peak) > std::abs(peak)) peak = b.peak;
    }
    const ParameterNaming naming{d.rotary};
    choice.process_forces = fmt::format(
        "{}: process forces: {} burst{} ({:.3g} s in all, the first at {:.4g} s) in which the drive force departs from "
        "the axis's model by up to {:.4g} {} ({:.1f} times the fit's robust scatter) for {:.3g} s and more at a time: "
        "cutting, or a load the model has no term for. identify needs a test run without them; for production traces "
        "use feedid scan, which identifies window by window with robust weights",
        d.source, bursts.size(), bursts.size() == 1 ? "" : "s", duration, bursts.front().start_s, peak,
        naming.force_unit(), std::abs(peak) / std::max(fast_scale, 1e-300),
        static_cast<double>(minimum) * d.sample_time_s);
}

/// On a move in one direction: a constant force is Coulomb friction as far as the data go. Said, and F_C, F_B and F_0
/// null unless nothing constant remains (tared, or zero force at rest).
void judge_one_way(const Derivatives& d, const Selection& selection, bool offset, bool drive_tared,
                   const std::optional<RestLevel>& rest_level, const ModelSelectionOptions& options,
                   ModelChoice& choice) {
    const ParameterNaming naming{d.rotary};
    choice.rest = rest_level;
    const auto [forward, reverse] = direction_counts(d, selection.step1);
    choice.findings.push_back(fmt::format(
        "the axis moved {} only: the friction reported is that direction's; the symmetric model takes the other "
        "direction's to be the same, which these data cannot check",
        forward >= reverse ? "forward" : "in reverse"));
    const std::string why = fmt::format(
        "the axis moves in one direction only (step 1's samples: {} forward, {} reverse): sgn(x') is constant, so a "
        "constant force (a weight, a sensor's zero) and Coulomb friction are one and the same in the data",
        direction_counts(d, selection.step1).first, direction_counts(d, selection.step1).second);
    if (offset) {
        choice.aliased_friction = why + "; F_C, F_B and F_0 left null (a move in both directions separates them)";
        return;
    }
    if (drive_tared) {
        choice.findings.push_back(why + "; F_C and F_B take the drive signal's tared zero as the only constant");
        return;
    }
    const double scale = typical_force(d, selection.step1);
    if (choice.rest) {
        const RestLevel& rest = *choice.rest;
        const bool zero = std::abs(rest.mean) <= options.rest_zero_standard_errors * rest.standard_error ||
                          std::abs(rest.mean) <= options.zero_force_fraction * scale;
        if (zero) {
            choice.findings.push_back(fmt::format(
                "{}; at rest before the move the drive force is {:.3g} +/- {:.2g} {}, so no constant force is taken",
                why, rest.mean, rest.standard_error, naming.force_unit()));
            return;
        }
        choice.aliased_friction = fmt::format(
            "{}; at rest before the move the drive force reads {:.4g} {} (a weight, or a sensor's zero: --tare "
            "current removes a zero): F_C, F_B and F_0 left null",
            why, rest.mean, naming.force_unit());
        return;
    }
    choice.aliased_friction =
        why + "; no samples at rest before the move show whether one is present: F_C, F_B and F_0 left null (--tare "
              "removes a sensor's zero; a move in both directions separates a weight)";
}

/// The integrated autocorrelation time [samples] of values at ascending sample indices `rows`, by blocking: with
/// blocks of b consecutive samples, the sum over blocks of (block sum)^2 / the sum of squares rises from 1 to 2 tau_int
/// once b is well beyond tau_int; the largest value over b (at least 50 blocks) is taken, erring long. 1 for
/// uncorrelated values (or too few).
/// `values`: anything with size() and values[i] (a vector, or values formed where they are read).
template <class Index, class Values>
double integrated_autocorrelation(std::span<const Index> rows, const Values& values) {
    double squares = 0.0;
    for (std::size_t i = 0; i < values.size(); ++i) squares += values[i] * values[i];
    if (rows.size() < 100 || !(squares > 0.0)) return 1.0;
    const std::size_t span = rows.back() - rows.front() + 1;
    double largest = 1.0;
    // blocks of b = 2^shift samples: the block of a row by a shift, not a division. The first levels from the rows,
    // all in one pass (each level's block sums in its own accumulator, in row order: the sums of a pass per level);
    // from the last of them on, each level's block sums are the sums of the level below's (one pass over fewer blocks
    // per level instead of one over every row: the same sums to rounding)
    constexpr unsigned direct_levels = 5;
    unsigned direct = 0;  // the first levels that have at least 50 blocks
    while (direct < direct_levels && span >> (direct + 1) >= 50) ++direct;
    if (direct == 0) return 0.5 * largest;
    // (block, sum of its values) at the current level; at most one block per row and per 2^direct_levels samples
    // (half a byte per sample at most)
    std::vector<std::pair<std::size_t, double>> blocks;
    std::size_t kept = 0;
    const bool keep = direct == direct_levels;
    if (keep) {
        const bool ascending = std::is_sorted(rows.begin(), rows.end());
        blocks.resize(ascending ? std::min(rows.size(), (span >> direct_levels) + 2) : rows.size());
    }
    std::array<double, direct_levels> block_sum{}, sum_of_squares{};
    std::array<std::size_t, direct_levels> current{};
    for (unsigned level = 0; level < direct_levels; ++level) current[level] = rows.front() >> (level + 1);
    for (std::size_t i = 0; i < rows.size(); ++i) {
        for (unsigned level = 0; level < direct_levels; ++level) {
            const std::size_t block = rows[i] >> (level + 1);
            if (block != current[level]) {
                sum_of_squares[level] += block_sum[level] * block_sum[level];
                if (keep && level + 1 == direct_levels) blocks[kept++] = {current[level], block_sum[level]};
                block_sum[level] = 0.0;
                current[level] = block;
            }
            block_sum[level] += values[i];
        }
    }
    for (unsigned level = 0; level < direct; ++level) {
        sum_of_squares[level] += block_sum[level] * block_sum[level];
        largest = std::max(largest, sum_of_squares[level] / squares);
    }
    if (keep) blocks[kept++] = {current[direct_levels - 1], block_sum[direct_levels - 1]};
    for (unsigned shift = direct_levels + 1; keep && span >> shift >= 50; ++shift) {
        std::size_t merged = 0;
        for (std::size_t i = 0; i < kept; ++i) {
            const std::size_t parent = blocks[i].first >> 1;
            if (merged > 0 && blocks[merged - 1].first == parent)
                blocks[merged - 1].second += blocks[i].second;
            else
                blocks[merged++] = {parent, blocks[i].second};
        }
        kept = merged;
        double squares_here = 0.0;
        for (std::size_t i = 0; i < kept; ++i) squares_here += blocks[i].second * blocks[i].second;
        largest = std::max(largest, squares_here / squares);
    }
    return 0.5 * largest;
}

/// A standard normal deviate for a chi-square statistic with `dof` degrees of freedom (Wilson-Hilferty).
double chi_square_deviate(double chi_square, double dof) {
    if (!(dof > 0.0)) return 0.0;
    const double k = 2.0 / (9.0 * dof);
    return (std::cbrt(chi_square / dof) - (1.0 - k)) / std::sqrt(k);
}

/// The mean of a group of residuals and its variance.
struct GroupMean {
    std::size_t count{0};
    double mean{0.0};
    double variance_of_mean{0.0};
};

/// A residual's group: a byte (the groupings below have at most 16 groups; a value of `groups` or more is in none),
/// so that three groupings of the checked rows hold 3 bytes per row, not 24.
using GroupIndex = std::uint8_t;

/// totals[g] += term(i) over the i in order whose group[i] == g (< groups), and counts[g] the number of them: each
/// group's total held in a register while consecutive i stay in that group (the same sums, in the same order, as adding
/// into the array at every i, without storing and reloading it at every i).
template <class Term>
void add_by_group(const std::vector<GroupIndex>& group, std::size_t groups, std::vector<double>& totals,
                  std::vector<std::size_t>& counts, Term term) {
    std::size_t open = groups, run = 0;
    double total = 0.0;
    for (std::size_t i = 0; i < group.size(); ++i) {
        const std::size_t g = group[i];
        if (g >= groups) continue;
        if (g != open) {
            if (open < groups) {
                totals[open] = total;
                counts[open] += run;
            }
            open = g;
            total = totals[g];
            run = 0;
        }
        total += term(i);
        ++run;
    }
    if (open < groups) {
        totals[open] = total;
        counts[open] += run;
    }
}

/// Means of `residual` over groups (group[i] that of rows[i]; groups or more: in none), with variances that count
/// correlated neighbours once: each group's variance over its effective number of samples, its count over twice the
/// integrated autocorrelation time of the residual's deviations from the group means (on a slow pass the residual
/// wanders together for seconds), at least one.
std::vector<GroupMean> group_means(std::span<const SampleIndex> rows, const std::vector<double>& residual,
                                   const std::vector<GroupIndex>& group, std::size_t groups) {
    std::vector<GroupMean> means(groups);
    std::vector<double> sums(groups, 0.0), squares(groups, 0.0);
    std::vector<std::size_t> counts(groups, 0), unused(groups, 0);
    add_by_group(group, groups, sums, counts, [&](std::size_t i) { return residual[i]; });
    for (std::size_t g = 0; g < groups; ++g) {
        means[g].count = counts[g];
        if (means[g].count > 0) means[g].mean = sums[g] / static_cast<double>(means[g].count);
    }
    // each residual's deviation from its group's mean (0 in none), formed where it is read, not held (a column of
    // the checked rows' length at identify's peak)
    struct Deviations {
        const std::vector<double>& residual;
        const std::vector<GroupIndex>& group;
        const std::vector<GroupMean>& means;
        std::size_t groups, n;
        [[nodiscard]] std::size_t size() const { return n; }
        double operator[](std::size_t i) const { return group[i] < groups ? residual[i] - means[group[i]].mean : 0.0; }
    };
    const Deviations deviation{residual, group, means, groups, rows.size()};
    add_by_group(group, groups, squares, unused, [&](std::size_t i) { return deviation[i] * deviation[i]; });
    const double inflation = std::max(1.0, 2.0 * integrated_autocorrelation<SampleIndex>(rows, deviation));
    for (std::size_t g = 0; g < groups; ++g) {
        const double n = static_cast<double>(means[g].count);
        if (n > 0.0) means[g].variance_of_mean = squares[g] / n / std::max(1.0, n / inflation);
    }
    return means;
}

/// One grouping of the residual: its group means and their labels.
struct Groups {
    std::vector<GroupMean> means;
    std::vector<std::string> labels;
};


FitCheck judge_groups(std::string name, Groups& groups, double typical, const ModelSelectionOptions& options,
                      double threshold) {
    FitCheck check;
    check.name = std::move(name);
    check.threshold = threshold;
    check.material_fraction = options.lack_of_fit_fraction;
    double chi_square = 0.0;
    for (std::size_t g = 0; g < groups.means.size(); ++g) {
        const GroupMean& m = groups.means[g];
        if (m.count < 20) continue;
        const double variance = m.variance_of_mean;
        if (!(variance > 0.0)) continue;
        chi_square += m.mean * m.mean / variance;
        ++check.groups;
        // the largest structure among the groups that show one
        if (std::abs(m.mean) > threshold * std::sqrt(variance) && std::abs(m.mean) > std::abs(check.largest)) {
            check.largest = m.mean;
            check.largest_standard_error = std::sqrt(variance);
            check.where = groups.labels[g];
        }
    }
    if (check.groups < 2) return check;
    check.chi_square = chi_square;
    check.statistic = std::max(0.0, chi_square_deviate(chi_square, static_cast<double>(check.groups)));
    check.relative = typical > 0.0 ? std::abs(check.largest) / typical : 0.0;
    check.passed = !(*check.statistic > threshold && check.relative > options.lack_of_fit_fraction);
    return check;
}

/// The friction at low speed by direction, beyond what a constant force explains: on the quasi-static slow samples,
/// the residual of the symmetric model with an offset, r = F - M x'' - B x' - F_C s - F_0, is the Stribeck rise,
/// +rise(|v|) forward and -rise(|v|) reverse when the rise is the same both ways. Per speed bin (log-spaced), the sum
/// of the two directions' mean residuals is tested against zero (chi-square over the bins, each mean's variance from
/// sums over blocks of correlated neighbours).
ModelCandidate low_speed_asymmetry(const Derivatives& d, const Selection& selection,
                                   const RegressorColumnCache* cache, const LeastSquaresResult& fit, double threshold) {
    ModelCandidate candidate;
    candidate.name = "per direction at low speed";
    candidate.tested = "Stribeck friction forward - reverse";
    candidate.threshold = threshold;
    const auto& rows = selection.step2;
    if (fit.rank_deficient || rows.size() < 40) {
        candidate.verdict = "too few slow samples to compare the directions";
        return candidate;
    }
    constexpr int bins = 8;
    double low = INFINITY, high = 0.0;
    for (const auto k : rows) {
        low = std::min(low, std::abs(d.velocity[k]));
        high = std::max(high, std::abs(d.velocity[k]));
    }
    low = std::max(low, 1e-12);
    const double span = std::log(std::max(high / low, 1.0 + 1e-9));
    // the symmetric model with an offset on the whole trace: the slow rows are about half of it, and its x'', x'
    // and sgn(x') columns are views of columns held anyway; the offset's column, the last, is 1 on every sample
    // unless decimating (the anti-alias filter scales it), and is then not formed (a whole column at identify's peak)
    Regressors regressors;
    regressors.columns = linear_columns(FrictionModelKind::symmetric, true);
    regressors.output = d.force;
    const bool constant_offset = d.used.decimation <= 1;
    for (const auto& column : regressors.columns) {
        if (constant_offset && column.term == Term::offset) continue;
        RegressorValues formed = regressor_values(d, column, cache);
        regressors.values.push_back(formed.values);
        if (formed.owned) regressors.owned.push_back(std::move(formed.owned));
    }
    std::vector<double> residual(rows.size());
    std::vector<GroupIndex> group(rows.size());
    Eigen::VectorXd phi(static_cast<Eigen::Index>(regressors.parameters()));
    if (constant_offset) phi(phi.size() - 1) = 1.0;  // row() fills the formed columns before it
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const std::size_t k = rows[i];
        residual[i] = regressors.row(k, phi.data()) - phi.dot(fit.estimate);
        const int b = std::clamp(static_cast<int>(bins * std::log(std::abs(d.velocity[k]) / low) / span), 0, bins - 1);
        group[i] = static_cast<GroupIndex>(2 * b + (d.velocity[k] > 0.0 ? 0 : 1));
    }
    const std::vector<GroupMean> cells = group_means(rows, residual, group, 2 * bins);
    double chi_square = 0.0;
    int compared = 0;
    double largest = 0.0, largest_se = 0.0;
    for (std::size_t b = 0; b < bins; ++b) {
        const GroupMean& forward = cells[2 * b];
        const GroupMean& reverse = cells[2 * b + 1];
        if (forward.count < 10 || reverse.count < 10) continue;
        const double difference = forward.mean + reverse.mean;
        const double v = forward.variance_of_mean + reverse.variance_of_mean;
        if (!(v > 0.0)) continue;
        chi_square += difference * difference / v;
        ++compared;
        if (std::abs(difference) > std::abs(largest)) {
            largest = difference;
            largest_se = std::sqrt(v);
        }
    }
    if (compared == 0) {
        candidate.verdict = "no speed at which both directions have slow samples";
        return candidate;
    }
    candidate.estimate = largest;
    candidate.standard_error = largest_se;
    candidate.statistic = std::max(0.0, chi_square_deviate(chi_square, compared));
    candidate.taken = *candidate.statistic > threshold;
    return candidate;
}

/// A fit's estimates as a vector; empty when the fit could not separate them.
std::vector<double> estimates_of(const LeastSquaresResult& fit) {
    if (fit.rank_deficient) return {};
    return {fit.estimate.data(), fit.estimate.data() + fit.estimate.size()};
}

/// Symmetric within symmetric with an offset within per direction, tested on the (aligned) force.
void choose_friction_model(const Derivatives& d, const Selection& selection, FrictionModelKind forced_model,
                           bool forced_offset, const ModelSelectionOptions& options, double threshold,
                           std::size_t block, RowColumns& columns, const RegressorColumnCache* cache,
                           ModelChoice& choice) {
    const ParameterNaming naming{d.rotary};
    const std::vector<double> force = at_rows(d.force, selection.step1);
    const RowRegressors with_offset = columns.regressors(FrictionModelKind::symmetric, true);
    const LeastSquaresResult offset_fit = fit_rows(with_offset, {}, force, block);
    Eigen::VectorXd c_offset = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(with_offset.parameters()));
    c_offset(column_index(with_offset.columns, Term::offset, Direction::both)) = 1.0;
    ModelCandidate offset = test_combination("offset", "F_0", offset_fit, c_offset, threshold);

    const RowRegressors per_direction = columns.regressors(FrictionModelKind::asymmetric, false);
    const LeastSquaresResult direction_fit = fit_rows(per_direction, {}, force, block);
    Eigen::VectorXd c_viscous = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(per_direction.parameters()));
    c_viscous(column_index(per_direction.columns, Term::viscous, Direction::forward)) = 1.0;
    c_viscous(column_index(per_direction.columns, Term::viscous, Direction::reverse)) = -1.0;
    ModelCandidate asymmetric = test_combination("per direction", "B+ - B-", direction_fit, c_viscous, threshold);
    ModelCandidate slow = low_speed_asymmetry(d, selection, cache, offset_fit, threshold);

    const auto unit = [&](Term term) { return std::string(naming.unit(term)); };
    const auto describe = [&](const ModelCandidate& c, Term term) {
        return c.estimate ? fmt::format("{} = {:.4g} +/- {:.2g} {} ({:.1f} standard errors)", c.tested, *c.estimate,
                                        *c.standard_error, unit(term), *c.statistic)
                          : c.tested + " not estimable";
    };
    if (options.automatic) {
        const bool per_direction = asymmetric.taken || slow.taken;
        choice.model = per_direction ? FrictionModelKind::asymmetric : FrictionModelKind::symmetric;
        choice.offset = !per_direction && offset.taken;
        // the chosen model's estimates on these samples, which a selection under the chosen model may change
        if (per_direction || choice.offset)
            choice.first_selection_estimate = estimates_of(per_direction ? direction_fit : offset_fit);
        asymmetric.verdict = asymmetric.taken ? "taken: the viscous friction differs by direction"
                                              : "not needed: the viscous friction is the same both ways";
        slow.verdict = slow.taken ? "taken: the friction at low speed differs by direction beyond a constant force"
                       : slow.statistic ? "not needed: the friction at low speed is the same both ways"
                                        : slow.verdict;
        offset.verdict = per_direction ? "carried by the per-direction Coulomb friction"
                         : offset.taken ? "taken: a constant force (a weight, a sensor's zero) is present"
                                        : "not needed";
        if (choice.offset) {
            choice.findings.push_back(fmt::format(
                "model: an offset was added ({}): a weight or a sensor's zero; F_0 also holds half of any difference "
                "of Coulomb friction between the directions, which a constant force cannot be told from",
                describe(offset, Term::offset)));
        }
        if (per_direction && offset.taken) {
            choice.findings.push_back(fmt::format(
                "model: friction per direction; the data also show a constant force ({}), which the per-direction "
                "Coulomb and breakaway friction carry: F_C+ holds +F_0, F_C- holds -F_0",
                describe(offset, Term::offset)));
        }
    } else {
        choice.model = forced_model;
        choice.offset = forced_offset;
        offset.verdict = asymmetric.verdict = slow.verdict = "forced";
        if (!forced_offset && forced_model == FrictionModelKind::symmetric && offset.taken) {
            choice.findings.push_back(fmt::format(
                "the data reject the forced model: they show a constant force ({}); --offset, or leave the model to "
                "identify",
                describe(offset, Term::offset)));
        }
        if (forced_model == FrictionModelKind::symmetric && slow.taken && !asymmetric.taken) {
            choice.findings.push_back(fmt::format(
                "the data reject the forced model: the friction at low speed differs by direction beyond a constant "
                "force ({:.1f} standard deviates); --model asymmetric, or leave the model to identify",
                *slow.statistic));
        }
        if (forced_model == FrictionModelKind::symmetric && asymmetric.taken) {
            choice.findings.push_back(fmt::format(
                "the data reject the forced model: the viscous friction differs by direction ({}); --model "
                "asymmetric, or leave the model to identify",
                describe(asymmetric, Term::viscous)));
        }
    }
    choice.candidates.push_back(offset);
    choice.candidates.push_back(asymmetric);
    choice.candidates.push_back(slow);
}

/// d theta / d tau of the chosen model's step-1 parameters: the regression of the delay column on its regressors.
std::vector<double> delay_sensitivity(const ModelChoice& choice, std::size_t block, RowColumns& columns) {
    const RowRegressors chosen = columns.regressors(choice.model, choice.offset);
    const RowSupport& support = *chosen.support;
    std::vector<double> column(support.size());
    for (std::size_t i = 0; i < support.size(); ++i) column[i] = support.negated_force_slope(i);
    const LeastSquaresResult fit = fit_rows(chosen, {}, column, block);
    if (fit.rank_deficient) return {};
    return {fit.estimate.data(), fit.estimate.data() + fit.estimate.size()};
}

}  // namespace

double integrated_autocorrelation_time(const std::vector<std::size_t>& rows, const std::vector<double>& values) {
    return integrated_autocorrelation<std::size_t>(std::span<const std::size_t>(rows), values);
}

double residual_autocorrelation_time(const Derivatives& d, const Regressors& regressors,
                                     std::span<const SampleIndex> rows) {
    (void)d;
    if (rows.size() < 100) return 1.0;
    const LeastSquaresResult fit = fit_columns(columns_of(regressors), regressors.output, rows, 1);
    if (fit.rank_deficient) return 1.0;
    std::vector<double> residual(rows.size());
    Eigen::VectorXd phi(static_cast<Eigen::Index>(regressors.parameters()));
    for (std::size_t i = 0; i < rows.size(); ++i)
        residual[i] = regressors.row(rows[i], phi.data()) - phi.dot(fit.estimate);
    return integrated_autocorrelation<SampleIndex>(rows, residual);
}

namespace {

/// The samples the checked model describes: step 1's, and step 2's where the friction has its Stribeck term.
SampleIndices checked_rows(const Selection& selection, const AxisModel& axis) {
    if (!axis.friction.forward.has_stribeck() && !axis.friction.reverse.has_stribeck()) return selection.step1;
    SampleIndices rows;
    rows.reserve(selection.step1.size() + selection.step2.size());
    std::set_union(selection.step1.begin(), selection.step1.end(), selection.step2.begin(), selection.step2.end(),
                   std::back_inserter(rows));
    return rows;
}

/// Group edges of a column over rows: `bins` quantiles of a sample of it.
std::vector<double> quantile_edges(std::span<const double> column, std::span<const SampleIndex> rows, int bins) {
    std::vector<double> values;
    const std::size_t stride = std::max<std::size_t>(1, rows.size() / 20000);
    for (std::size_t i = 0; i < rows.size(); i += stride) values.push_back(column[rows[i]]);
    std::vector<double> edges;
    for (int b = 1; b < bins; ++b) edges.push_back(percentile_in_place(values, static_cast<double>(b) / bins));
    return edges;
}

std::size_t group_of(double value, const std::vector<double>& edges) {
    return static_cast<std::size_t>(std::upper_bound(edges.begin(), edges.end(), value) - edges.begin());
}

/// The speed group of check_fit, clamp(int(bins * ln(|v| / low) / span), 0, bins - 1), without a logarithm per row:
/// |v| / low against the groups' edges exp(span * b / bins), and the logarithm itself only within a hair (1e-9
/// relative) of an edge, where rounding could decide (so the same group as the formula's for every speed).
class LogSpeedGroups {
public:
    static constexpr int max_bins = 16;
    LogSpeedGroups(double low, double span, int bins) : low_(low), span_(span), bins_(std::min(bins, max_bins)) {
        for (int b = 1; b < bins_; ++b) {
            const double edge = std::exp(span * b / bins_);
            below_[static_cast<std::size_t>(b)] = edge * (1.0 - 1e-9);
            above_[static_cast<std::size_t>(b)] = edge * (1.0 + 1e-9);
        }
    }
    [[nodiscard]] std::size_t operator()(double speed) const {
        const double ratio = speed / low_;
        int group = 0;
        bool near = false;
        for (std::size_t b = 1; b < static_cast<std::size_t>(bins_); ++b) {
            group += ratio > above_[b] ? 1 : 0;
            near |= ratio >= below_[b] && ratio <= above_[b];
        }
        if (near || !(ratio >= 1.0))
            group = std::clamp(static_cast<int>(bins_ * std::log(ratio) / span_), 0, bins_ - 1);
        return static_cast<std::size_t>(group);
    }

private:
    double low_, span_;
    int bins_;
    std::array<double, max_bins> below_{}, above_{};
};

}  // namespace

std::vector<FitCheck> check_fit(const Derivatives& d, const Selection& selection, const AxisModel& axis,
                                const ModelSelectionOptions& options) {
    const SampleIndices rows = checked_rows(selection, axis);
    if (rows.size() < 200) return {};
    constexpr int speed_bins = 8, acceleration_bins = 4, time_bins = 8;
    double low = INFINITY, high = 0.0;
    for (const auto k : rows) {
        low = std::min(low, std::abs(d.velocity[k]));
        high = std::max(high, std::abs(d.velocity[k]));
    }
    low = std::max(low, 1e-12);
    const double span = std::log(std::max(high / low, 1.0 + 1e-9));
    const std::vector<double> accelerations = quantile_edges(d.acceleration, rows, acceleration_bins);
    std::vector<double> residual(rows.size());
    std::vector<GroupIndex> by_speed(rows.size()), by_acceleration(rows.size()), by_time(rows.size());
    const LogSpeedGroups speed_group(low, span, speed_bins);
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const std::size_t k = rows[i];
        const double v = d.velocity[k];
        residual[i] = d.force[k] - axis.mass * d.acceleration[k] - axis.friction.force(v) - axis.offset;
        const std::size_t direction = v > 0.0 ? 0 : 1;
        by_speed[i] = static_cast<GroupIndex>(direction * speed_bins + speed_group(std::abs(v)));
        by_acceleration[i] =
            static_cast<GroupIndex>(direction * acceleration_bins + group_of(d.acceleration[k], accelerations));
        by_time[i] = static_cast<GroupIndex>(i * time_bins / rows.size());
    }
    Groups speed{group_means(rows, residual, by_speed, 2 * speed_bins), {}};
    Groups acceleration{group_means(rows, residual, by_acceleration, 2 * acceleration_bins), {}};
    Groups time{group_means(rows, residual, by_time, time_bins), {}};
    const std::string speed_unit = d.rotary ? "rad/s" : "m/s", acceleration_unit = d.rotary ? "rad/s^2" : "m/s^2";
    for (std::size_t direction = 0; direction < 2; ++direction) {
        const char* name = direction == 0 ? "forward" : "reverse";
        for (int b = 0; b < speed_bins; ++b) {
            speed.labels.push_back(fmt::format("{} at {:.3g} to {:.3g} {}", name, low * std::exp(span * b / speed_bins),
                                               low * std::exp(span * (b + 1) / speed_bins), speed_unit));
        }
        for (int b = 0; b < acceleration_bins; ++b) {
            const auto at = [&](int e) { return fmt::format("{:.3g}", accelerations[static_cast<std::size_t>(e)]); };
            acceleration.labels.push_back(fmt::format("{} with the acceleration {} {}", name,
                                                      b == 0 ? "below " + at(0)
                                                      : b == acceleration_bins - 1
                                                          ? "above " + at(b - 1)
                                                          : "from " + at(b - 1) + " to " + at(b),
                                                      acceleration_unit));
        }
    }
    for (int b = 0; b < time_bins; ++b) {
        const std::size_t first = rows[static_cast<std::size_t>(b) * rows.size() / time_bins];
        const std::size_t last = rows[(static_cast<std::size_t>(b) + 1) * rows.size() / time_bins - 1];
        time.labels.push_back(fmt::format("from {:.4g} s to {:.4g} s", d.time[first], d.time[last]));
    }
    const double typical = typical_force(d, selection.step1);
    const double threshold = normal_quantile(options.test_level);
    return {judge_groups("speed", speed, typical, options, threshold),
            judge_groups("acceleration", acceleration, typical, options, threshold),
            judge_groups("time", time, typical, options, threshold)};
}

ModelChoice choose_model(Derivatives& d, const Selection& selection, FrictionModelKind forced_model,
                         bool forced_offset, bool drive_tared, const std::optional<RestLevel>& rest,
                         const ModelSelectionOptions& options, double correlation_blocks,
                         const RegressorColumnCache* cache) {
    ModelChoice choice;
    choice.automatic = options.automatic;
    choice.model = forced_model;
    choice.offset = forced_offset;
    const SampleIndices& rows = selection.step1;
    const auto [forward, reverse] = direction_counts(d, rows);
    const double least = std::max(10.0, options.one_way_fraction * static_cast<double>(rows.size()));
    choice.one_way = static_cast<double>(std::min(forward, reverse)) < least;
    if (rows.size() < 50) return choice;  // step 1 will say why it cannot fit
    const std::size_t block = correlation_block(d, correlation_blocks);
    const double threshold = normal_quantile(options.test_level);
    // the models' columns on step 1's rows and their neighbours only, released with the stage; formed when a test
    // needs them (a rerun with the model, offset and delay given needs none)
    std::optional<RowSupport> support;
    std::optional<RowColumns> held;
    const auto columns = [&]() -> RowColumns& {
        if (!held) held.emplace(d, support.emplace(d, rows, true), cache);
        return *held;
    };
    if (options.automatic || options.test_forced) {
        detect_process_forces(d, selection, choice.one_way, options, columns(), choice);
        if (!choice.process_forces.empty()) return choice;
    }
    if (options.known_delay_s)
        apply_known_delay(d, *options.known_delay_s, choice);
    else if (options.delay != ModelSelectionOptions::Delay::none)
        choose_delay(d, choice.one_way, options, threshold, block, columns(), choice);
    if (choice.one_way) {
        if (options.automatic) {
            choice.model = FrictionModelKind::symmetric;
            choice.offset = false;
        }
        ModelCandidate offset;
        offset.name = "offset";
        offset.tested = "F_0";
        offset.threshold = threshold;
        offset.verdict = "not separable from Coulomb friction on a move in one direction";
        choice.candidates.push_back(offset);
        judge_one_way(d, selection, choice.offset, drive_tared, rest, options, choice);
    } else if (options.automatic || options.test_forced) {
        choose_friction_model(d, selection, forced_model, forced_offset, options, threshold, block, columns(), cache,
                              choice);
    }
    // applied, or too uncertain to apply: the delay is known only to its standard error, and the parameters move
    // with it (a significant one a forced model leaves out is said in a finding instead); a delay given has no
    // standard error, and its sensitivities would widen nothing (apply_model_choice)
    if ((choice.delay_applied || choice.delay_uncertain) && choice.delay_standard_error)
        choice.delay_sensitivity = delay_sensitivity(choice, block, columns());
    return choice;
}

}  // namespace feedid
