// RLS against batch least squares, the robust variant's covariance over 10^8 poorly exciting updates, the paper's
// variant winding up on the same data, and no heap allocation in the update path.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>
#include <string>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <fmt/core.h>

#include "feedid/numeric/least_squares.hpp"
#include "feedid/numeric/rls.hpp"

// Counts heap allocations while `counting` is set: the per-sample update must make none. The replacement operator
// new allocates with malloc, so its delete frees with free (GCC cannot see that they pair).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
namespace {
std::atomic<bool> counting{false};
std::atomic<long> allocations{0};
}  // namespace

void* operator new(std::size_t size) {
    if (counting.load(std::memory_order_relaxed)) allocations.fetch_add(1, std::memory_order_relaxed);
    if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
    std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
    std::free(p);
}

namespace {

using feedid::Rls;
using feedid::RlsOptions;
using feedid::RlsUpdate;
using feedid::RlsVariant;

// A drive excited in every direction: y = M*a + B*v + F_C*sgn(v) + F_0 + noise.
struct Sample {
    Eigen::Vector4d phi;
    double y;
};

std::vector<Sample> exciting_data(std::size_t n, unsigned seed) {
    std::mt19937 random(seed);
    std::normal_distribution<double> noise(0.0, 2.0);
    const Eigen::Vector4d truth(95.0, 203.0, 20.4, -3.2);
    std::vector<Sample> data(n);
    for (std::size_t k = 0; k < n; ++k) {
        const double t = 1e-3 * static_cast<double>(k);
        const double v = 0.1 * std::sin(2.0 * t) + 0.05 * std::sin(7.3 * t);
        const double a = 0.2 * std::cos(2.0 * t) + 0.365 * std::cos(7.3 * t);
        data[k].phi = Eigen::Vector4d(a, v, v > 0 ? 1.0 : -1.0, 1.0);
        data[k].y = data[k].phi.dot(truth) + noise(random);
    }
    return data;
}

feedid::LeastSquaresResult batch_of(const std::vector<Sample>& data) {
    Eigen::MatrixXd phi(static_cast<Eigen::Index>(data.size()), 4);
    Eigen::VectorXd y(static_cast<Eigen::Index>(data.size()));
    for (std::size_t k = 0; k < data.size(); ++k) {
        phi.row(static_cast<Eigen::Index>(k)) = data[k].phi.transpose();
        y(static_cast<Eigen::Index>(k)) = data[k].y;
    }
    return feedid::solve_least_squares(phi, y);
}

class RlsEqualsBatch : public ::testing::TestWithParam<RlsVariant> {};

TEST_P(RlsEqualsBatch, WithoutForgettingAndALargeInitialCovariance) {
    const auto data = exciting_data(20000, 1);
    Rls<4> rls(RlsOptions{1.0, 1e8, GetParam()});
    for (const auto& s : data) ASSERT_EQ(rls.update(s.phi, s.y), RlsUpdate::updated);
    const auto batch = batch_of(data);
    for (int i = 0; i < 4; ++i) {
        EXPECT_NEAR(rls.estimate()(i), batch.estimate(i), 1e-6 * std::abs(batch.estimate(i))) << "parameter " << i;
    }
}

INSTANTIATE_TEST_SUITE_P(BothVariants, RlsEqualsBatch,
                         ::testing::Values(RlsVariant::exponential, RlsVariant::directional), [](const auto& info) {
                             return info.param == RlsVariant::exponential ? std::string("Paper")
                                                                          : std::string("Directional");
                         });

TEST(Rls, BatchLeastSquaresRecoversAKnownModel) {
    const auto data = exciting_data(20000, 2);
    const auto batch = batch_of(data);
    const Eigen::Vector4d truth(95.0, 203.0, 20.4, -3.2);
    for (int i = 0; i < 4; ++i) {
        // 4 standard errors: a 1-in-15000 chance per parameter of a false alarm with correct code
        EXPECT_NEAR(batch.estimate(i), truth(i), 4.0 * batch.standard_error(i)) << "parameter " << i;
    }
    EXPECT_NEAR(batch.residual_std, 2.0, 0.05);
    EXPECT_FALSE(batch.rank_deficient);
}

// The streamed solve (rows one at a time, R of [Phi y] updated a block at a time, never the matrix) against the
// matrix solve and the long-run sandwich on the same rows: a few rows (all in the first block), many (many blocks and
// a partial one), rows in time order and shuffled (the batch means then per block, not streamed), white and
// correlated standard errors. Same figures to 1e-9 relative (rounding only).
TEST(StreamedLeastSquares, GivesTheMatrixSolvesFiguresWithoutTheMatrix) {
    for (const std::size_t n : {std::size_t{300}, std::size_t{20000}}) {
        for (const bool shuffled : {false, true}) {
            for (const std::size_t block : {std::size_t{1}, std::size_t{25}}) {
                const auto data = exciting_data(n, 3);
                std::vector<std::size_t> index(n);
                for (std::size_t k = 0; k < n; ++k) index[k] = 3 * k;  // a row set that skips samples
                if (shuffled) std::shuffle(index.begin(), index.end(), std::mt19937(7));
                Eigen::MatrixXd phi(static_cast<Eigen::Index>(n), 4);
                Eigen::VectorXd y(static_cast<Eigen::Index>(n));
                for (std::size_t i = 0; i < n; ++i) {
                    phi.row(static_cast<Eigen::Index>(i)) = data[index[i] / 3].phi.transpose();
                    y(static_cast<Eigen::Index>(i)) = data[index[i] / 3].y;
                }
                auto reference = feedid::solve_least_squares(phi, y);
                feedid::account_for_correlated_residuals(reference, phi, y, index, block);
                const auto streamed = feedid::solve_least_squares_rows(
                    n, 4,
                    [&](std::size_t i, double* row) {
                        for (Eigen::Index c = 0; c < 4; ++c) row[c] = phi(static_cast<Eigen::Index>(i), c);
                        return y(static_cast<Eigen::Index>(i));
                    },
                    [&](std::size_t i) { return index[i]; }, block);
                const std::string where = fmt::format("{} rows, shuffled {}, block {}", n, shuffled, block);
                const auto near = [&](double a, double b, const char* what) {
                    EXPECT_LE(std::abs(a - b), 1e-9 * std::max(std::abs(a), std::abs(b))) << what << ", " << where;
                };
                ASSERT_FALSE(streamed.rank_deficient) << where;
                EXPECT_EQ(streamed.samples, reference.samples) << where;
                near(streamed.residual_std, reference.residual_std, "residual std");
                near(streamed.relative_error_pct, reference.relative_error_pct, "relative error");
                near(streamed.condition_number, reference.condition_number, "condition");
                for (Eigen::Index i = 0; i < 4; ++i) {
                    near(streamed.estimate(i), reference.estimate(i), "estimate");
                    near(streamed.standard_error(i), reference.standard_error(i), "standard error");
                    near(streamed.white_noise_standard_error(i), reference.white_noise_standard_error(i),
                         "white-noise standard error");
                    near(streamed.r_diagonal(i), reference.r_diagonal(i), "|diag R|");
                }
            }
        }
    }
}

TEST(StreamedLeastSquares, SaysRankDeficientAsTheMatrixSolveDoes) {
    // the offset column equals sgn(v) over 5000 rows (one direction only): dependent
    const std::size_t n = 5000;
    const auto row = [](std::size_t k, double* phi) {
        const double v = 0.1 + 0.01 * std::sin(static_cast<double>(k));
        phi[0] = 0.3 * std::cos(static_cast<double>(k));
        phi[1] = v;
        phi[2] = 1.0;
        phi[3] = 1.0;
        return 50.0 * v + 20.0;
    };
    const auto result = feedid::solve_least_squares_rows(n, 4, row, [](std::size_t k) { return k; }, 1);
    EXPECT_TRUE(result.rank_deficient);
    EXPECT_TRUE(std::isnan(result.estimate(0)));
    const auto few = feedid::solve_least_squares_rows(3, 4, row, [](std::size_t k) { return k; }, 1);
    EXPECT_TRUE(few.rank_deficient);
}

// A constant-velocity test, back and forth: no acceleration, no offset excitation beyond sgn(v) - the regressor
// spans one direction of the three-dimensional parameter space.
Eigen::Vector3d constant_velocity_regressor(std::uint64_t k) {
    const double v = (k / 5000) % 2 == 0 ? 0.1 : -0.1;
    return {0.0, v, v > 0 ? 1.0 : -1.0};
}

TEST(Rls, DirectionalForgettingStaysBoundedOverOneHundredMillionPoorlyExcitingUpdates) {
    Rls<3> rls(RlsOptions{0.99995, 1e6, RlsVariant::directional});
    const Eigen::Vector3d truth(70.0, 54.0, 740.0);
    std::uint64_t updated = 0;
    for (std::uint64_t k = 0; k < 100'000'000; ++k) {
        const Eigen::Vector3d phi = constant_velocity_regressor(k);
        updated += rls.update(phi, phi.dot(truth)) == RlsUpdate::updated;
    }
    const Eigen::Matrix3d& p = rls.covariance();
    ASSERT_TRUE(p.allFinite());
    ASSERT_TRUE(rls.estimate().allFinite());
    EXPECT_LT((p - p.transpose()).cwiseAbs().maxCoeff(), 1e-12 * p.cwiseAbs().maxCoeff());
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(p);
    EXPECT_GT(eigen.eigenvalues().minCoeff(), 0.0) << eigen.eigenvalues().transpose();
    // bounded: nothing grows past P(0) in the directions the data never excites
    EXPECT_LE(eigen.eigenvalues().maxCoeff(), 1e6 * (1.0 + 1e-9));
    EXPECT_FALSE(rls.wound_up());
    EXPECT_GT(updated, 0u);
    // what is excited is learnt: the prediction along the regressor is exact
    const Eigen::Vector3d phi = constant_velocity_regressor(0);
    EXPECT_NEAR(phi.dot(rls.estimate()), phi.dot(truth), 1e-6 * std::abs(phi.dot(truth)));
}

TEST(Rls, ThePapersForgettingWindsUpOnTheSameDataAndSaysSo) {
    Rls<3> rls(RlsOptions{0.99995, 1e6, RlsVariant::exponential});
    const Eigen::Vector3d truth(70.0, 54.0, 740.0);
    std::uint64_t k = 0;
    for (; k < 100'000'000 && !rls.wound_up(); ++k) {
        const Eigen::Vector3d phi = constant_velocity_regressor(k);
        rls.update(phi, phi.dot(truth));
    }
    // P grows as lambda^-k in the unexcited directions: past 1e150 after about ln(1e144)/5e-5 = 6.6e6 samples
    EXPECT_TRUE(rls.wound_up());
    EXPECT_LT(k, 10'000'000u);
}

TEST(Rls, ThePapersForgettingKeepsItsCovarianceSymmetricOnWellExcitingData) {
    // Well-exciting data, forgetting at 0.9999 over 400,000 updates: P stays bounded, so it must also stay symmetric
    // (an update whose round-off is asymmetric grows that asymmetry by 1/lambda a sample: 1e32 after 200,000) and the
    // estimate right.
    const auto data = exciting_data(400000, 2);
    Rls<4> rls(RlsOptions{0.9999, 1e6, RlsVariant::exponential});
    for (const auto& sample : data) rls.update(sample.phi, sample.y);
    const Eigen::Matrix4d& p = rls.covariance();
    ASSERT_TRUE(p.allFinite());
    EXPECT_EQ((p - p.transpose()).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_FALSE(rls.wound_up());
    const Eigen::Vector4d truth(95.0, 203.0, 20.4, -3.2);
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(rls.estimate()(i), truth(i), 0.05 * std::abs(truth(i)) + 0.5) << i;
}

TEST(Rls, IgnoresNonFiniteSamplesAndNothingToLearn) {
    Rls<3> rls;
    const Eigen::Vector3d before = rls.estimate();
    EXPECT_EQ(rls.update(Eigen::Vector3d(NAN, 1.0, 1.0), 1.0), RlsUpdate::non_finite);
    EXPECT_EQ(rls.update(Eigen::Vector3d(1.0, 1.0, 1.0), INFINITY), RlsUpdate::non_finite);
    EXPECT_EQ(rls.update(Eigen::Vector3d::Zero(), 1.0), RlsUpdate::no_excitation);
    EXPECT_EQ(rls.estimate(), before);
    EXPECT_EQ(rls.updates(), 0u);
}

TEST(Rls, IgnoresNonFiniteInputsOnceItHasLearnt) {
    // The robust update finds non-finite input through the error and phi^T P phi; check every slot, both sizes
    // (odd and even sizes run different code), with an estimate that is no longer zero.
    const auto check = [](auto rls, auto phi) {
        for (int k = 0; k < 200; ++k) {
            phi.setConstant(1.0);
            phi(k % phi.size()) = 1.0 + 0.1 * k;
            ASSERT_EQ(rls.update(phi, 3.0), RlsUpdate::updated);
        }
        const auto before = rls.estimate();
        const auto covariance = rls.covariance();
        for (const double bad : {NAN, INFINITY, -INFINITY}) {
            for (int i = 0; i < phi.size(); ++i) {
                phi.setConstant(1.0);
                phi(i) = bad;
                EXPECT_EQ(rls.update(phi, 3.0), RlsUpdate::non_finite) << "phi(" << i << ") = " << bad;
            }
            phi.setConstant(1.0);
            EXPECT_EQ(rls.update(phi, bad), RlsUpdate::non_finite) << "y = " << bad;
        }
        EXPECT_EQ(rls.estimate(), before);
        EXPECT_EQ(rls.covariance(), covariance);
        EXPECT_EQ(rls.updates(), 200u);
    };
    check(Rls<3>{}, Eigen::Vector3d{});
    check(Rls<4>{}, Eigen::Vector4d{});
}

TEST(Rls, UpdateNeverAllocates) {
    const auto data = exciting_data(1000, 3);
    Rls<4> four(RlsOptions{0.99995, 1e6, RlsVariant::directional});
    Rls<4> paper(RlsOptions{0.99995, 1e6, RlsVariant::exponential});
    Rls<3> three;
    allocations = 0;
    counting = true;
    for (const auto& s : data) {
        four.update(s.phi, s.y);
        paper.update(s.phi, s.y);
        three.update(s.phi.head<3>(), s.y);
    }
    counting = false;
    EXPECT_EQ(allocations.load(), 0);
    // the counter works (a direct call of operator new cannot be elided, unlike a new-expression)
    counting = true;
    ::operator delete(::operator new(16));
    counting = false;
    EXPECT_GT(allocations.load(), 0);
}

}  // namespace
