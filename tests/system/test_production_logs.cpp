// Machines' own logs through identify and scan, 100 generated: coarse (10 Hz, 1 mm positions), positions that jump,
// cutting loads on the strokes. Whatever comes out with a result (not refused as bad input), a printed value is
// physically possible (M > 0, F_C > 0 on the symmetric model, B not negative beyond its standard error) and every
// null parameter comes with a reason.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "feedid/core/error.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/stream/scan.hpp"

namespace feedid {
namespace {

struct Log {
    Trace trace;
    std::vector<double> force;
    std::string kind;
};

/// Strokes at random speeds both ways (a sample or two of acceleration), rests between; the force is M a + B v +
/// F_C sgn(v), a level of its own per stroke, white noise and, on some strokes, a cutting force against the motion.
Log generated_log(unsigned seed) {
    std::mt19937 random(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const double rate = std::vector<double>{10.0, 10.0, 10.0, 50.0, 100.0}[seed % 5];
    const double quantum = std::vector<double>{1e-3, 1e-4, 1e-6}[(seed / 5) % 3];
    const bool jumps = seed % 4 == 3, cutting = seed % 2 == 1;
    const double mass = 50.0 + 350.0 * unit(random), viscous = 500.0 + 2500.0 * unit(random),
                 coulomb = 50.0 + 250.0 * unit(random);
    std::normal_distribution<double> noise(0.0, 2.0), level(0.0, 3.0);
    std::vector<double> t, x, v, f;
    double position = 0.2, speed = 0.0;
    const double dt = 1.0 / rate;
    const auto samples = [&](double target, double seconds, double load) {
        const auto n = static_cast<int>(std::lround(seconds * rate));
        for (int i = 0; i < n; ++i) {
            const double previous = speed;
            // 60 % of the way per sample: a sample or two of acceleration at 10 Hz, a few more at 100 Hz
            speed = std::abs(target - speed) < 0.01 * std::abs(target) + 1e-6 ? target : speed + (target - speed) * 0.6;
            position += speed * dt;
            t.push_back(dt * static_cast<double>(t.size()));
            x.push_back(std::round(position / quantum) * quantum);
            v.push_back(speed);
            const double sign = speed > 0.0 ? 1.0 : speed < 0.0 ? -1.0 : 0.0;
            f.push_back(mass * (speed - previous) / dt + viscous * speed + coulomb * sign + load * sign +
                        noise(random));
        }
    };
    for (int stroke = 0; stroke < 30; ++stroke) {
        samples(0.0, 0.5 + unit(random), 0.0);
        const double direction = stroke % 2 == 0 ? 1.0 : -1.0;
        const double target = direction * (0.002 + 0.038 * unit(random));
        const double load = (cutting && unit(random) < 0.5 ? 0.5 * coulomb * unit(random) : 0.0) + level(random);
        samples(target, 2.0 + 2.0 * unit(random), load);
    }
    samples(0.0, 1.0, 0.0);
    if (jumps)
        for (std::size_t k = 50; k < x.size(); k += 50) x[k] += 0.05;
    Log log;
    log.kind = "seed " + std::to_string(seed) + (jumps ? ", jumping" : "") + (cutting ? ", cutting" : "") + ", " +
               std::to_string(static_cast<int>(rate)) + " Hz, quantum " + std::to_string(quantum);
    log.trace.source_path = "generated.csv";
    log.trace.set("t", Role::time, "s", std::move(t));
    log.trace.set("x", Role::position, "m", std::move(x));
    log.trace.set("v", Role::velocity, "m/s", std::move(v));
    log.trace.set("F", Role::force, "N", f);
    log.trace.validate();
    log.force = std::move(f);
    return log;
}

/// The physically possible values and a reason for every null, of a result that was not refused.
void expect_honest(const IdentifyResult& r, const std::string& what) {
    if (r.status == Status::failed) {
        EXPECT_FALSE(r.diagnostics.empty()) << what << ": failed without a reason";
        return;
    }
    for (const Parameter& p : r.parameters) {
        const Estimate& e = p.estimate;
        if (!e.value) {
            EXPECT_FALSE(r.diagnostics.empty()) << what << ": " << p.key << " null without a reason";
            continue;
        }
        const double se = e.standard_error.value_or(0.0);
        if (p.term == Term::mass || p.term == Term::coulomb || p.term == Term::breakaway) {
            EXPECT_GT(*e.value, 0.0) << what << ": " << p.key;
        }
        if (p.term == Term::viscous) {
            EXPECT_GE(*e.value, -se) << what << ": " << p.key << " +- " << se;
        }
    }
}

TEST(ProductionLogs, AHundredCoarseJumpingAndCuttingLogsNeverPrintAnImpossibleValue) {
    int refused = 0, answered = 0, with_values = 0, with_mass = 0;
    const auto count = [&](const IdentifyResult& r) {
        if (r.status == Status::failed) return;
        ++with_values;
        if (r.find(Term::mass) != nullptr && r.find(Term::mass)->estimate.value) ++with_mass;
    };
    for (unsigned seed = 0; seed < 100; ++seed) {
        const Log log = generated_log(seed);
        try {
            const IdentifyResult r = identify(log.trace, IdentifyOptions{});
            expect_honest(r, "identify, " + log.kind);
            count(r);
            ++answered;
        } catch (const InputError&) {
            ++refused;  // exit 2: a position that jumps is named, never taken for motion
        }
        try {
            const ScanResult s = scan(log.trace, log.force, {}, OnlineOptions{}, 65536, false);
            expect_honest(s.result, "scan, " + log.kind);
            count(s.result);
            for (const auto& line : scan_verdicts(s))
                EXPECT_FALSE(line.ends_with("not determined: ")) << "scan, " << log.kind << ": " << line;
            ++answered;
        } catch (const InputError&) {
            ++refused;
        }
    }
    // the jumping logs (a quarter) are refused, the others answered, most of them with values
    EXPECT_EQ(refused, 50);
    EXPECT_EQ(answered, 150);
    EXPECT_GE(with_values, answered / 2);
    std::printf("answered %d (with values %d, with a mass %d), refused %d\n", answered, with_values, with_mass,
                refused);
}

}  // namespace
}  // namespace feedid
