#pragma once
// The mechanical fingerprint of an axis from a trace with two measuring systems: the load-side scale (`position`) and
// the motor encoder (`motor_position`, in load units). Their difference d = x_motor - x_load is the transmission's
// deflection. Where the axis stands or moves at constant speed (the reference has not accelerated for a settling
// time), the drive force F is what the transmission carries, and a dead band of width b with stiffness k gives
//   d = d_0 + s*b/2 + F/k,   s = +1 while the motor pushes forward (F > 0), -1 while it pulls (F < 0),
// so one least-squares fit with an intercept per direction and a common slope gives k (N/m) and b = a_+ - a_-;
// a fit per direction gives k per direction. Around each reversal of the commanded motion:
//   lost motion      s*(mean d after - mean d before), the settled part of the moves on either side (b plus the
//                    elastic part the friction forces of the two directions make);
//   reversal error   the peak following error s*(x_ref - x_load) after it, until the next reversal (at most 0.5 s);
//   breakaway force  the peak drive force s*F after it, until the load has moved in the new direction.
// Each per direction (s: the direction of the motion after the reversal), the mean over the reversals with its
// standard error (the scatter; one reversal: the noise of the signal). A figure the trace cannot tell is null with
// a reason: with one measuring system only the reversal error (following error) and the breakaway force (drive
// signal) are given; without a force constant the stiffness is null and the deflection per drive-signal unit is said.
// Rotary axes: rad, N*m, N*m/rad (a torsional stiffness).

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/core/estimate.hpp"
#include "feedid/core/trace.hpp"
#include "feedid/model/drive.hpp"

namespace feedid {

struct FingerprintOptions {
    DriveConstants drive;           ///< turns the drive signal into force (none needed with a force channel)
    double settle_s{0.05};          ///< the reference must have held its velocity this long for a sample to count [s]
    double reversal_window_s{0.5};  ///< the longest time after a reversal its peak following error is sought in [s]
    /// A sample counts for the force-deflection fit only where |F| is at least this fraction of the median |F| of the
    /// settled samples: inside the dead band the transmission carries no force.
    double contact_fraction{0.3};

    /// What is wrong ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// One figure per direction of the motion after a reversal, and both together.
struct DirectionalEstimate {
    Estimate forward;    ///< after reversals into + motion
    Estimate reverse;    ///< after reversals into - motion (a positive magnitude)
    Estimate both;       ///< all reversals (or one fit for both directions)
    std::string reason;  ///< why a figure is null ("" when all are given)
};

/// The samples a report plots, evenly thinned to at most `max_points`: the scale's position, the encoder difference
/// d = x_motor - x_load and the direction of the last commanded move at each, the drive force (or signal) and
/// whether the sample is in the force-deflection fit; the fitted lines d = a_+/- + c*F. Empty with one measuring
/// system.
struct FingerprintCurves {
    static constexpr std::size_t max_points = 2000;
    std::vector<double> position;    ///< x_load [m; rad]
    std::vector<double> deflection;  ///< d [m; rad]
    std::vector<int> direction;      ///< +1, -1 (0 before the first move)
    std::vector<double> drive;       ///< force [N; N*m] (or the drive signal); empty without a drive signal
    std::vector<char> in_fit;        ///< 1 where the sample is in the force-deflection fit
    std::optional<double> compliance;         ///< c of the fit [m/N; rad/(N*m)], or per signal unit
    std::optional<double> intercept_forward;  ///< a_+ [m; rad]
    std::optional<double> intercept_reverse;  ///< a_- [m; rad]
};

struct FingerprintResult {
    bool rotary{false};
    bool two_measuring_systems{false};
    int reversals_forward{0};  ///< reversals into + motion found
    int reversals_reverse{0};
    DirectionalEstimate lost_motion;     ///< [m; rad]
    Estimate backlash;                   ///< the dead band's width [m; rad]
    std::string backlash_reason;         ///< why it is null
    DirectionalEstimate stiffness;       ///< [N/m; N*m/rad]
    DirectionalEstimate reversal_error;  ///< [m; rad]
    DirectionalEstimate breakaway;       ///< [N; N*m]
    /// Deflection per unit of the drive signal where no constant makes it a force [m (rad) per signal unit].
    std::optional<double> deflection_per_signal;
    std::string signal_unit;  ///< the drive signal's unit for deflection_per_signal
    int samples_used{0};      ///< settled samples in contact in the force-deflection fit
    std::vector<std::string> diagnostics;
    FingerprintCurves curves;  ///< for the report's plots; not in the document
};

/// Estimates the fingerprint. InputError when the trace lacks a position, a reference position or a time base, or
/// the options are invalid; figures the data cannot tell are null with their reason, never an exception.
FingerprintResult fingerprint(const Trace& trace, const FingerprintOptions& options = {});

/// The result document: {"fingerprint": {"lost_motion_m": {...}, "lost_motion_forward_m": ..., "backlash_m",
/// "stiffness_N_per_m" (+ _forward/_reverse), "reversal_error_m" (...), "breakaway_N" (...)}, "reasons": {...},
/// "reversals": {"forward": n, "reverse": n}, "two_measuring_systems": bool, "samples_used": n, "diagnostics": [...]}
/// (rotary: _rad, _Nm_per_rad, _Nm).
nlohmann::json fingerprint_document(const FingerprintResult& result);

}  // namespace feedid
