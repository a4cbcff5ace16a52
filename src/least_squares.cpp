#include "feedid/least_squares.hpp"

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
    return result;
}

}  // namespace feedid
