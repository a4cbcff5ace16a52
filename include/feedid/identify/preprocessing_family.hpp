#pragma once
// The part of an estimate's uncertainty that the preprocessing makes: how far the estimate moves when the position
// is filtered and differentiated in other reasonable ways. The standard error says how the estimate scatters with
// the noise of this trace; it cannot say that a cut-off half or twice as high, or another differentiation method,
// would have moved the value by ten standard errors (on a real rotary trace F_C moved from 0.28 to 2.15 N*m across
// cut-offs with a standard error of 0.078). identify() reruns its stages over a small documented family of
// preprocessing choices and reports, per parameter, the largest deviation from the nominal estimate as
// `systematic`, and sqrt(standard_error^2 + systematic^2) as `uncertainty`.
//
// The family, around the preprocessing used:
//   Butterworth at f_c:        Butterworth at f_c/2, at 2*f_c (while below 0.45 fs), Savitzky-Golay (default window)
//   Savitzky-Golay window w:   Savitzky-Golay with 2w and w/2 (odd, at least 5 and above the order), Butterworth
//                              (default cut-off)
//   central differences:       Butterworth (default cut-off), Savitzky-Golay (default window)
// and, whatever the differentiation, step 1's split speed raised by half: a Stribeck friction that reaches past the
// split (too little of it above the noise for the split to rise by itself) biases B and F_C, and shows as their
// moving when the split does.

#include <optional>
#include <string>
#include <vector>

#include "feedid/identify/preprocess.hpp"
#include "feedid/core/status.hpp"

namespace feedid {

/// One member of the family: a label for messages ("Butterworth 50 Hz") and the options to preprocess with, or the
/// split speed to select with.
struct PreprocessingVariant {
    std::string label;
    PreprocessOptions options;
    std::optional<double> split_velocity{};  ///< [m/s or rad/s]; none = as the nominal run
};

/// The family around `nominal` (as given) and `used` (what preprocess() resolved), for a position sampled every
/// `position_interval_s`; `split_velocity` is the split the nominal run used (0: no split variant), shown in
/// `speed_unit` after multiplying by `speed_scale`.
std::vector<PreprocessingVariant> preprocessing_family(const PreprocessOptions& nominal, const PreprocessReport& used,
                                                       double position_interval_s, double split_velocity,
                                                       double speed_scale, const std::string& speed_unit);

/// What each variant gave, for the result document.
struct SystematicVariant {
    std::string label;
    Status status{Status::failed};
    std::vector<std::string> keys;              ///< the parameters' keys
    std::vector<std::optional<double>> values;  ///< the variant's estimate of each (null where undetermined)
};

struct SystematicReport {
    std::vector<SystematicVariant> variants;
};

}  // namespace feedid
