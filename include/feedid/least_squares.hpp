#pragma once
// Batch linear least squares by Householder QR: the certified cross-check for RLS.

#include <cstddef>

#include <Eigen/Core>

namespace feedid {

struct LeastSquaresResult {
    Eigen::VectorXd estimate;        ///< theta minimising ||y - Phi*theta||
    Eigen::VectorXd standard_error;  ///< sigma_hat * sqrt(diag((Phi^T Phi)^-1))
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

}  // namespace feedid
