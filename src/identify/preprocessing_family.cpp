#include "feedid/identify/preprocessing_family.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/core.h>

namespace feedid {

namespace {

/// An odd Savitzky-Golay window of at least 5 samples and above the polynomial order.
int odd_window(double samples, int order) {
    const int window = static_cast<int>(std::lround(samples)) | 1;
    return std::max({5, order + 2 + ((order + 2) % 2 == 0 ? 1 : 0), window});
}

PreprocessingVariant butterworth(const PreprocessOptions& base, std::optional<double> cutoff_hz, std::string label) {
    PreprocessingVariant v{std::move(label), base};
    v.options.differentiation = Differentiation::butterworth;
    v.options.cutoff_hz = cutoff_hz;
    v.options.edge_samples.reset();  // the filter's own settling
    return v;
}

PreprocessingVariant savitzky_golay(const PreprocessOptions& base, int window, std::string label) {
    PreprocessingVariant v{std::move(label), base};
    v.options.differentiation = Differentiation::savitzky_golay;
    v.options.savitzky_golay_window = window;
    v.options.edge_samples.reset();
    return v;
}

}  // namespace

std::vector<PreprocessingVariant> preprocessing_family(const PreprocessOptions& nominal, const PreprocessReport& used,
                                                       double position_interval_s, double split_velocity,
                                                       double speed_scale, const std::string& speed_unit) {
    PreprocessOptions base = nominal;
    // the same signal differentiated, whatever `automatic` chose
    base.velocity_source = used.velocity_source == "velocity" ? VelocitySource::logged : VelocitySource::position;
    std::vector<PreprocessingVariant> family;
    const double fs = 1.0 / position_interval_s;
    switch (nominal.differentiation) {
        case Differentiation::butterworth: {
            const double cutoff = used.cutoff_hz;
            family.push_back(butterworth(base, 0.5 * cutoff, fmt::format("Butterworth {:.4g} Hz", 0.5 * cutoff)));
            if (2.0 * cutoff < 0.45 * fs)
                family.push_back(butterworth(base, 2.0 * cutoff, fmt::format("Butterworth {:.4g} Hz", 2.0 * cutoff)));
            family.push_back(savitzky_golay(base, 0, "Savitzky-Golay (default window)"));
            break;
        }
        case Differentiation::savitzky_golay: {
            const int order = nominal.savitzky_golay_order;
            const int window = used.savitzky_golay_window;
            const int wider = odd_window(2.0 * window, order), narrower = odd_window(0.5 * window, order);
            family.push_back(savitzky_golay(base, wider, fmt::format("Savitzky-Golay window {}", wider)));
            if (narrower < window)
                family.push_back(savitzky_golay(base, narrower, fmt::format("Savitzky-Golay window {}", narrower)));
            family.push_back(butterworth(base, std::nullopt, "Butterworth (default cut-off)"));
            break;
        }
        case Differentiation::central:
            family.push_back(butterworth(base, std::nullopt, "Butterworth (default cut-off)"));
            family.push_back(savitzky_golay(base, 0, "Savitzky-Golay (default window)"));
            break;
    }
    if (split_velocity > 0.0) {
        PreprocessingVariant split{
            fmt::format("split speed x1.5 ({:.4g} {})", 1.5 * split_velocity * speed_scale, speed_unit), nominal,
            1.5 * split_velocity};
        family.push_back(std::move(split));
    }
    return family;
}

}  // namespace feedid
