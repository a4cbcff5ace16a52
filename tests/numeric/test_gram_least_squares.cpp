// Least squares from the Gram matrix of base vectors against Householder QR on the same columns: problems whose
// columns are combinations of the base vectors, rows masked, and dependent columns refused.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Dense>

#include "feedid/numeric/gram_least_squares.hpp"
#include "feedid/numeric/least_squares.hpp"

namespace {

struct BaseVectors {
    std::vector<std::vector<double>> columns;
    std::vector<char> use;
};

// `count` base vectors of `rows` samples, the last a noisy combination of the others; every third row unused.
BaseVectors random_base(int count, std::size_t rows, unsigned seed) {
    std::mt19937 generator(seed);
    std::normal_distribution<double> normal(0.0, 1.0);
    BaseVectors base;
    base.columns.assign(static_cast<std::size_t>(count), std::vector<double>(rows));
    for (int c = 0; c + 1 < count; ++c) {
        for (auto& value : base.columns[static_cast<std::size_t>(c)]) value = normal(generator) * (1.0 + c);
    }
    for (std::size_t k = 0; k < rows; ++k) {
        double y = 0.01 * normal(generator);
        for (int c = 0; c + 1 < count; ++c) y += (0.5 + c) * base.columns[static_cast<std::size_t>(c)][k];
        base.columns.back()[k] = y;
    }
    base.use.assign(rows, 1);
    for (std::size_t k = 0; k < rows; k += 3) base.use[k] = 0;
    return base;
}

std::vector<std::span<const double>> spans(const BaseVectors& base) {
    return {base.columns.begin(), base.columns.end()};
}

// V*C on the used rows, as a matrix.
Eigen::MatrixXd combined(const BaseVectors& base, const Eigen::MatrixXd& C) {
    std::vector<std::size_t> rows;
    for (std::size_t k = 0; k < base.use.size(); ++k) {
        if (base.use[k] != 0) rows.push_back(k);
    }
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()), C.cols());
    for (Eigen::Index i = 0; i < out.rows(); ++i) {
        for (Eigen::Index b = 0; b < C.rows(); ++b) {
            const double v = base.columns[static_cast<std::size_t>(b)][rows[static_cast<std::size_t>(i)]];
            out.row(i) += v * C.row(b);
        }
    }
    return out;
}

TEST(GramLeastSquares, CombinationsOfBaseVectorsSolveAsQrDoes) {
    const auto base = random_base(6, 20000, 7);
    const feedid::GramMatrix gram(spans(base), base.use);
    // three columns: the first two base vectors, and the third plus 0.3 times the fourth; y the last base vector
    // less 0.5 times the fifth
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(6, 3);
    C(0, 0) = 1.0;
    C(1, 1) = 1.0;
    C(2, 2) = 1.0;
    C(3, 2) = 0.3;
    Eigen::VectorXd c_y = Eigen::VectorXd::Zero(6);
    c_y(5) = 1.0;
    c_y(4) = -0.5;
    const auto solution = gram.solve(C, c_y);
    const Eigen::MatrixXd phi = combined(base, C);
    const Eigen::VectorXd y = combined(base, c_y);
    const auto qr = feedid::solve_least_squares(phi, y);
    const double rss = (y - phi * qr.estimate).squaredNorm();
    for (Eigen::Index j = 0; j < 3; ++j)
        EXPECT_NEAR(solution.theta(j), qr.estimate(j), 1e-9 * std::abs(qr.estimate(j)));
    EXPECT_NEAR(solution.rss, rss, 1e-9 * rss);
    EXPECT_GT(rss, 0.0);
}

TEST(GramLeastSquares, ResidualOfANearlyExactFitKeepsItsMagnitude) {
    // a fit that leaves a noise of 1e-2 of a signal of several units: the residual from y'y - b'theta within 1e-6 of
    // its own size
    const auto base = random_base(4, 50000, 11);
    const feedid::GramMatrix gram(spans(base), base.use);
    const Eigen::MatrixXd C = Eigen::MatrixXd::Identity(4, 3);
    const Eigen::VectorXd c_y = Eigen::VectorXd::Unit(4, 3);
    const auto solution = gram.solve(C, c_y);
    const Eigen::MatrixXd phi = combined(base, C);
    const Eigen::VectorXd y = combined(base, c_y);
    const auto qr = feedid::solve_least_squares(phi, y);
    const double rss = (y - phi * qr.estimate).squaredNorm();
    EXPECT_NEAR(solution.rss, rss, 1e-6 * rss);
}

TEST(GramLeastSquares, DependentColumnsLeaveNoResidual) {
    const auto base = random_base(4, 1000, 3);
    const feedid::GramMatrix gram(spans(base), {});
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(4, 2);
    C(0, 0) = 1.0;
    C(0, 1) = 2.0;  // the same column twice
    const auto solution = gram.solve(C, Eigen::VectorXd::Unit(4, 3));
    EXPECT_FALSE(std::isfinite(solution.rss));
}

TEST(GramLeastSquares, AGramMatrixSummedElsewhereSolvesAsTheOneSummedHere) {
    const auto base = random_base(5, 5000, 5);
    const feedid::GramMatrix summed(spans(base), base.use);
    const feedid::GramMatrix given(Eigen::MatrixXd(summed.matrix()));
    const Eigen::MatrixXd C = Eigen::MatrixXd::Identity(5, 4);
    const Eigen::VectorXd c_y = Eigen::VectorXd::Unit(5, 4);
    EXPECT_EQ(given.solve(C, c_y).theta, summed.solve(C, c_y).theta);
    EXPECT_EQ(given.solve(C, c_y).rss, summed.solve(C, c_y).rss);
}

// The normal equations and the residual of theta summed row by row over the used rows, as a search sums them.
struct RowSums {
    Eigen::MatrixXd normal;
    Eigen::VectorXd right;
    double y_squares{0.0};
    double residual{0.0};
};

RowSums row_sums(const BaseVectors& base, int columns, const Eigen::VectorXd& theta) {
    RowSums sums{Eigen::MatrixXd::Zero(columns, columns), Eigen::VectorXd::Zero(columns)};
    const auto& y = base.columns.back();
    for (std::size_t k = 0; k < y.size(); ++k) {
        if (base.use[k] == 0) continue;
        double fitted = 0.0;
        for (int r = 0; r < columns; ++r) {
            const double phi = base.columns[static_cast<std::size_t>(r)][k];
            for (int c = 0; c < columns; ++c) sums.normal(r, c) += phi * base.columns[static_cast<std::size_t>(c)][k];
            sums.right(r) += phi * y[k];
            fitted += phi * theta(r);
        }
        sums.y_squares += y[k] * y[k];
        sums.residual += (y[k] - fitted) * (y[k] - fitted);
    }
    return sums;
}

TEST(GramLeastSquares, TheResidualBoundIsNeverAboveTheResidualAndCloseBelowANoisyFit) {
    // y = sum_c (0.5 + c)*x_c + noise*N(0, 1); the residual at the least-squares theta (from the normal equations, as
    // a search solves them) and at a theta off it
    for (const double noise : {1e-2, 1e-9, 1e-14, 0.0}) {
        auto base = random_base(4, 200000, 13);
        std::mt19937 generator(17);
        std::normal_distribution<double> normal(0.0, 1.0);
        for (std::size_t k = 0; k < base.use.size(); ++k) {
            double y = noise * normal(generator);
            for (int c = 0; c < 3; ++c) y += (0.5 + c) * base.columns[static_cast<std::size_t>(c)][k];
            base.columns.back()[k] = y;
        }
        const RowSums sums = row_sums(base, 3, Eigen::VectorXd::Zero(3));
        const Eigen::VectorXd solved = sums.normal.ldlt().solve(sums.right);
        for (const Eigen::VectorXd& theta : {solved, Eigen::VectorXd(solved * (1.0 + 1e-7))}) {
            const RowSums at = row_sums(base, 3, theta);
            const double bound =
                feedid::residual_lower_bound(at.normal, at.right, at.y_squares, theta, base.use.size());
            EXPECT_LE(bound, at.residual) << "noise " << noise;
            if (noise == 1e-2 && theta == solved) {
                EXPECT_GT(bound, at.residual - 1e-6 * at.y_squares);
            }
        }
    }
}

}  // namespace
