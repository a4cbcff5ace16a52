// Identification of the cascaded P-PI gains from a trace (the paper's validation step; its Ref. 6).
//   with a logged velocity command:  v_cmd(k) = K_v*e(k - d) [+ k_ff*x_ref'(k - d)],    e = x_ref - x
//                                    F(k) = L[K_p*e_v + K_i*E_v + c](k),  e_v = v_cmd - v,  E_v = sum(e_v*T)
//   without it (the structure only): F(k) = L[K_p*(K_v*e - v) + K_i*sum(T*(K_v*e - v)) + c](k)
//                                        = L[th1*e + th2*(-v) + th3*sum(T*e) + th4*(-sum(T*v)) + c](k),
//                                    K_v = th1/th2, K_p = th2, K_i = th4   (th3 = K_i*K_v is left free)
// v is the controller's velocity measurement (x_k - x_{k-n})/(n*T); c is the integrator's initial state (it holds a
// weight or an offset); L is what lies between the force command and the logged drive signal: the current loop as
// a first-order lag with a fractional sample of delay,
//   y(k) = a*y(k-1) + (1-a)*((1-mu)*u(k) + mu*u(k-1)),  a = exp(-T/tau),
// which is exact for a lag sampled one integration step after the command. L commutes with the linear regression,
// so it filters every regressor column. The structure (n, reference delay d, tau, mu) is chosen by the smallest
// residual; the gains are then estimated by RLS on the normalised columns, with standard errors from the batch
// least-squares residuals.

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <stdexcept>
#include <tuple>
#include <type_traits>

#include <fmt/core.h>
#include <Eigen/Dense>

#include "feedid/core/error.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/numeric/gram_least_squares.hpp"
#include "feedid/numeric/least_squares.hpp"
#include "feedid/numeric/native_interval.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/core/trace.hpp"

namespace feedid {

std::string GainOptions::validate() const {
    if (velocity_difference_samples && (*velocity_difference_samples < 1 || *velocity_difference_samples > 8)) {
        return "--velocity-difference must be between 1 and 8 samples";
    }
    if (current_lag_s && !(*current_lag_s >= 0.0 && std::isfinite(*current_lag_s))) {
        return "--current-lag must be a time >= 0";
    }
    if (saturation_N && !(*saturation_N > 0.0 && std::isfinite(*saturation_N))) return "--saturation must be positive";
    if (servo_rate_hz && !(*servo_rate_hz > 0.0 && std::isfinite(*servo_rate_hz)))
        return "--servo-rate must be positive";
    if (!(rls.forgetting_factor > 0.0 && rls.forgetting_factor <= 1.0))
        return "the forgetting factor must be in (0, 1]";
    return {};
}

void set_drive_signal(GainOptions& options, const Trace& trace, const DriveConstants& drive,
                      std::optional<double> saturation_in_signal_units) {
    if (!trace.has(Role::force)) {
        if (const auto factor = drive.force_per_signal(trace)) {
            options.force_per_signal = *factor;
            if (const auto* current = trace.find(Role::current))
                options.signal_unit = current->unit.empty() ? current->source_unit : current->unit;
        }
    }
    if (saturation_in_signal_units) {
        options.saturation_N = std::abs(*saturation_in_signal_units) *
                               (options.force_per_signal != 0.0 ? std::abs(options.force_per_signal) : 1.0);
    }
}

namespace {

using Column = std::vector<double>;

// The lag-and-delay filter L above of `in` into `out` (its storage reused; `out` may be `in`); starts in steady state
// at the column's first value.
void filter_into(const Column& in, double a, double mu, Column& out) {
    out.resize(in.size());
    if (in.empty()) return;
    if (a == 0.0 && mu == 0.0) {
        if (&out != &in) std::copy(in.begin(), in.end(), out.begin());
        return;
    }
    double previous_in = in.front();
    double previous_out = in.front();
    for (std::size_t k = 0; k < in.size(); ++k) {
        const double value = in[k];
        const double filtered = a * previous_out + (1.0 - a) * ((1.0 - mu) * value + mu * previous_in);
        previous_in = value;
        previous_out = filtered;
        out[k] = filtered;
    }
}

// A structure's residual sum of squares in the search, and the drive filter's mu it was taken at.
struct StructureResidual {
    double rss{0.0};
    double mu{0.0};
};

struct Structure {
    int difference{1};       // n; 0 = the logged velocity channel
    int reference_delay{0};  // d
    double lag_s{0.0};       // tau
    double mu{0.0};
    int servo_delay_cycles{-1};  // on a servo grid: the delay in its cycles (-1: d of them per sample)

    bool operator==(const Structure&) const = default;
};

struct Problem {
    std::vector<Column> columns;  // regressors, filtered
    /// Each column's sum of squares over the used rows in the order of the rows, where whoever formed the columns
    /// summed them on the way; empty: normal_solution() sums them.
    std::vector<double> column_squares;
    std::size_t row_step{1};  // the samples between rows that follow each other (a held position's factor)
    const std::vector<char>* use{nullptr};

    /// What the regressors explain: a signal of the trace's, viewed (not copied for each candidate structure of a
    /// search), or the problem's own once changed.
    [[nodiscard]] const Column& y() const { return shared_y_ != nullptr ? *shared_y_ : own_y_; }
    void share_y(const Column& signal) { shared_y_ = &signal; }
    Column& own_y() {
        if (shared_y_ != nullptr) own_y_ = *shared_y_;
        shared_y_ = nullptr;
        return own_y_;
    }

private:
    const Column* shared_y_{nullptr};  // outlives the problem (the GainSignals')
    Column own_y_;
};

struct NormalSolution {
    Eigen::VectorXd theta;  // unscaled
    double rss{0.0};
};

// The least-squares fit on the selected rows (normal equations on normalised columns: fast enough for the structure
// search; the final estimate uses QR and RLS): its coefficients and residual sum of squares. Each pass over the rows
// has the column count Q known to the compiler (the structure search solves this hundreds of times) and keeps every
// sum in the order of the rows.
template <std::size_t Q>
std::array<const double*, Q> column_pointers(const Problem& problem) {
    std::array<const double*, Q> column{};
    for (std::size_t j = 0; j < Q; ++j) column[j] = problem.columns[j].data();
    return column;
}

/// The sum of squares of each column over the used rows (the Q sums side by side in one pass).
template <std::size_t Q>
void column_squares_of(const Problem& problem, Eigen::VectorXd& squares) {
    std::array<double, Q> sums{};
    const auto column = column_pointers<Q>(problem);
    const auto& use = *problem.use;
    const std::size_t n = problem.y().size();
    for (std::size_t k = 0; k < n; ++k) {
        if (!use[k]) continue;
        for (std::size_t j = 0; j < Q; ++j) sums[j] += column[j][k] * column[j][k];
    }
    for (std::size_t j = 0; j < Q; ++j) squares(static_cast<Eigen::Index>(j)) = sums[j];
}

/// Phi'Phi (lower triangle) and Phi'y of the used rows, the columns scaled, as a rank update per row would add them.
template <std::size_t Q>
void accumulate_normal_of(const Problem& problem, const Eigen::VectorXd& scale, Eigen::MatrixXd& normal,
                          Eigen::VectorXd& right, double& y_squares) {
    std::array<double, Q * Q> lower{};
    std::array<double, Q> sums{}, phi{}, factor{};
    double yy = 0.0;
    const auto column = column_pointers<Q>(problem);
    for (std::size_t j = 0; j < Q; ++j) factor[j] = scale(static_cast<Eigen::Index>(j));
    const auto& use = *problem.use;
    const auto& y = problem.y();
    for (std::size_t k = 0; k < y.size(); ++k) {
        if (!use[k]) continue;
        for (std::size_t j = 0; j < Q; ++j) phi[j] = column[j][k] * factor[j];
        for (std::size_t c = 0; c < Q; ++c) {
            for (std::size_t r = c; r < Q; ++r) lower[r * Q + c] += phi[c] * phi[r];
            sums[c] += phi[c] * y[k];
        }
        yy += y[k] * y[k];
    }
    y_squares = yy;
    for (std::size_t r = 0; r < Q; ++r) {
        right(static_cast<Eigen::Index>(r)) = sums[r];
        for (std::size_t c = 0; c <= r; ++c)
            normal(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = lower[r * Q + c];
    }
}

/// sum (y - Phi*diag(scale)*theta)^2 over the used rows.
template <std::size_t Q>
double residual_squares_of(const Problem& problem, const Eigen::VectorXd& scale, const Eigen::VectorXd& theta) {
    std::array<double, Q> factor{}, coefficient{};
    const auto column = column_pointers<Q>(problem);
    for (std::size_t j = 0; j < Q; ++j) {
        factor[j] = scale(static_cast<Eigen::Index>(j));
        coefficient[j] = theta(static_cast<Eigen::Index>(j));
    }
    const auto& use = *problem.use;
    const auto& y = problem.y();
    double rss = 0.0;
    for (std::size_t k = 0; k < y.size(); ++k) {
        if (!use[k]) continue;
        double fitted = 0.0;
        for (std::size_t j = 0; j < Q; ++j) fitted += column[j][k] * factor[j] * coefficient[j];
        rss += (y[k] - fitted) * (y[k] - fitted);
    }
    return rss;
}

/// Calls pass(std::integral_constant<std::size_t, Q>{}) for Q = count, 1 to 8 (the velocity loop
/// has at most 7: the structure's 5, a feed-forward's step, an injection's gain).
template <typename Pass>
void with_column_count(std::size_t count, Pass&& pass) {
    switch (count) {
        case 1: pass(std::integral_constant<std::size_t, 1>{}); return;
        case 2: pass(std::integral_constant<std::size_t, 2>{}); return;
        case 3: pass(std::integral_constant<std::size_t, 3>{}); return;
        case 4: pass(std::integral_constant<std::size_t, 4>{}); return;
        case 5: pass(std::integral_constant<std::size_t, 5>{}); return;
        case 6: pass(std::integral_constant<std::size_t, 6>{}); return;
        case 7: pass(std::integral_constant<std::size_t, 7>{}); return;
        case 8: pass(std::integral_constant<std::size_t, 8>{}); return;
        default: throw std::logic_error(fmt::format("{} regressor columns: at most 8", count));
    }
}

/// filter_into() for each of Q columns, side by side in one pass (each column's recursion waits on its last output),
/// and each filtered column's sum of squares over the used rows.
template <std::size_t Q>
void filter_columns_of(const std::vector<Column>& in, double a, double mu, const std::vector<char>& use, Problem& out) {
    const std::size_t n = in.front().size();
    const bool unchanged = a == 0.0 && mu == 0.0;  // no lag, no delay: L is the identity
    std::array<const double*, Q> from{};
    std::array<double*, Q> to{};
    std::array<double, Q> previous_in{}, previous_out{}, squares{};
    for (std::size_t j = 0; j < Q; ++j) {
        out.columns[j].resize(n);
        from[j] = in[j].data();
        to[j] = out.columns[j].data();
        previous_in[j] = previous_out[j] = in[j].front();
    }
    for (std::size_t k = 0; k < n; ++k) {
        for (std::size_t j = 0; j < Q; ++j) {
            const double value = from[j][k];
            const double filtered =
                unchanged ? value : a * previous_out[j] + (1.0 - a) * ((1.0 - mu) * value + mu * previous_in[j]);
            previous_in[j] = value;
            previous_out[j] = filtered;
            to[j][k] = filtered;
            if (use[k]) squares[j] += filtered * filtered;
        }
    }
    out.column_squares.assign(squares.begin(), squares.end());
}

/// L of the columns `in` into the first in.size() columns of `out` (their storage reused), with their sums of squares
/// over the used rows (`use`, the same length) where they are all of `out`'s columns.
void filter_columns(const std::vector<Column>& in, double a, double mu, const std::vector<char>& use, Problem& out) {
    with_column_count(in.size(), [&](auto q) { filter_columns_of<q()>(in, a, mu, use, out); });
    if (out.column_squares.size() != out.columns.size()) out.column_squares.clear();
}

// The drive filter at any mu from its response at mu = 0: L is linear in its input and starts in steady state, so
//   L_(a,mu)[u](k) = (1 - mu)*L_(a,0)[u](k) + mu*L_(a,0)[u](k - 1)
// (L_(a,0)[u](-1) = u(0)). The normal equations of every mu at one lag are therefore combinations of the Gram matrix
// of z = L_(a,0)[u] of each column, z(k - 1) and the drive signal y: (z_1..z_Q, z_1(k-1)..z_Q(k-1), y), summed over
// the used rows in one pass that filters on the way, a block of rows at a time as GramMatrix sums them. The sums serve
// to rank structures, not to fit them, so their order is free: four rows at a time, in two partial sums per entry
// (which the compiler keeps in vector registers), the filters' recursions running row by row beside them.
template <std::size_t Q>
GramMatrix lag_gram_of(const std::vector<Column>& in, double a, const std::vector<char>& use, const Column& y) {
    constexpr std::size_t width = 2 * Q + 1, entries = width * (width + 1) / 2;
    constexpr std::size_t lanes = 4, block_rows = 4096;
    std::array<const double*, Q> from{};
    std::array<double, Q> filtered{};                       // z(k)
    alignas(16) std::array<double, lanes * width> value{};  // z(k), z(k - 1), y(k) of four rows, 0 where unused
    alignas(16) std::array<double, 2 * entries> partial{};  // the lower triangle's entries, two partial sums each
    for (std::size_t j = 0; j < Q; ++j) {
        from[j] = in[j].data();
        filtered[j] = in[j].front();
    }
    Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(width, width);
    const std::size_t n = y.size();
    for (std::size_t start = 0; start < n; start += block_rows) {
        partial.fill(0.0);
        const std::size_t end = std::min(n, start + block_rows);
        for (std::size_t k = start; k < end; k += lanes) {
            for (std::size_t lane = 0; lane < lanes; ++lane) {
                const std::size_t row = k + lane;
                const bool used = row < end && use[row] != 0;
                for (std::size_t j = 0; j < Q; ++j) {
                    const double previous = filtered[j];
                    if (row < end) filtered[j] = a * filtered[j] + (1.0 - a) * from[j][row];
                    value[lanes * j + lane] = used ? filtered[j] : 0.0;
                    value[lanes * (Q + j) + lane] = used ? previous : 0.0;
                }
                value[lanes * 2 * Q + lane] = used ? y[row] : 0.0;
            }
            std::size_t entry = 0;
            for (std::size_t r = 0; r < width; ++r) {
                for (std::size_t c = 0; c <= r; ++c, ++entry) {
                    const double* u = &value[lanes * r];
                    const double* v = &value[lanes * c];
                    partial[2 * entry] += u[0] * v[0] + u[2] * v[2];
                    partial[2 * entry + 1] += u[1] * v[1] + u[3] * v[3];
                }
            }
        }
        std::size_t entry = 0;
        for (Eigen::Index r = 0; r < static_cast<Eigen::Index>(width); ++r) {
            for (Eigen::Index c = 0; c <= r; ++c, ++entry) gram(r, c) += partial[2 * entry] + partial[2 * entry + 1];
        }
    }
    Eigen::MatrixXd full = gram.selfadjointView<Eigen::Lower>();
    return GramMatrix(std::move(full));
}

// The residual sum of squares at each of `mus` from lag_gram_of()'s matrix of Q columns (GramMatrix::solve(): to about
// 1e-12 of y'y, enough to rank fits that leave the drive signal's noise).
std::vector<double> residuals_at_each_mu(const GramMatrix& gram, std::size_t q, std::span<const double> mus) {
    const auto columns = static_cast<Eigen::Index>(q);
    const Eigen::VectorXd right = Eigen::VectorXd::Unit(2 * columns + 1, 2 * columns);
    std::vector<double> residuals;
    for (const double mu : mus) {
        Eigen::MatrixXd combination = Eigen::MatrixXd::Zero(2 * columns + 1, columns);
        for (Eigen::Index j = 0; j < columns; ++j) {
            combination(j, j) = 1.0 - mu;
            combination(columns + j, j) = mu;
        }
        residuals.push_back(gram.solve(combination, right).rss);
    }
    return residuals;
}

// The normal equations of a problem on normalised columns and their solution: the first two passes of
// normal_solution(), the residual's pass left to residual_squares().
struct NormalEquations {
    Eigen::VectorXd scale;   // 1/||column|| (1 for a column of zeros)
    Eigen::MatrixXd normal;  // Phi'Phi of the scaled columns
    Eigen::VectorXd right;   // Phi'y
    Eigen::VectorXd theta;   // the solution, on the scaled columns
    double y_squares{0.0};   // y'y
    std::size_t rows{0};     // the rows summed over (at most)
};

NormalEquations normal_equations(const Problem& problem) {
    const auto p = static_cast<Eigen::Index>(problem.columns.size());
    NormalEquations equations;
    Eigen::VectorXd& scale = equations.scale;
    scale.resize(p);
    const std::size_t count = problem.columns.size();
    if (problem.column_squares.size() == count)
        scale = Eigen::Map<const Eigen::VectorXd>(problem.column_squares.data(), p);
    else
        with_column_count(count, [&](auto q) { column_squares_of<q()>(problem, scale); });
    for (Eigen::Index j = 0; j < p; ++j) scale(j) = scale(j) > 0.0 ? 1.0 / std::sqrt(scale(j)) : 1.0;
    Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(p, p);
    equations.right = Eigen::VectorXd::Zero(p);
    with_column_count(count, [&](auto q) {
        accumulate_normal_of<q()>(problem, scale, normal, equations.right, equations.y_squares);
    });
    equations.normal = normal.selfadjointView<Eigen::Lower>();
    equations.theta = equations.normal.ldlt().solve(equations.right);
    equations.rows = problem.y().size();
    return equations;
}

// sum (y - Phi*theta)^2 over the used rows, the residual's pass (infinity where it is not a finite number).
double residual_squares(const Problem& problem, const NormalEquations& equations) {
    double rss = 0.0;
    with_column_count(problem.columns.size(),
                      [&](auto q) { rss = residual_squares_of<q()>(problem, equations.scale, equations.theta); });
    return std::isfinite(rss) ? rss : std::numeric_limits<double>::infinity();
}

// A number that residual_squares() is never below, from the normal equations alone (residual_lower_bound()).
double residual_lower_bound(const NormalEquations& equations) {
    return feedid::residual_lower_bound(equations.normal, equations.right, equations.y_squares, equations.theta,
                                        equations.rows);
}

NormalSolution normal_solution(const Problem& problem) {
    const NormalEquations equations = normal_equations(problem);
    return {equations.theta.cwiseProduct(equations.scale), residual_squares(problem, equations)};
}

double residual_sum_of_squares(const Problem& problem) { return normal_solution(problem).rss; }

struct Fit {
    Eigen::VectorXd estimate;    // RLS, unscaled
    Eigen::VectorXd batch;       // batch LS, unscaled
    Eigen::MatrixXd covariance;  // batch, unscaled
    double relative_error_pct{0.0};
    double systematic_error_pct{0.0};  // the part of the residual that is not white noise
    std::size_t samples{0};
    bool rank_deficient{false};
};

// 100*||r_s||/||y||, r_s the part of the residual r that is not white noise. Sensor noise on the drive signal is
// white; what the model lacks (an injected signal, a missing term) varies slowly from sample to sample. For white
// noise of variance s^2, E[(r_k - r_{k-1})^2] = 2*s^2 (von Neumann), while a slowly varying part barely changes the
// differences; so ||r_s||^2 = ||r||^2 - N*s^2 with s^2 from the differences of rows that follow each other.
double systematic_error_pct(const Eigen::VectorXd& residual, const std::vector<std::size_t>& rows, double target_norm,
                            std::size_t row_step) {
    double squares = 0.0;
    double differences = 0.0;
    std::size_t pairs = 0;
    for (Eigen::Index k = 0; k < residual.size(); ++k) {
        squares += residual(k) * residual(k);
        if (k > 0 && rows[static_cast<std::size_t>(k)] == rows[static_cast<std::size_t>(k - 1)] + row_step) {
            differences += (residual(k) - residual(k - 1)) * (residual(k) - residual(k - 1));
            ++pairs;
        }
    }
    if (pairs == 0 || !(target_norm > 0.0)) return 0.0;
    const double white = static_cast<double>(residual.size()) * differences / (2.0 * static_cast<double>(pairs));
    return 100.0 * std::sqrt(std::max(0.0, squares - white)) / target_norm;
}

template <int N>
Eigen::VectorXd run_rls(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const RlsOptions& options) {
    Rls<N> rls(options);
    typename Rls<N>::Vector row;
    for (Eigen::Index k = 0; k < phi.rows(); ++k) {
        row = phi.row(k).transpose();
        rls.update(row, y(k));
    }
    return rls.estimate();
}

// RLS (the paper) and batch QR on normalised columns; returns both in the original scaling.
Fit fit(const Problem& problem, const RlsOptions& options) {
    const auto p = static_cast<Eigen::Index>(problem.columns.size());
    const auto& y = problem.y();
    const auto& use = *problem.use;
    const auto rows = static_cast<Eigen::Index>(std::count(use.begin(), use.end(), char{1}));
    Eigen::MatrixXd phi(rows, p);
    Eigen::VectorXd target(rows);
    std::vector<std::size_t> sample_of_row(static_cast<std::size_t>(rows));
    Eigen::Index row = 0;
    for (std::size_t k = 0; k < y.size(); ++k) {
        if (!use[k]) continue;
        for (Eigen::Index j = 0; j < p; ++j) phi(row, j) = problem.columns[static_cast<std::size_t>(j)][k];
        target(row) = y[k];
        sample_of_row[static_cast<std::size_t>(row)] = k;
        ++row;
    }
    Eigen::VectorXd scale(p);
    for (Eigen::Index j = 0; j < p; ++j) {
        const double rms = phi.col(j).norm() / std::sqrt(static_cast<double>(std::max<Eigen::Index>(rows, 1)));
        scale(j) = rms > 0.0 ? rms : 1.0;
        phi.col(j) /= scale(j);
    }
    const double y_scale =
        std::max(target.norm() / std::sqrt(static_cast<double>(std::max<Eigen::Index>(rows, 1))), 1e-300);
    const double target_norm = target.norm() / y_scale;
    target /= y_scale;  // the scaled target, formed once for the batch fit, its residual and RLS
    const Eigen::VectorXd& scaled_target = target;
    const LeastSquaresResult batch = solve_least_squares(phi, scaled_target);
    Fit result;
    result.samples = static_cast<std::size_t>(rows);
    result.rank_deficient = batch.rank_deficient;
    result.relative_error_pct = batch.relative_error_pct;
    if (!batch.rank_deficient) {
        const Eigen::VectorXd residual = scaled_target - phi * batch.estimate;
        result.systematic_error_pct = systematic_error_pct(residual, sample_of_row, target_norm, problem.row_step);
    }
    Eigen::VectorXd rls;
    switch (p) {
        case 1: rls = run_rls<1>(phi, scaled_target, options); break;
        case 2: rls = run_rls<2>(phi, scaled_target, options); break;
        case 3: rls = run_rls<3>(phi, scaled_target, options); break;
        case 4: rls = run_rls<4>(phi, scaled_target, options); break;
        case 5: rls = run_rls<5>(phi, scaled_target, options); break;
        case 6: rls = run_rls<6>(phi, scaled_target, options); break;  // PI structure and an injection's gain
        default: rls = run_rls<7>(phi, scaled_target, options); break;  // ... and a feed-forward's step
    }
    const Eigen::VectorXd unscale = scale.cwiseInverse() * y_scale;
    result.estimate = rls.cwiseProduct(unscale);
    result.batch = batch.estimate.cwiseProduct(unscale);
    result.covariance = unscale.asDiagonal() * batch.covariance * unscale.asDiagonal();
    return result;
}

// The relative resolution of a gain: a deterministic loop (a position loop logged with its command) fits to the last
// digits, and its residual then gives standard errors of 1e-15 of the gain, while the rounding of the logged numbers
// and of the controller's and the fit's arithmetic moves the gain by 1e-11 to 1e-9 of it (synthetic traces; a
// single-precision controller resolves 6e-8). No gain is known better than this.
constexpr double gain_resolution = 1e-8;

// A gain and its standard error from the fit's variance: sqrt(variance), at least gain_resolution of the gain, where
// that is a finite number >= 0, none otherwise (Estimate's rule). Unlike Estimate::of, a value that is not finite is
// kept as computed: the document writes it as null, and the controller and the printed report see what the fit gave.
Estimate estimate_from_variance(double value, double variance) {
    Estimate estimate;
    estimate.value = value;
    if (variance >= 0.0 && std::isfinite(variance)) {
        estimate.standard_error = std::sqrt(variance);
        if (std::isfinite(value))
            estimate.standard_error = std::max(*estimate.standard_error, gain_resolution * std::abs(value));
    }
    return estimate;
}

// Where K_p and K_i sit in the velocity loop's theta: (K_p, K_i, c) with the velocity command, and
// (K_p*K_v, K_p, K_i*K_v, K_i, c) from the structure alone.
struct GainIndices {
    Eigen::Index velocity_gain;
    Eigen::Index integral_gain;
};

GainIndices gain_indices(bool logged_command) {
    return logged_command ? GainIndices{0, 1} : GainIndices{1, 3};
}

// Var(a/b) by the delta method from the covariance of (a, b).
double ratio_variance(double a, double b, double var_a, double var_b, double cov_ab) {
    const double r = a / b;
    return (var_a - 2.0 * r * cov_ab + r * r * var_b) / (b * b);
}

// Velocity measurement with n-sample difference: (x_k - x_{k-n})/(n*T); the first samples use what exists.
Column difference_velocity(std::span<const double> x, int n, double dt) {
    Column v(x.size(), 0.0);
    for (std::size_t k = 0; k < x.size(); ++k) {
        const std::size_t back = k >= static_cast<std::size_t>(n) ? k - static_cast<std::size_t>(n) : 0;
        v[k] = (x[k] - x[back]) / (n * dt);
    }
    return v;
}

Column delayed(std::span<const double> x, int d) {
    Column out(x.size());
    for (std::size_t k = 0; k < x.size(); ++k)
        out[k] = x[k >= static_cast<std::size_t>(d) ? k - static_cast<std::size_t>(d) : 0];
    return out;
}

Column running_sum(const Column& x, double dt) {
    Column out(x.size());
    double sum = 0.0;
    for (std::size_t k = 0; k < x.size(); ++k) {
        sum += x[k] * dt;
        out[k] = sum;
    }
    return out;
}

// The candidate lag time constants [in samples] and fractional delays of the coarse search.
constexpr std::array<double, 12> lag_grid{0.0, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0, 1.4, 2.0, 3.0, 5.0};
constexpr std::array<double, 5> mu_grid{0.0, 0.25, 0.5, 0.75, 1.0};

double lag_coefficient(double lag_s, double dt) {
    return lag_s > 0.0 ? std::exp(-dt / lag_s) : 0.0;
}

// e(k) = x_ref(k - d) - x(k): the following error against the reference delayed by d samples.
Column following_error(std::span<const double> reference, std::span<const double> position, int delay) {
    Column error(position.size());
    for (std::size_t k = 0; k < error.size(); ++k) {
        const std::size_t j = k >= static_cast<std::size_t>(delay) ? k - static_cast<std::size_t>(delay) : 0;
        error[k] = reference[j] - position[k];
    }
    return error;
}

// The signals the gains are identified from.
struct GainSignals {
    std::string source;  // the trace's file, for messages
    bool rotary{false};  // rad and N*m instead of m and N
    std::size_t samples{0};
    double dt{0.0};                     // T [s]
    int hold_factor{1};                 // the position signal holds each value over this many samples
    int hold_phase{0};                  // the rows (k % hold_factor) where it takes a new value
    Column interpolated_position;       // a held position interpolated between its own samples (else empty)
    std::span<const double> position;   // x [m]
    std::span<const double> reference;  // x_ref [m]
    const Channel* velocity{nullptr};   // the logged velocity, when there is one
    bool logged_command{false};         // whether the trace holds the velocity command
    Column velocity_command;            // v_cmd [m/s], when logged
    Column force;                       // F [N]
    Column injection;                   // the test signal added to the controller's output [N]; empty = none
};

// A position held over k >= 2 samples (sampled at the position loop's cycle, the drive signal at the velocity loop's):
// the controller holds its reference and velocity command too, so those are exact at every sample, while the position
// it measured between its samples is interpolated (interpolate_held()). The regressions use the rows where the
// position is new.
void use_native_rate(const Trace& trace, GainSignals& signals) {
    const auto factor = static_cast<int>(std::lround(native_interval_of(trace, Role::position) / signals.dt));
    if (factor < 2) return;
    signals.hold_factor = factor;
    signals.hold_phase = hold_phase(signals.position, factor);
    signals.interpolated_position = interpolate_held(signals.position, factor, signals.hold_phase);
    signals.position = signals.interpolated_position;
}

// The trace's position, reference, velocity command and velocity, and the drive force, checked: position and
// reference there, as many force samples as trace samples, and enough of them.
GainSignals gain_signals(const Trace& trace, std::span<const double> drive_force, std::span<const double> injection) {
    GainSignals signals;
    signals.source = trace.source_path.empty() ? std::string("trace") : trace.source_path;
    signals.rotary = trace.rotary;
    const auto* reference_channel = trace.find(Role::reference_position);
    const auto* position_channel = trace.find(Role::position);
    if (position_channel == nullptr) {
        throw InputError(fmt::format("{}: no position channel: map one with --channel position=NAME", signals.source));
    }
    if (reference_channel == nullptr) {
        throw InputError(
            fmt::format("{}: no reference position channel, which the position loop's following error "
                        "needs: map one with --channel reference_position=NAME",
                        signals.source));
    }
    const std::size_t n = trace.samples();
    if (drive_force.size() != n)
        throw InputError(
            fmt::format("{}: the drive force has {} samples, the trace {}", signals.source, drive_force.size(), n));
    if (!injection.empty() && injection.size() != n)
        throw InputError(
            fmt::format("{}: the injection has {} samples, the trace {}", signals.source, injection.size(), n));
    if (n < 50) {
        throw AnalysisError(fmt::format("{}: {} samples are too few to identify controller gains", signals.source, n));
    }
    signals.samples = n;
    signals.dt = trace.time_base().sample_time_s;
    signals.position = position_channel->values;
    signals.reference = reference_channel->values;
    use_native_rate(trace, signals);
    signals.velocity = trace.find(Role::velocity);
    if (const auto* command_channel = trace.find(Role::velocity_command)) {
        signals.logged_command = true;
        signals.velocity_command.assign(command_channel->values.begin(), command_channel->values.end());
    }
    signals.force.assign(drive_force.begin(), drive_force.end());
    signals.injection.assign(injection.begin(), injection.end());
    return signals;
}

// Only the rows where a held position is new (all rows when it is not held).
void keep_fresh_rows(const GainSignals& signals, std::vector<char>& use) {
    if (signals.hold_factor < 2) return;
    const auto factor = static_cast<std::size_t>(signals.hold_factor);
    for (std::size_t k = 0; k < use.size(); ++k) {
        if (k % factor != static_cast<std::size_t>(signals.hold_phase)) use[k] = 0;
    }
}

// The following error must carry signal, or no position gain can be seen.
void require_following_error(const GainSignals& signals) {
    double following_rms = 0.0;
    for (std::size_t k = 0; k < signals.samples; ++k) {
        following_rms += (signals.reference[k] - signals.position[k]) * (signals.reference[k] - signals.position[k]);
    }
    following_rms = std::sqrt(following_rms / static_cast<double>(signals.samples));
    if (!(following_rms > 0.0)) {
        throw AnalysisError(
            fmt::format("{}: the position equals the reference everywhere (no following error), so the "
                        "position gain cannot be identified; a trace of a motion with the position "
                        "loop closed would",
                        signals.source));
    }
}

// Every row but the first ones, where the differences and filters start up.
std::vector<char> rows_past_start_up(std::size_t n) {
    std::vector<char> use(n, 1);
    for (std::size_t k = 0; k < std::min<std::size_t>(n, 10); ++k) use[k] = 0;
    return use;
}

// The velocity loop's rows: past the start-up, not at the force limit, with a finite force. The limit holds for the
// controller's output F - u_inj (before an injected signal is added) and for the drive's command F.
std::vector<char> velocity_loop_rows(const GainSignals& signals, std::optional<double> saturation_N,
                                     std::vector<std::string>& diagnostics) {
    const Column& force = signals.force;
    std::vector<char> use = rows_past_start_up(force.size());
    if (saturation_N) {
        std::size_t saturated = 0;
        for (std::size_t k = 0; k < force.size(); ++k) {
            const double controller_output = signals.injection.empty() ? force[k] : force[k] - signals.injection[k];
            if (std::max(std::abs(force[k]), std::abs(controller_output)) >= 0.999 * *saturation_N) {
                use[k] = 0;
                ++saturated;
            }
        }
        if (saturated > 0) diagnostics.push_back(fmt::format("{} samples at the force limit left out", saturated));
    }
    for (std::size_t k = 0; k < force.size(); ++k) {
        if (!std::isfinite(force[k])) use[k] = 0;
    }
    return use;
}

// The structures the search chooses from.
struct SearchSpace {
    std::vector<int> differences;       // n of the velocity measurement; 0 = the logged velocity
    std::vector<int> reference_delays;  // d
    std::vector<double> lags;           // tau [s]
};

SearchSpace search_space(const GainSignals& signals, const GainOptions& options) {
    SearchSpace space;
    if (options.velocity_difference_samples)
        space.differences.push_back(*options.velocity_difference_samples);
    else
        space.differences = {1, 2, 3, 4};
    if (signals.velocity != nullptr && !options.velocity_difference_samples) space.differences.push_back(0);
    space.reference_delays = signals.logged_command ? std::vector<int>{0} : std::vector<int>{0, 1, 2};
    if (options.current_lag_s)
        space.lags.push_back(*options.current_lag_s);
    else
        for (const double samples : lag_grid) space.lags.push_back(samples * signals.dt);
    return space;
}

// The position loop's fit v_cmd = K_v*e(k-d) [+ k_ff*x_ref'(k-d)], the delay d by the smallest residual, with its
// standard error from the residual's curvature in d (delay_standard_error()).
struct PositionLoopFit {
    Fit fit;
    double delay{0.0};  // d [samples]; whole samples for a held position
    std::optional<double> delay_standard_error;  // [samples]
};

// x_ref at `at` samples (a fraction between two: linear, the NC's fine interpolation), the first before the start and
// the last after the end.
double reference_at(std::span<const double> reference, double at) {
    if (!(at > 0.0)) return reference.front();
    if (!(at < static_cast<double>(reference.size()))) return reference.back();
    // a signed whole part: the same number as an unsigned one here, in one instruction instead of a branch
    const auto whole = static_cast<std::int64_t>(at);
    const auto i = static_cast<std::size_t>(whole);
    if (i + 1 >= reference.size()) return reference.back();
    const double f = at - static_cast<double>(whole);
    return reference[i] + f * (reference[i + 1] - reference[i]);
}

// Whether k - d is exact at every row of a trace of `samples` rows: d a whole number of 1/1024 samples (every delay of
// the search's grid and of the curvature's steps), k below 2^40.
bool exact_row_shift(double delay, std::size_t samples) {
    return delay >= 0.0 && delay < 1e6 && delay * 1024.0 == std::floor(delay * 1024.0) &&
           samples < (std::size_t{1} << 40);
}

// e(k) = x_ref(k - d) - x(k) as reference_at() gives it, for a delay with exact_row_shift(): every row between the
// ends then reads x_ref the same fraction f = ceil(d) - d past the sample k - ceil(d) (reference_at()'s whole part
// and fraction of the exact k - d), so those rows take the same numbers from contiguous samples without its checks;
// the ends ask reference_at(). Returns sum e^2 over the rows `use`, in their order.
double following_error_at_exact_delay(std::span<const double> reference, std::span<const double> position,
                                      double delay, const std::vector<char>& use, Column& error) {
    const std::size_t n = position.size();
    const double upper = std::ceil(delay);
    const auto shift = static_cast<std::size_t>(upper);
    const double fraction = upper - delay;
    std::size_t k = 0;
    for (; k < n && !(static_cast<double>(k) - delay > 0.0); ++k)
        error[k] = reference_at(reference, static_cast<double>(k) - delay) - position[k];
    for (const std::size_t stop = std::min(n, n - 1 + shift); k < stop; ++k) {
        const std::size_t i = k - shift;
        error[k] = reference[i] + fraction * (reference[i + 1] - reference[i]) - position[k];
    }
    for (; k < n; ++k) error[k] = reference_at(reference, static_cast<double>(k) - delay) - position[k];
    double squares = 0.0;
    for (k = 0; k < n; ++k) {
        if (use[k]) squares += error[k] * error[k];
    }
    return squares;
}

// The position loop's columns for a setpoint delay of `delay` samples: e(k) = x_ref(k - d) - x(k) and, with the
// feed-forward, the setpoint's velocity there, the slope of the interpolated reference just before k - d (its
// backward difference for a whole d). A held position (a slower position loop) keeps whole samples and differences
// over its own cycle.
// Into `problem` (its columns' storage reused), with their sums of squares over the rows `use`.
void position_loop_columns(const GainSignals& signals, double delay, bool feedforward, const std::vector<char>& use,
                           Problem& problem) {
    auto& columns = problem.columns;
    if (signals.hold_factor > 1) {
        const auto d = static_cast<int>(std::lround(delay));
        columns.clear();
        columns.push_back(following_error(signals.reference, signals.position, d));
        if (feedforward)
            columns.push_back(delayed(difference_velocity(signals.reference, signals.hold_factor, signals.dt), d));
        problem.column_squares.clear();
        return;
    }
    columns.resize(feedforward ? 2 : 1);
    Column& error = columns[0];
    error.resize(signals.samples);
    if (!feedforward && exact_row_shift(delay, signals.samples)) {
        problem.column_squares.assign(
            {following_error_at_exact_delay(signals.reference, signals.position, delay, use, error)});
        return;
    }
    if (feedforward) columns[1].resize(signals.samples);
    double error_squares = 0.0, velocity_squares = 0.0;
    const std::size_t last = signals.samples - 1;
    for (std::size_t k = 0; k < signals.samples; ++k) {
        const double at = static_cast<double>(k) - delay;
        error[k] = reference_at(signals.reference, at) - signals.position[k];
        if (use[k]) error_squares += error[k] * error[k];
        if (!feedforward) continue;
        const double upper = std::ceil(at);
        const std::size_t i = upper < 1.0 ? 0 : std::min(static_cast<std::size_t>(upper), last);
        const double velocity = i == 0 ? 0.0 : (signals.reference[i] - signals.reference[i - 1]) / signals.dt;
        columns[1][k] = velocity;
        if (use[k]) velocity_squares += velocity * velocity;
    }
    problem.column_squares.assign({error_squares});
    if (feedforward) problem.column_squares.push_back(velocity_squares);
}

// The standard error of a delay fitted by the smallest residual sum of squares S(d) beside p linear parameters on N
// rows: S is -2 log-likelihood times sigma^2 (Gaussian residuals), so var(d) = 2*sigma^2 / S''(d), sigma^2 = S/(N-p),
// S'' by central differences of step h (forward ones at d = 0). None where S'' is not positive (a flat profile).
std::optional<double> delay_standard_error(const std::function<double(double)>& rss, double delay, double step,
                                           std::size_t rows, std::size_t parameters) {
    if (rows <= parameters + 1) return std::nullopt;
    const double at = delay - step < 0.0 ? step : delay;  // the middle of three points at or above 0
    const double curvature = (rss(at + step) - 2.0 * rss(at) + rss(at - step)) / (step * step);
    const double sigma2 = rss(delay) / static_cast<double>(rows - parameters - 1);
    if (!(curvature > 0.0) || !std::isfinite(curvature)) return std::nullopt;
    return std::sqrt(2.0 * sigma2 / curvature);
}

// Steps per sample of the setpoint delay's search: a delay of a few servo cycles of a loop up to 16 times faster
// than the log is a whole number of them (4, 8, 16 kHz at 1 kHz); between them it is refined by golden section.
constexpr int delay_steps_per_sample = 16;

PositionLoopFit fit_position_loop(const GainSignals& signals, bool feedforward, const RlsOptions& rls) {
    std::vector<char> use = rows_past_start_up(signals.samples);
    keep_fresh_rows(signals, use);
    Problem problem;  // refilled for each delay
    problem.share_y(signals.velocity_command);
    problem.use = &use;
    struct Fitted {
        double delay;
        double rss;  // or, where not exact, a bound it is not below (residual_lower_bound())
        bool exact;
    };
    std::vector<Fitted> fitted;  // each delay fitted
    // The residual sum of squares at a delay where it may be below `below`, else a bound at least `below` (the
    // residual's pass left out); each delay fitted once.
    const auto rss_below = [&](double delay, double below) {
        auto found = std::find_if(fitted.begin(), fitted.end(), [&](const auto& f) { return f.delay == delay; });
        if (found != fitted.end() && (found->exact || found->rss >= below)) return found->rss;
        position_loop_columns(signals, delay, feedforward, use, problem);
        const NormalEquations equations = normal_equations(problem);
        const double at_least = residual_lower_bound(equations);
        const Fitted now = at_least >= below ? Fitted{delay, at_least, false}
                                             : Fitted{delay, residual_squares(problem, equations), true};
        if (found != fitted.end())
            *found = now;
        else
            fitted.push_back(now);
        return now.rss;
    };
    const auto rss = [&](double delay) { return rss_below(delay, std::numeric_limits<double>::infinity()); };
    // with a feed-forward a fraction of a sample is k_ff's doing here (setpoint_fraction())
    const bool whole = signals.hold_factor > 1 || feedforward;
    const int steps = whole ? 1 : delay_steps_per_sample;
    double best_rss = std::numeric_limits<double>::infinity();
    PositionLoopFit result;
    for (int j = 0; j <= 2 * steps; ++j) {
        const double delay = static_cast<double>(j) / steps;
        if (const double r = rss_below(delay, best_rss); r < best_rss) {
            best_rss = r;
            result.delay = delay;
        }
    }
    if (!whole) {
        // golden section within a step either side, 24 brackets, each keeping the inner point that stays inner (25
        // delays fitted); kept only where it fits better than the grid
        double low = std::max(0.0, result.delay - 1.0 / steps), high = result.delay + 1.0 / steps;
        const double ratio = 0.5 * (std::sqrt(5.0) - 1.0);
        double inner_low = high - ratio * (high - low), inner_high = low + ratio * (high - low);
        double rss_low = rss(inner_low), rss_high = rss(inner_high);
        for (int round = 1; round < 24; ++round) {
            if (rss_low < rss_high) {
                high = inner_high, inner_high = inner_low, rss_high = rss_low;
                inner_low = high - ratio * (high - low), rss_low = rss(inner_low);
            } else {
                low = inner_low, inner_low = inner_high, rss_low = rss_high;
                inner_high = low + ratio * (high - low), rss_high = rss(inner_high);
            }
        }
        if (rss_low < rss_high)
            high = inner_high;
        else
            low = inner_low;
        const double refined = 0.5 * (low + high);
        if (const double r = rss_below(refined, best_rss); r < best_rss) {
            best_rss = r;
            result.delay = refined;
        }
    }
    position_loop_columns(signals, result.delay, feedforward, use, problem);
    result.fit = fit(problem, rls);
    result.delay_standard_error = delay_standard_error(rss, result.delay, whole ? 1.0 : 1.0 / (4.0 * steps),
                                                       result.fit.samples, feedforward ? 2 : 1);
    return result;
}

// A feed-forward shows when fitting it halves the position loop's relative error and k_ff lies beyond three standard
// errors from 0: the P-only fit of such a loop gives an effective K_v, not the loop's gain.
bool feedforward_shows(const PositionLoopFit& with, const PositionLoopFit& without) {
    if (with.fit.rank_deficient) return false;
    // a loop that the fit without it reproduces to the rounding of the logged numbers (gain_resolution) has none
    if (!(without.fit.relative_error_pct > 100.0 * gain_resolution)) return false;
    const double kff = with.fit.estimate(1);
    const double se = std::sqrt(std::max(0.0, with.fit.covariance(1, 1)));
    return std::isfinite(kff) && std::abs(kff) > 3.0 * se &&
           with.fit.relative_error_pct < 0.5 * without.fit.relative_error_pct;
}

// K_v over the position loop's models P and P+FF (their Akaike weights; AIC = N*ln(RSS/N) + 2*p, RSS proportional to
// the squared relative error on the same rows): the chosen model's K_v with the unconditional standard error
// sum_m w_m*sqrt(se_m^2 + (K_v,m - K_v)^2) (Burnham and Anderson, Model Selection and Multimodel Inference, 2002,
// eq. 4.9, centred on the chosen K_v): as wide as its own where the other model has no weight, and taking in the
// other's K_v where the data cannot tell the two apart.
// One of the position loop's models: its K_v, the relative error of its fit and its number of parameters.
struct ModelCandidate {
    Estimate position_gain_per_s;
    double relative_error_pct{0.0};
    int parameters{0};
};

void add_model_choice(const ModelCandidate& plain, const ModelCandidate& with, std::size_t samples,
                      GainResult& result) {
    const auto rows = static_cast<double>(samples);
    const double smallest = std::max({std::min(plain.relative_error_pct, with.relative_error_pct), 1e-300});
    const auto delta_aic = [&](const ModelCandidate& f) {
        return rows * 2.0 * std::log(std::max(f.relative_error_pct, smallest) / smallest) + 2.0 * f.parameters;
    };
    const double plain_aic = delta_aic(plain), with_aic = delta_aic(with);
    const double low = std::min(plain_aic, with_aic);
    const double plain_w = std::exp(-0.5 * (plain_aic - low)), with_w = std::exp(-0.5 * (with_aic - low));
    const double kv = result.position_gain_per_s.value.value_or(0.0);
    double band = 0.0;
    for (const auto& [name, f, weight] : {std::tuple{"P", &plain, plain_w / (plain_w + with_w)},
                                          std::tuple{"P+FF", &with, with_w / (plain_w + with_w)}}) {
        PositionLoopModel model{name, f->position_gain_per_s, f->relative_error_pct, weight};
        const double se = model.position_gain_per_s.standard_error.value_or(0.0);
        const double apart = model.position_gain_per_s.value.value_or(kv) - kv;
        band += weight * std::sqrt(se * se + apart * apart);
        result.position_loop_models.push_back(std::move(model));
    }
    result.position_gain_within_model_stderr = result.position_gain_per_s.standard_error;
    if (std::isfinite(band) && result.position_gain_per_s.standard_error)
        result.position_gain_per_s.standard_error = std::max(*result.position_gain_per_s.standard_error, band);
}

// Position loop (only with a logged velocity command): v_cmd = K_v*e(k-d) [+ k_ff*x_ref'(k-d)], the feed-forward as
// asked (--feedforward) or where it shows. Sets K_v (and k_ff), d and the position loop's relative error.
void identify_position_loop(const GainSignals& signals, const GainOptions& options, GainResult& result) {
    PositionLoopFit plain = fit_position_loop(signals, false, options.rls);
    PositionLoopFit with = fit_position_loop(signals, true, options.rls);
    const bool feedforward = options.feedforward || (!plain.fit.rank_deficient && feedforward_shows(with, plain));
    if (feedforward && !options.feedforward) {
        result.diagnostics.push_back(fmt::format(
            "a velocity feed-forward shows in the position loop (k_ff = {:.4g} with the setpoint at whole samples; "
            "the position loop's relative "
            "error falls from {:.3g} % to {:.3g} % with it): fitted with it, as --feedforward would; K_v fitted "
            "without it would be {:.4g} 1/s, an effective gain of the loop with its feed-forward",
            with.fit.estimate(1), plain.fit.relative_error_pct, with.fit.relative_error_pct, plain.fit.estimate(0)));
    }
    const PositionLoopFit& loop = feedforward ? with : plain;
    if (loop.fit.rank_deficient) {
        throw AnalysisError(
            fmt::format("{}: the following error does not determine the position gain", signals.source));
    }
    result.reference_delay_samples = static_cast<int>(std::lround(loop.delay));
    result.setpoint_delay_s.value = loop.delay * signals.dt;
    if (loop.delay_standard_error) result.setpoint_delay_s.standard_error = *loop.delay_standard_error * signals.dt;
    result.position_gain_per_s = estimate_from_variance(loop.fit.estimate(0), loop.fit.covariance(0, 0));
    result.position_loop_relative_error_pct = loop.fit.relative_error_pct;
    if (feedforward) {
        result.velocity_feedforward = estimate_from_variance(loop.fit.estimate(1), loop.fit.covariance(1, 1));
        if (!plain.fit.rank_deficient)
            result.effective_position_gain_per_s =
                estimate_from_variance(plain.fit.estimate(0), plain.fit.covariance(0, 0));
    }
    if (!plain.fit.rank_deficient && !with.fit.rank_deficient) {
        add_model_choice({estimate_from_variance(plain.fit.estimate(0), plain.fit.covariance(0, 0)),
                          plain.fit.relative_error_pct, 1},
                         {estimate_from_variance(with.fit.estimate(0), with.fit.covariance(0, 0)),
                          with.fit.relative_error_pct, 2},
                         with.fit.samples, result);
    }
}

// The velocity the controller measures: (x_k - x_{k-n})/(n*T), or the logged velocity for n = 0.
Column measured_velocity(const GainSignals& signals, int difference) {
    if (difference == 0) return Column(signals.velocity->values.begin(), signals.velocity->values.end());
    return difference_velocity(signals.position, difference, signals.dt);
}

// The PI columns of an error e sampled every dt: (e, sum(e*dt), 1), or (e) for a P loop.
std::vector<Column> pi_columns(Column error, double dt, bool integral) {
    std::vector<Column> columns;
    if (integral) {
        Column error_sum = running_sum(error, dt);
        const std::size_t n = error.size();
        columns.push_back(std::move(error));
        columns.push_back(std::move(error_sum));
        columns.push_back(Column(n, 1.0));
    } else {
        columns.push_back(std::move(error));
    }
    return columns;
}

// With the velocity command: F = K_p*e_v [+ K_i*E_v + c],  e_v = v_cmd - v,  E_v = sum(e_v*T).
std::vector<Column> command_columns(const GainSignals& signals, const Column& v, bool integral) {
    Column error(signals.samples);
    for (std::size_t k = 0; k < signals.samples; ++k) error[k] = signals.velocity_command[k] - v[k];
    return pi_columns(std::move(error), signals.dt, integral);
}

// The structure's columns from the following error e and the measured velocity v sampled every dt:
// (e, -v [, sum(dt*e), -sum(dt*v), 1]).
std::vector<Column> structure_columns_of(Column error, const Column& v, double dt, bool integral) {
    Column minus_v(v.size());
    for (std::size_t k = 0; k < v.size(); ++k) minus_v[k] = -v[k];
    std::vector<Column> columns;
    if (integral) {
        Column error_sum = running_sum(error, dt);
        Column minus_v_sum = running_sum(minus_v, dt);
        columns.push_back(std::move(error));
        columns.push_back(std::move(minus_v));
        columns.push_back(std::move(error_sum));
        columns.push_back(std::move(minus_v_sum));
        columns.push_back(Column(v.size(), 1.0));
    } else {
        columns.push_back(std::move(error));
        columns.push_back(std::move(minus_v));
    }
    return columns;
}

// From the structure alone: F = th1*e + th2*(-v) [+ th3*sum(T*e) + th4*(-sum(T*v)) + c],  e = x_ref(k - d) - x.
std::vector<Column> structure_columns(const GainSignals& signals, const Column& v, int reference_delay, bool integral) {
    return structure_columns_of(following_error(signals.reference, signals.position, reference_delay), v, signals.dt,
                                integral);
}

// The velocity loop between the logged samples: an NC runs its speed controller m times per logged sample (8 kHz
// logged at 1 kHz), so each logged force is the current loop's answer to m force commands, each from a velocity
// measured over servo cycles T_s = T/m that the trace never shows. The fit simulates the controller on that grid,
// driven by the logged signals: the reference interpolated linearly between its samples (the NC's fine
// interpolation), the position by a cubic through four logged samples (the motion is smooth at the servo rate), a
// held position (its own cycle) and velocity command as they are held. The controller's output, through the
// current loop at T_s, is then compared with the logged force at the logged instants: an output-error fit of the
// controller. Linear in the gains, it stays a least-squares fit of the simulated columns.
struct ServoGrid {
    int factor{1};         // m
    double cycle_s{0.0};   // T_s
    Column position;       // x at the servo instants
    Column reference;      // x_ref at the servo instants
    Column last_loop_row;  // the logged row of the position loop's last run, per servo instant
};

// The cubic through the samples k-1, k, k+1, k+2 of x (every `step`-th value from `first`: a held signal's fresh
// ones) at k + f (0 <= f < 1); the ends repeat their samples.
double cubic_at(std::span<const double> x, std::size_t first, std::size_t step, std::size_t k, double f) {
    const std::size_t last = (x.size() - 1 - first) / step;
    const auto at = [&](std::size_t q) { return x[first + std::min(q, last) * step]; };
    const double p0 = at(k == 0 ? 0 : k - 1), p1 = at(k), p2 = at(k + 1), p3 = at(k + 2);
    // Lagrange on the nodes -1, 0, 1, 2
    return p0 * (-f * (f - 1.0) * (f - 2.0) / 6.0) + p1 * ((f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0) +
           p2 * (-(f + 1.0) * f * (f - 2.0) / 2.0) + p3 * ((f + 1.0) * f * (f - 1.0) / 6.0);
}

ServoGrid servo_grid(const GainSignals& signals, int factor) {
    ServoGrid grid;
    const auto m = static_cast<std::size_t>(factor);
    grid.factor = factor;
    grid.cycle_s = signals.dt / static_cast<double>(m);
    const std::size_t n = signals.samples;
    grid.position.resize(n * m);
    grid.reference.resize(n * m);
    grid.last_loop_row.resize(n * m);
    const auto hold = static_cast<std::size_t>(signals.hold_factor);
    const auto phase = static_cast<std::size_t>(signals.hold_phase);
    for (std::size_t k = 0; k < n; ++k) {
        const std::size_t next = std::min(k + 1, n - 1);
        // the position loop's last run: this row when it runs every servo cycle, else the last fresh row
        const std::size_t loop_row = hold < 2 || k < phase ? k : k - (k - phase) % hold;
        for (std::size_t i = 0; i < m; ++i) {
            const double f = static_cast<double>(i) / static_cast<double>(m);
            // a held position: the cubic through its fresh samples, at the time since the last one
            const double since = k < phase ? 0.0 : (static_cast<double>(k - loop_row) + f) / static_cast<double>(hold);
            grid.position[k * m + i] =
                hold < 2 ? cubic_at(signals.position, 0, 1, k, f)
                         : cubic_at(signals.position, phase, hold, k < phase ? 0 : (loop_row - phase) / hold, since);
            grid.reference[k * m + i] =
                hold < 2 ? signals.reference[k] + f * (signals.reference[next] - signals.reference[k])
                         : signals.reference[k];
            grid.last_loop_row[k * m + i] = static_cast<double>(loop_row);
        }
    }
    return grid;
}

// The position loop as identified from a logged velocity command (K_v, k_ff, reference delay d), to run it between
// the logged samples.
struct PositionLoop {
    double gain_per_s{0.0};
    double feedforward{0.0};
    double delay{0.0};  // [samples]
};

// v_cmd at the servo instants: held from the logged command when the position loop runs on its own cycle, else the
// identified position loop run at the servo rate (it reproduces the logged command at the logged instants).
Column servo_velocity_command(const GainSignals& signals, const ServoGrid& grid, const PositionLoop& loop) {
    Column command(grid.position.size());
    if (signals.hold_factor > 1) {
        for (std::size_t j = 0; j < command.size(); ++j)
            command[j] = signals.velocity_command[static_cast<std::size_t>(grid.last_loop_row[j])];
        return command;
    }
    // the setpoint d samples late, between the logged samples as the NC interpolates it; its velocity over the
    // servo cycle before
    const double per_cycle = 1.0 / static_cast<double>(grid.factor);
    for (std::size_t j = 0; j < command.size(); ++j) {
        const double at = static_cast<double>(j) * per_cycle - loop.delay;
        const double setpoint = reference_at(signals.reference, at);
        const double reference_velocity =
            at - per_cycle < 0.0 ? 0.0 : (setpoint - reference_at(signals.reference, at - per_cycle)) / grid.cycle_s;
        command[j] = loop.gain_per_s * (setpoint - grid.position[j]) + loop.feedforward * reference_velocity;
    }
    return command;
}

// The velocity loop's error and minus the measured velocity at one servo instant.
struct ServoRow {
    double error{0.0};  // e_v with a logged command, else e
    double minus_v{0.0};
    double reference_velocity{0.0};  // from the structure alone: the delayed setpoint's, over the servo cycle before
};

// The drive signal less L[u_inj], an injection that enters it with gain 1.
void subtract_injection(Problem& problem, const Column& injected) {
    Column& y = problem.own_y();
    for (std::size_t k = 0; k < y.size(); ++k) y[k] -= injected[k];
}

// What a search keeps from one structure to the next at the log rate: the unfiltered columns of the last velocity
// measurement and reference delay (a lag and a fractional delay only filter them), and a problem whose columns are
// refilled in place: no allocation per structure.
struct ProblemWorkspace {
    int difference{-1};
    int reference_delay{-1};
    bool integral{false};
    std::vector<Column> unfiltered;
    Column injected;  // L[u_inj], where it is taken out of the drive signal
    Problem problem;
};

// The velocity loop's regression on its rows: one problem per structure, every column through the drive filter L.
// An injected signal u_inj is added to the controller's output before the drive, so the logged force is
// F = L[F_cmd + u_inj] = L[F_cmd] + L[u_inj]: the controller explains F - L[u_inj].
struct VelocityLoopRegression {
    const GainSignals& signals;
    const std::vector<char>& use;
    const ServoGrid* grid{nullptr};  // the servo grid, when the velocity loop runs faster than the log
    Column servo_command{};          // v_cmd on it (logged command only)
    bool injection_gain_known{false};  // the injection enters with gain 1 (else its gain is fitted)
    // From the structure alone on the servo grid, a velocity command K_v*e + k_ff*x_ref': whether the bank keeps
    // L[x_ref'] and L[sum(T_s*x_ref')] (problem_at_feedforward()), and whether each structure's problem is taken at
    // the k_ff that fits it best.
    bool feedforward_columns{false};
    bool feedforward_profiled{false};  // k_ff the best for each structure (profiled_feedforward())

    [[nodiscard]] Problem problem(const Structure& s, bool integral) const {
        ProblemWorkspace workspace;
        fill_problem(s, integral, workspace);
        return std::move(workspace.problem);
    }

    // problem() into `workspace`: at the log rate its columns refilled in place from the unfiltered ones, which are
    // formed again only when the velocity measurement, the reference delay or the integral changes; on the servo
    // grid a new problem.
    void fill_problem(const Structure& s, bool integral, ProblemWorkspace& workspace) const {
        if (grid != nullptr) {
            workspace.problem = servo_rate_problem(s, integral);
            return;
        }
        const auto& unfiltered = unfiltered_columns(s, integral, workspace);
        Problem& problem = workspace.problem;
        const double a = lag_coefficient(s.lag_s, signals.dt);
        const bool injection_column = !signals.injection.empty() && !injection_gain_known;
        problem.columns.resize(unfiltered.size() + (injection_column ? 1 : 0));
        filter_columns(unfiltered, a, s.mu, use, problem);
        problem.share_y(signals.force);
        if (injection_column) {
            filter_into(signals.injection, a, s.mu, problem.columns.back());
        } else if (!signals.injection.empty()) {
            filter_into(signals.injection, a, s.mu, workspace.injected);
            subtract_injection(problem, workspace.injected);
        }
        problem.use = &use;
        problem.row_step = static_cast<std::size_t>(signals.hold_factor);
    }

    // The columns of `s` before the drive filter, kept in `workspace` and formed again only when the velocity
    // measurement, the reference delay or the integral changes (at the log rate).
    const std::vector<Column>& unfiltered_columns(const Structure& s, bool integral,
                                                  ProblemWorkspace& workspace) const {
        auto& unfiltered = workspace.unfiltered;
        if (unfiltered.empty() || workspace.difference != s.difference ||
            workspace.reference_delay != s.reference_delay || workspace.integral != integral) {
            unfiltered.clear();  // released before the next are formed
            const Column v = measured_velocity(signals, s.difference);
            unfiltered = signals.logged_command ? command_columns(signals, v, integral)
                                                : structure_columns(signals, v, s.reference_delay, integral);
            workspace.difference = s.difference;
            workspace.reference_delay = s.reference_delay;
            workspace.integral = integral;
        }
        return unfiltered;
    }

    /// Whether residuals_over_mu() serves: on the logged samples (no servo grid) without an injection, whose drive
    /// signal does not change with mu.
    [[nodiscard]] bool mu_from_shared_sums() const { return grid == nullptr && signals.injection.empty(); }

    /// The residual sums of squares of the structure `s` (its mu aside) at each of `mus`, from one pass over the rows
    /// for all of them (lag_gram_of()); for ranking structures, not for their final fit.
    std::vector<double> residuals_over_mu(const Structure& s, bool integral, std::span<const double> mus,
                                          ProblemWorkspace& workspace) const {
        const auto& unfiltered = unfiltered_columns(s, integral, workspace);
        const double a = lag_coefficient(s.lag_s, signals.dt);
        std::vector<double> residuals;
        with_column_count(unfiltered.size(), [&](auto q) {
            residuals = residuals_at_each_mu(lag_gram_of<q()>(unfiltered, a, use, signals.force), q(), mus);
        });
        return residuals;
    }

    // The same on the servo grid (ServoGrid): the columns and the injection (held over its logged sample) through
    // the current loop at T_s, taken at the logged instants; in one pass, the servo grid's columns never stored.
    [[nodiscard]] Problem servo_rate_problem(const Structure& s, bool integral) const;

    /// The residual sum of squares of problem(s, integral), for the structure search; from the structure alone on
    /// the servo grid (mu_profiled()) at the mu that leaves the least, by the bank's Gram matrix (BankGram): one
    /// pass over the rows for every mu and k_ff tried.
    [[nodiscard]] StructureResidual structure_residual(const Structure& s, bool integral) const;

    struct ServoFilterBank;
    [[nodiscard]] Problem bank_problem(const ServoFilterBank& bank) const;

    struct ServoFilterBank {
        std::vector<Column> columns;  // at the logged instants
        Column injection;             // L[u_inj] at the logged instants (zeros without one)
        std::vector<Column> feedforward;  // L[x_ref'], L[sum(T_s*x_ref')] (feedforward_columns only)
        // With `delta`: the same for mu = 0, and after them the lag's response to u(j-1) - u(j) for each, so that the
        // bank of any mu is the first half plus mu times the second (the drive filter is linear in mu's input).
        bool delta{false};
    };

    [[nodiscard]] ServoFilterBank servo_columns(const Structure& s, bool integral, bool delta = false) const;

    /// Whether the structure search profiles the drive filter's mu out (structure_residual()): from the structure
    /// alone on a servo grid, where the lag, mu and the setpoint delay trade against each other.
    [[nodiscard]] bool mu_profiled() const { return grid != nullptr && !signals.logged_command; }

    // The injection through the drive filter, L[u_inj], enters the drive signal with the gain g of whatever lies
    // between the logged test signal and the drive (a DAC, an amplifier): a column of its own, g fitted with the
    // gains, the last in theta; with injection_gain_known, g = 1 and L[u_inj] is taken out of the drive signal.
    void add_injection(Problem& problem, Column injected) const {
        if (!injection_gain_known) {
            problem.columns.push_back(std::move(injected));
            return;
        }
        subtract_injection(problem, injected);
    }
};

Problem VelocityLoopRegression::bank_problem(const ServoFilterBank& bank) const {
    Problem problem;
    problem.columns = bank.columns;
    problem.share_y(signals.force);
    if (!signals.injection.empty()) add_injection(problem, bank.injection);
    problem.use = &use;
    problem.row_step = static_cast<std::size_t>(signals.hold_factor);
    return problem;
}

ServoRow servo_row(const VelocityLoopRegression& r, const Column& logged_error, std::size_t j, int difference,
                   int reference_delay, int delay_cycles) {
    const ServoGrid& g = *r.grid;
    const auto n = static_cast<std::size_t>(difference);
    const double v = (g.position[j] - g.position[j >= n ? j - n : 0]) / (difference * g.cycle_s);
    ServoRow row;
    if (r.signals.logged_command) {
        row.error = r.servo_command[j] - v;
    } else if (r.signals.hold_factor > 1) {
        row.error = logged_error[static_cast<std::size_t>(g.last_loop_row[j])];
    } else {
        const auto shift = static_cast<std::size_t>(delay_cycles >= 0 ? delay_cycles : reference_delay * g.factor);
        row.error = g.reference[j >= shift ? j - shift : 0] - g.position[j];
        if (j > shift) row.reference_velocity = (g.reference[j - shift] - g.reference[j - shift - 1]) / g.cycle_s;
    }
    row.minus_v = -v;
    return row;
}

VelocityLoopRegression::ServoFilterBank VelocityLoopRegression::servo_columns(const Structure& s, bool integral,
                                                                            bool delta) const {
    const ServoGrid& g = *grid;
    const bool structure = !signals.logged_command;
    const std::size_t p = structure ? (integral ? 5 : 2) : (integral ? 3 : 1);
    const auto m = static_cast<std::size_t>(g.factor);
    const std::size_t fine = g.position.size();
    const Column logged_error = structure && signals.hold_factor > 1
                                    ? following_error(signals.reference, signals.position, s.reference_delay)
                                    : Column{};
    ServoFilterBank bank;
    bank.delta = delta;
    const std::size_t copies = delta ? 2 : 1;
    bank.columns.assign(p * copies, Column(signals.samples));
    bank.injection.assign(signals.samples * copies, 0.0);
    if (feedforward_columns) bank.feedforward.assign(2 * copies, Column(signals.samples));
    const double a = lag_coefficient(s.lag_s, g.cycle_s);
    const double mu = delta ? 0.0 : s.mu;
    // per column (the injection sixth, then L[x_ref'] and its sum): its running sums, the filter's last in- and output
    // (and with `delta` the lag's response to the input's step back)
    std::array<double, 8> in{}, last_in{}, last_out{}, delta_out{};
    double error_sum = 0.0, minus_v_sum = 0.0, reference_sum = 0.0;
    for (std::size_t j = 0; j < fine; ++j) {
        const ServoRow row = servo_row(*this, logged_error, j, std::max(1, s.difference), s.reference_delay,
                                        s.servo_delay_cycles);
        error_sum += row.error * g.cycle_s;
        minus_v_sum += row.minus_v * g.cycle_s;
        reference_sum += row.reference_velocity * g.cycle_s;
        if (structure) {
            in = {row.error, row.minus_v, error_sum, minus_v_sum, 1.0, 0.0, row.reference_velocity, reference_sum};
            if (!integral) in[2] = in[3] = in[4] = in[7] = 0.0;
        } else {
            in = {row.error, error_sum, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0};
        }
        in[5] = signals.injection.empty() ? 0.0 : signals.injection[j / m];
        for (std::size_t c = 0; c < in.size(); ++c) {
            if (j == 0) last_in[c] = last_out[c] = in[c];  // the filter starts in steady state
            const double out = a * last_out[c] + (1.0 - a) * ((1.0 - mu) * in[c] + mu * last_in[c]);
            if (delta) delta_out[c] = a * delta_out[c] + (1.0 - a) * (last_in[c] - in[c]);
            last_in[c] = in[c];
            last_out[c] = out;
        }
        if (j % m != 0) continue;
        const std::size_t k = j / m;
        for (std::size_t c = 0; c < p; ++c) bank.columns[c][k] = last_out[c];
        bank.injection[k] = last_out[5];
        if (feedforward_columns) {
            bank.feedforward[0][k] = last_out[6];
            bank.feedforward[1][k] = last_out[7];
        }
        if (!delta) continue;
        for (std::size_t c = 0; c < p; ++c) bank.columns[p + c][k] = delta_out[c];
        bank.injection[signals.samples + k] = delta_out[5];
        if (feedforward_columns) {
            bank.feedforward[2][k] = delta_out[6];
            bank.feedforward[3][k] = delta_out[7];
        }
    }
    return bank;
}

// From the structure alone with a velocity feed-forward k_ff the drive signal is
// F = L[K_p*(K_v*e + k_ff*x_ref' - v) + K_i*sum(T_s*(K_v*e + k_ff*x_ref' - v)) + c], linear in
// th = (K_p*K_v, K_p, K_i*K_v, K_i, c) for a given k_ff; L being linear, its columns at k_ff are those at 0 plus k_ff
// times L[x_ref'] (the second) and L[sum(T_s*x_ref')] (the fourth): one pass over the servo grid serves every k_ff.
Problem problem_at_feedforward(const VelocityLoopRegression& regression,
                               const VelocityLoopRegression::ServoFilterBank& bank, bool integral, double k) {
    Problem problem = regression.bank_problem(bank);
    for (std::size_t i = 0; i < problem.y().size(); ++i) {
        problem.columns[1][i] += k * bank.feedforward[0][i];
        if (integral) problem.columns[3][i] += k * bank.feedforward[1][i];
    }
    return problem;
}

// The same with, after the structure's columns, F's derivative in k_ff, th2*L[x_ref'] + th4*L[sum(T_s*x_ref')] with
// th fitted at k_ff: its coefficient is the Gauss-Newton step in k_ff, and the fit with it gives the covariance of
// (th, k_ff) linearised there (variable projection).
Problem feedforward_problem(const VelocityLoopRegression& regression,
                            const VelocityLoopRegression::ServoFilterBank& bank, bool integral, double k) {
    Problem problem = problem_at_feedforward(regression, bank, integral, k);
    const NormalSolution at = normal_solution(problem);
    const double th2 = at.theta(1), th4 = integral ? at.theta(3) : 0.0;
    Column derivative(problem.y().size());
    for (std::size_t i = 0; i < derivative.size(); ++i)
        derivative[i] = th2 * bank.feedforward[0][i] + th4 * bank.feedforward[1][i];
    problem.columns.insert(problem.columns.begin() + (integral ? 5 : 2), std::move(derivative));
    return problem;
}

// A bank's problems from one pass over its rows (GramMatrix): the base vectors are the bank's columns, its
// injection (where the trace has one), L[x_ref'] and L[sum(T_s*x_ref')] (feedforward_columns), with a delta bank the
// same again for mu's part, and the drive signal; each problem of the structure search (bank_problem(),
// problem_at_feedforward(), feedforward_problem()) at any k_ff and mu is a combination of them. For the structure
// alone, whose fits leave the drive signal's noise: the residuals rank the structures as the problems' own passes
// would (GramMatrix::solve()).
class BankGram {
public:
    BankGram(const VelocityLoopRegression& regression, const VelocityLoopRegression::ServoFilterBank& bank,
             bool integral)
        : p_(static_cast<Eigen::Index>(bank.columns.size() / (bank.delta ? 2 : 1))),
          integral_(integral),
          injection_(!regression.signals.injection.empty()),
          injection_column_(injection_ && !regression.injection_gain_known),
          feedforward_(!bank.feedforward.empty()),
          delta_(bank.delta),
          gram_(base_vectors(regression, bank), regression.use) {}

    /// The fit at k_ff (0 without the feed-forward's columns) and mu (that of the bank without a delta bank).
    [[nodiscard]] GramMatrix::Solution at(double k, double mu) const { return gram_.solve(columns(k, mu), right(mu)); }

    /// The fit at k_ff and mu with F's derivative in k_ff after the structure's columns: its coefficient
    /// (derivative_index()) is the Gauss-Newton step in k_ff.
    [[nodiscard]] GramMatrix::Solution with_derivative(double k, double mu) const {
        const Eigen::VectorXd theta = at(k, mu).theta;
        Eigen::VectorXd derivative = Eigen::VectorXd::Zero(vectors());
        add(derivative, feedforward_at(), theta(1), mu);
        if (integral_) add(derivative, feedforward_at() + 1, theta(3), mu);
        return gram_.solve(inserted(columns(k, mu), derivative), right(mu));
    }

    /// A starting k_ff: with x_ref' over one servo cycle, sum(T_s*x_ref') = e + sum(T_s*v) + const, so
    ///   F = L[(K_p*K_v + K_i*k_ff)*e + K_p*(-v) + K_p*k_ff*x_ref' + K_i*K_v*sum(T_s*e)
    ///         + K_i*(1 - k_ff)*(-sum(T_s*v)) + c]
    /// is linear in its coefficients (exactly for a velocity over one cycle, nearly over n): k_ff is that of
    /// L[x_ref'] over that of -L[v].
    [[nodiscard]] double starting_feedforward(double mu) const {
        Eigen::VectorXd column = Eigen::VectorXd::Zero(vectors());
        add(column, feedforward_at(), 1.0, mu);
        const Eigen::VectorXd theta = gram_.solve(inserted(columns(0.0, mu), column), right(mu)).theta;
        const double k = theta(derivative_index()) / theta(1);
        return std::isfinite(k) ? k : 0.0;
    }

    [[nodiscard]] Eigen::Index derivative_index() const { return integral_ ? 5 : 2; }
    [[nodiscard]] bool feedforward() const { return feedforward_; }

private:
    static std::vector<std::span<const double>> base_vectors(const VelocityLoopRegression& regression,
                                                             const VelocityLoopRegression::ServoFilterBank& bank) {
        const std::size_t copies = bank.delta ? 2 : 1, p = bank.columns.size() / copies;
        const std::size_t n = regression.signals.samples, f = bank.feedforward.size() / copies;
        std::vector<std::span<const double>> vectors;
        for (std::size_t copy = 0; copy < copies; ++copy) {
            for (std::size_t c = 0; c < p; ++c) vectors.emplace_back(bank.columns[copy * p + c]);
            if (!regression.signals.injection.empty())
                vectors.emplace_back(std::span<const double>(bank.injection).subspan(copy * n, n));
            for (std::size_t c = 0; c < f; ++c) vectors.emplace_back(bank.feedforward[copy * f + c]);
        }
        vectors.emplace_back(regression.signals.force);
        return vectors;
    }
    [[nodiscard]] Eigen::Index vectors() const { return gram_.matrix().rows(); }
    // the base vectors of one copy (the bank at mu = 0, or mu's part)
    [[nodiscard]] Eigen::Index copy_size() const { return p_ + (injection_ ? 1 : 0) + (feedforward_ ? 2 : 0); }
    [[nodiscard]] Eigen::Index feedforward_at() const { return p_ + (injection_ ? 1 : 0); }
    // `weight` times base vector i of the bank at mu (with mu's part)
    void add(Eigen::Ref<Eigen::VectorXd> column, Eigen::Index i, double weight, double mu) const {
        column(i) += weight;
        if (delta_) column(copy_size() + i) += weight * mu;
    }

    // bank_problem()'s columns, the second and fourth with k_ff times L[x_ref'] and L[sum(T_s*x_ref')]
    [[nodiscard]] Eigen::MatrixXd columns(double k, double mu) const {
        Eigen::MatrixXd c = Eigen::MatrixXd::Zero(vectors(), p_ + (injection_column_ ? 1 : 0));
        for (Eigen::Index j = 0; j < p_; ++j) add(c.col(j), j, 1.0, mu);
        if (injection_column_) add(c.col(p_), p_, 1.0, mu);
        if (feedforward_ && k != 0.0) {
            add(c.col(1), feedforward_at(), k, mu);
            if (integral_) add(c.col(3), feedforward_at() + 1, k, mu);
        }
        return c;
    }
    // the drive signal, less the injection where its gain is known to be 1
    [[nodiscard]] Eigen::VectorXd right(double mu) const {
        Eigen::VectorXd y = Eigen::VectorXd::Unit(vectors(), vectors() - 1);
        if (injection_ && !injection_column_) add(y, p_, -1.0, mu);
        return y;
    }
    [[nodiscard]] Eigen::MatrixXd inserted(const Eigen::MatrixXd& c, const Eigen::VectorXd& column) const {
        Eigen::MatrixXd out(c.rows(), c.cols() + 1);
        const Eigen::Index at = derivative_index();
        out << c.leftCols(at), column, c.rightCols(c.cols() - at);
        return out;
    }

    Eigen::Index p_;
    bool integral_;
    bool injection_;         // the trace has an injection (a base vector)
    bool injection_column_;  // its gain fitted: a column of the problem
    bool feedforward_;
    bool delta_;             // mu's part of the bank follows the bank at mu = 0
    GramMatrix gram_;
};

// The k_ff that leaves the least unexplained for the structure of `gram`'s bank at mu: Gauss-Newton steps from
// BankGram::starting_feedforward() (F is bilinear in th and k_ff), a step halved while it leaves more; every step on
// the bank's Gram matrix.
double profiled_feedforward(const BankGram& gram, double mu) {
    double k = gram.starting_feedforward(mu);
    double now = gram.at(k, mu).rss;
    for (int step = 0; step < 30; ++step) {
        double delta = gram.with_derivative(k, mu).theta(gram.derivative_index());
        if (!std::isfinite(delta)) break;
        double next = std::numeric_limits<double>::infinity();
        for (int halving = 0; halving < 20; ++halving) {
            next = gram.at(k + delta, mu).rss;
            if (next <= now) break;
            delta *= 0.5;
        }
        if (!(next <= now)) break;
        k += delta;
        now = next;
        if (!(std::abs(delta) > 1e-10 * std::max(1.0, std::abs(k)))) break;
    }
    return k;
}

double profiled_feedforward(const VelocityLoopRegression& regression,
                            const VelocityLoopRegression::ServoFilterBank& bank, bool integral, double mu) {
    return profiled_feedforward(BankGram(regression, bank, integral), mu);
}

// The residual at mu with k_ff profiled where the bank has its columns.
double residual_at(const BankGram& gram, double mu) {
    return gram.at(gram.feedforward() ? profiled_feedforward(gram, mu) : 0.0, mu).rss;
}

// mu in [0, 1] that leaves the least unexplained (k_ff profiled at each): the best of nine, then golden sections
// between its neighbours to 1e-4.
double profiled_mu(const BankGram& gram) {
    constexpr int grid = 8;
    int best = 0;
    double best_rss = std::numeric_limits<double>::infinity();
    for (int i = 0; i <= grid; ++i) {
        const double rss = residual_at(gram, static_cast<double>(i) / grid);
        if (rss < best_rss) best_rss = rss, best = i;
    }
    double lo = std::max(0, best - 1) / static_cast<double>(grid),
           hi = std::min(grid, best + 1) / static_cast<double>(grid);
    const double ratio = 0.5 * (std::sqrt(5.0) - 1.0);
    double x1 = hi - ratio * (hi - lo), x2 = lo + ratio * (hi - lo);
    double f1 = residual_at(gram, x1), f2 = residual_at(gram, x2);
    while (hi - lo > 1e-4) {
        if (f1 <= f2) {
            hi = x2, x2 = x1, f2 = f1;
            x1 = hi - ratio * (hi - lo), f1 = residual_at(gram, x1);
        } else {
            lo = x1, x1 = x2, f1 = f2;
            x2 = lo + ratio * (hi - lo), f2 = residual_at(gram, x2);
        }
    }
    const double mu = f1 <= f2 ? x1 : x2;
    return std::min(f1, f2) <= best_rss ? mu : static_cast<double>(best) / grid;
}

Problem VelocityLoopRegression::servo_rate_problem(const Structure& s, bool integral) const {
    if (!feedforward_profiled) return bank_problem(servo_columns(s, integral));
    const ServoFilterBank bank = servo_columns(s, integral);
    return problem_at_feedforward(*this, bank, integral, profiled_feedforward(*this, bank, integral, s.mu));
}

StructureResidual VelocityLoopRegression::structure_residual(const Structure& s, bool integral) const {
    if (!mu_profiled()) return {residual_sum_of_squares(problem(s, integral)), s.mu};
    const BankGram gram(*this, servo_columns(s, integral, true), integral);
    const double mu = profiled_mu(gram);
    return {residual_at(gram, mu), mu};
}

// The structure of the smallest residual so far.
class StructureSearch {
public:
    StructureSearch(const VelocityLoopRegression& regression, bool integral)
        : regression_(regression), integral_(integral) {}

    // Fits `s` (at the mu that fits best where the regression profiles it; once: the stages and the refinement come
    // back to structures already fitted); true when it is the best so far.
    bool consider(const Structure& s) {
        Structure fitted = s;
        double rss = 0.0;
        if (regression_.mu_profiled()) {
            // mu is not the search's: a structure that differs only in it was fitted already
            const auto key = std::tuple{s.difference, s.reference_delay, s.servo_delay_cycles, s.lag_s};
            auto found = profiled_.find(key);
            if (found == profiled_.end())
                found = profiled_.emplace(key, regression_.structure_residual(s, integral_)).first;
            rss = found->second.rss;
            fitted.mu = found->second.mu;
        } else if (const auto found =
                       std::find_if(tried_.begin(), tried_.end(), [&](const auto& t) { return t.first == s; });
                   found != tried_.end()) {
            rss = found->second;
        } else {
            regression_.fill_problem(s, integral_, workspace_);
            const NormalEquations equations = normal_equations(workspace_.problem);
            // a structure that cannot leave less than the best is told by its bound, without the residual's pass
            // (the bound stands for it here, and when a stage comes back to it: the best only gets smaller)
            const double at_least = residual_lower_bound(equations);
            rss = at_least >= best_rss_ ? at_least : residual_squares(workspace_.problem, equations);
            tried_.emplace_back(s, rss);
        }
        if (!(rss < best_rss_)) return false;
        best_rss_ = rss;
        best_ = fitted;
        return true;
    }
    [[nodiscard]] const Structure& best() const { return best_; }

    // The best of `group` (runs of structures that differ only in mu, one run per lag), fitted: where the regression
    // takes a lag's mus from shared sums (residuals_over_mu()), the group ranked by those residuals and the best of it
    // fitted alone (consider()), one pass per run instead of three per structure; else each fitted. What a stage
    // finds next is compared with fitted residuals only.
    void consider_best_of(const std::vector<Structure>& group) {
        if (!regression_.mu_from_shared_sums()) {
            for (const auto& s : group) consider(s);
            return;
        }
        const Structure* best = nullptr;
        double best_rss = std::numeric_limits<double>::infinity();
        for (std::size_t first = 0; first < group.size();) {
            std::size_t last = first + 1;
            std::vector<double> mus{group[first].mu};
            for (; last < group.size() && same_but_mu(group[last], group[first]); ++last) mus.push_back(group[last].mu);
            const auto residuals = regression_.residuals_over_mu(group[first], integral_, mus, workspace_);
            for (std::size_t i = 0; i < residuals.size(); ++i) {
                if (residuals[i] < best_rss) best_rss = residuals[i], best = &group[first + i];
            }
            first = last;
        }
        if (best == nullptr) {  // no fit from the shared sums (dependent columns): each fitted
            for (const auto& s : group) consider(s);
            return;
        }
        consider(*best);
    }

    // Takes the best of another search over the same regression when it left less; true when it did.
    bool adopt(const StructureSearch& other) {
        if (!(other.best_rss_ < best_rss_)) return false;
        best_rss_ = other.best_rss_;
        best_ = other.best_;
        return true;
    }

private:
    static bool same_but_mu(const Structure& a, const Structure& b) {
        return a.difference == b.difference && a.reference_delay == b.reference_delay && a.lag_s == b.lag_s &&
               a.servo_delay_cycles == b.servo_delay_cycles;
    }

    const VelocityLoopRegression& regression_;
    bool integral_;
    ProblemWorkspace workspace_;
    std::vector<std::pair<Structure, double>> tried_;  // each structure fitted and its residual sum of squares
    Structure best_;
    double best_rss_{std::numeric_limits<double>::infinity()};
    std::map<std::tuple<int, int, int, double>, StructureResidual> profiled_;  // by all but mu
};

// Staged: the velocity measurement and reference delay first (no lag, a few delays), then the lag and the
// fractional delay for them, then the first stage again with the lag found.
void search_grid(StructureSearch& search, const SearchSpace& space, const GainOptions& options) {
    const double first_lag = options.current_lag_s.value_or(0.0);
    std::vector<Structure> group;
    for (int difference : space.differences) {
        for (int d : space.reference_delays) {
            for (double mu : {0.0, 0.5, 1.0}) group.push_back({difference, d, first_lag, mu});
        }
    }
    search.consider_best_of(group);
    group.clear();
    for (double lag : space.lags) {
        for (double mu : mu_grid) group.push_back({search.best().difference, search.best().reference_delay, lag, mu});
    }
    search.consider_best_of(group);
    const Structure lagged = search.best();
    for (int difference : space.differences) {
        for (int d : space.reference_delays) search.consider({difference, d, lagged.lag_s, lagged.mu});
    }
}

// Refines tau and mu by coordinate search with shrinking steps (the residual is smooth in both).
void refine_lag_and_delay(StructureSearch& search, const GainOptions& options, double dt) {
    double lag_step = options.current_lag_s ? 0.0 : 0.1 * dt;
    double mu_step = 0.1;
    for (int round = 0; round < 12; ++round) {
        bool improved = false;
        for (const auto& [dl, dm] :
             {std::pair{lag_step, 0.0}, std::pair{-lag_step, 0.0}, std::pair{0.0, mu_step}, std::pair{0.0, -mu_step}}) {
            Structure s = search.best();
            s.lag_s = std::max(0.0, s.lag_s + dl);
            s.mu = std::clamp(s.mu + dm, 0.0, 1.0);
            if (s.lag_s == search.best().lag_s && s.mu == search.best().mu) continue;
            if (search.consider(s)) improved = true;
        }
        if (!improved) {
            lag_step *= 0.5;
            mu_step *= 0.5;
        }
    }
}

// The lag alone, where the search profiles mu (VelocityLoopRegression::mu_profiled(): each lag fitted at its best mu):
// a step either way while one leaves less, halved where neither does, until it has shrunk by 2^-12.
void refine_lag(StructureSearch& search, const GainOptions& options, double dt) {
    if (options.current_lag_s) return;
    double step = 0.1 * dt;
    constexpr int max_evaluations = 400;
    int evaluations = 0;
    for (int halvings = 0; halvings < 12 && evaluations < max_evaluations;) {
        bool improved = false;
        for (const double direction : {-1.0, 1.0}) {
            Structure s = search.best();
            s.lag_s = std::max(0.0, s.lag_s + direction * step);
            if (s.lag_s == search.best().lag_s) continue;
            ++evaluations;
            if (search.consider(s)) improved = true;
        }
        if (!improved) {
            step *= 0.5;
            ++halvings;
        }
    }
}

// From the structure alone on a servo grid of m cycles per sample: the setpoint delay in servo cycles, within a
// sample of the whole samples found (the residual varies smoothly between them).
void search_servo_delay(StructureSearch& search, const VelocityLoopRegression& regression) {
    if (regression.grid == nullptr || regression.signals.logged_command) return;
    const int m = regression.grid->factor;
    const Structure found = search.best();
    const int cycles = found.servo_delay_cycles >= 0 ? found.servo_delay_cycles : found.reference_delay * m;
    for (int q = std::max(0, cycles - m + 1); q < cycles + m; ++q) {
        Structure s = found;
        s.servo_delay_cycles = q;
        search.consider(s);
    }
}

// From the structure alone on a servo grid: the setpoint delay in servo cycles and the lag, searched from the best
// structure so far once for every velocity measurement. A velocity over more cycles stands in for a lag, and a lag
// for a setpoint delay within a sample: searched one after the other for the one velocity measurement that fits best
// at a whole sample's delay, the search can stay with a velocity over several cycles and no lag, while the true
// structure, a cycle's velocity and a lag at a setpoint delay between two samples, leaves less unexplained (a 4 kHz
// loop logged at 1 kHz: K_v 0.85 % high, K_p and K_i 0.8 % low, beyond 4 standard errors).
void search_servo_structure(StructureSearch& search, const VelocityLoopRegression& regression,
                            const SearchSpace& space, const GainOptions& options, bool integral) {
    const Structure start = search.best();
    for (int difference : space.differences) {
        StructureSearch local(regression, integral);
        Structure s = start;
        s.difference = difference;
        local.consider(s);
        for (int round = 0; round < 2; ++round) {
            search_servo_delay(local, regression);
            refine_lag(local, options, regression.signals.dt);
        }
        search.adopt(local);
    }
}

Structure search_structure(const VelocityLoopRegression& regression, const SearchSpace& space,
                           const GainOptions& options, bool integral) {
    StructureSearch search(regression, integral);
    search_grid(search, space, options);
    refine_lag_and_delay(search, options, regression.signals.dt);
    // the lag and the drive signal's fractional delay move with the setpoint delay: searched again after it
    if (regression.grid != nullptr && !regression.signals.logged_command)
        search_servo_structure(search, regression, space, options, integral);
    return search.best();
}

// The setpoint delay's part within a logged sample, in servo cycles (setpoint_fraction()).
struct SampleFraction {
    int cycles{0};
    std::optional<double> standard_error_cycles;
};

// A velocity loop fitted at one of the rates rate detection tried: its servo cycles per logged sample, its gains and
// the relative error of its fit.
struct RateAlternative {
    int factor{1};
    Estimate position_gain;  // from the structure alone
    Estimate velocity_gain;
    Estimate integral_gain;
    double relative_error_pct{0.0};
};

struct VelocityLoopFit {
    std::optional<SampleFraction> setpoint_fraction;  // with a logged command and a feed-forward, on a servo grid
    // From the structure alone on a servo grid: k_ff (theta then holds its Gauss-Newton step after the structure's
    // columns), the position loop's models P and P+FF, and the P-only K_v where the loop is fitted with k_ff.
    Estimate feedforward;
    std::vector<ModelCandidate> models;
    std::optional<Estimate> effective_position_gain;
    Structure structure;
    Fit fit;
    bool integral{false};
    bool injection_gain{false};  // theta ends in the injection's gain
    double setpoint_delay{0.0};  // [samples], from the structure alone
    std::optional<double> setpoint_delay_standard_error;  // [samples]
    // A detected servo rate: the gains of every rate tried, for their uncertainty over the choice (add_rate_choice())
    std::vector<RateAlternative> rate_alternatives;
};

// From the structure alone, the setpoint delay the search found (in servo cycles on a grid, search_servo_delay()),
// with its standard error from the residual's curvature in it (delay_standard_error()).
void fit_setpoint_delay(const VelocityLoopRegression& regression, VelocityLoopFit& loop) {
    const int m = regression.grid != nullptr ? regression.grid->factor : 1;
    const Structure& best = loop.structure;
    const auto rss = [&](double cycles) {
        Structure s = best;
        if (m > 1)
            s.servo_delay_cycles = static_cast<int>(std::lround(cycles));
        else
            s.reference_delay = static_cast<int>(std::lround(cycles));
        return residual_sum_of_squares(regression.problem(s, loop.integral));
    };
    const int cycles = m > 1 && best.servo_delay_cycles >= 0 ? best.servo_delay_cycles : best.reference_delay * m;
    loop.setpoint_delay = static_cast<double>(cycles) / m;
    const auto parameters = static_cast<std::size_t>(loop.fit.batch.size());
    if (const auto se = delay_standard_error(rss, cycles, 1.0, loop.fit.samples, parameters))
        loop.setpoint_delay_standard_error = *se / m;
}

// Why the PI fit shows no integral action ("" when it does): K_i not significant (not above three standard errors),
// or significant but with a reset time T_n = K_p/K_i longer than the trace, over which an integrator that slow cannot
// be told from a drift. "" also when the fit gave numbers that are not finite: gate_finite() fails those.
std::string integral_action_missing(const Fit& fit, const GainSignals& signals) {
    const auto [kp_index, ki_index] = gain_indices(signals.logged_command);
    const std::string unit = ParameterNaming{signals.rotary}.velocity_integral_gain_unit();
    if (fit.rank_deficient)
        return fmt::format("significant integral action in the velocity loop (K_i = 0 +- 0 {})", unit);
    const double ki = fit.estimate(ki_index);
    const double se = std::sqrt(std::max(0.0, fit.covariance(ki_index, ki_index)));
    const double reset_time = fit.estimate(kp_index) / ki;
    if (!std::isfinite(ki) || !std::isfinite(se)) return {};
    if (!(ki > 3.0 * se)) {
        return fmt::format("significant integral action in the velocity loop (K_i = {:.4g} +- {:.2g} {})", ki, se,
                           unit);
    }
    const double duration = static_cast<double>(signals.samples) * signals.dt;
    if (std::isfinite(reset_time) && reset_time > duration) {
        return fmt::format(
            "integral action in the velocity loop within the trace: T_n = K_p/K_i = {:.4g} ms is longer than the "
            "trace ({:.4g} s), so K_i = {:.4g} +- {:.2g} {} cannot be told from a drift",
            reset_time * 1e3, duration, ki, se, unit);
    }
    return {};
}

// The velocity loop, PI or P as asked; automatic: PI, and P when it shows no integral action
// (integral_action_missing()).
VelocityLoopFit fit_velocity_loop(const VelocityLoopRegression& regression, const SearchSpace& space,
                                  const GainOptions& options, std::vector<std::string>& diagnostics) {
    VelocityLoopFit loop;
    loop.integral = options.velocity_loop != VelocityLoopStructure::p;
    loop.structure = search_structure(regression, space, options, loop.integral);
    loop.fit = fit(regression.problem(loop.structure, loop.integral), options.rls);
    if (loop.integral) {
        const std::string why_not = integral_action_missing(loop.fit, regression.signals);
        if (!why_not.empty() && options.velocity_loop == VelocityLoopStructure::automatic) {
            diagnostics.push_back(fmt::format("no {}: identified as P only", why_not));
            loop.integral = false;
            loop.structure = search_structure(regression, space, options, false);
            loop.fit = fit(regression.problem(loop.structure, false), options.rls);
        } else if (!why_not.empty()) {
            diagnostics.push_back(
                fmt::format("no {}: K_i and T_n, fitted as --velocity-loop pi asks, are not to be trusted", why_not));
        }
    }
    if (loop.fit.rank_deficient) {
        throw AnalysisError(
            fmt::format("{}: the velocity error does not determine the velocity-loop gains (the axis "
                        "barely moved); a trace of a motion would",
                        regression.signals.source));
    }
    if (!regression.signals.logged_command) fit_setpoint_delay(regression, loop);
    return loop;
}

// K_p, K_i and T_n = K_p/K_i from the velocity loop's fit; from the structure alone also K_v = th1/th2 and the
// reference delay.
void set_velocity_loop_gains(const VelocityLoopFit& loop, bool logged_command, GainResult& result) {
    const auto& theta = loop.fit.estimate;
    const auto& covariance = loop.fit.covariance;
    if (logged_command) {
        result.velocity_gain_N_s_per_m = estimate_from_variance(theta(0), covariance(0, 0));
        if (loop.integral) result.velocity_integral_gain_N_per_m = estimate_from_variance(theta(1), covariance(1, 1));
    } else {
        // th1 = K_p*K_v, th2 = K_p
        const double kv = theta(0) / theta(1);
        result.position_gain_per_s = estimate_from_variance(
            kv, ratio_variance(theta(0), theta(1), covariance(0, 0), covariance(1, 1), covariance(0, 1)));
        result.velocity_gain_N_s_per_m = estimate_from_variance(theta(1), covariance(1, 1));
        if (loop.integral) result.velocity_integral_gain_N_per_m = estimate_from_variance(theta(3), covariance(3, 3));
        result.reference_delay_samples = loop.structure.reference_delay;
    }
    if (loop.integral) {
        const auto [kp, ki] = gain_indices(logged_command);
        result.reset_time_s = estimate_from_variance(
            theta(kp) / theta(ki),
            ratio_variance(theta(kp), theta(ki), covariance(kp, kp), covariance(ki, ki), covariance(kp, ki)));
    }
}

// A servo rate detected from the data: the velocity loop at the other rates tried fits nearly as well where the drive
// signal's noise hides what sets them apart, and its gains move with the rate by more than their standard errors
// (the demo drive at 16 kHz from the structure alone, detected at 4 kHz: K_p 0.87 % low at 23 standard errors). So
// each gain's standard error takes in the rates as K_v's does the position loop's models (add_model_choice()): the
// rates' Akaike weights (the same parameters at every rate, AIC = N*ln(RSS/N) + const), the unconditional standard
// error sum_m w_m*sqrt(se_m^2 + (g_m - g)^2) centred on the detected rate's gain, never below its own. A note says
// which gains it widens more than twofold.
void add_rate_choice(const VelocityLoopFit& loop, GainResult& result) {
    const auto& rates = loop.rate_alternatives;
    if (rates.size() < 2) return;
    const auto rows = static_cast<double>(loop.fit.samples);
    double smallest = std::numeric_limits<double>::infinity();
    for (const auto& rate : rates) smallest = std::min(smallest, std::max(rate.relative_error_pct, 1e-300));
    std::vector<double> weights;
    double total = 0.0;
    for (const auto& rate : rates) {
        const double delta_aic = rows * 2.0 * std::log(std::max(rate.relative_error_pct, smallest) / smallest);
        weights.push_back(std::exp(-0.5 * delta_aic));
        total += weights.back();
    }
    std::vector<std::string> widened;
    const auto widen = [&](Estimate& gain, Estimate RateAlternative::*of, const char* name) {
        if (!gain.value || !gain.standard_error) return;
        double band = 0.0;
        for (std::size_t r = 0; r < rates.size(); ++r) {
            const Estimate& other = rates[r].*of;
            const double se = other.standard_error.value_or(0.0),
                         apart = other.value.value_or(*gain.value) - *gain.value;
            band += weights[r] / total * std::sqrt(se * se + apart * apart);
        }
        if (!(std::isfinite(band) && band > *gain.standard_error)) return;
        if (band > 2.0 * *gain.standard_error)
            widened.push_back(fmt::format("{} ({:.3g} -> {:.3g})", name, *gain.standard_error, band));
        gain.standard_error = band;
    };
    widen(result.position_gain_per_s, &RateAlternative::position_gain, "K_v");
    widen(result.velocity_gain_N_s_per_m, &RateAlternative::velocity_gain, "K_p");
    widen(result.velocity_integral_gain_N_per_m, &RateAlternative::integral_gain, "K_i");
    if (widened.empty()) return;
    std::string list;
    for (const auto& w : widened) list += (list.empty() ? "" : ", ") + w;
    result.diagnostics.push_back(fmt::format(
        "the servo rate was detected from the data, and the velocity loop at the other rates tried fits nearly as "
        "well with other gains: the standard errors take in the rate's choice ({}); give the rate (--servo-rate) "
        "where it is known",
        list));
}

// From the structure alone on a servo grid: k_ff, the P-only K_v as the effective gain where k_ff is fitted, and K_v's
// standard error over the models P and P+FF (add_model_choice()).
void apply_structure_feedforward(const VelocityLoopFit& loop, GainResult& result) {
    if (loop.feedforward.value) result.velocity_feedforward = loop.feedforward;
    if (loop.effective_position_gain) result.effective_position_gain_per_s = *loop.effective_position_gain;
    if (loop.models.size() == 2) add_model_choice(loop.models[0], loop.models[1], loop.fit.samples, result);
}

// The structure found and the velocity loop's fit figures, with a note on a logged velocity used and one on gains of
// the wrong sign.
void set_structure_and_fit(const VelocityLoopFit& loop, double dt, GainResult& result) {
    const Structure& structure = loop.structure;
    result.velocity_difference_samples = structure.difference == 0 ? 1 : structure.difference;
    if (structure.difference == 0) result.diagnostics.push_back("velocity loop fitted on the logged velocity channel");
    // A lag below a thousandth of a sample is no lag: only the search's steps, added and taken away, leave it.
    result.current_lag_s = structure.lag_s < 1e-3 * dt ? 0.0 : structure.lag_s;
    result.drive_delay_samples = structure.mu > 0.5 ? 1 : 0;
    result.relative_error_pct = loop.fit.relative_error_pct;
    result.systematic_error_pct = loop.fit.systematic_error_pct;
    result.samples_used = loop.fit.samples;
    if (result.method == "structure") {
        result.reference_delay_samples = static_cast<int>(std::lround(loop.setpoint_delay));
        result.setpoint_delay_s.value = loop.setpoint_delay * dt;
        if (loop.setpoint_delay_standard_error)
            result.setpoint_delay_s.standard_error = *loop.setpoint_delay_standard_error * dt;
    }
}

// The identified controller, for simulation: the gains (0 where the data did not determine them), the structure
// found, both loops at the trace's sample time.
ControllerModel identified_controller(const GainResult& result, const GainOptions& options, double dt,
                                      int hold_factor) {
    ControllerModel controller;
    controller.position_gain_per_s = result.position_gain_per_s.value.value_or(0.0);
    controller.velocity_gain_N_s_per_m = result.velocity_gain_N_s_per_m.value.value_or(0.0);
    controller.velocity_integral_gain_N_per_m = result.velocity_integral_gain_N_per_m.value.value_or(0.0);
    controller.velocity_feedforward = result.velocity_feedforward.value.value_or(0.0);
    controller.saturation_N = options.saturation_N;
    controller.current_lag_s = result.current_lag_s;
    controller.setpoint_delay_s = result.setpoint_delay_s.value.value_or(0.0);
    const double servo_cycle = result.servo_rate_hz > 0.0 ? 1.0 / result.servo_rate_hz : dt;
    controller.position_cycle_s = hold_factor > 1 ? dt * hold_factor : servo_cycle;
    controller.velocity_cycle_s = servo_cycle;
    controller.velocity_difference_samples = result.velocity_difference_samples;
    controller.injection_gain = result.injection_gain.value.value_or(1.0);
    return controller;
}

// Gains from a fit that leaves more of the drive signal unexplained than a correct model does (gains.hpp) are not to
// be trusted: status failed, with the figures and the likely causes first among the diagnostics.
void gate_fit_quality(bool injection_given, GainResult& result) {
    if (result.systematic_error_pct <= gain_fit_error_limit_pct) return;
    result.status = Status::failed;
    const std::string injection =
        injection_given ? std::string("the injection channel may not be the signal added (its sign, units or scale)")
                        : std::string(
                              "a signal added to the controller's output that the model lacks (an injected test "
                              "signal, an additive torque setpoint, a torque feed-forward: map it with "
                              "--channel injection=NAME)");
    result.diagnostics.insert(
        result.diagnostics.begin(),
        fmt::format("the controller fit is poor: {:.3g} % of the drive signal is left unexplained beyond its noise "
                    "(relative error {:.3g} %; a correct model leaves less than {:.3g} %), so the gains are not to be "
                    "trusted. Likely causes: {}; a velocity feed-forward (--feedforward); channels with the wrong "
                    "role or sign; a trace without motion",
                    result.systematic_error_pct, result.relative_error_pct, gain_fit_error_limit_pct, injection));
}

// The largest |F| over the velocity loop's rows, and where it is.
struct LargestForce {
    double magnitude{0.0};
    std::size_t sample{0};
};

LargestForce largest_force(const GainSignals& signals, const std::vector<char>& use) {
    LargestForce largest;
    for (std::size_t k = 0; k < signals.force.size(); ++k) {
        if (use[k] && std::abs(signals.force[k]) > largest.magnitude) largest = {std::abs(signals.force[k]), k};
    }
    return largest;
}

// A drive force whose squares over the rows are not finite numbers (a current of 1e300 A, a force constant far off)
// cannot be fitted: the reason, with the figures; none when it can.
std::optional<std::string> force_beyond_arithmetic(const GainSignals& signals, const std::vector<char>& use) {
    double squares = 0.0;
    for (std::size_t k = 0; k < signals.force.size(); ++k) {
        if (use[k]) squares += signals.force[k] * signals.force[k];
    }
    if (std::isfinite(squares)) return std::nullopt;
    const LargestForce largest = largest_force(signals, use);
    return fmt::format(
        "the drive force reaches {:.4g} {} (at t = {:.6g} s): so large that its squares are not finite numbers, and "
        "no gains can be fitted to it; is the drive signal's unit or the force constant right?",
        largest.magnitude, signals.rotary ? "N*m" : "N", static_cast<double>(largest.sample) * signals.dt);
}

// Gains or fit figures that are not finite numbers are no gains: status failed, with a diagnostic first that names
// them and gives the largest drive force; the values are dropped (null in the document, "—" in print).
void gate_finite(const GainSignals& signals, const std::vector<char>& use, GainResult& result) {
    std::string names;
    const auto check = [&](Estimate& estimate, const char* symbol) {
        if (estimate.value && !std::isfinite(*estimate.value)) {
            names += fmt::format("{}{}", names.empty() ? "" : ", ", symbol);
            estimate = Estimate{};
        }
    };
    check(result.position_gain_per_s, "K_v");
    check(result.velocity_gain_N_s_per_m, "K_p");
    check(result.velocity_integral_gain_N_per_m, "K_i");
    check(result.velocity_feedforward, "k_ff");
    check(result.reset_time_s, "T_n");
    check(result.injection_gain, "the injection's gain");
    for (const auto& [value, name] :
         {std::pair{result.relative_error_pct, "the relative error"},
          std::pair{result.systematic_error_pct, "the systematic error"},
          std::pair{result.position_loop_relative_error_pct, "the position loop's error"}}) {
        if (!std::isfinite(value)) names += fmt::format("{}{}", names.empty() ? "" : ", ", name);
    }
    if (names.empty()) return;
    result.status = Status::failed;
    result.diagnostics.insert(
        result.diagnostics.begin(),
        fmt::format("the controller fit gave numbers that are not finite ({}): no gains (the drive force reaches "
                    "{:.4g} {}); are the channels' units and the force constant right?",
                    names, largest_force(signals, use).magnitude, signals.rotary ? "N*m" : "N"));
}

// A loop gain of the wrong sign is no controller that could run the axis (its loop would be unstable): status failed,
// with the likely cause and the fix first among the diagnostics. K_p < 0 with K_v > 0 is a drive signal whose sign is
// the opposite of the motion's (drive and NC count directions differently); K_v < 0 is a reference and position
// mapped the wrong way round, or of opposite signs.
void gate_signs(const GainOptions& options, bool rotary, GainResult& result) {
    const double kv = result.position_gain_per_s.value.value_or(1.0);
    const double kp = result.velocity_gain_N_s_per_m.value.value_or(1.0);
    const ParameterNaming naming{rotary};
    std::string why;
    if (kv <= 0.0) {
        why = fmt::format(
            "the position loop gain came out negative (K_v = {:.4g} 1/s), which no stable controller has: are the "
            "reference and the position mapped to their roles (--channel reference_position=NAME, --channel "
            "position=NAME), with the same sign?",
            kv);
    } else if (kp <= 0.0) {
        const std::string fix = options.force_per_signal != 0.0
                                    ? fmt::format("give the force constant with the other sign, --force-constant {:g}",
                                                  -options.force_per_signal)
                                    : std::string("turn the drive signal's sign (a negative --force-constant)");
        why = fmt::format(
            "the velocity loop gain came out negative (K_p = {:.4g} {}), which no stable controller has: the drive "
            "signal's sign is the opposite of the motion's (drive and NC count directions differently); {}",
            kp, naming.velocity_gain_unit(), fix);
    }
    if (why.empty()) return;
    result.status = Status::failed;
    result.diagnostics.insert(result.diagnostics.begin(), std::move(why));
}

// K_v = th1/th2 of a structure fit, with its variance by the delta method.
Estimate structure_position_gain(const Fit& fit) {
    const auto& theta = fit.estimate;
    const auto& covariance = fit.covariance;
    return estimate_from_variance(
        theta(0) / theta(1), ratio_variance(theta(0), theta(1), covariance(0, 0), covariance(1, 1), covariance(0, 1)));
}

// The structure with k_ff profiled (feedforward_profiled): as search_structure(), but the current-loop lag searched
// for every velocity measurement, not only the one that fits best without a lag: with k_ff free, a velocity over
// more cycles stands in for the lag, and the staged search stays there.
Structure search_feedforward_structure(const VelocityLoopRegression& regression, const SearchSpace& space,
                                       const GainOptions& options, bool integral) {
    StructureSearch search(regression, integral);
    search_grid(search, space, options);
    const int delay = search.best().reference_delay;
    for (int difference : space.differences) {
        for (double lag : space.lags) {
            for (double mu : mu_grid) search.consider({difference, delay, lag, mu});
        }
    }
    refine_lag_and_delay(search, options, regression.signals.dt);
    search_servo_structure(search, regression, space, options, integral);
    return search.best();
}

// The velocity loop from the structure alone on the servo grid with a velocity feed-forward: the structure searched
// with k_ff profiled out (the setpoint delay in servo cycles with it: with k_ff held, a delay would be traded for k_ff,
// K_v*e(d + f) + k_ff*x_ref' being nearly K_v*e(d) + (k_ff - K_v*f*T_s)*x_ref'), then k_ff, its standard error and
// K_v's from the fit with the derivative column (feedforward_problem()). None where the fit cannot tell k_ff.
std::optional<VelocityLoopFit> fit_structure_feedforward(VelocityLoopRegression regression, const SearchSpace& space,
                                                         const GainOptions& options, const VelocityLoopFit& plain) {
    regression.feedforward_columns = true;
    regression.feedforward_profiled = true;
    VelocityLoopFit loop;
    loop.integral = plain.integral;
    loop.structure = search_feedforward_structure(regression, space, options, loop.integral);
    const auto bank = regression.servo_columns(loop.structure, loop.integral);
    const double k = profiled_feedforward(regression, bank, loop.integral, loop.structure.mu);
    if (!std::isfinite(k)) return std::nullopt;
    loop.fit = fit(feedforward_problem(regression, bank, loop.integral, k), options.rls);
    if (loop.fit.rank_deficient) return std::nullopt;
    const Eigen::Index i = loop.integral ? 5 : 2;
    loop.feedforward = estimate_from_variance(k, loop.fit.covariance(i, i));
    loop.injection_gain = plain.injection_gain;
    fit_setpoint_delay(regression, loop);  // k_ff profiled: the profile likelihood's curvature
    return loop;
}

// A feed-forward shows from the structure alone as from a logged command (feedforward_shows()): fitting it halves
// the part of the drive signal left unexplained beyond its noise (the structure's fit error; its white noise stays
// whatever the model) and k_ff lies beyond three standard errors from 0.
bool structure_feedforward_shows(const VelocityLoopFit& with, const VelocityLoopFit& plain) {
    const double kff = with.feedforward.value.value_or(0.0);
    const double se = with.feedforward.standard_error.value_or(std::numeric_limits<double>::infinity());
    return std::isfinite(kff) && std::abs(kff) > 3.0 * se &&
           with.fit.systematic_error_pct < 0.5 * plain.fit.systematic_error_pct;
}

// From the structure alone on the servo grid: the loop fitted with k_ff where --feedforward asks or it shows, with
// the P and P+FF models for K_v's uncertainty (add_model_choice()), else the plain one with both models.
VelocityLoopFit choose_structure_feedforward(const VelocityLoopRegression& regression, const SearchSpace& space,
                                             const GainOptions& options, VelocityLoopFit plain,
                                             std::vector<std::string>& diagnostics) {
    auto with = fit_structure_feedforward(regression, space, options, plain);
    if (!with) return plain;
    const ModelCandidate plain_model{structure_position_gain(plain.fit), plain.fit.relative_error_pct,
                                     static_cast<int>(plain.fit.batch.size())};
    const ModelCandidate with_model{structure_position_gain(with->fit), with->fit.relative_error_pct,
                                    static_cast<int>(with->fit.batch.size())};
    if (!options.feedforward && !structure_feedforward_shows(*with, plain)) {
        plain.models = {plain_model, with_model};
        return plain;
    }
    if (!options.feedforward) {
        diagnostics.push_back(fmt::format(
            "a velocity feed-forward shows in the structure (k_ff = {:.4g}; the part of the drive signal left "
            "unexplained beyond its noise falls from {:.3g} % to {:.3g} % with it): fitted with it, as --feedforward "
            "would; K_v fitted without it would be {:.4g} 1/s, an effective gain of the loop with its feed-forward",
            with->feedforward.value.value_or(0.0), plain.fit.systematic_error_pct, with->fit.systematic_error_pct,
            plain_model.position_gain_per_s.value.value_or(0.0)));
    }
    with->models = {plain_model, with_model};
    with->effective_position_gain = plain_model.position_gain_per_s;
    return std::move(*with);
}

}  // namespace

// With a feed-forward, the position loop on the logged samples cannot tell a setpoint delay within a sample from
// k_ff: for 0 <= f < 1, x_ref(k - d - f) = x_ref(k - d) - f*(x_ref(k - d) - x_ref(k - d - 1)) on the interpolated
// reference, so K_v*e(d + f) + k_ff*x_ref'(k - d) = K_v*e(d) + (k_ff - K_v*f*T)*x_ref'(k - d) at every logged sample
// (its fit takes whole samples). Between the samples the two differ where the delayed setpoint crosses a logged
// sample, which the velocity loop on the servo grid sees: the fraction is the whole number q of servo cycles whose
// position loop (d + q/m, k_ff + K_v*q*T_s, k_ff that of the whole-sample fit) leaves the least of the drive signal unexplained, with its standard error
// from the residual's curvature in q (delay_standard_error()). Sets regression.servo_command to that position loop's.
SampleFraction setpoint_fraction(VelocityLoopRegression& regression, const PositionLoop& whole,
                                 const SearchSpace& space, const GainOptions& options) {
    const ServoGrid& grid = *regression.grid;
    const int m = grid.factor;
    const auto command_at = [&](double cycles) {
        const PositionLoop loop{whole.gain_per_s, whole.feedforward + whole.gain_per_s * cycles * grid.cycle_s,
                                whole.delay + cycles / m};
        return servo_velocity_command(regression.signals, grid, loop);
    };
    const bool integral = options.velocity_loop != VelocityLoopStructure::p;
    const Structure structure = search_structure(regression, space, options, integral);
    std::size_t parameters = 0;
    const auto rss = [&](double cycles) {
        VelocityLoopRegression shifted = regression;
        shifted.servo_command = command_at(cycles);
        const Problem problem = shifted.problem(structure, integral);
        parameters = problem.columns.size();
        return residual_sum_of_squares(problem);
    };
    SampleFraction fraction;
    double best = rss(0.0);
    for (int q = 1; q < m; ++q) {
        if (const double r = rss(q); r < best) {
            best = r;
            fraction.cycles = q;
        }
    }
    const auto rows = static_cast<std::size_t>(std::count(regression.use.begin(), regression.use.end(), char{1}));
    fraction.standard_error_cycles = delay_standard_error(rss, fraction.cycles, 1.0, rows, parameters);
    regression.servo_command = command_at(fraction.cycles);
    return fraction;
}

// The position loop with the setpoint's fraction of a sample that the velocity loop on the servo grid found
// (setpoint_fraction()): the delay d + q/m and k_ff + K_v*q*T_s, whose standard error takes in the delay's.
void apply_setpoint_fraction(const SampleFraction& fraction, double servo_cycle_s, double dt, GainResult& result) {
    const double kv = result.position_gain_per_s.value.value_or(0.0);
    const double shift = fraction.cycles * servo_cycle_s;
    result.setpoint_delay_s.value = result.setpoint_delay_s.value.value_or(0.0) + shift;
    result.setpoint_delay_s.standard_error.reset();
    if (fraction.standard_error_cycles)
        result.setpoint_delay_s.standard_error = *fraction.standard_error_cycles * servo_cycle_s;
    result.reference_delay_samples = static_cast<int>(std::lround(*result.setpoint_delay_s.value / dt));
    Estimate& kff = result.velocity_feedforward;
    if (!kff.value) return;
    *kff.value += kv * shift;
    if (kff.standard_error && fraction.standard_error_cycles) {
        const double from_delay = kv * servo_cycle_s * *fraction.standard_error_cycles;
        kff.standard_error = std::hypot(*kff.standard_error, from_delay);
    }
}

// An injection's gain is taken from the data when its standard error is below this fraction of it: it is there to
// catch a DAC's or an amplifier's scale, a few per cent (a recording whose 5 V pulses act as 5.07 V).
constexpr double injection_gain_resolution = 0.02;

// The velocity loop fitted at `factor` servo cycles per logged sample (1: the equation-error fit on the logged
// samples), with the gain of an injection (varying) fitted, or 1 where the data cannot tell it (said).
VelocityLoopFit fit_at_servo_factor(const GainSignals& signals, const std::vector<char>& use, int factor,
                                    const GainOptions& options, const GainResult& position_loop,
                                    std::vector<std::string>& diagnostics) {
    SearchSpace space = search_space(signals, options);
    std::optional<ServoGrid> grid;
    if (factor > 1) {
        std::erase(space.differences, 0);  // a logged velocity is no measurement between the samples
        if (space.differences.empty()) space.differences = {1, 2, 3, 4};
        grid = servo_grid(signals, factor);
    }
    VelocityLoopRegression regression{signals, use, grid ? &*grid : nullptr};
    const auto [low, high] = std::minmax_element(signals.injection.begin(), signals.injection.end());
    regression.injection_gain_known = signals.injection.empty() || !(*high > *low);  // a constant is an offset
    std::optional<SampleFraction> fraction;
    if (grid && signals.logged_command) {
        const PositionLoop loop{position_loop.position_gain_per_s.value.value_or(0.0),
                                position_loop.velocity_feedforward.value.value_or(0.0),
                                position_loop.setpoint_delay_s.value.value_or(0.0) / signals.dt};
        regression.servo_command = servo_velocity_command(signals, *grid, loop);
        if (position_loop.velocity_feedforward.value) fraction = setpoint_fraction(regression, loop, space, options);
    }
    VelocityLoopFit loop = fit_velocity_loop(regression, space, options, diagnostics);
    loop.setpoint_fraction = fraction;
    loop.injection_gain = !regression.injection_gain_known;
    if (!loop.injection_gain) return loop;
    const Eigen::Index g = loop.fit.estimate.size() - 1;
    const double gain = loop.fit.estimate(g), se = std::sqrt(std::max(0.0, loop.fit.covariance(g, g)));
    if (std::isfinite(gain) && std::isfinite(se) && se < injection_gain_resolution * std::abs(gain)) return loop;
    diagnostics.push_back(fmt::format(
        "the data cannot tell the gain with which the injection enters the drive signal (g = {:.4g} +- {:.2g}, "
        "not within {:g} %): taken as 1",
        gain, se, 100.0 * injection_gain_resolution));
    regression.injection_gain_known = true;
    loop = fit_velocity_loop(regression, space, options, diagnostics);
    return loop;
}

// From the structure alone at `factor` servo cycles per logged sample: the plain loop, or the loop with a velocity
// feed-forward where one is asked or shows (choose_structure_feedforward()).
VelocityLoopFit structure_feedforward_at(const GainSignals& signals, const std::vector<char>& use, int factor,
                                         const GainOptions& options, VelocityLoopFit plain,
                                         std::vector<std::string>& diagnostics) {
    SearchSpace space = search_space(signals, options);
    std::erase(space.differences, 0);  // a logged velocity is no measurement between the samples
    if (space.differences.empty()) space.differences = {1, 2, 3, 4};
    const ServoGrid grid = servo_grid(signals, factor);
    VelocityLoopRegression regression{signals, use, &grid};
    regression.injection_gain_known = !plain.injection_gain;
    return choose_structure_feedforward(regression, space, options, std::move(plain), diagnostics);
}

// Servo cycles per logged sample of a rate [Hz]; InputError unless a whole multiple (1 to 64) of the sample rate.
int servo_factor_of(double rate_hz, double dt, const std::string& what) {
    const double per_sample = rate_hz * dt;
    if (!(per_sample > 1.0 - 1e-6 && per_sample < 64.5) || std::abs(per_sample - std::round(per_sample)) > 1e-3) {
        throw InputError(fmt::format("{} {:g} Hz is not a whole multiple (1 to 64) of the trace's sample rate {:g} Hz",
                                     what, rate_hz, 1.0 / dt));
    }
    return static_cast<int>(std::lround(per_sample));
}

// The gains of the log rate's fit and of each candidate rate's, for add_rate_choice().
std::vector<RateAlternative> rate_alternatives(const VelocityLoopFit& log_rate,
                                               const std::vector<std::pair<int, VelocityLoopFit>>& candidates,
                                               bool logged_command) {
    std::vector<RateAlternative> alternatives;
    const auto add = [&](int factor, const VelocityLoopFit& loop) {
        if (loop.fit.rank_deficient) return;
        GainResult gains;
        set_velocity_loop_gains(loop, logged_command, gains);
        alternatives.push_back({factor, gains.position_gain_per_s, gains.velocity_gain_N_s_per_m,
                                gains.velocity_integral_gain_N_per_m, loop.fit.relative_error_pct});
    };
    add(1, log_rate);
    for (const auto& [factor, loop] : candidates) add(factor, loop);
    return alternatives;
}

// Above this part [%] of the drive signal left unexplained beyond its noise by the log-rate fit, a faster velocity
// loop is looked for (EMPS leaves 0.00 %, a 1 kHz synthetic loop 0.06 %; a loop at 8 kHz fitted at 1 kHz 0.5 to 3 %).
constexpr double servo_rate_search_above_pct = 0.1;

// The velocity loop at its own rate: --servo-rate, the trace's servo_cycle_s, or the log rate; without either, a loop
// at 2, 4, 8 or 16 times the log rate when the log-rate fit leaves more than servo_rate_search_above_pct unexplained
// and a faster one halves that. Sets the rate, the fit's kind and why.
VelocityLoopFit fit_velocity_loop_at_its_rate(const Trace& trace, const GainSignals& signals,
                                              const std::vector<char>& use, const GainOptions& options,
                                              GainResult& result) {
    int factor = 1;
    if (options.servo_rate_hz) {
        factor = servo_factor_of(*options.servo_rate_hz, signals.dt, "--servo-rate");
        result.servo_rate_from = "--servo-rate";
    } else if (const auto found = trace.constants.find("servo_cycle_s"); found != trace.constants.end()) {
        factor = servo_factor_of(1.0 / found->second, signals.dt, "the trace's servo cycle (servo_cycle_s): a rate of");
        result.servo_rate_from = "trace";
    }
    std::vector<std::string> notes;
    VelocityLoopFit best = fit_at_servo_factor(signals, use, factor, options, result, notes);
    if (factor == 1 && !options.servo_rate_hz && best.fit.systematic_error_pct > servo_rate_search_above_pct) {
        // A loop at m times the rate nearly contains one at m/2 (its velocity over two of its cycles): of the rates
        // that halve the log rate's unexplained part, the slowest within a quarter of the best.
        std::vector<std::pair<int, VelocityLoopFit>> candidates;
        std::vector<std::vector<std::string>> candidate_notes(4);
        double smallest = best.fit.systematic_error_pct;
        for (const int candidate : {2, 4, 8, 16}) {
            candidates.emplace_back(candidate, fit_at_servo_factor(signals, use, candidate, options, result,
                                                                   candidate_notes[candidates.size()]));
            smallest = std::min(smallest, candidates.back().second.fit.systematic_error_pct);
        }
        for (std::size_t c = 0; c < candidates.size(); ++c) {
            const double error = candidates[c].second.fit.systematic_error_pct;
            if (error < 0.5 * best.fit.systematic_error_pct && error <= 1.25 * smallest) {
                auto alternatives = rate_alternatives(best, candidates, signals.logged_command);
                factor = candidates[c].first;
                best = std::move(candidates[c].second);
                best.rate_alternatives = std::move(alternatives);
                notes = std::move(candidate_notes[c]);
                result.servo_rate_from = "detected";
                break;
            }
        }
    }
    // the feed-forward from the structure alone where the velocity loop runs between the logged samples: at the log
    // rate (EMPS) and on a held position the structure fit stays P-only
    if (factor > 1 && !signals.logged_command && signals.hold_factor < 2) {
        best = structure_feedforward_at(signals, use, factor, options, std::move(best), notes);
        // the other rates' plain structures give a loop with a feed-forward effective gains, not its own
        if (best.feedforward.value) best.rate_alternatives.clear();
    }
    for (auto& note : notes) result.diagnostics.push_back(std::move(note));
    result.servo_rate_hz = static_cast<double>(factor) / signals.dt;
    if (best.setpoint_fraction && factor > 1)
        apply_setpoint_fraction(*best.setpoint_fraction, signals.dt / factor, signals.dt, result);
    if (factor > 1) {
        result.fit_kind = "output_error";
        result.diagnostics.push_back(fmt::format(
            "the velocity loop runs at {:.6g} Hz ({}), {} times per logged sample: fitted by simulating the "
            "controller at that rate between the logged samples (output error), its velocity measured over its own "
            "cycles",
            result.servo_rate_hz,
            result.servo_rate_from == "detected" ? "detected: it explains the drive signal better than the log rate"
            : result.servo_rate_from == "trace"  ? "the trace's servo cycle"
                                                 : "--servo-rate",
            factor));
    }
    return best;
}

namespace {

bool named_like_injection(std::string name) {
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
    for (const char* word : {"pulse", "inject", "excitation", "dither", "prbs"}) {
        if (name.find(word) != std::string::npos) return true;
    }
    return false;
}

// Pearson's correlation of a and b; 0 when either is constant.
double correlation(std::span<const double> a, std::span<const double> b) {
    const auto n = static_cast<double>(a.size());
    const double mean_a = std::accumulate(a.begin(), a.end(), 0.0) / n;
    const double mean_b = std::accumulate(b.begin(), b.end(), 0.0) / n;
    double ab = 0.0, aa = 0.0, bb = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        ab += (a[k] - mean_a) * (b[k] - mean_b);
        aa += (a[k] - mean_a) * (a[k] - mean_a);
        bb += (b[k] - mean_b) * (b[k] - mean_b);
    }
    return aa > 0.0 && bb > 0.0 ? ab / std::sqrt(aa * bb) : 0.0;
}

// A square wave: nine in ten samples at its lowest or highest level (within 1 % of the range), switching between
// them at least four times.
bool square_wave(std::span<const double> values) {
    const auto [low, high] = std::minmax_element(values.begin(), values.end());
    const double range = *high - *low;
    if (!(range > 0.0) || !std::isfinite(range)) return false;
    std::size_t at_levels = 0, switches = 0;
    int last = 0;
    for (const double value : values) {
        const int level = value <= *low + 0.01 * range ? -1 : value >= *high - 0.01 * range ? 1 : 0;
        if (level == 0) continue;
        ++at_levels;
        if (last != 0 && level != last) ++switches;
        last = level;
    }
    return at_levels >= values.size() * 9 / 10 && switches >= 4;
}

}  // namespace

std::optional<InjectionLike> unmapped_injection(const Trace& trace) {
    if (trace.has(Role::injection) || trace.samples() < 50) return std::nullopt;
    const auto* reference = trace.find(Role::reference_position);
    const auto* position = trace.find(Role::position);
    Column error;
    if (reference != nullptr && position != nullptr) {
        error.resize(trace.samples());
        for (std::size_t k = 0; k < error.size(); ++k) error[k] = reference->values[k] - position->values[k];
    }
    for (const auto& channel : trace.channels) {
        if (channel.role != Role::other || channel.values.size() != trace.samples()) continue;
        if (named_like_injection(channel.name)) return InjectionLike{channel.name, "named like one"};
        if (square_wave(channel.values) && (error.empty() || std::abs(correlation(channel.values, error)) < 0.3))
            return InjectionLike{channel.name, "a square wave that the loop's following error does not follow"};
    }
    return std::nullopt;
}

std::string unmapped_injection_message(const InjectionLike& found) {
    return fmt::format(
        "channel '{}' looks like a test signal injected at the controller's output ({}) but has no role, so it is "
        "not taken out of the drive signal; if it is one, map it with --channel injection={}",
        found.channel, found.why, found.channel);
}

GainResult identify_gains(const Trace& trace, std::span<const double> drive_force, const GainOptions& options,
                          std::span<const double> injection) {
    if (const auto problem = options.validate(); !problem.empty()) throw InputError(problem);
    const TimeBaseMemo time_base(trace);  // one pass over the time column for the sample time and the native rate
    const GainSignals signals = gain_signals(trace, drive_force, injection);
    require_following_error(signals);
    GainResult result;
    result.method = signals.logged_command ? "velocity_command" : "structure";
    std::vector<char> use = velocity_loop_rows(signals, options.saturation_N, result.diagnostics);
    keep_fresh_rows(signals, use);
    if (auto beyond = force_beyond_arithmetic(signals, use)) {
        result.status = Status::failed;
        result.diagnostics.insert(result.diagnostics.begin(), std::move(*beyond));
        // nothing fitted: no fit figures (null in the document), a controller without gains
        result.relative_error_pct = result.systematic_error_pct = result.position_loop_relative_error_pct =
            std::numeric_limits<double>::quiet_NaN();
        result.controller = identified_controller(result, options, signals.dt, signals.hold_factor);
        return result;
    }
    if (signals.logged_command) identify_position_loop(signals, options, result);
    const VelocityLoopFit velocity_loop = fit_velocity_loop_at_its_rate(trace, signals, use, options, result);
    if (!signals.logged_command && options.feedforward && !velocity_loop.feedforward.value) {
        result.diagnostics.push_back(
            "--feedforward: a velocity feed-forward is fitted only from a logged velocity command (the position loop "
            "on its own) or from the structure with the velocity loop faster than the log, which this trace lacks; "
            "from the structure alone K_v is that of a P position loop, for a loop with a feed-forward an effective "
            "gain, not its K_v (map the command with --channel velocity_command=NAME, or give --servo-rate)");
    }
    if (signals.hold_factor > 1) {
        result.diagnostics.insert(
            result.diagnostics.end() - (result.fit_kind == "output_error" ? 1 : 0),
            fmt::format("the position holds each value over {} samples: fitted on the samples where it is new, the "
                        "position loop taken to run every {:.6g} ms and the velocity loop every {:.6g} ms{}",
                        signals.hold_factor, signals.dt * signals.hold_factor * 1e3, 1e3 / result.servo_rate_hz,
                        result.fit_kind == "output_error" ? "" : " (the drive signal's interval)"));
    }
    set_velocity_loop_gains(velocity_loop, signals.logged_command, result);
    add_rate_choice(velocity_loop, result);
    apply_structure_feedforward(velocity_loop, result);
    set_structure_and_fit(velocity_loop, signals.dt, result);
    result.injection_subtracted = !signals.injection.empty();
    if (velocity_loop.injection_gain) {
        const Eigen::Index g = velocity_loop.fit.estimate.size() - 1;
        result.injection_gain =
            estimate_from_variance(velocity_loop.fit.estimate(g), velocity_loop.fit.covariance(g, g));
    } else if (result.injection_subtracted) {
        result.injection_gain.value = 1.0;
    }
    gate_finite(signals, use, result);
    if (result.status != Status::failed) gate_fit_quality(result.injection_subtracted, result);
    gate_signs(options, signals.rotary, result);
    if (signals.injection.empty()) {
        if (const auto found = unmapped_injection(trace))
            result.diagnostics.push_back(unmapped_injection_message(*found));
    }
    result.controller = identified_controller(result, options, signals.dt, signals.hold_factor);
    return result;
}

}  // namespace feedid
