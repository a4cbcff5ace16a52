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

}  // namespace feedid
