#pragma once
// Many least-squares problems over the same rows from one pass: where each problem's columns and right-hand side are
// linear combinations of a fixed set of base vectors, the base vectors' Gram matrix holds every problem's normal
// equations. A structure search that tries hundreds of problems reads the rows once per set of base vectors.

#include <cstddef>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace feedid {

class GramMatrix {
public:
    /// G = V'V of the base vectors (equal lengths) over the rows k where `use` is non-zero (every row when `use` is
    /// empty), summed row by row.
    GramMatrix(std::span<const std::span<const double>> vectors, std::span<const char> use);

    /// A Gram matrix V'V summed elsewhere (square and symmetric), for a pass that forms its base vectors on the way.
    explicit GramMatrix(Eigen::MatrixXd gram) : gram_(std::move(gram)) {}

    struct Solution {
        Eigen::VectorXd theta;  ///< minimises ||V*c_y - V*C*theta||
        double rss{0.0};        ///< that minimum squared (infinity where the columns are dependent)
    };

    /// The problem whose columns are V*C (C: base vectors x parameters) and whose right-hand side is V*c_y, solved
    /// on normalised columns. The residual is y'y - b'theta: accurate to about 1e-12 of y'y, enough to rank fits that
    /// leave a noise behind, not to resolve a fit to the rounding of its data.
    [[nodiscard]] Solution solve(const Eigen::MatrixXd& C, const Eigen::VectorXd& c_y) const;

    [[nodiscard]] const Eigen::MatrixXd& matrix() const { return gram_; }

private:
    Eigen::MatrixXd gram_;
};

/// A number that the residual sum of squares sum_k (y_k - phi_k'theta)^2 of a theta, summed in double precision row
/// by row over at most `rows` rows, is never below, from the normal equations alone: `normal` = Phi'Phi and `right` =
/// Phi'y and `y_squares` = y'y, each summed row by row over the same rows. For a search that needs a candidate's
/// residual only where it may beat the best so far: the residual's pass is left out where this is not below the best.
/// -infinity where theta or the sums are not finite numbers.
[[nodiscard]] double residual_lower_bound(const Eigen::MatrixXd& normal, const Eigen::VectorXd& right, double y_squares,
                                          const Eigen::VectorXd& theta, std::size_t rows);

}  // namespace feedid
