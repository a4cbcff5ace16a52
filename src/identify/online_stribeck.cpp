// The online identifier's breakaway friction and Stribeck velocity: the quasi-static slow samples of qualified windows
// binned by speed, and the paper's eq. (13) fitted on the bins at estimate time.

#include <algorithm>
#include <array>
#include <cmath>

#include <fmt/core.h>
#include <Eigen/LU>

#include "feedid/core/parameters.hpp"
#include "online_state.hpp"

namespace feedid {

using State = OnlineIdentifier::State;

void State::bin_slow_samples(std::size_t first, std::size_t last) {
    const double low = std::log(options_.stribeck_lowest_speed);
    const double span = std::log(options_.split()) - low;
    for (std::size_t k = first; k < last; ++k) {
        const double speed = std::abs(v_[k]);
        if (use_[k] == 0 || speed <= options_.moving_threshold || speed > options_.split() ||
            speed < options_.stribeck_lowest_speed || std::abs(a_[k]) > options_.quasi_static_acceleration)
            continue;
        // the quasi-static slow samples: the force is friction (and M*x'', small); away from a reversal, where the
        // filtered sgn would not be +-1
        if (std::abs(sf_[k]) < 0.999) continue;
        const double d = v_[k] > 0.0 ? 1.0 : -1.0;
        const auto index = std::min(bins_per_direction - 1,
                                    static_cast<std::size_t>((std::log(speed) - low) / span * bins_per_direction));
        StribeckBin& bin = bins_[d > 0.0 ? 0 : 1][index];
        if (bin.last_window != counts_.total) {
            bin.last_window = counts_.total;
            ++bin.windows;
        }
        bin.n += 1.0;
        bin.speed += speed;
        bin.force += d * ff_[k];
        bin.force_sq += ff_[k] * ff_[k];
        bin.acceleration += d * a_[k];
    }
}

namespace {

// eq. (13) on the bins: ln(F_stri) = ln(F_B - F_C) - |v| / v_s, weighted by each bin's precision.
struct BinPoint {
    double speed, stribeck, standard_error;
};

struct StribeckFit {
    bool ok{false};
    double rise{0.0}, vs{0.0}, rise_se{0.0}, vs_se{0.0};
    std::size_t used{0};
    std::size_t slow{0};  ///< bins below 3 v_s
};

// The bins' points F_stri = friction - B |v| - F_C (- F_0 sgn) above twice their noise; bins with too few samples or
// from too few windows (one slow move is one realisation of the noise and of any cutting force) are left out.
template <class Bins, class Theta>
std::size_t stribeck_points(const Bins& bins, const Theta& theta, bool offset, double correlation,
                            const OnlineOptions& options, std::span<BinPoint> points, std::size_t& slow_samples,
                            std::size_t& populated) {
    std::size_t used = 0;
    slow_samples = 0;
    populated = 0;
    for (std::size_t direction = 0; direction < 2; ++direction) {
        for (const auto& bin : bins[direction]) {
            slow_samples += static_cast<std::size_t>(bin.n);
            if (bin.n < static_cast<double>(options.minimum_bin_samples) ||
                bin.windows < options.minimum_stribeck_windows)
                continue;
            ++populated;
            const double speed = bin.speed / bin.n;
            const double mean = bin.force / bin.n;
            double stribeck = mean - theta(0) * bin.acceleration / bin.n - theta(1) * speed - theta(2);
            if (offset) stribeck -= (direction == 0 ? 1.0 : -1.0) * theta(3);
            const double se = std::sqrt(std::max(0.0, bin.force_sq / bin.n - mean * mean) * correlation / bin.n);
            if (stribeck > 2.0 * se + 1e-12 && used < points.size()) points[used++] = {speed, stribeck, se + 1e-12};
        }
    }
    return used;
}

StribeckFit fit_stribeck(std::span<const BinPoint> points, std::size_t minimum_bins) {
    StribeckFit f;
    f.used = points.size();
    if (points.size() < minimum_bins) return f;
    Eigen::Matrix2d normal = Eigen::Matrix2d::Zero();
    Eigen::Vector2d right = Eigen::Vector2d::Zero();
    for (const auto& point : points) {
        const double w = std::pow(point.stribeck / point.standard_error, 2);  // 1 / var(ln F_stri)
        const Eigen::Vector2d phi(1.0, point.speed);
        normal += w * phi * phi.transpose();
        right += w * std::log(point.stribeck) * phi;
    }
    const Eigen::Vector2d line = normal.inverse() * right;
    // the bins' scatter about the fitted line beyond their own noise (the log-linear law's misfit, bins correlated by
    // the filter) widens the covariance: reduced chi^2, when above 1
    double chi2 = 0.0;
    for (const auto& point : points) {
        const double w = std::pow(point.stribeck / point.standard_error, 2);
        chi2 += w * std::pow(std::log(point.stribeck) - line(0) - line(1) * point.speed, 2);
    }
    const double inflation = points.size() > 2 ? std::max(1.0, chi2 / static_cast<double>(points.size() - 2)) : 1.0;
    const Eigen::Matrix2d cov = inflation * normal.inverse();
    if (!(line(1) < 0.0)) return f;
    f.ok = true;
    f.rise = std::exp(line(0));
    f.vs = -1.0 / line(1);
    f.vs_se = std::sqrt(cov(1, 1)) / (line(1) * line(1));
    f.rise_se = f.rise * std::sqrt(cov(0, 0));
    for (const auto& point : points) f.slow += point.speed < 3.0 * f.vs ? 1 : 0;
    return f;
}

}  // namespace

void State::estimate_stribeck(const Vec& theta, const Vec& standard_error, OnlineEstimate& e) const {
    // the quasi-static bins: F_stri = friction - B |v| - F_C per bin, eq. (13) on those above their noise
    std::array<BinPoint, 2 * bins_per_direction> points{};
    const double correlation = std::max(1.0, 1.0 / (dt_ * cutoff_hz_));
    std::size_t slow_samples = 0;
    std::size_t populated = 0;
    // the bins' points for B + db and F_C + dc (F_B and v_s extrapolate the rise above F_C to zero speed: an error
    // of F_C or B moves them, and their uncertainty must say so)
    const auto fit = [&](double db, double dc) {
        Vec moved = theta;
        moved(1) += db;
        moved(2) += dc;
        const bool offset = moved.size() == max_p;
        const std::size_t used =
            stribeck_points(bins_, moved, offset, correlation, options_, points, slow_samples, populated);
        return fit_stribeck(std::span<const BinPoint>(points.data(), used), options_.minimum_stribeck_bins);
    };
    const StribeckFit nominal = fit(0.0, 0.0);
    const ParameterNaming naming{options_.rotary};
    const double scale = naming.display_velocity_scale();
    const std::string unit = naming.display_velocity_unit();
    if (nominal.used < options_.minimum_stribeck_bins) {
        e.stribeck_reason =
            populated < options_.minimum_stribeck_bins
                ? fmt::format(
                      "the trace has no moves slow enough to determine F_B and v_s: its quasi-static samples "
                      "below {:.3g} {} ({}) fill {} speed bin(s) of {} or more from {} or more windows; {} needed",
                      options_.split() * scale, unit, slow_samples, populated, options_.minimum_bin_samples,
                      options_.minimum_stribeck_windows, options_.minimum_stribeck_bins)
                : fmt::format(
                      "the slow moves ({} quasi-static samples below {:.3g} {}) show a friction rise above "
                      "F_C in only {} speed bin(s); {} needed",
                      slow_samples, options_.split() * scale, unit, nominal.used, options_.minimum_stribeck_bins);
        return;
    }
    if (!nominal.ok) {
        e.stribeck_reason = "the slow moves' friction does not fall with speed: no Stribeck term to determine";
        return;
    }
    // the decay must be seen: several bins below 3 v_s (above it the rise is under 5 % of its size)
    if (nominal.slow < options_.minimum_stribeck_bins) {
        e.stribeck_reason = fmt::format(
            "v_s = {:.3g} {} is not determined by the slow moves: only {} speed bin(s) below 3 v_s; {} needed",
            nominal.vs * scale, unit, nominal.slow, options_.minimum_stribeck_bins);
        return;
    }
    // F_C's and B's standard errors carried through: the fit again with each moved by one standard error
    double vs_shift = 0.0;
    double rise_shift = 0.0;
    for (const auto& [db, dc] : {std::pair{standard_error(1), 0.0}, std::pair{-standard_error(1), 0.0},
                                 std::pair{0.0, standard_error(2)}, std::pair{0.0, -standard_error(2)}}) {
        const StribeckFit moved = fit(db, dc);
        if (!moved.ok) {
            e.stribeck_reason = fmt::format(
                "v_s = {:.3g} {} is not determined: the slow moves' rise above F_C vanishes within F_C's and B's "
                "standard errors",
                nominal.vs * scale, unit);
            return;
        }
        vs_shift = std::max(vs_shift, std::abs(moved.vs - nominal.vs));
        rise_shift = std::max(rise_shift, std::abs(moved.rise + dc - nominal.rise));  // F_B = F_C + rise
    }
    const double vs_se = std::hypot(nominal.vs_se, vs_shift);
    const double fb_se = std::hypot(nominal.rise_se, rise_shift);
    if (!(vs_se < 0.3 * nominal.vs)) {
        e.stribeck_reason = fmt::format("v_s = {:.3g} {} is not determined by the slow moves (standard error {:.0f} %)",
                                        nominal.vs * scale, unit, 100.0 * vs_se / nominal.vs);
        return;
    }
    e.breakaway = Estimate::of(theta(2) + nominal.rise, fb_se);
    e.stribeck_velocity = Estimate::of(nominal.vs, vs_se);
    e.stribeck_bins_used = nominal.used;
}

}  // namespace feedid
