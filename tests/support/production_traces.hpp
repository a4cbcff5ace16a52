#pragma once
// Production-like traces for the online identifier's tests (until the part programs of issue 15's item 4 land): a
// reference of random rapids and feed moves at many speeds with smooth (bounded-jerk) speed changes, and a cutting
// force on some feed moves, opposing the motion, of up to `cut_fraction` of the drive force, with a slow engagement
// variation and a tooth-passing ripple.

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "feedid/sim/synth.hpp"

namespace feedid::testing {

struct ProductionTrace {
    std::vector<double> reference;
    std::vector<double> cutting_force;  ///< [N], acting in +x
};

struct ProductionOptions {
    double duration_s{240.0};
    double sample_time_s{1e-3};
    double acceleration{3.0};  ///< peak [m/s^2]
    double cut_fraction{0.3};  ///< cutting force up to this fraction of the drive force on cutting moves
    double cut_probability{0.6};
    bool slow_moves{true};        ///< feed moves at 1..15 mm/s too (for F_B, v_s)
    double single_speed{0.0};     ///< > 0: every move at this speed, back and forth (nothing separates B and F_C)
    double drive_force_N{800.0};  ///< typical drive force at feed, for the cutting force's scale [N]
};

inline ProductionTrace production_trace(std::uint64_t seed, const ProductionOptions& o = {}) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const double dt = o.sample_time_s;
    ProductionTrace out;
    double x = 0.0;
    double v = 0.0;
    double t = 0.0;
    auto emit = [&](double force) {
        x += v * dt;
        out.reference.push_back(x);
        out.cutting_force.push_back(force);
        t += dt;
    };
    // a smooth speed change from v to target: v(t) = v0 + dv (1 - cos(pi t / T)) / 2, peak acceleration pi dv / 2T
    auto ramp = [&](double target, double force_sign, double cut) {
        const double dv = target - v;
        const double duration = std::max(dt, std::numbers::pi * std::abs(dv) / (2.0 * o.acceleration));
        const double v0 = v;
        const auto n = static_cast<std::size_t>(std::ceil(duration / dt));
        for (std::size_t k = 1; k <= n; ++k) {
            v = v0 + dv * (1.0 - std::cos(std::numbers::pi * static_cast<double>(k) / static_cast<double>(n))) / 2.0;
            emit(-force_sign * cut * static_cast<double>(k) / static_cast<double>(n));
        }
    };
    while (t < o.duration_s) {
        const int direction = std::abs(x) > 0.2 ? (x > 0 ? -1 : 1) : (unit(rng) < 0.5 ? -1 : 1);
        double speed = 0.0;
        bool cutting = false;
        const double kind = unit(rng);
        if (o.single_speed > 0.0) {
            speed = o.single_speed;
        } else if (kind < 0.35) {
            speed = 0.1 + 0.2 * unit(rng);  // rapid
        } else if (kind < 0.85 || !o.slow_moves) {
            speed = 0.022 + 0.06 * unit(rng);  // feed
            cutting = unit(rng) < o.cut_probability;
        } else {
            speed = 0.001 + 0.014 * unit(rng);  // slow feed
        }
        const double cut = cutting ? o.cut_fraction * o.drive_force_N * (0.3 + 0.7 * unit(rng)) : 0.0;
        const double cruise_s = o.single_speed > 0.0 ? 0.1 / speed : 0.2 + 1.5 * unit(rng);
        const double engagement_hz = 1.0 + 4.0 * unit(rng);
        const double tooth_hz = 200.0 + 300.0 * unit(rng);
        ramp(direction * speed, direction, cut);
        const auto n = static_cast<std::size_t>(cruise_s / dt);
        for (std::size_t k = 0; k < n; ++k) {
            const double s = static_cast<double>(k) * dt;
            const double shape = 1.0 + 0.2 * std::sin(2.0 * std::numbers::pi * engagement_hz * s) +
                                 0.15 * std::sin(2.0 * std::numbers::pi * tooth_hz * s);
            emit(-direction * cut * shape);
        }
        ramp(0.0, direction, 0.0);
        const auto dwell = static_cast<std::size_t>((0.02 + 0.2 * unit(rng)) / dt);
        for (std::size_t k = 0; k < dwell; ++k) emit(0.0);
    }
    return out;
}

/// The demo drive on a production trace; the spec's sample time is the trace's.
inline Trace production_synth(std::uint64_t seed, const ProductionOptions& o = {}) {
    SynthSpec spec = demo_spec();
    spec.seed = seed;
    spec.sensors.sample_time_s = o.sample_time_s;
    const ProductionTrace p = production_trace(seed, o);
    return synthesize(spec, p.reference, p.cutting_force);
}

}  // namespace feedid::testing
