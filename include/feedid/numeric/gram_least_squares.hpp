#pragma once
// Many least-squares problems over the same rows from one pass: where each problem's columns and right-hand side are
// linear combinations of a fixed set of base vectors, the base vectors' Gram matrix holds every problem's normal
// equations. A structure search that tries hundreds of problems reads the rows once per set of base vectors.

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

}  // namespace feedid
