#pragma once
// Friction along the axis: a trace of a multi-centre test (feedid plan --centers ...) is cut into one segment per
// centre and each segment is identified on its own, so that a worn stretch of the screw shows up as a location whose
// friction stands out from the others.
//
// Centres come from the user or from the trace: the axis strokes back and forth around each centre, so the midpoints
// of its strokes (between turning points) pile up at the centres, while the moves between centres leave isolated
// midpoints.

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/identify/identify.hpp"
#include "feedid/core/trace.hpp"

namespace feedid {

struct FrictionMapOptions {
    IdentifyOptions identify;         ///< applied to every segment
    std::vector<double> centers;      ///< centres [m] (rotary axis: [rad]); empty = detect them from the strokes
    double turning_hysteresis{2e-5};  ///< a turning point needs the axis to come back this far [m]
    double center_tolerance{5e-4};    ///< stroke midpoints this close belong to one centre [m]
    int min_strokes{4};               ///< a detected centre needs at least this many strokes about it
    /// A location's parameter stands out when it differs from the median of the locations by more than this
    /// fraction and by more than 3 combined standard errors.
    double deviation_threshold{0.10};

    /// What is wrong with these options ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

struct LocationResult {
    double center{0.0};        ///< [m]
    std::size_t first{0};      ///< first sample of the segment
    std::size_t last{0};       ///< one past the last sample
    double from_s{0.0};        ///< [s]
    double to_s{0.0};          ///< [s]
    double min_position{0.0};  ///< [m]
    double max_position{0.0};  ///< [m]
    IdentifyResult result;
    std::optional<std::string> error;  ///< why this segment could not be identified (bad or too little data)
};

struct FrictionMap {
    std::vector<LocationResult> locations;
    bool centers_detected{false};
    bool rotary{false};                 ///< positions in rad (keys `center_rad`, ...), shown in deg
    std::vector<std::string> findings;  ///< which locations stand out, in words
    nlohmann::json document;            ///< the friction-map document (see friction_map_document)
};

/// Centres of the strokes found in the trace (reference position when present, else position) [m], ascending.
/// Empty when no position about which the axis strokes at least `min_strokes` times.
std::vector<double> detect_centers(const Trace& trace, const FrictionMapOptions& options);

/// Cuts the trace by centre (each sample goes to the nearest centre; a segment runs from the first to the last of its
/// samples) and identifies every segment. InputError when the trace lacks a position, when no centre is found, or
/// when the test returns to a centre after visiting another (the segments would overlap).
FrictionMap friction_map(const Trace& trace, const FrictionMapOptions& options);

}  // namespace feedid
