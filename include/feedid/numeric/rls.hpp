#pragma once
// Recursive least squares with exponential forgetting, fixed size (the paper's eq. 7-9), and a robust variant whose
// forgetting acts only in the direction the data excites. The per-sample update never allocates and never throws.

#include <cmath>
#include <cstddef>

#include <Eigen/Core>

namespace feedid {

enum class RlsVariant {
    /// The paper's eq. (7)-(9): P(k) = (I - L*phi^T)*P(k-1)/lambda. With lambda < 1 and a regressor that does not
    /// excite every direction (no acceleration on a constant-velocity test), P grows as lambda^-k in the unexcited
    /// directions until it overflows ("covariance wind-up"); the estimator reports it (Rls::wound_up()).
    exponential,
    /// Directional forgetting (Kulhavy 1987): the information matrix R = P^-1 forgets only along the current
    /// regressor, R <- R - (1-lambda)*phi*phi^T/(phi^T*P*phi) + phi*phi^T, so information in directions the data does
    /// not excite is kept, and P stays symmetric positive definite and bounded by P(0) there. Same gain as eq. (8).
    directional,
};

struct RlsOptions {
    double forgetting_factor{0.99995};  ///< lambda, in (0, 1]
    double initial_covariance{1e6};     ///< P(0) = initial_covariance * I
    RlsVariant variant{RlsVariant::directional};
};

/// What one update did.
enum class RlsUpdate : unsigned char {
    updated,        ///< estimate and covariance updated
    no_excitation,  ///< phi^T*P*phi below round-off: nothing to learn, nothing forgotten (robust variant)
    non_finite,     ///< phi or y not finite: sample ignored
};

template <int N>
class Rls {
public:
    using Vector = Eigen::Matrix<double, N, 1>;
    using Matrix = Eigen::Matrix<double, N, N>;

    explicit Rls(const RlsOptions& options = {}, const Vector& initial_estimate = Vector::Zero())
        : options_(options), theta_(initial_estimate) {
        reset(initial_estimate);
    }

    void reset(const Vector& initial_estimate = Vector::Zero()) {
        theta_ = initial_estimate;
        covariance_ = Matrix::Identity() * options_.initial_covariance;
        updates_ = 0;
        wound_up_ = false;
    }

    /// One sample: y = phi^T * theta + noise.
    RlsUpdate update(const Vector& phi, double y) noexcept {
        if (options_.variant == RlsVariant::exponential) return update_exponential(phi, y);
        return update_directional(phi, y);
    }

    [[nodiscard]] const Vector& estimate() const noexcept { return theta_; }
    [[nodiscard]] const Matrix& covariance() const noexcept { return covariance_; }
    [[nodiscard]] std::size_t updates() const noexcept { return updates_; }
    [[nodiscard]] const RlsOptions& options() const noexcept { return options_; }
    /// The exponential variant's covariance has grown past 1e150 or overflowed (its estimate is then unreliable).
    [[nodiscard]] bool wound_up() const noexcept { return wound_up_; }

    static constexpr double wind_up_limit = 1e150;

private:
    RlsUpdate update_exponential(const Vector& phi, double y) noexcept {
        if (!phi.allFinite() || !std::isfinite(y)) return RlsUpdate::non_finite;
        const double lambda = options_.forgetting_factor;
        const Vector p_phi = covariance_ * phi;
        const double r = phi.dot(p_phi);  // phi^T P phi
        const double error = y - phi.dot(theta_);
        // eq. (8): L = P*phi / (lambda + phi^T*P*phi); eq. (7); eq. (9): P = (I - L*phi^T)*P / lambda
        const double inverse_denominator = 1.0 / (lambda + r);
        const Vector gain = p_phi * inverse_denominator;
        theta_ += gain * error;
        // L*phi^T*P = P*phi*phi^T*P / (lambda + r), written as the outer product of P*phi with itself: each entry
        // p_i*p_j equals p_j*p_i to the last bit, so P stays symmetric. (gain * p_phi^T is not: its round-off is
        // asymmetric, and dividing by lambda every sample grew it to 1e32 within 200,000 samples at lambda 0.9999.)
        covariance_ = (covariance_ - (p_phi * p_phi.transpose()) * inverse_denominator) * inverse_lambda_;
        // P is positive semi-definite, so its trace bounds every entry; NaN fails the comparison too
        if (!(covariance_.trace() <= wind_up_limit)) wound_up_ = true;
        ++updates_;
        return RlsUpdate::updated;
    }

    RlsUpdate update_directional(const Vector& phi, double y) noexcept {
        const double lambda = options_.forgetting_factor;
        // P*phi and the rank-1 update read and write P the same way: in 16-byte packets (Eigen) when N is even, in
        // plain scalar loops when N is odd. Mixing the two (Eigen's packet loads of a P the previous update wrote
        // with 8-byte stores) defeats store-to-load forwarding; that cost a quarter of the update (26.6 -> 21.7 ns
        // for N = 3 in bench_rls).
        Vector p_phi;
        if constexpr (N % 2 == 0) {
            p_phi.noalias() = covariance_ * phi;
        } else {
            for (int i = 0; i < N; ++i) {
                double sum = 0.0;
                for (int j = 0; j < N; ++j) sum += covariance_(i, j) * phi(j);
                p_phi(i) = sum;
            }
        }
        double r = 0.0;      // phi^T P phi
        double error = y;    // y - phi^T theta
        double scale = 0.0;  // trace(P) >= the largest eigenvalue of P
        double phi_norm2 = 0.0;
        for (int i = 0; i < N; ++i) {
            r += phi(i) * p_phi(i);
            error -= phi(i) * theta_(i);
            scale += covariance_(i, i);
            phi_norm2 += phi(i) * phi(i);
        }
        // A non-finite phi or y makes the error or r non-finite (theta and P are finite), so one test catches both.
        if (!std::isfinite(error) || !std::isfinite(r)) return RlsUpdate::non_finite;
        if (!(r > 1e-14 * scale * phi_norm2) || !(r > 0.0)) return RlsUpdate::no_excitation;
        // With R_new = R + eps*phi*phi^T, eps = 1 - (1 - lambda)/r:
        //   P_new = P - eps/(lambda + r) * (P*phi)(P*phi)^T,   P_new*phi = P*phi/(lambda + r) = L (eq. 8).
        // One division: with q = 1/(r*(lambda + r)), 1/(lambda + r) = r*q and eps/(lambda + r) = (r - (1 - lambda))*q.
        const double q = 1.0 / (r * (lambda + r));
        const double step = r * q * error;
        for (int i = 0; i < N; ++i) theta_(i) += p_phi(i) * step;
        // The outer product a*a^T is exactly symmetric in floating point (a_i*a_j == a_j*a_i), so P stays exactly
        // symmetric without re-symmetrising.
        const double c = (r - (1.0 - lambda)) * q;
        if constexpr (N % 2 == 0) {
            const Matrix outer = p_phi * p_phi.transpose();  // formed first: c*(a_i*a_j), never (c*a_i)*a_j
            covariance_.noalias() -= c * outer;
        } else {
            for (int j = 0; j < N; ++j) {
                for (int i = 0; i < N; ++i) covariance_(i, j) -= c * (p_phi(i) * p_phi(j));
            }
        }
        ++updates_;
        return RlsUpdate::updated;
    }

    RlsOptions options_;
    double inverse_lambda_{1.0 / options_.forgetting_factor};
    Vector theta_;
    Matrix covariance_;
    std::size_t updates_{0};
    bool wound_up_{false};
};

}  // namespace feedid
