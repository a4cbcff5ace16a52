#pragma once
// The trace bench_identify's benchmarks share: a drive with Stribeck friction (M 69 kg, B 54 N*s/m, F_C 740 N, a
// 200 N Stribeck rise, v_s 5 mm/s, force constant 450 N/A) on sinusoidal strokes at nine speeds (0.5 to 200 mm/s),
// 1 kHz, a 50 nm encoder, +-0.01 A of uniform current noise.

#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

namespace feedid::bench {

struct StribeckColumns {
    std::vector<double> time, position, current;  ///< [s], [m], [A]
};

inline StribeckColumns stribeck_columns(std::size_t samples) {
    StribeckColumns c{std::vector<double>(samples), std::vector<double>(samples), std::vector<double>(samples)};
    const double dt = 1e-3;
    const double feeds[] = {0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2};
    double position = 0.0;
    std::uint32_t state = 12345;
    for (std::size_t k = 0; k < samples; ++k) {
        const double t = static_cast<double>(k) * dt;
        const double feed = feeds[(k / 10000) % 9];
        const double w = 2.0 * std::numbers::pi / 2.0;
        const double v = feed * std::sin(w * t), a = feed * w * std::cos(w * t);
        position += v * dt;
        const double speed = std::abs(v);
        const double friction = speed > 0 ? 54.0 * speed + 740.0 + 200.0 * std::exp(-speed / 0.005) : 0.0;
        state = state * 1664525u + 1013904223u;
        c.time[k] = t;
        c.position[k] = 50e-9 * std::round(position / 50e-9);
        c.current[k] = (69.0 * a + std::copysign(friction, v)) / 450.0 +
                       (static_cast<double>(state >> 8) / 16777216.0 - 0.5) * 0.02;
    }
    return c;
}

}  // namespace feedid::bench
