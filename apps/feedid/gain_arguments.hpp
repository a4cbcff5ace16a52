#pragma once
// Gain-identification options shared by `feedid gains` and `feedid simulate` (which identifies the gains from the
// trace when no gains document is given).
#include <optional>
#include <string>

#include "cli.hpp"
#include "feedid/core/error.hpp"
#include "feedid/identify/gains.hpp"
#include "feedid/identify/option_names.hpp"

namespace feedid::cli {

/// Options shared by `feedid gains` and `feedid simulate` (which identifies the gains when none are given).
struct GainArguments {
    std::string velocity_loop{name_of(velocity_loop_names, GainOptions{}.velocity_loop)};
    bool feedforward{GainOptions{}.feedforward};
    std::optional<int> velocity_difference;
    std::optional<double> current_lag_ms;
    std::optional<double> servo_rate_hz;
    std::optional<double> saturation;
    double forgetting{GainOptions{}.rls.forgetting_factor};

    void add_to(CLI::App& app) {
        app.add_option("--velocity-loop", velocity_loop,
                       "Velocity loop structure: pi, p, or auto (PI, or P when the integral gain is not significant)")
            ->check(CLI::IsMember(names_of(velocity_loop_names)));
        app.add_flag("--feedforward", feedforward, "Also identify a velocity feed-forward in the position loop");
        app.add_option("--velocity-difference", velocity_difference,
                       "The controller measures velocity as (x_k - x_{k-N})/(N*T); default: N chosen from the data")
            ->check(allowed_range(1, 8, "samples"));
        app.add_option("--current-lag-ms", current_lag_ms,
                       "Current-loop time constant [ms]; default: estimated from the data")
            ->check(allowed_range(0.0, 1000.0, "ms"));
        app.add_option("--servo-rate", servo_rate_hz,
                       "The rate the velocity loop runs at [Hz], a whole multiple of the trace's sample rate (e.g. "
                       "8000 for a speed controller at 8 kHz logged at 1 kHz); default: the trace's servo cycle, else "
                       "detected from the data")
            ->check(allowed_range(1.0, 1e6, "Hz"));
        app.add_option("--saturation", saturation,
                       "Limit of the drive signal, in its own units (e.g. 10 for 10 V); samples at the limit are left "
                       "out and the simulation saturates there")
            ->check(allowed_range(1e-9, 1e12, "drive signal units"));
        app.add_option("--forgetting", forgetting, "RLS forgetting factor lambda (1 = none: gains are constant)")
            ->capture_default_str()
            ->check(allowed_range(1e-6, 1.0, ""));
    }

    /// The options as given, before the trace's drive signal sets what it sets (simulate's twin does that).
    [[nodiscard]] GainOptions given() const {
        GainOptions options;
        options.velocity_loop = value_named(velocity_loop_names, velocity_loop).value_or(options.velocity_loop);
        options.feedforward = feedforward;
        options.velocity_difference_samples = velocity_difference;
        if (current_lag_ms) options.current_lag_s = *current_lag_ms * 1e-3;
        options.servo_rate_hz = servo_rate_hz;
        options.rls.forgetting_factor = forgetting;
        return options;
    }

    [[nodiscard]] GainOptions options(const Trace& trace, const DriveConstants& drive) const {
        GainOptions options = given();
        set_drive_signal(options, trace, drive, saturation);
        if (const auto problem = options.validate(); !problem.empty()) throw InputError(problem);
        return options;
    }
};

}  // namespace feedid::cli
