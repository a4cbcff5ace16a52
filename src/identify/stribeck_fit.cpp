#include "feedid/identify/stribeck_fit.hpp"

#include "feedid/numeric/least_squares.hpp"

#include "feedid/model/friction.hpp"
#include "feedid/core/parameters.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Dense>
#include <unsupported/Eigen/LevenbergMarquardt>

namespace feedid::detail {

LogLinearStribeck fit_log_linear(const FitSamples& samples, double mass, double viscous, double coulomb, double offset,
                                 double noise_level, const RlsOptions& rls_options) {
    return fit_log_linear_over(
        samples.size(),
        [&](std::size_t k) {
            return std::array<double, 3>{samples.acceleration[k], samples.velocity[k], samples.force[k]};
        },
        mass, viscous, coulomb, offset, noise_level, rls_options);
}

CurveLayout::CurveLayout(const CurveModel& model) {
    int next = 0;
    if (model.mass) mass = next++;
    const int groups = model.asymmetric ? 2 : 1;
    for (int g = 0; g < groups; ++g) {
        viscous[g] = next++;
        coulomb[g] = next++;
        const bool stribeck = g == 0 ? model.stribeck_forward : model.stribeck_reverse;
        if (stribeck) {
            delta[g] = next++;
            log_vs[g] = next++;
        }
    }
    if (model.offset) offset = next++;
    size = next;
}

double CurveLayout::friction(const Eigen::VectorXd& x, double velocity, bool asymmetric) const {
    const int g = group(velocity, asymmetric);
    const bool stribeck = delta[g] >= 0;
    const double rise = stribeck ? x(delta[g]) : 0.0;
    const double inverse_vs = stribeck ? std::exp(-x(log_vs[g])) : 0.0;
    const FrictionLaw law{x(viscous[g]), x(coulomb[g]), rise, inverse_vs};
    double f = sign(velocity) * law.magnitude(std::abs(velocity));
    if (offset >= 0) f += x(offset);
    return f;
}

namespace {

struct CurveFunctor : Eigen::DenseFunctor<double> {
    CurveFunctor(const FitSamples& samples, const CurveModel& model, const CurveLayout& layout)
        : Eigen::DenseFunctor<double>(layout.size, static_cast<int>(samples.size())),
          samples_(samples),
          model_(model),
          layout_(layout) {}

    int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& residual) const {
        for (std::size_t k = 0; k < samples_.size(); ++k) {
            residual(static_cast<Eigen::Index>(k)) = (predict(x, k) - samples_.force[k]) * samples_.root_weight(k);
        }
        return 0;
    }

    int df(const Eigen::VectorXd& x, Eigen::MatrixXd& jacobian) const {
        jacobian.setZero();
        for (std::size_t k = 0; k < samples_.size(); ++k) {
            const auto row = static_cast<Eigen::Index>(k);
            const double v = samples_.velocity[k];
            const double s = sign(v);
            const int g = layout_.group(v, model_.asymmetric);
            if (layout_.mass >= 0) jacobian(row, layout_.mass) = samples_.acceleration[k];
            jacobian(row, layout_.viscous[g]) = v;
            jacobian(row, layout_.coulomb[g]) = s;
            if (layout_.delta[g] >= 0) {
                const double vs = std::exp(x(layout_.log_vs[g]));
                const double decay = std::exp(-std::abs(v) / vs);
                jacobian(row, layout_.delta[g]) = s * decay;
                // d/d(ln v_s) exp(-|v|/v_s) = exp(-|v|/v_s) * |v|/v_s
                jacobian(row, layout_.log_vs[g]) = s * x(layout_.delta[g]) * decay * std::abs(v) / vs;
            }
            if (layout_.offset >= 0) jacobian(row, layout_.offset) = 1.0;
            if (!samples_.weight.empty()) jacobian.row(row) *= samples_.root_weight(k);
        }
        return 0;
    }

    [[nodiscard]] double predict(const Eigen::VectorXd& x, std::size_t k) const {
        const double inertia = layout_.mass >= 0 ? x(layout_.mass) * samples_.acceleration[k] : 0.0;
        return inertia + layout_.friction(x, samples_.velocity[k], model_.asymmetric);
    }

    const FitSamples& samples_;
    const CurveModel& model_;
    const CurveLayout& layout_;
};

// Variable projection: for fixed v_s per group the model is linear in the rest; solve it by normal equations and
// return the residual sum of squares, filling the linear parameters of x.
double solve_linear_part(const FitSamples& samples, const CurveModel& model, const CurveLayout& layout,
                         Eigen::VectorXd& x) {
    const int p = layout.size;
    Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(p, p);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(p);
    Eigen::VectorXd row(p);
    double yy = 0.0;
    for (std::size_t k = 0; k < samples.size(); ++k) {
        row.setZero();
        const double v = samples.velocity[k];
        const double s = sign(v);
        const int g = layout.group(v, model.asymmetric);
        if (layout.mass >= 0) row(layout.mass) = samples.acceleration[k];
        row(layout.viscous[g]) = v;
        row(layout.coulomb[g]) = s;
        if (layout.delta[g] >= 0) row(layout.delta[g]) = s * std::exp(-std::abs(v) / std::exp(x(layout.log_vs[g])));
        if (layout.offset >= 0) row(layout.offset) = 1.0;
        const double w = samples.root_weight(k);
        row *= w;
        add_outer_product_lower(normal, row.data());
        add_scaled(rhs.data(), row.data(), w * samples.force[k], p);
        yy += w * w * samples.force[k] * samples.force[k];
    }
    // the ln v_s entries are not linear parameters: pin them (unit diagonal, zero right-hand side)
    for (int g = 0; g < 2; ++g) {
        if (layout.log_vs[g] >= 0) {
            normal.row(layout.log_vs[g]).setZero();
            normal.col(layout.log_vs[g]).setZero();
            normal(layout.log_vs[g], layout.log_vs[g]) = 1.0;
            rhs(layout.log_vs[g]) = 0.0;
        }
    }
    const Eigen::MatrixXd full = normal.selfadjointView<Eigen::Lower>();
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(full);
    if (ldlt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
    Eigen::VectorXd solution = ldlt.solve(rhs);
    double rss = yy - 2.0 * solution.dot(rhs) + solution.dot(full * solution);
    for (int g = 0; g < 2; ++g) {
        if (layout.log_vs[g] >= 0) solution(layout.log_vs[g]) = x(layout.log_vs[g]);
    }
    x = solution;
    return rss;
}

}  // namespace

namespace {

/// Starting values for Levenberg-Marquardt: a grid search over ln v_s, one group at a time (twice round for two
/// groups), on an evenly spread subsample of at most 20000 samples, with the linear parameters projected out. It only
/// has to find the basin; Levenberg-Marquardt then uses every sample.
Eigen::VectorXd grid_search(const FitSamples& samples, const CurveModel& model, const CurveLayout& layout,
                            double vs_low, double vs_high) {
    constexpr std::size_t coarse_samples = 20000;
    constexpr int grid_points = 41;
    Eigen::VectorXd x = Eigen::VectorXd::Zero(layout.size);
    const double mid = std::sqrt(vs_low * vs_high);
    for (int g = 0; g < 2; ++g) {
        if (layout.log_vs[g] >= 0) x(layout.log_vs[g]) = std::log(mid);
    }
    FitSamples coarse;
    const std::size_t coarse_stride = std::max<std::size_t>(1, samples.size() / coarse_samples);
    for (std::size_t k = 0; k < samples.size(); k += coarse_stride) {
        coarse.push(samples.acceleration[k], samples.velocity[k], samples.force[k], samples.index[k]);
        if (!samples.weight.empty()) coarse.weight.push_back(samples.weight[k]);
    }
    const int rounds = model.asymmetric ? 2 : 1;
    double best_rss = solve_linear_part(coarse, model, layout, x);
    for (int round = 0; round < rounds; ++round) {
        for (int g = 0; g < 2; ++g) {
            if (layout.log_vs[g] < 0) continue;
            Eigen::VectorXd best = x;
            for (int i = 0; i < grid_points; ++i) {
                Eigen::VectorXd trial = x;
                trial(layout.log_vs[g]) =
                    std::log(vs_low) + (std::log(vs_high) - std::log(vs_low)) * i / (grid_points - 1.0);
                const double rss = solve_linear_part(coarse, model, layout, trial);
                if (rss < best_rss) {
                    best_rss = rss;
                    best = trial;
                }
            }
            x = best;
        }
    }
    return x;
}

/// Residual statistics and the covariance sigma^2 (J^T J)^-1 at the solution x (with ln v_s); the v_s entries are
/// turned into v_s by the delta method.
void fill_statistics(const FitSamples& samples, const CurveModel& model, const CurveLayout& layout,
                     const Eigen::VectorXd& x, CurveFit& fit) {
    const int p = layout.size;
    CurveFunctor functor(samples, model, layout);
    Eigen::VectorXd residual(static_cast<Eigen::Index>(samples.size()));
    functor(x, residual);
    Eigen::MatrixXd jacobian(static_cast<Eigen::Index>(samples.size()), p);
    functor.df(x, jacobian);
    const double rss = residual.squaredNorm();
    double yy = 0.0;
    for (const double f : samples.force) yy += f * f;
    fit.residual_std = std::sqrt(rss / static_cast<double>(samples.size() - static_cast<std::size_t>(p)));
    fit.relative_error_pct = yy > 0.0 ? 100.0 * std::sqrt(rss / yy) : 0.0;
    const Eigen::MatrixXd information = jacobian.transpose() * jacobian;
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(information);
    fit.covariance = Eigen::MatrixXd::Constant(p, p, std::numeric_limits<double>::infinity());
    if (qr.rank() == p) {
        const Eigen::MatrixXd inverse = qr.inverse();
        if (!samples.weight.empty()) {
            // weighted by the inverse variances of the bin means: (J^T W J)^-1 is the covariance itself
            fit.covariance = inverse;
        } else if (samples.correlation_block > 1) {
            fit.covariance =
                inverse * long_run_covariance(jacobian, residual, samples.index, samples.correlation_block) * inverse;
        } else {
            fit.covariance = fit.residual_std * fit.residual_std * inverse;
        }
    }
    fit.parameters = x;
    for (int g = 0; g < 2; ++g) {
        if (layout.log_vs[g] >= 0) {
            // delta method: v_s = exp(ln v_s), so its row and column of the covariance scale by v_s
            const double vs = std::exp(x(layout.log_vs[g]));
            fit.parameters(layout.log_vs[g]) = vs;
            fit.covariance.row(layout.log_vs[g]) *= vs;
            fit.covariance.col(layout.log_vs[g]) *= vs;
        }
    }
    fit.standard_errors = fit.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
}

}  // namespace

namespace {

/// One speed bin: its sums, and those of its clusters (the blocks of `correlation_block` consecutive samples, over
/// which residuals are correlated) for the variance of its mean.
struct SpeedBin {
    double n{0.0};
    double sum_v{0.0};
    double sum_f{0.0};
    double sum_ff{0.0};
    std::size_t cluster{std::numeric_limits<std::size_t>::max()};
    double cluster_sum{0.0};
    double cluster_n{0.0};
    double clusters{0.0};
    double sum_ss{0.0};  ///< sum over clusters of S_c^2 (S_c: the cluster's sum of forces)
    double sum_sn{0.0};  ///< ... of S_c n_c
    double sum_nn{0.0};  ///< ... of n_c^2

    void close_cluster() {
        if (cluster_n > 0.0) {
            sum_ss += cluster_sum * cluster_sum;
            sum_sn += cluster_sum * cluster_n;
            sum_nn += cluster_n * cluster_n;
            clusters += 1.0;
        }
        cluster_sum = 0.0;
        cluster_n = 0.0;
    }
    void add(double v, double f, std::size_t in_cluster) {
        if (in_cluster != cluster) {
            close_cluster();
            cluster = in_cluster;
        }
        n += 1.0;
        sum_v += v;
        sum_f += f;
        sum_ff += f * f;
        cluster_sum += f;
        cluster_n += 1.0;
    }
    [[nodiscard]] double mean() const { return sum_f / n; }
    /// Sum of squares about the mean: of the samples, and of the clusters' sums (sum_c (S_c - n_c mean)^2).
    [[nodiscard]] double within() const { return std::max(0.0, sum_ff - sum_f * sum_f / n); }
    [[nodiscard]] double between_clusters() const {
        const double m = mean();
        return std::max(0.0, sum_ss - 2.0 * m * sum_sn + m * m * sum_nn);
    }
};

/// A cluster's samples in one bin: their count and force sum (for the covariance of the binned fit).
struct ClusterPiece {
    std::size_t cluster;
    std::size_t bin;
    double n;
    double sum_f;
};

struct SpeedBins {
    std::vector<SpeedBin> bins;
    std::vector<ClusterPiece> pieces;  ///< in order of cluster
};

/// The samples' speed bins (|v| bins 1 % wide, per direction), and how each cluster's samples fall into them; no
/// bins when a speed is zero or not finite.
SpeedBins speed_bins(const FitSamples& samples) {
    double low = std::numeric_limits<double>::infinity();
    double high = 0.0;
    for (const double v : samples.velocity) {
        const double speed = std::abs(v);
        if (!(speed > 0.0) || !std::isfinite(speed)) return {};
        low = std::min(low, speed);
        high = std::max(high, speed);
    }
    const double width = std::log(1.01);
    const auto per_direction = static_cast<std::size_t>(std::log(high / low) / width) + 1;
    SpeedBins out;
    std::vector<SpeedBin> bins(2 * per_direction);
    const std::size_t block = std::max<std::size_t>(1, samples.correlation_block);
    std::size_t cluster = 0, cluster_start = 0, cluster_end = 0;  // the last cluster: a division per cluster met
    for (std::size_t k = 0; k < samples.size(); ++k) {
        const double v = samples.velocity[k];
        const std::size_t bin =
            std::min(per_direction - 1, static_cast<std::size_t>(std::log(std::abs(v) / low) / width)) +
            (v < 0.0 ? per_direction : 0);
        if (samples.index[k] < cluster_start || samples.index[k] >= cluster_end) {
            cluster = samples.index[k] / block;
            cluster_start = cluster * block;
            cluster_end = cluster_start + block;
        }
        bins[bin].add(v, samples.force[k], cluster);
        if (out.pieces.empty() || out.pieces.back().cluster != cluster || out.pieces.back().bin != bin)
            out.pieces.push_back({cluster, bin, 0.0, 0.0});
        out.pieces.back().n += 1.0;
        out.pieces.back().sum_f += samples.force[k];
    }
    std::vector<std::size_t> compact(bins.size());
    for (std::size_t b = 0; b < bins.size(); ++b) {
        compact[b] = out.bins.size();
        if (bins[b].n == 0.0) continue;
        bins[b].close_cluster();
        out.bins.push_back(bins[b]);
    }
    for (auto& piece : out.pieces) piece.bin = compact[piece.bin];
    std::stable_sort(out.pieces.begin(), out.pieces.end(),
                     [](const ClusterPiece& a, const ClusterPiece& b) { return a.cluster < b.cluster; });
    return out;
}

/// The bins as weighted samples: mean speed, mean force, and the inverse variance of the mean. A bin's variance is
/// its own, cluster-robust (sum_c (S_c - n_c mean)^2 / n^2, times C / (C - 1)), when it spans at least 5 clusters;
/// otherwise its own scatter (the pooled one below 10 samples) times the design effect pooled over the bins that do
/// (the ratio of their cluster-robust variances to their plain s^2 / n; the block length without any).
FitSamples weighted_bin_means(const std::vector<SpeedBin>& bins, std::size_t correlation_block) {
    constexpr double min_clusters = 5.0;
    constexpr double min_samples = 10.0;
    double within = 0.0, samples = 0.0, robust = 0.0, plain = 0.0;
    for (const auto& b : bins) {
        within += b.within();
        samples += b.n;
        if (b.clusters >= min_clusters && b.n > 1.0) {
            robust += b.between_clusters() * b.clusters / (b.clusters - 1.0) / b.n;
            plain += b.within() / (b.n - 1.0);
        }
    }
    const double pooled = within / std::max(1.0, samples - static_cast<double>(bins.size()));
    const double design_effect =
        plain > 0.0 ? std::max(1.0, robust / plain) : static_cast<double>(std::max<std::size_t>(1, correlation_block));
    FitSamples means;
    for (std::size_t i = 0; i < bins.size(); ++i) {
        const auto& b = bins[i];
        const double scatter = b.n >= min_samples ? b.within() / (b.n - 1.0) : pooled;
        double variance = design_effect * scatter / b.n;
        // a bin whose forces happen to agree exactly must not take all the weight
        variance = std::max(variance, 1e-6 * pooled / b.n);
        means.push(0.0, b.sum_v / b.n, b.mean(), i);
        means.weight.push_back(variance > 0.0 ? 1.0 / variance : 1.0);
    }
    return means;
}

/// The covariance (with ln v_s) of the weighted fit to the bin means, from the samples behind them: the sandwich
/// A^-1 (sum_c g_c g_c^T) A^-1 with A = sum_b w_b J_b J_b^T and g_c = sum_b (w_b / n_b) J_b (S_cb - n_cb f_b) over
/// the clusters c (S_cb, n_cb: the force sum and count of cluster c in bin b), times n / (n - p): the long-run
/// covariance the sample-by-sample fit uses, with the Jacobian taken at each bin's mean speed. Right whatever the
/// weights, which only make the estimate efficient.
Eigen::MatrixXd binned_covariance(const SpeedBins& binned, const FitSamples& means, const CurveModel& model,
                                  const CurveLayout& layout, const Eigen::VectorXd& x) {
    FitSamples plain = means;
    plain.weight.clear();
    const Eigen::MatrixXd jacobian = curve_jacobian(plain, model, x);
    const int p = layout.size;
    Eigen::MatrixXd information = Eigen::MatrixXd::Zero(p, p);
    Eigen::VectorXd fitted(static_cast<Eigen::Index>(means.size()));
    for (std::size_t b = 0; b < means.size(); ++b) {
        const auto row = static_cast<Eigen::Index>(b);
        information += means.weight[b] * jacobian.row(row).transpose() * jacobian.row(row);
        fitted(row) = layout.friction(x, means.velocity[b], model.asymmetric);
    }
    Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(p, p);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(p);
    double n = 0.0;
    for (std::size_t i = 0; i < binned.pieces.size(); ++i) {
        const auto& piece = binned.pieces[i];
        const auto row = static_cast<Eigen::Index>(piece.bin);
        g += (means.weight[piece.bin] / binned.bins[piece.bin].n) * (piece.sum_f - piece.n * fitted(row)) *
             jacobian.row(row).transpose();
        n += piece.n;
        if (i + 1 == binned.pieces.size() || binned.pieces[i + 1].cluster != piece.cluster) {
            meat += g * g.transpose();
            g.setZero();
        }
    }
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(information);
    if (qr.rank() < p) return Eigen::MatrixXd::Constant(p, p, std::numeric_limits<double>::infinity());
    const Eigen::MatrixXd inverse = qr.inverse();
    return inverse * meat * inverse * (n > p ? n / (n - p) : 1.0);
}

/// Residual statistics of the samples behind the bins, the curve evaluated at each bin's mean speed.
void binned_residual_statistics(const std::vector<SpeedBin>& bins, const CurveModel& model, const CurveLayout& layout,
                                const Eigen::VectorXd& x, CurveFit& fit) {
    double rss = 0.0, yy = 0.0, n = 0.0;
    for (const auto& b : bins) {
        const double f = layout.friction(x, b.sum_v / b.n, model.asymmetric);
        rss += std::max(0.0, b.sum_ff - 2.0 * f * b.sum_f + b.n * f * f);
        yy += b.sum_ff;
        n += b.n;
    }
    fit.residual_std = std::sqrt(rss / std::max(1.0, n - static_cast<double>(layout.size)));
    fit.relative_error_pct = yy > 0.0 ? 100.0 * std::sqrt(rss / yy) : 0.0;
    fit.samples = static_cast<std::size_t>(n);
}

/// The binned fit's covariance and residual statistics from the samples behind its bins (the fit to the means has
/// given the estimates).
void finish_binned_fit(const SpeedBins& binned, const FitSamples& means, const CurveModel& model, CurveFit& fit) {
    const CurveLayout layout(model);
    Eigen::VectorXd x = fit.parameters;  // back to ln v_s, the fit's internal form
    for (const int index : layout.log_vs) {
        if (index >= 0) x(index) = std::log(x(index));
    }
    binned_residual_statistics(binned.bins, model, layout, x, fit);
    fit.covariance = binned_covariance(binned, means, model, layout, x);
    for (const int index : layout.log_vs) {
        if (index < 0) continue;
        // delta method, as fill_statistics
        const double vs = fit.parameters(index);
        fit.covariance.row(index) *= vs;
        fit.covariance.col(index) *= vs;
    }
    fit.standard_errors = fit.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
}

}  // namespace

Eigen::VectorXd curve_residuals(const FitSamples& samples, const CurveModel& model, const Eigen::VectorXd& x) {
    const CurveLayout layout(model);
    Eigen::VectorXd residual(static_cast<Eigen::Index>(samples.size()));
    CurveFunctor(samples, model, layout)(x, residual);
    return residual;
}

Eigen::MatrixXd curve_jacobian(const FitSamples& samples, const CurveModel& model, const Eigen::VectorXd& x) {
    const CurveLayout layout(model);
    Eigen::MatrixXd jacobian(static_cast<Eigen::Index>(samples.size()), layout.size);
    CurveFunctor(samples, model, layout).df(x, jacobian);
    return jacobian;
}

CurveFit fit_curve(const FitSamples& samples, const CurveModel& model, double vs_low, double vs_high,
                   std::size_t bin_above) {
    if (!model.mass && samples.weight.empty() && samples.size() > bin_above) {
        const SpeedBins binned = speed_bins(samples);
        if (binned.bins.size() > 3 * static_cast<std::size_t>(CurveLayout(model).size)) {
            const FitSamples means = weighted_bin_means(binned.bins, samples.correlation_block);
            CurveFit fit = fit_curve(means, model, vs_low, vs_high);
            if (fit.parameters.size() > 0) finish_binned_fit(binned, means, model, fit);
            fit.samples = samples.size();
            return fit;
        }
    }
    const CurveLayout layout(model);
    CurveFit fit;
    fit.samples = samples.size();
    if (samples.size() <= static_cast<std::size_t>(layout.size) + 2 || !(vs_low > 0.0) || !(vs_high > vs_low)) {
        return fit;
    }
    Eigen::VectorXd x = grid_search(samples, model, layout, vs_low, vs_high);
    if (layout.log_vs[0] < 0 && layout.log_vs[1] < 0) {
        // linear model: the projection is the answer
        (void)solve_linear_part(samples, model, layout, x);
        fit.converged = true;
    } else {
        CurveFunctor functor(samples, model, layout);
        Eigen::LevenbergMarquardt<CurveFunctor> solver(functor);
        solver.setMaxfev(400);
        const auto status = solver.minimize(x);
        fit.iterations = static_cast<int>(solver.nfev());
        fit.converged = status == Eigen::LevenbergMarquardtSpace::RelativeReductionTooSmall ||
                        status == Eigen::LevenbergMarquardtSpace::RelativeErrorTooSmall ||
                        status == Eigen::LevenbergMarquardtSpace::RelativeErrorAndReductionTooSmall ||
                        status == Eigen::LevenbergMarquardtSpace::CosinusTooSmall;
        if (!x.allFinite()) fit.converged = false;
    }
    fill_statistics(samples, model, layout, x, fit);
    return fit;
}

}  // namespace feedid::detail
