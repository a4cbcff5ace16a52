#pragma once
// Batch linear least squares by Householder QR: the certified cross-check for RLS.

#include <cstddef>
#include <span>

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

}  // namespace feedid
