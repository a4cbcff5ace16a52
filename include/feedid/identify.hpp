#pragma once
// The identification pipeline: a Trace and options in, a result with values, uncertainties and diagnostics out.
//   step 1 (the paper's eq. 11, or per direction): y = F_d, phi = [x'', x', sgn(x') (, 1)], theta = [M, B, F_C (, F_0)]
//          on samples fast enough for the Stribeck term to be negligible; RLS and batch QR side by side;
//   step 2: Stribeck on the slow samples: the paper's log-linear RLS (eq. 12-14) and a Levenberg-Marquardt fit of the
//          whole friction curve, per direction; null where the data cannot determine F_B and v_s.

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/drive.hpp"
#include "feedid/estimate.hpp"
#include "feedid/friction.hpp"
#include "feedid/rls.hpp"
#include "feedid/trace.hpp"

namespace feedid {

enum class FrictionModelKind { symmetric, asymmetric };
enum class Differentiation { central, butterworth, savitzky_golay };

struct IdentifyOptions {
    FrictionModelKind model{FrictionModelKind::symmetric};
    bool offset{false};  ///< also estimate a constant force offset F_0 (gravity, sensor offset)
    DriveConstants drive;
    bool stribeck{true};  ///< run step 2

    // Preprocessing
    Differentiation differentiation{Differentiation::butterworth};
    int filter_order{4};              ///< Butterworth order
    std::optional<double> cutoff_hz;  ///< default: min(100 Hz, 0.1 * sample rate)
    int savitzky_golay_window{0};     ///< default: odd number of samples spanning ~20 ms
    int savitzky_golay_order{3};
    int decimation{0};                        ///< 0 = automatic (1 for sample rates <= 1 kHz... see README); 1 = none
    std::optional<std::size_t> edge_samples;  ///< samples dropped at each end (default: derived from the filter)

    // Data selection
    std::optional<double> from_s;            ///< time window start [s]
    std::optional<double> to_s;              ///< time window end [s]
    std::optional<double> split_velocity;    ///< step 1 above, step 2 below [m/s or rad/s]; default from the data
    std::optional<double> moving_threshold;  ///< |v| above which a sample is "moving"; default from the noise floor

    // RLS
    RlsOptions rls;

    /// What is wrong with these options ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// One reported parameter, keyed as in the result document ("mass_kg", "coulomb_forward_N", ...).
struct Parameter {
    std::string key;
    std::string symbol;  ///< "M", "B", "F_C+", ...
    std::string unit;    ///< "kg", "N*s/m", ...
    Estimate estimate;
};

struct SelectionReport {
    std::size_t total{0};            ///< samples in the trace
    std::size_t window{0};           ///< inside --from/--to and the edge trim
    std::size_t moving{0};           ///< |v| above the moving threshold
    std::size_t step1{0};            ///< used in step 1 (after decimation)
    std::size_t step2{0};            ///< used in step 2
    double moving_threshold{0.0};    ///< [m/s]
    double split_velocity{0.0};      ///< [m/s]
    std::vector<std::string> notes;  ///< why samples were dropped, in words
};

struct IdentifyResult {
    std::string status{"ok"};  ///< "ok", "partial" (some parameters null), "failed"
    std::string model;         ///< "symmetric" | "asymmetric"
    bool offset{false};
    bool rotary{false};
    std::vector<Parameter> parameters;
    AxisModel axis;           ///< the identified model (no Stribeck term where F_B / v_s are null)
    nlohmann::json document;  ///< the full result document of DESIGN.md (stable keys)
    std::vector<std::string> diagnostics;

    [[nodiscard]] const Parameter* find(const std::string& key) const;
};

/// Runs the whole pipeline. Throws InputError for a trace that lacks what is needed (position, drive signal);
/// numerical trouble (nothing identifiable) comes back as status "failed" with diagnostics, never an exception.
IdentifyResult identify(const Trace& trace, const IdentifyOptions& options);

}  // namespace feedid
