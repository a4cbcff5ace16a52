#pragma once
// Stage 2 of identify: which samples each step uses, every dropped sample counted and explained.
//   moving:       |x'| above a threshold set by the velocity noise floor and the position resolution;
//   quasi-static: within a short window around the sample the velocity keeps its sign and stays within a fraction of
//                 its value (constant-velocity passes; not the ramps through reversals, nor stick-slip, where the
//                 friction is anywhere between the static limits);
//   step 1:       moving samples at or above the split speed (the Stribeck term negligible, the paper's section 3);
//   step 2:       quasi-static samples below it.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "feedid/identify/preprocess.hpp"
#include "feedid/identify/step1.hpp"
#include "feedid/identify/stick_slip.hpp"

namespace feedid {

struct SelectionOptions {
    std::optional<double> split_velocity;    ///< [m/s or rad/s]; default from the data (below)
    std::optional<double> moving_threshold;  ///< [m/s or rad/s]; default from the noise floor (below)
    bool stribeck{true};                     ///< keep slow samples for step 2 (false: split at the threshold)

    /// Moving: |v| above this multiple of the velocity noise floor (and above the position resolution times the
    /// cut-off frequency, the smallest speed the filtered position can show).
    double rest_noise_multiple{5.0};
    /// ... and above this fraction of the largest speed (a noise-free synthetic trace has a zero noise floor).
    double rest_fraction_of_max_speed{1e-6};
    /// Quasi-static: the half-window [s] (50 ms in all), the tolerated spread of v in it as a fraction of |v|, plus
    /// this many velocity noise floors.
    double steady_half_window_s{0.025};
    double steady_spread_fraction{0.25};
    double steady_noise_multiple{6.0};
    /// The typical constant-velocity speed is this percentile of the quasi-static speeds; the default split speed is
    /// split_fraction of it (the paper's data: Stribeck friction has decayed at a tenth of the feed).
    double typical_speed_percentile{0.95};
    double split_fraction{0.1};
    /// The split doubles at most this often while the speeds just above it still show Stribeck friction.
    int max_split_doublings{3};
    /// Fewer quasi-static samples than this below the split cannot determine F_B and v_s; a speed band with fewer
    /// samples is no witness of a Stribeck rise either.
    std::size_t minimum_slow_samples{20};
    /// Step 1 needs at least this many samples per parameter (identify() sets it from Step1Options).
    std::size_t minimum_step1_samples_per_parameter{10};
    /// Step 1 and the mass fit leave out the samples within the low-pass's reach of a stop (Selection::resting_reach):
    /// stopped is slower than this fraction of the initial split speed (or the moving threshold, if higher), so
    /// that a dwell's creep and noise count as the stop they are.
    double rest_split_fraction{0.05};
    /// Passes that stick-slip are kept out of both steps (stick_slip.hpp).
    StickSlipOptions stick_slip;
};

/// The counts reported in the result document.
struct SelectionReport {
    std::size_t total{0};            ///< samples in the trace
    std::size_t window{0};           ///< inside --from/--to and the edge trim
    std::size_t moving{0};           ///< |v| above the moving threshold
    std::size_t step1{0};            ///< used in step 1 (after decimation)
    std::size_t step2{0};            ///< used in step 2
    std::size_t passes{0};           ///< passes of (commanded) motion in one direction
    std::size_t stick_slip_passes{0};  ///< of them, stick-slipping (left out of both steps)
    std::size_t stick_slip_samples{0};
    std::size_t clipped{0};          ///< samples left out because the drive signal sits at its limit near them
    std::size_t near_rest{0};        ///< fast samples left out of step 1: the low-pass's reach of a stop
    double moving_threshold{0.0};    ///< [m/s]
    double split_velocity{0.0};      ///< [m/s]
    double initial_split{0.0};       ///< the split before the Stribeck checks moved it [m/s]
    std::vector<std::string> notes;  ///< why samples were dropped, in words
};

/// The part of a selection that depends neither on the split speed nor on the regressors: the moving threshold, the
/// moving samples, the quasi-static flags and the stick-slip passes. Selections of one Derivatives at another split
/// (the preprocessing family's split variant) or for another model (after the model-adequacy stage) share it.
struct MovingSamples {
    SelectionReport report;  ///< the counts and notes of this part (total, window, moving, passes, clipped, threshold)
    SampleIndices moving;    ///< indices into Derivatives, ascending
    std::vector<char> quasi_static;  ///< per sample of Derivatives
    StickSlip stick_slip;
};

struct Selection {
    SelectionReport report;
    /// The first this many of report.notes are the moving samples' (MovingSamples).
    std::size_t moving_notes{0};
    SampleIndices moving;             ///< indices into Derivatives, ascending
    SampleIndices step1;              ///< ascending
    SampleIndices step2;              ///< ascending
    std::vector<char> quasi_static;   ///< per sample of Derivatives
    /// Per sample of Derivatives: within the low-pass's reach of a sample where the axis rests. The force went
    /// through the same low-pass as the position, so there it carries the smeared static force of the stop, which
    /// no function of x' models: step 1 and the mass fit leave these samples out.
    std::vector<char> resting_reach;
    StickSlip stick_slip;             ///< the passes and which of them stick-slip
    double initial_split{0.0};        ///< the split before the Stribeck check raised it [m/s]
    double stribeck_band{0.0};        ///< step 2 looks for quasi-static samples below this speed [m/s]

    [[nodiscard]] bool steady(std::size_t k) const { return quasi_static[k] != 0; }
    [[nodiscard]] bool near_rest(std::size_t k) const { return resting_reach[k] != 0; }
    [[nodiscard]] double moving_threshold() const { return report.moving_threshold; }
    [[nodiscard]] double split_velocity() const { return report.split_velocity; }
};

/// Selects the samples of each step. The Stribeck checks (is the band above the split still Stribeck? may the slow
/// ramp samples join step 1?) fit the step-1 model, hence the regressors.
Selection select_samples(const Derivatives& derivatives, const Regressors& regressors, const SelectionOptions& options);

/// The moving samples, the quasi-static flags and the stick-slip passes (the first part of select_samples()).
MovingSamples select_moving_samples(const Derivatives& derivatives, const SelectionOptions& options);

/// select_samples() with its first part done already: `moving` must come from select_moving_samples() on the same
/// Derivatives with the same moving threshold, stick-slip and quasi-static options (the split, the Stribeck checks
/// and the regressors may differ). The selection holds the moved-in samples; the result is select_samples()'s.
Selection select_samples(const Derivatives& derivatives, const Regressors& regressors, const SelectionOptions& options,
                         MovingSamples moving);

/// The first part back out of a selection, for another selection of the same Derivatives (`selection` is left
/// without its moving samples, quasi-static flags and stick-slip passes).
MovingSamples release_moving_samples(Selection&& selection);

}  // namespace feedid
