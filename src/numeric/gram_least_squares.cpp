#include "feedid/numeric/gram_least_squares.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

namespace feedid {

GramMatrix::GramMatrix(std::span<const std::span<const double>> vectors, std::span<const char> use) {
    const auto q = static_cast<Eigen::Index>(vectors.size());
    gram_ = Eigen::MatrixXd::Zero(q, q);
    if (q == 0) return;
    const std::size_t rows = vectors.front().size();
    // the lower triangle row by row, a block of rows at a time summed into the matrix, so that a long trace's sums
    // lose no more to rounding than a short one's
    constexpr std::size_t block_rows = 4096;
    std::vector<double> lower(static_cast<std::size_t>(q * q), 0.0), value(static_cast<std::size_t>(q));
    const auto width = static_cast<std::size_t>(q);
    for (std::size_t start = 0; start < rows; start += block_rows) {
        std::fill(lower.begin(), lower.end(), 0.0);
        const std::size_t end = std::min(rows, start + block_rows);
        for (std::size_t k = start; k < end; ++k) {
            if (!use.empty() && use[k] == 0) continue;
            for (std::size_t i = 0; i < width; ++i) value[i] = vectors[i][k];
            for (std::size_t r = 0; r < width; ++r) {
                const double v = value[r];
                for (std::size_t c = 0; c <= r; ++c) lower[r * width + c] += v * value[c];
            }
        }
        for (Eigen::Index r = 0; r < q; ++r) {
            for (Eigen::Index c = 0; c <= r; ++c) gram_(r, c) += lower[static_cast<std::size_t>(r * q + c)];
        }
    }
    gram_ = gram_.selfadjointView<Eigen::Lower>();
}

GramMatrix::Solution GramMatrix::solve(const Eigen::MatrixXd& C, const Eigen::VectorXd& c_y) const {
    const Eigen::MatrixXd GC = gram_ * C;
    Eigen::MatrixXd normal = C.transpose() * GC;
    Eigen::VectorXd right = GC.transpose() * c_y;
    const double yy = c_y.dot(gram_ * c_y);
    const Eigen::Index p = C.cols();
    Eigen::VectorXd scale(p);
    for (Eigen::Index j = 0; j < p; ++j) scale(j) = normal(j, j) > 0.0 ? 1.0 / std::sqrt(normal(j, j)) : 1.0;
    normal = scale.asDiagonal() * normal * scale.asDiagonal();
    right = scale.cwiseProduct(right);
    const Eigen::LDLT<Eigen::MatrixXd> solver(normal);
    Solution solution;
    const Eigen::VectorXd scaled = solver.solve(right);
    solution.theta = scaled.cwiseProduct(scale);
    const double rss = yy - right.dot(scaled);
    // on unit diagonals a pivot near 0 is a column that the others make up (to the rounding of the sums)
    constexpr double dependent_pivot = 1e-14;
    const bool independent = solver.info() == Eigen::Success && solver.vectorD().minCoeff() > dependent_pivot;
    solution.rss = std::isfinite(rss) && independent ? std::max(0.0, rss) : std::numeric_limits<double>::infinity();
    return solution;
}

// For the theta given, sum (y - Phi*theta)^2 = y'y - 2*theta'Phi'y + theta'Phi'Phi*theta exactly. The sums of n
// products and the residual's sum each round by at most gamma_n = n*u/(1 - n*u) of the sum of their terms'
// magnitudes (u the unit roundoff; Higham, Accuracy and Stability of Numerical Algorithms, 2nd ed. 2002, eq. 3.5),
// which Cauchy-Schwarz and Minkowski bound by M^2, M = ||y|| + sum_j |theta_j|*||phi_j||; each row's residual
// rounds by at most gamma_(p+2)*(|y_k| + sum_j |phi_kj*theta_j|), whose norm over the rows is at most gamma_(p+2)*M.
// The bound is the quadratic form less twice all of these.
double residual_lower_bound(const Eigen::MatrixXd& normal, const Eigen::VectorXd& right, double y_squares,
                            const Eigen::VectorXd& theta, std::size_t rows) {
    constexpr double none = -std::numeric_limits<double>::infinity();
    if (!theta.allFinite() || !right.allFinite() || !normal.allFinite() || !std::isfinite(y_squares)) return none;
    const double unit = 0.5 * std::numeric_limits<double>::epsilon();
    const auto gamma = [&](double n) { return n * unit < 0.01 ? n * unit / (1.0 - n * unit) : 1.0; };
    const auto p = static_cast<double>(theta.size());
    const double sums = gamma(static_cast<double>(rows) + 1.0), row = gamma(p + 2.0);
    double magnitude = std::sqrt(std::abs(y_squares));
    for (Eigen::Index j = 0; j < theta.size(); ++j) magnitude += std::abs(theta(j)) * std::sqrt(std::abs(normal(j, j)));
    magnitude *= 1.01;  // the norms themselves from rounded sums
    const double m2 = magnitude * magnitude;
    const double form = y_squares - 2.0 * right.dot(theta) + theta.dot(normal * theta);
    const double form_error = sums * m2 + gamma(2.0 * p + 3.0) * 2.0 * m2;  // the sums, and the form's own rounding
    const double root = std::sqrt(std::max(form, 0.0) + form_error) + row * magnitude;  // >= the residual pass's norm
    const double pass_error = 2.0 * row * magnitude * root + row * row * m2 + sums * root * root;
    const double bound = form - 2.0 * (form_error + pass_error);
    return std::isfinite(bound) ? bound : none;
}

}  // namespace feedid
