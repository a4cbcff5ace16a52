// The estimator on its own, as a streaming source would use it: one fixed-size, allocation-free RLS update per
// sample. Here the samples come from a drive with known parameters; the estimate converges to them.
//   example_02_streaming_rls
#include <cmath>
#include <random>

#include <fmt/core.h>

#include "feedid/numeric/rls.hpp"

int main() {
    const double mass = 69.1, viscous = 54.2, coulomb = 742.8;  // the paper's drive
    feedid::Rls<3> rls;                                         // lambda 0.99995, P(0) = 1e6 I, directional
    std::mt19937 random(1);
    std::normal_distribution<double> noise(0.0, 5.0);  // N
    for (int k = 0; k < 20000; ++k) {
        const double t = 1e-3 * k;
        const double v = 0.1 * std::sin(3.0 * t), a = 0.3 * std::cos(3.0 * t);
        const Eigen::Vector3d phi(a, v, v > 0 ? 1.0 : -1.0);
        const double force = mass * a + viscous * v + coulomb * phi(2) + noise(random);
        rls.update(phi, force);
        if (k % 4000 == 3999) {
            fmt::print("t = {:4.1f} s   M = {:7.2f} kg   B = {:7.2f} N*s/m   F_C = {:7.2f} N\n", t, rls.estimate()(0),
                       rls.estimate()(1), rls.estimate()(2));
        }
    }
    fmt::print("true:        M = {:7.2f} kg   B = {:7.2f} N*s/m   F_C = {:7.2f} N\n", mass, viscous, coulomb);
}
