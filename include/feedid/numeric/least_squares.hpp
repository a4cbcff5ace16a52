#pragma once
// Batch linear least squares by Householder QR: the certified cross-check for RLS.

#include <algorithm>
#include <cstddef>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace feedid {

struct LeastSquaresResult {
    Eigen::VectorXd estimate;        ///< theta minimising ||y - Phi*theta||
    Eigen::VectorXd standard_error;  ///< sigma_hat * sqrt(diag((Phi^T Phi)^-1)), or the long-run sandwich's below
    /// sigma_hat * sqrt(diag((Phi^T Phi)^-1)): the textbook value, right only for uncorrelated residuals
    Eigen::VectorXd white_noise_standard_error;
    Eigen::MatrixXd covariance;      ///< sigma_hat^2 * (Phi^T Phi)^-1
    Eigen::VectorXd r_diagonal;      ///< |diag(R)| of the QR factorisation
    double residual_std{0.0};        ///< sigma_hat = ||y - Phi*theta|| / sqrt(n - p)
    double relative_error_pct{0.0};  ///< 100 * ||y - Phi*theta|| / ||y||
    double condition_number{0.0};    ///< sigma_max / sigma_min of Phi (2-norm)
    std::size_t samples{0};
    bool rank_deficient{false};  ///< Phi has numerically dependent columns; estimate is then not unique
};

/// gram += weight * phi phi^T in its lower triangle (p = gram.rows() values at phi): what
/// gram.selfadjointView<Eigen::Lower>().rankUpdate(phi, weight) adds, the same products in the same order, without
/// the dispatch Eigen spends on a matrix of a few columns, a cost that dominated sums over millions of rows.
inline void add_outer_product_lower(Eigen::MatrixXd& gram, const double* phi, double weight = 1.0) {
    const Eigen::Index p = gram.rows();
    double* column = gram.data();
    for (Eigen::Index j = 0; j < p; ++j, column += p) {
        const double scaled = weight * phi[j];
        for (Eigen::Index i = j; i < p; ++i) column[i] += scaled * phi[i];
    }
}

/// sum += scale * x over n values: Eigen's `sum += x * scale` on vectors of a few entries, the same products and
/// sums, without its dispatch.
inline void add_scaled(double* sum, const double* x, double scale, Eigen::Index n) {
    for (Eigen::Index i = 0; i < n; ++i) sum[i] += x[i] * scale;
}

/// Solves min ||y - Phi*theta||. Requires rows >= columns; returns rank_deficient when Phi lacks full column rank.
LeastSquaresResult solve_least_squares(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y);

/// The long-run covariance S = sum over blocks b of g_b g_b^T, g_b = sum of phi_t * e_t over the block, by batch
/// means: a row belongs to block index[t] / block, so rows whose sample indices lie within the same `block`
/// consecutive samples sum together (in any order; a row set may skip samples). Residuals correlated over fewer than
/// `block` samples (a low-pass filtered force and regressors) are then counted as often as they carry independent
/// information, not once per sample. Scaled by n / (n - p) as the plain estimate is.
Eigen::MatrixXd long_run_covariance(const Eigen::MatrixXd& phi, const Eigen::VectorXd& residual,
                                    std::span<const std::size_t> index, std::size_t block);

/// Replaces the covariance and standard errors of `result` (a fit of y on phi) by the sandwich
/// (Phi^T Phi)^-1 S (Phi^T Phi)^-1 with S the long-run covariance above: standard errors that hold when the residuals
/// are correlated over up to `block` neighbouring samples. A `block` of 1 or a rank-deficient fit leaves it as it is.
void account_for_correlated_residuals(LeastSquaresResult& result, const Eigen::MatrixXd& phi, const Eigen::VectorXd& y,
                                      std::span<const std::size_t> index, std::size_t block);

/// Batch least squares on rows given one at a time, never held as a matrix: the R factor of [Phi y] is updated a block
/// of rows at a time (Householder QR of the previous R stacked on the next rows), a second pass over the rows gives
/// the residuals, their sums and, with `block` > 1, the long-run covariance (as account_for_correlated_residuals
/// does; rows whose `index` is not ascending fall back to a sum per block). The same figures as
/// solve_least_squares(Phi, y) followed by account_for_correlated_residuals, up to rounding, in memory of the order
/// of the parameters, not of the rows. Use through solve_least_squares_rows().
class StreamedLeastSquares {
public:
    explicit StreamedLeastSquares(Eigen::Index parameters);
    /// First pass: one row of Phi (parameters() values) and its y.
    void add(const double* phi, double y);
    /// After the first pass: the QR's figures (estimate, R, condition, rank); false when nothing more can be
    /// computed (too few rows, rank deficient): result() is then final.
    bool factor();
    /// Before the second pass: the block length of the long-run covariance (1 = none), and whether the rows' sample
    /// indices ascend (else up to `largest_index` / `block` + 1 block sums are held).
    void start_residuals(std::size_t block, bool ascending, std::size_t largest_index);
    /// Second pass: the same rows in the same order, with each row's sample index.
    void add_residual(const double* phi, double y, std::size_t index);
    /// After the second pass: the residual figures and the standard errors (the long-run sandwich for a block > 1).
    LeastSquaresResult finish();
    [[nodiscard]] const LeastSquaresResult& result() const { return result_; }

private:
    void reduce();
    void close_block();
    Eigen::Index p_;
    Eigen::MatrixXd stack_;  ///< rows 0..p: R of [Phi y] so far (once have_r_), then the pending rows
    Eigen::Index pending_{0};
    bool have_r_{false};
    std::size_t rows_{0};
    Eigen::MatrixXd r_;  ///< R of Phi (p x p)
    LeastSquaresResult result_;
    double rss_{0.0}, y_squared_{0.0};
    std::size_t block_{1};
    bool ascending_{true};
    Eigen::MatrixXd long_run_;  ///< sum over blocks of g_b g_b^T
    Eigen::VectorXd g_;         ///< the current block's sum of phi_t e_t (ascending indices)
    std::size_t block_end_{0};  ///< the first index past the current block
    bool in_block_{false};
    Eigen::MatrixXd sums_;  ///< per block (indices not ascending)
};

/// solve_least_squares() and account_for_correlated_residuals() on `n` rows given by row(i, phi) -> y (phi: parameters
/// values to fill), each called twice in order; index(i) the sample index of row i (for the batch means).
template <class Row, class Index>
LeastSquaresResult solve_least_squares_rows(std::size_t n, Eigen::Index parameters, const Row& row, const Index& index,
                                            std::size_t block) {
    StreamedLeastSquares solver(parameters);
    Eigen::VectorXd phi(parameters);
    for (std::size_t i = 0; i < n; ++i) {
        const double y = row(i, phi.data());
        solver.add(phi.data(), y);
    }
    if (!solver.factor()) return solver.result();
    bool ascending = true;
    std::size_t largest = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const std::size_t k = index(i);
        if (i > 0 && k < largest) ascending = false;
        largest = std::max(largest, k);
    }
    solver.start_residuals(block, ascending, largest);
    for (std::size_t i = 0; i < n; ++i) {
        const double y = row(i, phi.data());
        solver.add_residual(phi.data(), y, index(i));
    }
    return solver.finish();
}

}  // namespace feedid
