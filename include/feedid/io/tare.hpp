#pragma once
// Tare: a sensor's zero taken from the samples at rest before the move. A load cell or a current sensor reads an
// offset at rest; on a move in one direction only that offset is collinear with Coulomb friction (sgn(v) is constant),
// so it cannot be estimated with the model and must be removed from the data.
//
// The rest samples: the leading run of samples where the speed stays at or below a fraction of the trace's largest
// speed (the logged velocity, or the position's central difference without one), less its last part (a drive
// pushes before the velocity shows it).

#include <cstddef>

#include "feedid/core/trace.hpp"

namespace feedid {

struct TareOptions {
    /// At rest: |v| at or below this fraction of the largest |v| in the trace.
    double rest_fraction_of_max_speed{0.01};
    /// The last part of the leading rest run left out, as a fraction of it: the force already rises there.
    double margin_fraction{0.2};
    /// Fewer rest samples than this (after the margin) give no tare: an InputError.
    std::size_t minimum_samples{10};
};

struct TareReport {
    double removed{0.0};     ///< the mean subtracted, in the channel's SI unit
    std::size_t samples{0};  ///< rest samples averaged
    double rest_end_s{0.0};  ///< time of the last averaged sample [s]
};

/// The leading samples at rest that a tare averages (the run at rest before the move less its last part); 0 without
/// a velocity or position channel.
std::size_t leading_rest_samples(const Trace& trace, const TareOptions& options = {});

/// Subtracts from the channel of `role` its mean over the leading rest samples and adds a finding with the value.
/// Throws InputError naming the channel when the trace has no such channel, no speed signal, or too few rest
/// samples.
TareReport tare(Trace& trace, Role role, const TareOptions& options = {});

}  // namespace feedid
