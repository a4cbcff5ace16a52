#include "feedid/numeric/signal.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <complex>
#include <cstdint>
#include <functional>
#include <numbers>
#include <stdexcept>

#include <Eigen/Dense>

namespace feedid {

namespace {

using Complex = std::complex<double>;

// Builds second-order sections from analog low-pass poles (left half plane, conjugate pairs adjacent or real),
// mapped by the bilinear transform s = 2*fs*(z-1)/(z+1); all zeros at z = -1. The DC gain is set to `dc_gain`.
SecondOrderSections from_analog_poles(const std::vector<Complex>& poles, double sample_rate_hz, double dc_gain) {
    const double k = 2.0 * sample_rate_hz;
    SecondOrderSections filter;
    std::vector<bool> used(poles.size(), false);
    for (std::size_t i = 0; i < poles.size(); ++i) {
        if (used[i]) continue;
        used[i] = true;
        const Complex z = (k + poles[i]) / (k - poles[i]);
        if (std::abs(poles[i].imag()) < 1e-12 * std::abs(poles[i])) {
            // first-order section: (1 + z^-1) / (1 - z_r z^-1)
            filter.sections.push_back({1.0, 1.0, 0.0, 1.0, -z.real(), 0.0});
            continue;
        }
        // its conjugate
        for (std::size_t j = i + 1; j < poles.size(); ++j) {
            if (!used[j] && std::abs(poles[j] - std::conj(poles[i])) < 1e-9 * std::abs(poles[i])) {
                used[j] = true;
                break;
            }
        }
        filter.sections.push_back({1.0, 2.0, 1.0, 1.0, -2.0 * z.real(), std::norm(z)});
    }
    // normalise the DC gain (z = 1)
    double gain = 1.0;
    for (const auto& s : filter.sections) gain *= (s[0] + s[1] + s[2]) / (s[3] + s[4] + s[5]);
    const double correction = dc_gain / gain;
    auto& first = filter.sections.front();
    first[0] *= correction;
    first[1] *= correction;
    first[2] *= correction;
    return filter;
}

double prewarped(double cutoff_hz, double sample_rate_hz) {
    if (!(cutoff_hz > 0.0) || !(cutoff_hz < 0.5 * sample_rate_hz)) {
        throw std::invalid_argument("filter cut-off must lie between 0 and half the sample rate");
    }
    return 2.0 * sample_rate_hz * std::tan(std::numbers::pi * cutoff_hz / sample_rate_hz);
}

// One section over x forwards (transposed direct form II) from steady state for `level`, its output written `shift`
// samples earlier (the first `shift` outputs dropped): the write goes where the input was already read.
void section_forward(const std::array<double, 6>& s, double level, std::span<double> x, std::size_t shift) {
    const double b0 = s[0], b1 = s[1], b2 = s[2], a1 = s[4], a2 = s[5];
    const double g = (b0 + b1 + b2) / (1.0 + a1 + a2);
    double s2 = (b2 - a2 * g) * level;
    double s1 = (b1 - a1 * g) * level + s2;
    for (std::size_t k = 0; k < x.size(); ++k) {
        const double in = x[k];
        const double out = b0 * in + s1;
        s1 = b1 * in - a1 * out + s2;
        s2 = b2 * in - a2 * out;
        if (k >= shift) x[k - shift] = out;
    }
}

// The same section over x backwards, in place, from steady state for `level`.
void section_backward(const std::array<double, 6>& s, double level, std::span<double> x) {
    const double b0 = s[0], b1 = s[1], b2 = s[2], a1 = s[4], a2 = s[5];
    const double g = (b0 + b1 + b2) / (1.0 + a1 + a2);
    double s2 = (b2 - a2 * g) * level;
    double s1 = (b1 - a1 * g) * level + s2;
    for (std::size_t k = x.size(); k-- > 0;) {
        const double in = x[k];
        const double out = b0 * in + s1;
        s1 = b1 * in - a1 * out + s2;
        s2 = b2 * in - a2 * out;
        x[k] = out;
    }
}

// A cascade of S sections run sample by sample (each section's state in registers): the same arithmetic, in the same
// order, as one pass per section, with the sections of neighbouring samples overlapping in the pipeline instead of
// each waiting on its own recursion, and one pass over memory instead of S.
template <std::size_t S>
struct Cascade {
    std::array<std::array<double, 5>, S> c{};  // b0, b1, b2, a1, a2
    std::array<double, S> s1{}, s2{};

    // from steady state for `level` at the input; the level at each later section is the one before times the
    // section's DC gain
    Cascade(const SecondOrderSections& filter, double level) {
        for (std::size_t i = 0; i < S; ++i) {
            const auto& s = filter.sections[i];
            c[i] = {s[0], s[1], s[2], s[4], s[5]};
            const double g = (s[0] + s[1] + s[2]) / (1.0 + s[4] + s[5]);
            s2[i] = (s[2] - s[5] * g) * level;
            s1[i] = (s[1] - s[4] * g) * level + s2[i];
            level *= (s[0] + s[1] + s[2]) / (1.0 + s[4] + s[5]);
        }
    }
    double operator()(double in) {
        for (std::size_t i = 0; i < S; ++i) {
            const double out = c[i][0] * in + s1[i];
            s1[i] = c[i][1] * in - c[i][3] * out + s2[i];
            s2[i] = c[i][2] * in - c[i][4] * out;
            in = out;
        }
        return in;
    }
};

template <std::size_t S>
void cascade_passes(const SecondOrderSections& filter, std::span<double> y, std::size_t pad) {
    Cascade<S> forward(filter, y.front());
    for (std::size_t k = 0; k < y.size(); ++k) {
        const double out = forward(y[k]);
        if (k >= pad) y[k - pad] = out;
    }
    const auto kept = y.first(y.size() - pad);
    Cascade<S> backward(filter, kept.back());
    for (std::size_t k = kept.size(); k-- > 0;) kept[k] = backward(kept[k]);
}

// filtfilt's two passes over the padded signal y (pad samples before and after the n of the signal), without
// reversing it twice and without moving it: the forward pass writes its last section's output `pad` samples earlier,
// dropping the front padding's outputs, which the backward pass would only have carried into outputs that are cut
// off anyway; the backward pass then runs over y[0, n + pad), and the signal is in y[0, n). The same arithmetic, in
// the same order, as filtering y, reversing, filtering and reversing.
void filtfilt_passes(const SecondOrderSections& filter, std::span<double> y, std::size_t pad) {
    switch (filter.sections.size()) {
        case 1: return cascade_passes<1>(filter, y, pad);
        case 2: return cascade_passes<2>(filter, y, pad);
        case 3: return cascade_passes<3>(filter, y, pad);
        case 4: return cascade_passes<4>(filter, y, pad);
        default: break;
    }
    double level = y.front();
    for (std::size_t i = 0; i < filter.sections.size(); ++i) {
        const auto& s = filter.sections[i];
        section_forward(s, level, y, i + 1 == filter.sections.size() ? pad : 0);
        level *= (s[0] + s[1] + s[2]) / (1.0 + s[4] + s[5]);
    }
    const auto kept = y.first(y.size() - pad);
    level = kept.back();
    for (const auto& s : filter.sections) {
        section_backward(s, level, kept);
        level *= (s[0] + s[1] + s[2]) / (1.0 + s[4] + s[5]);
    }
}

// The order of the cascade's transfer function (MATLAB's filtord): the larger of the numerator's and the
// denominator's degree in z^-1, each the sum over the sections of its highest non-zero power. A first-order section
// (b2 = a2 = 0) adds one, so an odd-order design has an odd order, not twice its number of sections.
std::size_t filter_order(const SecondOrderSections& filter) {
    auto degree = [](double c1, double c2) -> std::size_t { return c2 != 0.0 ? 2 : c1 != 0.0 ? 1 : 0; };
    std::size_t numerator = 0;
    std::size_t denominator = 0;
    for (const auto& s : filter.sections) {
        numerator += degree(s[1], s[2]);
        denominator += degree(s[4], s[5]);
    }
    return std::max(numerator, denominator);
}

// filtfilt's padding of a signal of n samples: max(1, 3 * (filter order)), at most n - 1.
std::size_t filtfilt_padding(const SecondOrderSections& filter, std::size_t n) {
    return std::min(std::max<std::size_t>(1, 3 * filter_order(filter)), n - 1);
}

// x with its odd reflections about the end points, `pad` samples each (as MATLAB's filtfilt, which refuses a signal of
// no more samples than that; here the padding is cut to n - 1), at the front of `workspace` (grown when too short).
std::span<double> padded(std::span<const double> x, std::size_t pad, std::vector<double>& workspace) {
    const std::size_t n = x.size();
    if (workspace.size() < n + 2 * pad) {
        // appended, not resized and overwritten: a fresh column is written once, not zeroed first
        workspace.clear();
        workspace.reserve(n + 2 * pad);
        for (std::size_t k = pad; k >= 1; --k) workspace.push_back(2.0 * x[0] - x[k]);
        workspace.insert(workspace.end(), x.begin(), x.end());
        for (std::size_t k = 1; k <= pad; ++k) workspace.push_back(2.0 * x[n - 1] - x[n - 1 - k]);
        return {workspace.data(), n + 2 * pad};
    }
    const std::span<double> y(workspace.data(), n + 2 * pad);
    for (std::size_t k = pad; k >= 1; --k) y[pad - k] = 2.0 * x[0] - x[k];
    std::copy(x.begin(), x.end(), y.begin() + static_cast<std::ptrdiff_t>(pad));
    for (std::size_t k = 1; k <= pad; ++k) y[pad + n - 1 + k] = 2.0 * x[n - 1] - x[n - 1 - k];
    return y;
}

}  // namespace

SecondOrderSections butterworth_lowpass(int order, double cutoff_hz, double sample_rate_hz) {
    if (order < 1 || order > 20) throw std::invalid_argument("Butterworth order must be 1..20");
    const double wa = prewarped(cutoff_hz, sample_rate_hz);
    std::vector<Complex> poles;
    for (int k = 0; k < order; ++k) {
        const double angle = std::numbers::pi * (2.0 * k + order + 1.0) / (2.0 * order);
        poles.push_back(wa * Complex(std::cos(angle), std::sin(angle)));
    }
    return from_analog_poles(poles, sample_rate_hz, 1.0);
}

SecondOrderSections chebyshev1_lowpass(int order, double ripple_db, double cutoff_hz, double sample_rate_hz) {
    if (order < 1 || order > 20) throw std::invalid_argument("Chebyshev order must be 1..20");
    const double wa = prewarped(cutoff_hz, sample_rate_hz);
    const double eps = std::sqrt(std::pow(10.0, ripple_db / 10.0) - 1.0);
    const double mu = std::asinh(1.0 / eps) / order;
    std::vector<Complex> poles;
    for (int k = 0; k < order; ++k) {
        const double theta = std::numbers::pi * (2.0 * k + 1.0) / (2.0 * order);
        poles.push_back(wa * Complex(-std::sinh(mu) * std::sin(theta), std::cosh(mu) * std::cos(theta)));
    }
    const double dc_gain = order % 2 == 0 ? 1.0 / std::sqrt(1.0 + eps * eps) : 1.0;
    return from_analog_poles(poles, sample_rate_hz, dc_gain);
}

std::vector<double> filtfilt(const SecondOrderSections& filter, std::span<const double> x) {
    std::vector<double> workspace;
    if (x.size() < 2) return std::vector<double>(x.begin(), x.end());
    // the padded signal filtered in its own buffer, then the padding cut off in place: one column, not two
    workspace.reserve(x.size() + 2 * filtfilt_padding(filter, x.size()));
    filtfilt(filter, x, std::span<double>(), workspace);
    workspace.resize(x.size());  // the signal is at the front (filtfilt_passes)
    return workspace;
}

void filtfilt(const SecondOrderSections& filter, std::span<const double> x, std::span<double> out,
              std::vector<double>& workspace) {
    const std::size_t n = x.size();
    if (n == 0) return;
    if (n == 1) {
        out[0] = x[0];
        return;
    }
    // odd reflection about the end points, max(1, 3 * (filter order)) samples, as MATLAB's filtfilt (which refuses a
    // signal of no more samples than that; here the padding is cut to n - 1)
    const std::size_t pad = filtfilt_padding(filter, n);
    const std::span<double> y = padded(x, pad, workspace);
    if (filter.sections.empty()) {
        std::copy(y.begin() + static_cast<std::ptrdiff_t>(pad), y.begin() + static_cast<std::ptrdiff_t>(pad + n),
                  y.begin());
    } else {
        filtfilt_passes(filter, y, pad);
    }
    if (out.empty()) return;  // the caller takes the filtered signal from the front of the workspace
    std::copy(y.begin(), y.begin() + static_cast<std::ptrdiff_t>(n), out.begin());
}

void filtfilt_in_place(const SecondOrderSections& filter, std::vector<double>& x) {
    const std::size_t n = x.size();
    if (n < 2) return;
    const std::size_t pad = filtfilt_padding(filter, n);
    x.reserve(n + 2 * pad);
    // the reflections of padded(), formed before the signal moves: the front's from x[1..pad], the back's appended
    std::vector<double> front;
    front.reserve(pad);
    for (std::size_t k = pad; k >= 1; --k) front.push_back(2.0 * x[0] - x[k]);
    for (std::size_t k = 1; k <= pad; ++k) x.push_back(2.0 * x[n - 1] - x[n - 1 - k]);
    x.insert(x.begin(), front.begin(), front.end());  // within the capacity: the signal moves up, not elsewhere
    if (filter.sections.empty()) {
        x.erase(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(pad));
    } else {
        filtfilt_passes(filter, x, pad);
    }
    x.resize(n);  // the signal is at the front (filtfilt_passes)
}

std::size_t filtfilt_capacity(const SecondOrderSections& filter, std::size_t n) {
    return n < 2 ? n : n + 2 * filtfilt_padding(filter, n);
}

std::vector<double> central_difference(std::span<const double> x, double dt) {
    const std::size_t n = x.size();
    if (n < 2) return std::vector<double>(n, 0.0);
    // appended in order, not zeroed and overwritten: a million-sample column is written once
    std::vector<double> d;
    d.reserve(n);
    d.push_back((x[1] - x[0]) / dt);
    for (std::size_t k = 1; k + 1 < n; ++k) d.push_back((x[k + 1] - x[k - 1]) / (2.0 * dt));
    d.push_back((x[n - 1] - x[n - 2]) / dt);
    return d;
}

std::vector<double> savitzky_golay(std::span<const double> x, int window, int polynomial, int derivative, double dt) {
    if (window < 3 || window % 2 == 0) throw std::invalid_argument("Savitzky-Golay window must be odd and >= 3");
    if (polynomial < derivative || polynomial >= window) {
        throw std::invalid_argument("Savitzky-Golay polynomial order must be >= the derivative and < the window");
    }
    const std::size_t n = x.size();
    const int half = window / 2;
    if (n < static_cast<std::size_t>(window))
        throw std::invalid_argument("signal shorter than the Savitzky-Golay window");
    // Vandermonde on offsets -half..half; row `derivative` of the pseudo-inverse, times derivative!, gives the
    // derivative of the fitted polynomial at offset t (evaluated by the polynomial basis).
    Eigen::MatrixXd vandermonde(window, polynomial + 1);
    for (int i = 0; i < window; ++i) {
        for (int j = 0; j <= polynomial; ++j) vandermonde(i, j) = std::pow(static_cast<double>(i - half), j);
    }
    const Eigen::MatrixXd pseudo_inverse = vandermonde.completeOrthogonalDecomposition().pseudoInverse();
    // derivative of sum_j c_j t^j at offset t: sum_j c_j * j!/(j-d)! * t^(j-d)
    auto weights_at = [&](double t) {
        Eigen::RowVectorXd basis = Eigen::RowVectorXd::Zero(polynomial + 1);
        for (int j = derivative; j <= polynomial; ++j) {
            double factor = 1.0;
            for (int m = 0; m < derivative; ++m) factor *= (j - m);
            basis(j) = factor * std::pow(t, j - derivative);
        }
        return Eigen::RowVectorXd(basis * pseudo_inverse);
    };
    const double scale = std::pow(dt, -derivative);
    std::vector<double> y(n);
    const Eigen::RowVectorXd centre = weights_at(0.0);
    for (std::size_t k = static_cast<std::size_t>(half); k + static_cast<std::size_t>(half) < n; ++k) {
        double sum = 0.0;
        for (int i = 0; i < window; ++i)
            sum += centre(i) * x[k - static_cast<std::size_t>(half) + static_cast<std::size_t>(i)];
        y[k] = sum * scale;
    }
    for (int k = 0; k < half; ++k) {
        const Eigen::RowVectorXd head = weights_at(static_cast<double>(k - half));
        const Eigen::RowVectorXd tail = weights_at(static_cast<double>(half - k));
        double sum_head = 0.0, sum_tail = 0.0;
        for (int i = 0; i < window; ++i) {
            sum_head += head(i) * x[static_cast<std::size_t>(i)];
            sum_tail += tail(i) * x[n - static_cast<std::size_t>(window) + static_cast<std::size_t>(i)];
        }
        y[static_cast<std::size_t>(k)] = sum_head * scale;
        y[n - 1 - static_cast<std::size_t>(k)] = sum_tail * scale;
    }
    return y;
}

std::vector<std::size_t> decimation_indices(std::size_t n, int factor) {
    std::vector<std::size_t> indices;
    if (n == 0 || factor < 1) return indices;
    const std::size_t r = static_cast<std::size_t>(factor);
    const std::size_t out = (n + r - 1) / r;
    // MATLAB: nbeg = r - (r*nout - nd), 1-based; keeps the last sample
    const std::size_t first = r - (r * out - n) - 1;
    for (std::size_t k = first; k < n; k += r) indices.push_back(k);
    return indices;
}

namespace {

SecondOrderSections decimation_filter(int factor) { return chebyshev1_lowpass(8, 0.05, 0.8 * 0.5 / factor, 1.0); }

}  // namespace

double decimation_dc_gain(int factor) {
    if (factor <= 1) return 1.0;
    double gain = 1.0;
    for (const auto& s : decimation_filter(factor).sections) gain *= (s[0] + s[1] + s[2]) / (s[3] + s[4] + s[5]);
    return gain * gain;
}

std::vector<double> decimate(std::span<const double> x, int factor) {
    if (factor <= 1) return {x.begin(), x.end()};
    const auto filter = decimation_filter(factor);
    const auto filtered = filtfilt(filter, x);
    std::vector<double> y;
    for (const auto k : decimation_indices(x.size(), factor)) y.push_back(filtered[k]);
    return y;
}

std::vector<std::size_t> extreme_preserving_indices(std::span<const std::span<const double>> signals, std::size_t n,
                                                    std::size_t max_points) {
    std::vector<std::size_t> indices;
    if (n <= max_points) {
        indices.resize(n);
        for (std::size_t k = 0; k < n; ++k) indices[k] = k;
        return indices;
    }
    // Each bucket keeps at most two samples per signal, so this many buckets stay within max_points.
    const std::size_t buckets = std::max<std::size_t>(1, max_points / std::max<std::size_t>(1, 2 * signals.size()));
    std::vector<std::size_t> kept;
    for (std::size_t b = 0; b < buckets; ++b) {
        const std::size_t begin = b * n / buckets;
        const std::size_t end = (b + 1) * n / buckets;
        kept.clear();
        for (const auto& signal : signals) {
            std::size_t low = begin;
            std::size_t high = begin;
            for (std::size_t k = begin; k < end; ++k) {
                // NaN compares false: a NaN is never kept over a number, and a leading NaN is replaced by one
                if (signal[k] < signal[low] || std::isnan(signal[low])) low = k;
                if (signal[k] > signal[high] || std::isnan(signal[high])) high = k;
            }
            kept.push_back(low);
            kept.push_back(high);
        }
        std::sort(kept.begin(), kept.end());
        kept.erase(std::unique(kept.begin(), kept.end()), kept.end());
        indices.insert(indices.end(), kept.begin(), kept.end());
    }
    return indices;
}

double noise_floor(std::span<const double> x) {
    if (x.size() < 3) return 0.0;
    // A threshold, not a result: above robust_sample_size differences, every stride-th (evenly spread over the
    // signal) stands for all, at a relative standard error of about 1.2 / sqrt(robust_sample_size / 2) = 0.5 %
    // (that of a median absolute deviation of Gaussian noise) instead of a copy and two selections of the whole column.
    const std::size_t stride = robust_sample_stride(x.size() - 1);
    std::vector<double> d;
    d.reserve((x.size() - 2) / stride + 1);
    for (std::size_t k = 0; k + 1 < x.size(); k += stride) d.push_back(x[k + 1] - x[k]);
    auto median_of = [](std::vector<double>& v) {
        auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
        std::nth_element(v.begin(), mid, v.end());
        return *mid;
    };
    const double centre = median_of(d);
    for (double& v : d) v = std::abs(v - centre);
    return 1.4826 * median_of(d) / std::numbers::sqrt2;
}

double percentile(std::vector<double> values, double fraction) {
    return percentile_in_place(values, fraction);
}

std::size_t percentile_rank(std::size_t count, double fraction) {
    return static_cast<std::size_t>(std::clamp(fraction, 0.0, 1.0) * static_cast<double>(count - 1));
}

double percentile_in_place(std::span<double> values, double fraction) {
    if (values.empty()) return 0.0;
    const std::size_t index = percentile_rank(values.size(), fraction);
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(index), values.end());
    return values[index];
}

double detail::select_rank(std::vector<double>& members, std::size_t rank) {
    const auto nth = members.begin() + static_cast<std::ptrdiff_t>(rank);
    std::nth_element(members.begin(), nth, members.end());
    return *nth;
}

double absolute_percentile(std::span<const double> values, double fraction) {
    return absolute_percentile_of(
        values.size(),
        [values](const auto& f) {
            for (const double v : values) f(v);
        },
        fraction);
}

bool percentile_at_least(std::span<const double> values, double fraction, double threshold) {
    if (values.empty()) return false;
    const std::size_t index = percentile_rank(values.size(), fraction);
    std::size_t below = 0;
    for (const double v : values) below += v < threshold ? 1 : 0;
    return below <= index;
}

}  // namespace feedid
