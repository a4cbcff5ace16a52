#include "feedid/numeric/least_squares.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace feedid {

namespace {

// The figures of the upper-triangular R of Phi = Q R (batch or streamed): |diag R|, the condition number (Phi and R
// share their singular values) and whether the columns are numerically independent (false: rank deficient, set).
bool judge_r(const Eigen::MatrixXd& r, LeastSquaresResult& result) {
    const auto p = r.cols();
    result.r_diagonal = r.diagonal().cwiseAbs();
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(r);
    const auto& singular = svd.singularValues();
    result.condition_number = singular(p - 1) > 0.0 ? singular(0) / singular(p - 1) : INFINITY;
    result.rank_deficient = !(singular(p - 1) > singular(0) * 1e-12);
    return !result.rank_deficient;
}

}  // namespace

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
    if (!judge_r(r, result)) return result;
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
    std::size_t current = 0, start = 0, end = 0;  // the last row's block: a division per block met, not per row
    for (Eigen::Index t = 0; t < n; ++t) {
        const std::size_t k = index[static_cast<std::size_t>(t)];
        if (k < start || k >= end) {
            current = k / block;
            start = current * block;
            end = start + block;
        }
        double* sum = sums.col(static_cast<Eigen::Index>(current)).data();
        for (Eigen::Index c = 0; c < p; ++c) sum[c] += phi(t, c) * residual(t);
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

namespace feedid {

namespace {
constexpr Eigen::Index stream_block_rows = 512;
}  // namespace

StreamedLeastSquares::StreamedLeastSquares(Eigen::Index parameters)
    : p_(parameters), stack_(parameters + 1 + stream_block_rows, parameters + 1) {}

void StreamedLeastSquares::add(const double* phi, double y) {
    const Eigen::Index at = (have_r_ ? p_ + 1 : 0) + pending_;
    for (Eigen::Index c = 0; c < p_; ++c) stack_(at, c) = phi[c];
    stack_(at, p_) = y;
    ++pending_;
    ++rows_;
    if (at + 1 == stack_.rows()) reduce();
}

void StreamedLeastSquares::reduce() {
    const Eigen::Index m = (have_r_ ? p_ + 1 : 0) + pending_;
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(stack_.topRows(m));
    stack_.topRows(p_ + 1) = qr.matrixQR().topRows(p_ + 1).triangularView<Eigen::Upper>();
    have_r_ = true;
    pending_ = 0;
}

bool StreamedLeastSquares::factor() {
    const auto n = static_cast<Eigen::Index>(rows_);
    if (!have_r_) {
        // every row still in the buffer: the matrix solve itself (the same figures, bit for bit)
        const Eigen::MatrixXd phi = stack_.topLeftCorner(n, p_);
        const Eigen::VectorXd y = stack_.col(p_).head(n);
        result_ = solve_least_squares(phi, y);
        if (result_.rank_deficient) return false;
        r_ = Eigen::HouseholderQR<Eigen::MatrixXd>(phi).matrixQR().topRows(p_).triangularView<Eigen::Upper>();
        return true;
    }
    if (pending_ > 0) reduce();
    result_.samples = rows_;
    result_.estimate = Eigen::VectorXd::Constant(p_, std::nan(""));
    result_.standard_error = Eigen::VectorXd::Constant(p_, std::nan(""));
    result_.covariance = Eigen::MatrixXd::Constant(p_, p_, std::nan(""));
    if (n < p_ || p_ == 0) {
        result_.rank_deficient = true;
        return false;
    }
    r_ = stack_.topLeftCorner(p_, p_).triangularView<Eigen::Upper>();
    if (!judge_r(r_, result_)) return false;
    result_.estimate = r_.triangularView<Eigen::Upper>().solve(stack_.col(p_).head(p_));
    return true;
}

void StreamedLeastSquares::start_residuals(std::size_t block, bool ascending, std::size_t largest_index) {
    block_ = std::max<std::size_t>(1, block);
    ascending_ = ascending;
    long_run_ = Eigen::MatrixXd::Zero(p_, p_);
    g_ = Eigen::VectorXd::Zero(p_);
    if (!ascending_ && block_ > 1)
        sums_ = Eigen::MatrixXd::Zero(p_, static_cast<Eigen::Index>(largest_index / block_ + 1));
}

void StreamedLeastSquares::close_block() {
    if (in_block_) long_run_.noalias() += g_ * g_.transpose();
    g_.setZero();
}

void StreamedLeastSquares::add_residual(const double* phi, double y, std::size_t index) {
    const Eigen::Map<const Eigen::VectorXd> row(phi, p_);
    const double e = y - row.dot(result_.estimate);
    rss_ += e * e;
    y_squared_ += y * y;
    if (block_ <= 1) return;
    if (!ascending_) {
        add_scaled(sums_.col(static_cast<Eigen::Index>(index / block_)).data(), phi, e, p_);
        return;
    }
    // ascending indices leave a block only past its end: a division per block, not per row
    if (!in_block_ || index >= block_end_) {
        close_block();
        block_end_ = (index / block_ + 1) * block_;
        in_block_ = true;
    }
    add_scaled(g_.data(), phi, e, p_);
}

LeastSquaresResult StreamedLeastSquares::finish() {
    LeastSquaresResult& result = result_;
    const auto n = static_cast<Eigen::Index>(rows_);
    const double dof = static_cast<double>(n - p_);
    result.residual_std = dof > 0 ? std::sqrt(rss_ / dof) : 0.0;
    const double y_norm = std::sqrt(y_squared_);
    result.relative_error_pct = y_norm > 0.0 ? 100.0 * std::sqrt(rss_) / y_norm : 0.0;
    const Eigen::MatrixXd r_inverse = r_.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(p_, p_));
    result.covariance = result.residual_std * result.residual_std * (r_inverse * r_inverse.transpose());
    result.standard_error = result.covariance.diagonal().cwiseSqrt();
    result.white_noise_standard_error = result.standard_error;
    if (block_ <= 1 || !(result.residual_std > 0.0)) return result;
    Eigen::MatrixXd s;
    if (ascending_) {
        close_block();
        s = long_run_;
    } else {
        s = sums_ * sums_.transpose();
    }
    if (n > p_) s *= static_cast<double>(n) / static_cast<double>(n - p_);
    const Eigen::MatrixXd inverse_information = result.covariance / (result.residual_std * result.residual_std);
    result.covariance = inverse_information * s * inverse_information;
    result.standard_error = result.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    return result;
}

}  // namespace feedid
