#include "feedid/identify/step1.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "feedid/numeric/signal.hpp"

namespace feedid {

std::vector<RegressorColumn> linear_columns(FrictionModelKind model, bool offset) {
    std::vector<RegressorColumn> columns{{Term::mass, Direction::both}};
    if (model == FrictionModelKind::asymmetric) {
        columns.push_back({Term::viscous, Direction::forward});
        columns.push_back({Term::viscous, Direction::reverse});
        columns.push_back({Term::coulomb, Direction::forward});
        columns.push_back({Term::coulomb, Direction::reverse});
    } else {
        columns.push_back({Term::viscous, Direction::both});
        columns.push_back({Term::coulomb, Direction::both});
    }
    if (offset) columns.push_back({Term::offset, Direction::both});
    return columns;
}

namespace {

/// RegressorColumn c of eq. (11) at every sample of (a, v), in a vector of at least `capacity` (room for the padding
/// of the low-pass it goes through next).
std::vector<double> regressor_column(const RegressorColumn& column, std::span<const double> a,
                                     std::span<const double> v, std::size_t capacity) {
    std::vector<double> out;
    out.reserve(std::max(capacity, v.size()));
    out.resize(v.size());
    // one loop per kind of column, each vectorised (appending value by value called vector's growth path per value)
    const auto fill = [&](std::span<const double> from, auto value) {
        std::transform(from.begin(), from.end(), out.begin(), value);
    };
    const Direction direction = column.direction;
    switch (column.term) {
        case Term::mass: std::copy_n(a.begin(), v.size(), out.begin()); break;
        case Term::viscous:
            if (direction == Direction::forward)
                fill(v, [](double x) { return std::max(x, 0.0); });
            else if (direction == Direction::reverse)
                fill(v, [](double x) { return std::min(x, 0.0); });
            else
                std::copy(v.begin(), v.end(), out.begin());
            break;
        case Term::coulomb:
            if (direction == Direction::forward)
                fill(v, [](double x) { return x > 0.0 ? 1.0 : 0.0; });
            else if (direction == Direction::reverse)
                fill(v, [](double x) { return x < 0.0 ? -1.0 : 0.0; });
            else
                fill(v, [](double x) { return sign(x); });
            break;
        default: std::fill(out.begin(), out.end(), 1.0); break;
    }
    return out;
}

/// Columns that are not linear in x'' or x' (whose filtered version is not the column of the filtered signals).
bool nonlinear(const RegressorColumn& column) {
    return column.term == Term::coulomb || (column.term == Term::viscous && column.direction != Direction::both);
}

/// RLS over n rows given by row(k, phi) -> y; time(k) the row's time [s].
template <int N, class Row, class Time>
RlsRun run_rls_fixed(std::size_t n, const Row& next_row, const Time& time, const RlsOptions& options,
                     const Eigen::VectorXd& tolerance, std::size_t history_points) {
    Rls<N> rls(options);
    const std::size_t stride = std::max<std::size_t>(1, n / history_points);
    std::vector<Eigen::VectorXd> trajectory;
    trajectory.reserve(n / stride + 2);
    std::vector<std::size_t> trajectory_index;
    typename Rls<N>::Vector row;
    for (std::size_t k = 0; k < n; ++k) {
        const double y = next_row(k, row.data());
        rls.update(row, y);
        if (k % stride == 0 || k + 1 == n) {
            trajectory.emplace_back(rls.estimate());
            trajectory_index.push_back(k);
        }
    }
    RlsRun run;
    run.final_estimate = rls.estimate();
    run.wound_up = rls.wound_up();
    const auto& p = rls.covariance();
    run.covariance_ok = p.allFinite() && (p - p.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * p.cwiseAbs().maxCoeff();
    // Transient: the first point after which every parameter stays within its tolerance of the final estimate.
    std::size_t first_settled = trajectory.size();
    for (std::size_t i = trajectory.size(); i-- > 0;) {
        const Eigen::VectorXd deviation = (trajectory[i] - run.final_estimate).cwiseAbs();
        if ((deviation.array() <= tolerance.array()).all())
            first_settled = i;
        else
            break;
    }
    run.settled = first_settled + 1 < trajectory.size() && first_settled < trajectory.size() * 9 / 10;
    run.settled_index = first_settled < trajectory.size() ? trajectory_index[first_settled] : n;
    // The paper's value: the average of the estimate after the transient (over the thinned trajectory, uniformly
    // spaced in samples).
    if (run.settled) {
        Eigen::VectorXd sum = Eigen::VectorXd::Zero(N);
        for (std::size_t i = first_settled; i < trajectory.size(); ++i) sum += trajectory[i];
        run.averaged = sum / static_cast<double>(trajectory.size() - first_settled);
    } else {
        run.averaged = run.final_estimate;
    }
    for (std::size_t i = 0; i < trajectory.size(); ++i) run.history_time.push_back(time(trajectory_index[i]));
    run.history = std::move(trajectory);
    run.transient_end_s = run.settled_index < n ? time(run.settled_index) : (n == 0 ? 0.0 : time(n - 1));
    return run;
}

template <class Row, class Time>
RlsRun run_rls_rows(Eigen::Index parameters, std::size_t n, const Row& row, const Time& time, const RlsOptions& options,
                    const Eigen::VectorXd& tolerance, std::size_t history_points) {
    switch (parameters) {
        case 3: return run_rls_fixed<3>(n, row, time, options, tolerance, history_points);
        case 4: return run_rls_fixed<4>(n, row, time, options, tolerance, history_points);
        case 5: return run_rls_fixed<5>(n, row, time, options, tolerance, history_points);
        case 6: return run_rls_fixed<6>(n, row, time, options, tolerance, history_points);
        default: throw std::logic_error("unsupported RLS size");
    }
}

}  // namespace

RlsRun run_rls(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const std::vector<double>& time,
               const RlsOptions& options, const Eigen::VectorXd& tolerance, std::size_t history_points) {
    const auto row = [&](std::size_t k, double* out) {
        for (Eigen::Index c = 0; c < phi.cols(); ++c) out[c] = phi(static_cast<Eigen::Index>(k), c);
        return y(static_cast<Eigen::Index>(k));
    };
    return run_rls_rows(
        phi.cols(), static_cast<std::size_t>(phi.rows()), row, [&](std::size_t k) { return time[k]; }, options,
        tolerance, history_points);
}

std::shared_ptr<const std::vector<double>> RegressorColumnCache::find(const RegressorColumn& column) const {
    for (const auto& [key, values] : columns_) {
        if (key.term == column.term && key.direction == column.direction) return values;
    }
    return nullptr;
}

void RegressorColumnCache::store(const RegressorColumn& column, std::shared_ptr<const std::vector<double>> values) {
    if (!find(column)) columns_.emplace_back(column, std::move(values));
}

void RegressorColumnCache::remember(const Regressors& regressors) {
    std::size_t owned = 0;
    for (const auto& column : regressors.columns) {
        const bool viewed = column.term == Term::mass || (column.term == Term::viscous && column.direction == Direction::both);
        if (!viewed && owned < regressors.owned.size()) store(column, regressors.owned[owned++]);
    }
}

RegressorValues regressor_values(const Derivatives& derivatives, const RegressorColumn& column,
                                 const RegressorColumnCache* cache) {
    // x'' and x' are the Derivatives' columns: decimated (when decimating) by the same decimate_segments over the
    // same stretches, so the same values; viewed, not copied
    if (column.term == Term::mass) return {derivatives.acceleration, nullptr};
    if (column.term == Term::viscous && column.direction == Direction::both) return {derivatives.velocity, nullptr};
    if (auto kept = cache != nullptr ? cache->find(column) : nullptr) return {*kept, std::move(kept)};
    const int factor = derivatives.used.decimation;
    const bool decimated = factor > 1;
    const auto& a = decimated ? derivatives.full_rate_acceleration : derivatives.acceleration;
    const auto& v = decimated ? derivatives.full_rate_velocity : derivatives.velocity;
    const bool filtered = nonlinear(column);
    std::vector<double> values =
        regressor_column(column, a, v, filtered ? filter_like_force_capacity(derivatives, v.size()) : v.size());
    if (filtered) {
        // sgn(x') (and x' per direction) of the filtered x' is not the filtered sgn(x'): through the force's
        // low-pass, then decimated like every column; filtered where it stands (no second whole column)
        values = filter_like_force(std::move(values), derivatives);
    } else if (decimated) {
        // every column through the same anti-alias filter, the constant one too (IDIM practice): whatever the
        // filter does to a constant, it does to the force alike
        values = decimate_segments(values, derivatives.full_rate_segment_starts, factor);
    }
    auto formed = std::make_shared<const std::vector<double>>(std::move(values));
    return {*formed, std::move(formed)};
}

Regressors build_regressors(const Derivatives& derivatives, FrictionModelKind model, bool offset,
                            RegressorColumnCache* cache) {
    Regressors r;
    r.columns = linear_columns(model, offset);
    r.output = derivatives.force;
    for (const auto& column : r.columns) {
        RegressorValues formed = regressor_values(derivatives, column, cache);
        r.values.push_back(formed.values);
        if (!formed.owned) continue;
        if (cache != nullptr) cache->store(column, formed.owned);
        r.owned.push_back(std::move(formed.owned));
    }
    return r;
}

Eigen::MatrixXd Regressors::matrix(std::span<const SampleIndex> rows) const {
    Eigen::MatrixXd m(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(columns.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) {
        for (std::size_t c = 0; c < columns.size(); ++c) {
            m(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(c)) = values[c][rows[i]];
        }
    }
    return m;
}

Eigen::VectorXd Regressors::outputs(std::span<const SampleIndex> rows) const {
    Eigen::VectorXd out(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) out(static_cast<Eigen::Index>(i)) = output[rows[i]];
    return out;
}

std::optional<std::string> opposed_drive_signal(const std::vector<RegressorColumn>& columns,
                                                const LeastSquaresResult& batch, const Derivatives& derivatives,
                                                double standard_errors) {
    std::vector<std::string> terms;
    const ParameterNaming naming{derivatives.rotary};
    for (std::size_t c = 0; c < columns.size(); ++c) {
        const Term term = columns[c].term;
        if (term != Term::mass && term != Term::coulomb) continue;
        const auto i = static_cast<Eigen::Index>(c);
        if (!(batch.estimate(i) + standard_errors * batch.standard_error(i) < 0.0)) return std::nullopt;
        terms.push_back(fmt::format("{} = {:.4g} +/- {:.2g} {}", ParameterNaming::symbol(term, columns[c].direction),
                                    batch.estimate(i), batch.standard_error(i), naming.unit(term)));
    }
    if (terms.empty()) return std::nullopt;
    return fmt::format(
        "{}: the drive force opposes the motion ({}: it {}pushes against the direction of travel): the drive signal "
        "counts the other way than the position. Flip it with --invert current (or --invert force, or give the "
        "force constant negated, e.g. --force-constant -K)",
        derivatives.source, fmt::join(terms, ", "),
        columns.front().term == Term::mass ? "falls as the axis accelerates and " : "");
}

double Step1Fit::coefficient(Term term, Direction direction) const {
    for (std::size_t c = 0; c < columns.size(); ++c) {
        if (columns[c].term == term && columns[c].direction == direction) {
            return batch.estimate(static_cast<Eigen::Index>(c));
        }
    }
    return 0.0;
}

std::size_t correlation_block(const Derivatives& derivatives, double blocks) {
    return static_cast<std::size_t>(std::ceil(blocks * static_cast<double>(derivatives.correlation_samples)));
}

namespace {

/// Which parameter is missing its excitation, when the regressors are linearly dependent.
std::string rank_deficiency_message(const Step1Fit& fit, const Regressors& regressors,
                                    std::span<const SampleIndex> rows, const Derivatives& derivatives, bool offset) {
    std::vector<std::string> silent;
    for (std::size_t c = 0; c < fit.columns.size(); ++c) {
        const auto& column = regressors.values[c];
        if (std::all_of(rows.begin(), rows.end(), [&](std::size_t k) { return column[k] == 0.0; })) {
            silent.push_back(ParameterNaming::symbol(fit.columns[c].term, fit.columns[c].direction));
        }
    }
    return fmt::format(
        "{}: the step-1 regressors are linearly dependent{}: the data cannot separate the parameters (does the axis "
        "move in both directions{}?)",
        derivatives.source, silent.empty() ? "" : fmt::format(" (no excitation of {})", fmt::join(silent, ", ")),
        offset ? ", and is the offset separable from Coulomb friction" : "");
}

/// For every analysed sample, the time to the nearest reversal (a sign change of x') [s].
std::vector<double> time_to_reversal(const Derivatives& d) {
    const std::size_t n = d.size();
    std::vector<double> distance(n, INFINITY);
    double last = -INFINITY;
    for (std::size_t k = 1; k < n; ++k) {
        if (d.velocity[k] * d.velocity[k - 1] < 0.0) last = d.time[k];
        distance[k] = d.time[k] - last;
    }
    double next = INFINITY;
    for (std::size_t k = n; k-- > 1;) {
        if (d.velocity[k] * d.velocity[k - 1] < 0.0) next = d.time[k];
        distance[k] = std::min(distance[k], next - d.time[k]);
    }
    return distance;
}

/// Where a poor step-1 fit's residual sits: the share of the squared residual carried by the accelerating samples,
/// the slow ones and those near reversals, against their share of the samples; the class most over-represented
/// names the likely cause.
std::string investigate_residual(const Step1Fit& fit, const Regressors& regressors, const Derivatives& d,
                                 std::span<const SampleIndex> rows, const Step1Options& options) {
    Eigen::VectorXd residual(static_cast<Eigen::Index>(rows.size()));
    Eigen::VectorXd phi(static_cast<Eigen::Index>(regressors.parameters()));
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const double y = regressors.row(rows[i], phi.data());
        residual(static_cast<Eigen::Index>(i)) = y - phi.dot(fit.batch.estimate);
    }
    const std::vector<double> reversal = time_to_reversal(d);
    double slowest = INFINITY;
    for (const auto k : rows) slowest = std::min(slowest, std::abs(d.velocity[k]));
    struct Group {
        const char* name;
        const char* cause;
        double samples{0.0}, share{0.0};
    };
    std::array<Group, 3> groups{
        Group{"accelerating",
              "the force and the acceleration do not match where the axis accelerates: a lag between "
              "the drive signal and the position (current-loop lag, two recorders' clocks: --join "
              "@SHIFT), elasticity between motor and table, or an injected test signal"},
        Group{"slow",
              "the friction at low speed is not the model's (Stribeck friction or stick-slip): raise "
              "--split-velocity"},
        Group{"near reversals",
              "the drive force changes sign late or early against the motion at reversals: a lag "
              "between the drive signal and the position (two recorders' clocks: --join @SHIFT), "
              "backlash, or pre-sliding friction"}};
    const double total = residual.squaredNorm();
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const auto k = rows[i];
        const double r2 = residual(static_cast<Eigen::Index>(i)) * residual(static_cast<Eigen::Index>(i)) / total;
        const bool member[3] = {
            std::abs(d.acceleration[k]) > options.residual_acceleration_fraction * fit.max_acceleration,
            std::abs(d.velocity[k]) < options.residual_slow_multiple * slowest,
            reversal[k] < options.residual_reversal_s};
        for (std::size_t g = 0; g < 3; ++g) {
            if (!member[g]) continue;
            groups[g].samples += 1.0 / static_cast<double>(rows.size());
            groups[g].share += r2;
        }
    }
    const Group* worst = nullptr;
    for (const auto& g : groups) {
        if (g.samples > 0.0 && g.share > options.residual_concentration * g.samples &&
            (worst == nullptr || g.share / g.samples > worst->share / worst->samples))
            worst = &g;
    }
    std::string finding = fmt::format("step 1 fits poorly (relative error {:.3g} %): ", fit.batch.relative_error_pct);
    for (const auto& g : groups) {
        finding += fmt::format("{} samples ({:.0f} % of them) carry {:.0f} % of the squared residual; ", g.name,
                               100.0 * g.samples, 100.0 * g.share);
    }
    if (worst == nullptr) {
        return finding +
               "it is spread over all samples: noise, or a force the model lacks (an offset: --offset; "
               "friction that varies along the axis: --by-location)";
    }
    return finding + fmt::format("most likely cause: {}", worst->cause);
}

}  // namespace

Step1Fit fit_step1(const Regressors& regressors, const Derivatives& derivatives, std::span<const SampleIndex> rows,
                   const Step1Options& options) {
    Step1Fit fit;
    fit.columns = regressors.columns;
    fit.samples = rows.size();
    fit.rls_options = options.rls;
    const std::size_t p = fit.columns.size();
    if (rows.size() < options.minimum_samples_per_parameter * p) {
        fit.failure = fmt::format(
            "{}: only {} moving samples fast enough for step 1 (need at least {}): the axis barely moves; record "
            "constant-velocity strokes (see feedid plan)",
            derivatives.source, rows.size(), options.minimum_samples_per_parameter * p);
        return fit;
    }
    // the rows straight from the regressors' columns, never gathered into a matrix (a 16M-sample trace's step 1
    // would hold several hundred MB)
    const auto row = [&](std::size_t i, double* phi) { return regressors.row(rows[i], phi); };
    fit.batch = solve_least_squares_rows(
        rows.size(), static_cast<Eigen::Index>(p), row, [&](std::size_t i) { return rows[i]; },
        correlation_block(derivatives, options.correlation_blocks));
    for (const auto k : rows)
        fit.max_acceleration = std::max(fit.max_acceleration, std::abs(derivatives.acceleration[k]));
    const bool offset = !fit.columns.empty() && fit.columns.back().term == Term::offset;
    if (fit.batch.rank_deficient) {
        fit.failure = rank_deficiency_message(fit, regressors, rows, derivatives, offset);
        return fit;
    }
    if (auto opposed = opposed_drive_signal(fit.columns, fit.batch, derivatives, options.sign_standard_errors)) {
        fit.failure = std::move(*opposed);
        return fit;
    }
    // Mass: identifiable only when acceleration explains a significant part of the force.
    const double mass = fit.batch.estimate(0), mass_se = fit.batch.standard_error(0);
    if (!(mass > 0.0) || !(mass_se < options.mass_relative_standard_error * mass)) {
        const ParameterNaming naming{derivatives.rotary};
        fit.mass_unidentifiable = true;
        const std::string why =
            derivatives.travel < options.creep_travel
                ? fmt::format("a micro-step or creep test (the axis travelled {:.3g} {}) cannot determine mass",
                              derivatives.travel * (derivatives.rotary ? 1.0 : 1e6), derivatives.rotary ? "rad" : "um")
                : std::string("the strokes hold too little acceleration against the force's scatter");
        fit.failure = fmt::format(
            "{}: the trace carries no usable mass information: the acceleration (at most {:.3g} {}/s^2 in the samples "
            "used) explains too little of the drive force (estimate {:.4g} +/- {:.2g} {}); {}. Record strokes with "
            "real accelerations and reversals (see feedid plan)",
            derivatives.source, fit.max_acceleration, derivatives.rotary ? "rad" : "m", mass, mass_se,
            naming.unit(Term::mass), why);
        return fit;
    }
    if (fit.batch.relative_error_pct > options.investigate_relative_error_pct) {
        fit.residual_finding = investigate_residual(fit, regressors, derivatives, rows, options);
    }
    if (!options.run_rls) return fit;
    // RLS on the same samples, in time order.
    const Eigen::VectorXd tolerance = (fit.batch.estimate.cwiseAbs() * options.rls_settle_fraction)
                                          .cwiseMax(options.rls_settle_standard_errors * fit.batch.standard_error);
    fit.rls = run_rls_rows(
        static_cast<Eigen::Index>(p), rows.size(), row, [&](std::size_t i) { return derivatives.time[rows[i]]; },
        options.rls, tolerance, options.rls_history_points);
    return fit;
}

}  // namespace feedid
