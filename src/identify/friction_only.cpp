#include "feedid/identify/friction_only.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/numeric/signal.hpp"
#include "feedid/identify/model_adequacy.hpp"
#include "feedid/identify/step1.hpp"

namespace feedid {

namespace {

/// Lengths in mm, speeds in mm/s on a linear axis; rad and rad/s on a rotary one.
struct Display {
    bool rotary;
    [[nodiscard]] double length(double x) const { return rotary ? x : x * 1e3; }
    [[nodiscard]] const char* length_unit() const { return rotary ? "rad" : "mm"; }
    [[nodiscard]] const char* speed_unit() const { return rotary ? "rad/s" : "mm/s"; }
};

/// The samples the friction comes from: the logged velocity and force over the whole window when the velocity is
/// logged (unfiltered: no edge lost), else x' and the force of the analysed samples.
struct SteadySource {
    const std::vector<double>& velocity;
    const std::vector<double>& force;
};
SteadySource steady_source(const Derivatives& d) {
    if (d.logged_velocity.empty()) return {d.velocity, d.force};
    return {d.logged_velocity, d.logged_force};
}

/// The rows that belong to runs of at least `minimum` consecutive indices.
std::vector<std::size_t> passes_only(const std::vector<std::size_t>& rows, std::size_t minimum) {
    std::vector<std::size_t> kept;
    for (std::size_t begin = 0; begin < rows.size();) {
        std::size_t end = begin + 1;
        while (end < rows.size() && rows[end] == rows[end - 1] + 1) ++end;
        if (end - begin >= minimum)
            kept.insert(kept.end(), rows.begin() + static_cast<std::ptrdiff_t>(begin),
                        rows.begin() + static_cast<std::ptrdiff_t>(end));
        begin = end;
    }
    return kept;
}

/// Steady samples: moving, and the logged velocity of the sample and both neighbours keeps its sign within a
/// fraction of |v|; without a logged velocity, step 2's quasi-static moving samples.
std::vector<std::size_t> steady_samples(const Derivatives& d, const Selection& s, const FrictionOnlyOptions& options) {
    std::vector<std::size_t> rows;
    if (d.logged_velocity.empty()) {
        for (const auto k : s.moving) {
            if (s.steady(k)) rows.push_back(k);
        }
        return rows;
    }
    const auto& v = d.logged_velocity;
    for (std::size_t k = 1; k + 1 < v.size(); ++k) {
        if (std::abs(v[k]) <= s.moving_threshold()) continue;
        const double low = std::min({v[k - 1], v[k], v[k + 1]}), high = std::max({v[k - 1], v[k], v[k + 1]});
        if ((low > 0.0 || high < 0.0) && high - low <= options.steady_spread_fraction * std::abs(v[k]))
            rows.push_back(k);
    }
    return passes_only(rows, options.minimum_steady_run);
}

/// Per direction, the speeds must differ enough for B (and each direction needs its samples).
std::string speed_spread_problem(const Derivatives& d, const std::vector<std::size_t>& rows, FrictionModelKind model,
                                 const FrictionOnlyOptions& options, std::size_t needed) {
    const auto& v = steady_source(d).velocity;
    const Display display{d.rotary};
    const bool asymmetric = model == FrictionModelKind::asymmetric;
    for (int g = 0; g < (asymmetric ? 2 : 1); ++g) {
        std::vector<double> speeds;
        for (const auto k : rows) {
            if (!asymmetric || (v[k] > 0.0) == (g == 0)) speeds.push_back(std::abs(v[k]));
        }
        const char* which = !asymmetric ? "" : g == 0 ? " forward" : " reverse";
        if (speeds.size() < needed) {
            return fmt::format("only {} steady-speed samples{} ({} needed)", speeds.size(), which, needed);
        }
        const double typical = percentile(speeds, 0.5);
        const auto apart = std::count_if(speeds.begin(), speeds.end(), [&](double speed) {
            return speed >= options.minimum_speed_ratio * typical || speed * options.minimum_speed_ratio <= typical;
        });
        if (static_cast<std::size_t>(apart) < options.minimum_samples_at_another_speed) {
            return fmt::format(
                "the steady speeds{} are nearly all {:.3g} {} ({} samples {:g}x faster or slower, {} needed): viscous "
                "and Coulomb friction need two speeds{}",
                which, display.length(typical), display.speed_unit(), apart, options.minimum_speed_ratio,
                options.minimum_samples_at_another_speed,
                asymmetric ? " in each direction (--model symmetric shares them between the directions)" : "");
        }
    }
    return {};
}


/// Each row's pass: runs of consecutive sample indices.
std::vector<std::size_t> pass_of_rows(const std::vector<std::size_t>& rows) {
    std::vector<std::size_t> pass(rows.size(), 0);
    for (std::size_t i = 1; i < rows.size(); ++i) pass[i] = pass[i - 1] + (rows[i] != rows[i - 1] + 1 ? 1 : 0);
    return pass;
}

double tukey_weight(double r, double limit) {
    if (!(std::abs(r) < limit)) return 0.0;
    const double u = r / limit;
    return (1.0 - u * u) * (1.0 - u * u);
}

/// 1.4826 times the median of |r|: the standard deviation of Gaussian residuals, unmoved by a minority of outliers.
double robust_scale_of(const Eigen::VectorXd& r) {
    return 1.4826 * absolute_percentile(std::span<const double>(r.data(), static_cast<std::size_t>(r.size())), 0.5);
}

/// Least squares with row weights w (a row of weight 0 drops out); NaN where the weighted rows are rank deficient.
Eigen::VectorXd weighted_solution(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const Eigen::VectorXd& w) {
    const Eigen::VectorXd root = w.cwiseSqrt();
    const LeastSquaresResult r = solve_least_squares(root.asDiagonal() * phi, root.cwiseProduct(y));
    if (r.rank_deficient) return Eigen::VectorXd::Constant(phi.cols(), std::numeric_limits<double>::quiet_NaN());
    return r.estimate;
}

/// The M-scale of residuals (the S-estimator's): s with mean(rho(r / s)) = 1/2, rho Tukey's bisquare loss scaled to
/// 1 beyond c = 1.547 (50 % breakdown). It compares fits by all their residuals, where the MAD looks at the middle
/// one only (a fit that splits the difference to a load can have the smaller MAD). From the MAD, by fixed point.
double m_scale(const Eigen::VectorXd& r, double mad) {
    constexpr double c = 1.547;
    double scale = mad;
    if (!(scale > 0.0)) return scale;
    for (int iteration = 0; iteration < 50; ++iteration) {
        double loss = 0.0;
        for (Eigen::Index i = 0; i < r.size(); ++i) {
            const double u = r(i) / (c * scale), t = 1.0 - u * u;
            loss += std::abs(u) >= 1.0 ? 1.0 : 1.0 - t * t * t;
        }
        const double next = scale * std::sqrt(loss / static_cast<double>(r.size()) / 0.5);
        if (std::abs(next - scale) <= 1e-9 * scale) return next;
        scale = next;
    }
    return scale;
}

struct RobustFit {
    Eigen::VectorXd theta;
    Eigen::VectorXd weights;
    double scale{std::numeric_limits<double>::max()};    ///< 1.4826 MAD, the weights' scale
    double m_scale{std::numeric_limits<double>::max()};  ///< the residuals' M-scale, by which fits compare
};

/// Tukey's biweight by IRLS from `start` (up to `iterations` steps), the scale the residuals' MAD at each step (as
/// scan's windows are fitted); rows not `judged` keep weight 1.
RobustFit tukey_fit(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, Eigen::VectorXd theta,
                    const std::vector<char>& judged, const FrictionOnlyOptions& options, int iterations) {
    const double floor = 1e-12 * std::max(1.0, y.cwiseAbs().maxCoeff());
    RobustFit fit;
    Eigen::VectorXd residual;
    const auto weigh = [&] {
        residual = y - phi * theta;
        fit.scale = robust_scale_of(residual);
        const double limit = options.tukey_c * std::max(fit.scale, floor);
        fit.weights.resize(residual.size());
        for (Eigen::Index i = 0; i < residual.size(); ++i)
            fit.weights(i) = fit.scale > floor && judged[static_cast<std::size_t>(i)] != 0
                                 ? tukey_weight(residual(i), limit)
                                 : 1.0;
    };
    for (int iteration = 0; iteration < iterations; ++iteration) {
        weigh();
        const Eigen::VectorXd next = weighted_solution(phi, y, fit.weights);
        if (!next.allFinite()) break;
        const bool converged = (next - theta).cwiseAbs().maxCoeff() <= 1e-10 * (theta.cwiseAbs().maxCoeff() + 1e-300);
        theta = next;
        if (converged) break;
    }
    weigh();
    fit.theta = theta;
    fit.m_scale = m_scale(residual, fit.scale);
    return fit;
}

/// The fit's rows: each one's sample index, pass (runs of consecutive indices, in time order) and signed velocity.
struct SteadyRows {
    std::vector<std::size_t> index;
    std::vector<std::size_t> pass;
    Eigen::VectorXd velocity;
};

/// A start that loads on a minority of the strokes do not pull: each pass's median speed and median friction
/// magnitude (sgn(v) F), and through these points Theil-Sen's line (the median of the slopes between passes whose
/// speeds differ by 10 % or more, then the median intercept), as every direction's B and F_C (an offset 0). NaN
/// where no two passes differ in speed. Up to 400 passes, evenly spread, are used (160,000 slopes).
Eigen::VectorXd pass_median_start(const SteadyRows& rows, const Eigen::VectorXd& y,
                                  const std::vector<RegressorColumn>& columns) {
    std::vector<double> speeds, magnitudes, buffer;
    for (std::size_t begin = 0; begin < rows.index.size();) {
        std::size_t end = begin + 1;
        while (end < rows.index.size() && rows.pass[end] == rows.pass[begin]) ++end;
        for (int part = 0; part < 2; ++part) {
            buffer.clear();
            for (std::size_t i = begin; i < end; ++i) {
                const double v = rows.velocity(static_cast<Eigen::Index>(i));
                buffer.push_back(part == 0 ? std::abs(v) : (v > 0.0 ? 1.0 : -1.0) * y(static_cast<Eigen::Index>(i)));
            }
            (part == 0 ? speeds : magnitudes).push_back(percentile(buffer, 0.5));
        }
        begin = end;
    }
    const std::size_t stride = speeds.size() / 400 + 1;
    std::vector<double> slopes;
    for (std::size_t i = 0; i < speeds.size(); i += stride)
        for (std::size_t j = i + stride; j < speeds.size(); j += stride)
            if (std::abs(speeds[i] - speeds[j]) >= 0.1 * std::max(speeds[i], speeds[j]))
                slopes.push_back((magnitudes[i] - magnitudes[j]) / (speeds[i] - speeds[j]));
    Eigen::VectorXd start = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(columns.size()),
                                                      std::numeric_limits<double>::quiet_NaN());
    if (slopes.empty()) return start;
    const double slope = percentile(std::move(slopes), 0.5);
    for (std::size_t i = 0; i < speeds.size(); ++i) magnitudes[i] -= slope * speeds[i];
    const double intercept = percentile(std::move(magnitudes), 0.5);
    for (std::size_t c = 0; c < columns.size(); ++c)
        start(static_cast<Eigen::Index>(c)) = columns[c].term == Term::viscous   ? slope
                                              : columns[c].term == Term::coulomb ? intercept
                                                                                 : 0.0;
    return start;
}

/// The rows the robust weights may judge: those of passes with two more passes at their speed (within 10 %, either
/// direction). A load shows as a stroke whose friction stands off the others' at its speed; a pass alone at its speed
/// (the one rapid of a log) is what determines B, and no other pass can say it is off: it keeps its weight.
std::vector<char> judged_rows(const SteadyRows& rows) {
    std::vector<std::size_t> begin;
    std::vector<double> speed;
    for (std::size_t i = 0; i < rows.index.size(); ++i) {
        if (i > 0 && rows.pass[i] == rows.pass[i - 1]) continue;
        begin.push_back(i);
        std::size_t end = i + 1;
        while (end < rows.index.size() && rows.pass[end] == rows.pass[i]) ++end;
        std::vector<double> magnitude(end - i);
        for (std::size_t j = i; j < end; ++j) magnitude[j - i] = std::abs(rows.velocity(static_cast<Eigen::Index>(j)));
        speed.push_back(percentile(std::move(magnitude), 0.5));
    }
    begin.push_back(rows.index.size());
    std::vector<char> judged(rows.index.size(), 0);
    std::vector<double> sorted = speed;
    std::sort(sorted.begin(), sorted.end());
    for (std::size_t q = 0; q < speed.size(); ++q) {
        // |other - s| <= 0.1 max(other, s): other within [0.9 s, s / 0.9]
        const auto alike = std::upper_bound(sorted.begin(), sorted.end(), speed[q] / 0.9) -
                           std::lower_bound(sorted.begin(), sorted.end(), 0.9 * speed[q]);
        if (alike >= 3) std::fill(judged.begin() + static_cast<std::ptrdiff_t>(begin[q]),
                                  judged.begin() + static_cast<std::ptrdiff_t>(begin[q + 1]), char{1});
    }
    return judged;
}

/// Tukey's biweight from least squares, from the fastest third of the rows (rapids do not cut) and from the passes'
/// medians (pass_median_start): a feed stroke's cutting load pulls least squares, and IRLS from there keeps it when
/// the scale it starts from covers the load. The fit of smallest M-scale is kept (the S-estimator's rule).
RobustFit robust_friction_fit(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const SteadyRows& rows,
                              const std::vector<RegressorColumn>& columns, const Eigen::VectorXd& least_squares,
                              const FrictionOnlyOptions& options) {
    // each start a few steps, then the best one to convergence (a day's log at 10 Hz has 10^6 steady samples)
    constexpr int trial_iterations = 5;
    const std::vector<char> judged = judged_rows(rows);
    RobustFit best = tukey_fit(phi, y, least_squares, judged, options, trial_iterations);
    const Eigen::VectorXd speed = rows.velocity.cwiseAbs();
    std::vector<double> speeds(speed.data(), speed.data() + speed.size());
    const double fast = percentile(std::move(speeds), 2.0 / 3.0);
    const Eigen::VectorXd fastest =
        weighted_solution(phi, y, speed.unaryExpr([&](double s) { return s >= fast ? 1.0 : 0.0; }));
    for (const Eigen::VectorXd& start : {fastest, pass_median_start(rows, y, columns)}) {
        if (!start.allFinite()) continue;
        RobustFit other = tukey_fit(phi, y, start, judged, options, trial_iterations);
        if (other.m_scale < best.m_scale) best = std::move(other);
    }
    return tukey_fit(phi, y, best.theta, judged, options, options.irls_iterations);
}

/// Robust weights on the steady rows: phi, y and the rows reduced to those of positive weight, each scaled by the
/// root of its weight (least squares on them is the weighted fit, and the standard errors below are its sandwich).
/// A failure where more than the breakdown fraction is rejected.
void apply_robust_weights(FrictionOnlyFit& fit, Eigen::MatrixXd& phi, Eigen::VectorXd& y, SteadyRows& rows,
                          const FrictionOnlyOptions& options) {
    const RobustFit robust = robust_friction_fit(phi, y, rows, fit.columns, fit.batch.estimate, options);
    fit.robust_scale = robust.scale;
    std::vector<Eigen::Index> kept;
    for (Eigen::Index i = 0; i < robust.weights.size(); ++i)
        if (robust.weights(i) > 0.0) kept.push_back(i);
    fit.rejected = rows.index.size() - kept.size();
    if (static_cast<double>(fit.rejected) > options.maximum_rejected_fraction * static_cast<double>(rows.index.size())) {
        fit.failure = fmt::format(
            "the steady-speed samples do not follow one friction law: the robust fit rejects {} of {} (more than "
            "{:.0f} %): a load the model has no term for (cutting) on most strokes?",
            fit.rejected, rows.index.size(), 100.0 * options.maximum_rejected_fraction);
        return;
    }
    const auto n = static_cast<Eigen::Index>(kept.size());
    Eigen::MatrixXd kept_phi(n, phi.cols());
    Eigen::VectorXd kept_y(n);
    SteadyRows kept_rows{std::vector<std::size_t>(kept.size()), std::vector<std::size_t>(kept.size()),
                         Eigen::VectorXd(n)};
    for (Eigen::Index j = 0; j < n; ++j) {
        const auto i = kept[static_cast<std::size_t>(j)];
        const double root = std::sqrt(robust.weights(i));
        kept_phi.row(j) = root * phi.row(i);
        kept_y(j) = root * y(i);
        kept_rows.index[static_cast<std::size_t>(j)] = rows.index[static_cast<std::size_t>(i)];
        kept_rows.pass[static_cast<std::size_t>(j)] = rows.pass[static_cast<std::size_t>(i)];
        kept_rows.velocity(j) = rows.velocity(i);
    }
    phi = std::move(kept_phi);
    y = std::move(kept_y);
    rows = std::move(kept_rows);
    fit.batch = solve_least_squares(phi, y);
}

/// The pass levels' correlation from one pass to the next, in the friction's sense (each pass's mean residual times
/// its direction: a friction that drifts, warming up, keeps its level over several passes, whichever way they run),
/// as an AR(1) coefficient: the lag-1 autocovariance over the level variance, less the downward bias of a short
/// series ((P r + 1) / (P - 3)), within [0, (P - 3) / (P + 3)]: at most a correlation that leaves the P levels the
/// information of 3 independent ones (P (1 - rho) / (1 + rho) = 3); a drift slower than that, one log cannot tell
/// from a constant. Needs 8 passes; 0 otherwise.
double level_correlation(const std::vector<double>& magnitude, double level_variance) {
    const std::size_t passes = magnitude.size();
    if (passes < 8 || !(level_variance > 0.0)) return 0.0;
    double lag = 0.0;
    for (std::size_t q = 0; q + 1 < passes; ++q) lag += magnitude[q] * magnitude[q + 1];
    const double r = lag / static_cast<double>(passes - 1) / level_variance;
    const auto count = static_cast<double>(passes);
    return std::clamp((count * r + 1.0) / (count - 3.0), 0.0, (count - 3.0) / (count + 3.0));
}

/// Sum over pass pairs of rho^|p - q| h_p h_q^T, h_p the pass's regressor sum times its direction (for p = q, g_p
/// g_p^T), lags cut where rho^lag < 1e-6.
Eigen::MatrixXd correlated_level_sum(const Eigen::MatrixXd& sums, const std::vector<double>& direction, double rho) {
    const Eigen::Index passes = sums.cols();
    Eigen::MatrixXd h = sums;
    for (Eigen::Index q = 0; q < passes; ++q) h.col(q) *= direction[static_cast<std::size_t>(q)];
    Eigen::MatrixXd total = h * h.transpose();
    double factor = rho;
    for (Eigen::Index lag = 1; lag < passes && factor > 1e-6; ++lag, factor *= rho) {
        const Eigen::MatrixXd cross = h.leftCols(passes - lag) * h.rightCols(passes - lag).transpose();
        total += factor * (cross + cross.transpose());
    }
    return total;
}

/// Standard errors that count each steady pass's own level once. On a machine's log the residual of a pass keeps
/// one level along it (a load, friction that differs by place or direction): the residual is e = u_pass + w with
/// u_pass ~ (0, s_u^2) per pass and w the within-pass noise, and Cov(theta) = A^-1 (S_w + s_u^2 sum_p g_p g_p^T)
/// A^-1, A = Phi^T Phi, g_p the sum of a pass's regressor rows, S_w the batch-means long-run covariance of w (blocks
/// of `correlation_block` samples). s_u^2 by moments: the passes' mean residuals squared less their within-pass
/// variance (2 tau_w s_w^2 / n_p, tau_w w's integrated autocorrelation time), over P - p (the fit absorbs p of
/// the pass levels). A pass whose level alone sets a parameter (B from one rapid) then carries a level's
/// uncertainty, not that of its n_p samples. A friction that drifts over the log (warming up) keeps its level from
/// pass to pass: the levels are taken as an AR(1) in the friction's sense (level_correlation), Cov(u_p, u_q) =
/// s_u^2 rho^|p-q| d_p d_q (d the pass's direction), s_u^2 raised for the run's mean level the fit absorbs (by 1 /
/// (1 - 2 rho / ((1 - rho) P))). Fewer than p + 2 passes: the batch means of e alone.
void account_for_pass_levels(FrictionOnlyFit& fit, const Eigen::MatrixXd& phi, const Eigen::VectorXd& y,
                             const SteadyRows& rows) {
    LeastSquaresResult& batch = fit.batch;
    if (batch.rank_deficient || !(batch.residual_std > 0.0)) return;
    const Eigen::VectorXd residual = y - phi * batch.estimate;
    const auto p = phi.cols();
    std::vector<std::size_t> starts;  // of each pass, into rows; a sentinel at the end
    for (std::size_t i = 0; i < rows.index.size(); ++i)
        if (i == 0 || rows.pass[i] != rows.pass[i - 1]) starts.push_back(i);
    starts.push_back(rows.index.size());
    const std::size_t passes = starts.size() - 1;
    if (passes < static_cast<std::size_t>(p) + 2) {
        account_for_correlated_residuals(batch, phi, y, rows.index, fit.correlation_block);
        return;
    }
    std::vector<double> within(rows.index.size()), mean(passes), direction(passes);
    Eigen::MatrixXd sums(p, static_cast<Eigen::Index>(passes));
    double squares = 0.0;
    for (std::size_t q = 0; q < passes; ++q) {
        const auto first = static_cast<Eigen::Index>(starts[q]), n = static_cast<Eigen::Index>(starts[q + 1]) - first;
        mean[q] = residual.segment(first, n).mean();
        direction[q] = rows.velocity(first) > 0.0 ? 1.0 : -1.0;
        sums.col(static_cast<Eigen::Index>(q)) = phi.middleRows(first, n).colwise().sum().transpose();
        for (std::size_t i = starts[q]; i < starts[q + 1]; ++i) {
            within[i] = residual(static_cast<Eigen::Index>(i)) - mean[q];
            squares += within[i] * within[i];
        }
    }
    const double within_variance = squares / static_cast<double>(rows.index.size() - passes);
    const double inflation = std::max(1.0, 2.0 * integrated_autocorrelation_time(rows.index, within));
    double excess = 0.0;
    for (std::size_t q = 0; q < passes; ++q)
        excess += mean[q] * mean[q] - inflation * within_variance / static_cast<double>(starts[q + 1] - starts[q]);
    double level_variance = std::max(0.0, excess / static_cast<double>(passes - static_cast<std::size_t>(p)));
    std::vector<double> magnitude(passes);
    for (std::size_t q = 0; q < passes; ++q) magnitude[q] = mean[q] * direction[q];
    const double rho = level_correlation(magnitude, level_variance);
    // the run's mean level, which the fit absorbs, varies (1 + rho) / (1 - rho) times as much as P independent
    // levels' (whose share the P - p above counts already): at most a factor 3 / 2
    level_variance /= 1.0 - 2.0 * rho / ((1.0 - rho) * static_cast<double>(passes));
    LeastSquaresResult blocks = batch;  // the batch means of e alone, for the larger of the two below
    account_for_correlated_residuals(blocks, phi, y, rows.index, fit.correlation_block);
    const Eigen::VectorXd w = Eigen::Map<const Eigen::VectorXd>(within.data(), static_cast<Eigen::Index>(within.size()));
    const Eigen::MatrixXd inverse_information = batch.covariance / (batch.residual_std * batch.residual_std);
    const Eigen::MatrixXd middle = long_run_covariance(phi, w, rows.index, fit.correlation_block) +
                                   level_variance * correlated_level_sum(sums, direction, rho);
    batch.covariance = inverse_information * middle * inverse_information;
    batch.standard_error = batch.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    // each parameter's standard error the larger of the two (the pass levels' correlations kept): with no scatter
    // of the levels beyond their noise (s_u = 0) the batch means of e count the short correlations the within-pass
    // residual lost with its pass means
    const Eigen::VectorXd scale =
        blocks.standard_error.cwiseMax(batch.standard_error).cwiseQuotient(batch.standard_error.cwiseMax(1e-300));
    batch.covariance = scale.asDiagonal() * batch.covariance * scale.asDiagonal();
    batch.standard_error = batch.standard_error.cwiseProduct(scale);
    fit.passes = passes;
    fit.pass_level_std = std::sqrt(level_variance);
    fit.level_correlation = rho;
}
}  // namespace

Resolution assess_resolution(const Derivatives& d, const FrictionOnlyOptions& options, double moving_speed) {
    Resolution r;
    const double dt = d.sample_time_s * d.used.decimation;
    r.sample_rate_hz = 1.0 / dt;
    r.position_quantum = d.position_quantum;
    const auto& v = steady_source(d).velocity;
    if (v.size() < 2) return r;
    const auto moving = [&](std::size_t k) { return !(moving_speed > 0.0) || std::abs(v[k]) > moving_speed; };
    const auto each_moving = [&](const auto& f) {
        for (std::size_t k = 0; k < v.size(); ++k)
            if (moving(k)) f(v[k]);
    };
    const std::size_t moving_count = visited_count(each_moving);
    if (moving_count < 2) return r;
    r.typical_speed = absolute_percentile_of(moving_count, each_moving, 0.95);
    // whether the steps' 99th percentile exceeds the limit, by counting the steps at or below it (the element of
    // rank i exceeds it exactly when at most i steps do not); the percentile itself, for the description, only then
    constexpr double step_fraction = 0.99;  // Resolution::largest_speed_step's percentile
    const double limit = options.unresolved_speed_step_fraction * r.typical_speed;
    std::size_t steps = 0, within = 0;
    for (std::size_t k = 1; k < v.size(); ++k) {
        if (!moving(k) && !moving(k - 1)) continue;
        ++steps;
        within += std::abs(v[k] - v[k - 1]) <= limit ? 1 : 0;
    }
    if (steps == 0) return r;
    const double travel = r.typical_speed * dt;
    r.position_too_coarse = r.position_quantum > options.coarse_position_fraction * travel;
    r.accelerations_unresolved = within <= percentile_rank(steps, step_fraction);
    if (r.accelerations_unresolved) {
        std::vector<double> step_sizes;
        step_sizes.reserve(steps);
        for (std::size_t k = 1; k < v.size(); ++k)
            if (moving(k) || moving(k - 1)) step_sizes.push_back(std::abs(v[k] - v[k - 1]));
        r.largest_speed_step = percentile(std::move(step_sizes), step_fraction);
    }
    const Display display{d.rotary};
    r.description = fmt::format("{:.4g} Hz sampling", r.sample_rate_hz);
    if (r.position_quantum > 0.0) {
        r.description += fmt::format(
            " and {:.3g} {} position resolution ({:.3g} {} of travel per sample at the typical "
            "speed {:.3g} {})",
            display.length(r.position_quantum), display.length_unit(), display.length(travel), display.length_unit(),
            display.length(r.typical_speed), display.speed_unit());
    }
    if (r.accelerations_unresolved) {
        r.description += fmt::format(
            "; the speed changes by up to {:.3g} {} between two samples ({:.0f} % of the typical speed): the "
            "accelerations last only a few samples and are not resolved",
            display.length(r.largest_speed_step), display.speed_unit(), 100.0 * r.largest_speed_step / r.typical_speed);
    }
    return r;
}

Resolution assess_trace_resolution(const Trace& trace, std::span<const double> force,
                                   const PreprocessOptions& preprocess_options, const FrictionOnlyOptions& options,
                                   double moving_speed) {
    Derivatives d;
    try {
        d = preprocess(trace, force, preprocess_options);
    } catch (const InputError&) {
        return {};
    }
    if (!d.failure.empty() || d.velocity.size() < 2) return {};
    return assess_resolution(d, options, moving_speed);
}

FrictionOnlyFit fit_friction_only(const Derivatives& d, const Selection& s, FrictionModelKind model, bool offset,
                                  const FrictionOnlyOptions& options) {
    FrictionOnlyFit fit;
    for (const auto& column : linear_columns(model, offset)) {
        if (column.term != Term::mass) fit.columns.push_back(column);
    }
    std::vector<std::size_t> rows = steady_samples(d, s, options);
    fit.samples = rows.size();
    for (const auto k : s.moving)
        fit.largest_acceleration = std::max(fit.largest_acceleration, std::abs(d.acceleration[k]));
    const std::size_t needed = options.minimum_samples_per_parameter * fit.columns.size();
    if (rows.size() < needed) {
        fit.failure = fmt::format("only {} steady-speed samples ({} needed)", rows.size(), needed);
        return fit;
    }
    if (auto problem = speed_spread_problem(d, rows, model, options, needed / fit.columns.size() * 2);
        !problem.empty()) {
        fit.failure = std::move(problem);
        return fit;
    }
    const SteadySource source = steady_source(d);
    const auto& v = source.velocity;
    Eigen::MatrixXd phi(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(fit.columns.size()));
    Eigen::VectorXd y(static_cast<Eigen::Index>(rows.size())), velocity(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const double x = v[rows[i]];
        const auto row = static_cast<Eigen::Index>(i);
        y(row) = source.force[rows[i]];
        velocity(row) = x;
        for (std::size_t c = 0; c < fit.columns.size(); ++c) {
            const auto& column = fit.columns[c];
            const bool forward = column.direction == Direction::forward,
                       reverse = column.direction == Direction::reverse;
            double value = 1.0;  // the offset
            if (column.term == Term::viscous) value = forward ? std::max(x, 0.0) : reverse ? std::min(x, 0.0) : x;
            if (column.term == Term::coulomb) value = forward ? (x > 0.0) : reverse ? -double(x < 0.0) : sign(x);
            phi(row, static_cast<Eigen::Index>(c)) = value;
        }
    }
    fit.batch = solve_least_squares(phi, y);
    SteadyRows steady{std::move(rows), {}, std::move(velocity)};
    steady.pass = pass_of_rows(steady.index);
    if (options.robust && !fit.batch.rank_deficient) {
        apply_robust_weights(fit, phi, y, steady, options);
        if (fit.failed()) return fit;
    }
    fit.correlation_block = correlation_block(d, options.correlation_blocks);
    account_for_pass_levels(fit, phi, y, steady);
    if (fit.batch.rank_deficient) {
        fit.failure =
            "the steady-speed samples cannot separate the friction parameters (one direction only, and an "
            "offset?)";
        return fit;
    }
    if (fit.largest_acceleration > 0.0)
        fit.smallest_detectable_mass =
            options.detectable_force_multiple * fit.batch.residual_std / fit.largest_acceleration;
    return fit;
}

}  // namespace feedid
