#include "feedid/least_squares.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace feedid {

LeastSquaresResult solve_least_squares(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y) {
    LeastSquaresResult result;
    const auto n = phi.rows();
    const auto p = phi.cols();
    result.samples = static_cast<std::size_t>(n);
    result.estimate = Eigen::VectorXd::Constant(p, std::nan(""));
    result.standard_error = Eigen::VectorXd::Constant(p, std::nan(""));
    result.covariance = Eigen::MatrixXd::Constant(p, p, std::nan(""));
    if (n < p || p == 0) {
        result.rank_deficient = true;
        return result;
    }
    // Householder QR (no pivoting, so that |diag(R)| belongs to the columns in their order).
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(phi);
    const Eigen::MatrixXd r = qr.matrixQR().topRows(p).triangularView<Eigen::Upper>();
    result.r_diagonal = r.diagonal().cwiseAbs();
    // Phi = Q*R with orthonormal Q: Phi and R share their singular values.
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(r);
    const auto& singular = svd.singularValues();
    result.condition_number = singular(p - 1) > 0.0 ? singular(0) / singular(p - 1) : INFINITY;
    if (!(singular(p - 1) > singular(0) * 1e-12)) {
        result.rank_deficient = true;
        return result;
    }
    result.estimate = qr.solve(y);
    const Eigen::VectorXd residual = y - phi * result.estimate;
    const double rss = residual.squaredNorm();
    const double dof = static_cast<double>(n - p);
    result.residual_std = dof > 0 ? std::sqrt(rss / dof) : 0.0;
    const double y_norm = y.norm();
    result.relative_error_pct = y_norm > 0.0 ? 100.0 * std::sqrt(rss) / y_norm : 0.0;
    // (Phi^T Phi)^-1 = R^-1 R^-T
    const Eigen::MatrixXd r_inverse = r.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(p, p));
    result.covariance = result.residual_std * result.residual_std * (r_inverse * r_inverse.transpose());
    result.standard_error = result.covariance.diagonal().cwiseSqrt();
    result.white_noise_standard_error = result.standard_error;
    return result;
}

Eigen::MatrixXd long_run_covariance(const Eigen::MatrixXd& phi, const Eigen::VectorXd& residual,
                                    std::span<const std::size_t> index, std::size_t block) {
    const auto n = phi.rows();
    const auto p = phi.cols();
    // g_b summed per block of sample indices, in one pass (the rows need not be in order)
    const std::size_t blocks = index.empty() ? 0 : *std::max_element(index.begin(), index.end()) / block + 1;
    Eigen::MatrixXd sums = Eigen::MatrixXd::Zero(p, static_cast<Eigen::Index>(blocks));
    for (Eigen::Index t = 0; t < n; ++t) {
        sums.col(static_cast<Eigen::Index>(index[static_cast<std::size_t>(t)] / block)) +=
            phi.row(t).transpose() * residual(t);
    }
    Eigen::MatrixXd s = sums * sums.transpose();
    return n > p ? Eigen::MatrixXd(s * (static_cast<double>(n) / static_cast<double>(n - p))) : s;
}

void account_for_correlated_residuals(LeastSquaresResult& result, const Eigen::MatrixXd& phi, const Eigen::VectorXd& y,
                                      std::span<const std::size_t> index, std::size_t block) {
    if (block <= 1 || result.rank_deficient || !(result.residual_std > 0.0)) return;
    const Eigen::VectorXd residual = y - phi * result.estimate;
    const Eigen::MatrixXd inverse_information = result.covariance / (result.residual_std * result.residual_std);
    result.covariance = inverse_information * long_run_covariance(phi, residual, index, block) * inverse_information;
    result.standard_error = result.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
}

}  // namespace feedid
