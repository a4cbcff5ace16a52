#!/usr/bin/python3
"""Writes tests/numeric/signal_reference.hpp: SciPy's answers for the preprocessing primitives of feedid/numeric/signal.hpp
(Butterworth and Chebyshev I design, zero-phase filtering, central differences, Savitzky-Golay, decimation, the noise
floor), for tests/numeric/test_signal.cpp. Not a test dependency: run it by hand after changing a case, commit both files.

    /usr/bin/python3 scripts/reference/signal_reference.py     (Debian's python3-scipy and python3-numpy)

feedid follows MATLAB's conventions, so SciPy is called the way that computes the same thing:
  - filtfilt: sosfiltfilt(sos, x, padtype="odd", padlen=3 * order, clamped to n - 1), which is MATLAB's
    filtfilt(b, a, x). SciPy's default padding is 3 * (2 * sections + 1), less one if there are first-order sections,
    and the transients of that difference reach far into a 200-sample signal, so the padding is passed explicitly.
    SciPy accepts a padding up to n - 1, as feedid clamps it; MATLAB refuses a signal that short.
  - decimate: feedid keeps every factor-th sample ending on the last one (MATLAB); scipy.signal.decimate keeps x[::q]
    and filters with SciPy's default padding (27 instead of 24 for the order-8 filter). The reference is therefore
    sosfiltfilt(cheby1(8, 0.05, 0.8 / q), padlen=24) at feedid's indices; below it is checked that
    scipy.signal.decimate is exactly sosfiltfilt(padlen=27)[::q], so that padding and indices are all that differ.
  - savitzky_golay: savgol_filter(mode="interp") (the end windows' polynomial evaluated at the end samples).
  - central_difference: numpy.gradient(edge_order=1).
  - noise_floor: median_abs_deviation(diff(x), scale="normal") / sqrt(2); feedid rounds the constant to 1.4826 and takes
    the upper of the two middle values as the median of an even count.
"""
import math
import os
import shutil
import subprocess

import numpy as np
import scipy
import scipy.signal as signal
import scipy.stats as stats

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "data", "signal_reference.hpp")

SAMPLE_TIME = 1e-3  # [s]
SAMPLE_RATE = 1.0 / SAMPLE_TIME  # [Hz]


def drive_trace(n):
    """A drive-like trace: offset and ramp (the ends are not at rest), a slow and a fast sine, white noise."""
    t = np.arange(n) * SAMPLE_TIME
    noise = np.random.default_rng(20240611).normal(0.0, 0.05, n)
    return 0.3 + 2.0 * t + np.sin(2 * np.pi * 5.0 * t) + 0.4 * np.sin(2 * np.pi * 120.0 * t + 0.7) + noise


def feedid_padding(sos, n):
    """MATLAB's 3 * filtord: the degree of the cascade's transfer function."""
    b, a = signal.sos2tf(sos)
    order = max(len(np.trim_zeros(b, "b")), len(np.trim_zeros(a, "b"))) - 1
    return min(max(1, 3 * order), n - 1)


def filtfilt(sos, x):
    return signal.sosfiltfilt(sos, x, padtype="odd", padlen=feedid_padding(sos, len(x)))


def kept_indices(n, factor):
    """MATLAB's decimate: every factor-th sample, ending on the last one."""
    return np.arange(n)[::-1][::factor][::-1]


def decimated(x, factor):
    sos = signal.cheby1(8, 0.05, 0.8 / factor, output="sos")
    return filtfilt(sos, x)[kept_indices(len(x), factor)]


x = drive_trace(200)

# Designs: (order, ripple [dB] or None for Butterworth, cut-off [Hz], sample rate [Hz]); odd orders have a first-order
# section. The Chebyshev ones at fs = 1 are those decimate(x, 2), (x, 4), (x, 10) use.
butterworth_designs = [(2, None, 50.0, SAMPLE_RATE), (4, None, 100.0, SAMPLE_RATE), (5, None, 30.0, SAMPLE_RATE),
                       (8, None, 300.0, SAMPLE_RATE)]
chebyshev_designs = [(8, 0.05, 0.8 * 0.5 / 2, 1.0), (8, 0.05, 0.8 * 0.5 / 4, 1.0), (8, 0.05, 0.8 * 0.5 / 10, 1.0),
                     (5, 0.5, 100.0, SAMPLE_RATE)]


def design(order, ripple_db, cutoff_hz, sample_rate_hz):
    if ripple_db is None:
        return signal.butter(order, cutoff_hz, output="sos", fs=sample_rate_hz)
    return signal.cheby1(order, ripple_db, cutoff_hz, output="sos", fs=sample_rate_hz)


designs = [(d, design(*d)) for d in butterworth_designs + chebyshev_designs]

# Zero-phase filtering: the 200-sample signal through a 4th- and a 5th-order Butterworth and decimate's Chebyshev, and
# a 10-sample signal shorter than the padding (clamped to n - 1).
filtfilt_cases = []
for (order, ripple_db, cutoff_hz, sample_rate_hz), samples in [((4, None, 100.0, SAMPLE_RATE), 200),
                                                               ((5, None, 30.0, SAMPLE_RATE), 200),
                                                               ((8, 0.05, 0.1, 1.0), 200),
                                                               ((4, None, 100.0, SAMPLE_RATE), 10)]:
    sos = design(order, ripple_db, cutoff_hz, sample_rate_hz)
    signal_in = x[:samples]
    # the same as MATLAB's filtfilt(b, a, x) on the transfer function (but for the rounding of its coefficients)
    b, a = signal.sos2tf(sos)
    by_transfer_function = signal.filtfilt(b, a, signal_in, padtype="odd", padlen=feedid_padding(sos, samples))
    assert np.max(np.abs(by_transfer_function - filtfilt(sos, signal_in))) < 1e-9 * np.max(np.abs(signal_in))
    filtfilt_cases.append(((order, ripple_db, cutoff_hz, sample_rate_hz), sos, samples, filtfilt(sos, signal_in),
                           feedid_padding(sos, samples)))

derivative = np.gradient(x, SAMPLE_TIME, edge_order=1)

savgol_cases = []
for window, polynomial, deriv in [(11, 3, 0), (11, 3, 1), (11, 3, 2), (21, 4, 1), (7, 2, 2)]:
    coefficients = signal.savgol_coeffs(window, polynomial, deriv=deriv, delta=SAMPLE_TIME, use="dot")
    filtered = signal.savgol_filter(x, window, polynomial, deriv=deriv, delta=SAMPLE_TIME, mode="interp")
    savgol_cases.append((window, polynomial, deriv, coefficients, filtered))

decimate_cases = [(factor, decimated(x, factor)) for factor in (2, 4, 5, 10)]
# scipy.signal.decimate is the same filter with two other conventions: it keeps x[::q] and pads with SciPy's default
# (27 samples). With 201 samples (201 = 1 mod 2, 4, 5, 10) both keep the same samples and only the padding is left:
# checked here bit for bit, and how far it moves the result printed (not a small difference: the slow Chebyshev poles
# carry it through the whole signal).
x201 = drive_trace(201)
for factor in (2, 4, 5, 10):
    sos = signal.cheby1(8, 0.05, 0.8 / factor, output="sos")
    assert np.array_equal(kept_indices(201, factor), np.arange(201)[::factor])
    scipy_decimated = signal.decimate(x201, factor, ftype="iir")
    assert np.array_equal(scipy_decimated, signal.sosfiltfilt(sos, x201, padlen=27)[::factor])
    moved = np.max(np.abs(scipy_decimated - decimated(x201, factor))) / np.max(np.abs(scipy_decimated))
    print(f"scipy.signal.decimate(x, {factor}) differs from feedid's by {moved:.1e} of the signal (padding 27, not 24)")

index_cases = [(0, 3), (1, 4), (3, 4), (7, 3), (8, 3), (9, 3), (10, 1), (200, 4), (201, 4), (203, 10)]

noise_floor_200 = stats.median_abs_deviation(np.diff(x), scale="normal") / math.sqrt(2.0)
noise_floor_200_rounded = 1.4826 * stats.median_abs_deviation(np.diff(x)) / math.sqrt(2.0)


# ---- The header: constexpr arrays (no static constructors), the cases viewing them through spans ----------------------


def number(v):
    return repr(float(v))  # the shortest text that reads back as the same double


def array(name, values, type_name="double", text=number):
    items = ", ".join(text(v) for v in values)
    return f"inline constexpr std::array<{type_name}, {len(values)}> {name}{{{items}}};"


def sections_array(name, sos):
    rows = ", ".join("{" + ", ".join(number(c) for c in row) + "}" for row in sos)
    return f"inline constexpr std::array<std::array<double, 6>, {len(sos)}> {name}{{{{{rows}}}}};"


def design_literal(d, sos_name):
    order, ripple_db, cutoff_hz, sample_rate_hz = d
    return f"{{{order}, {number(ripple_db or 0.0)}, {number(cutoff_hz)}, {number(sample_rate_hz)}, {sos_name}}}"


out = [f"""#pragma once
// Generated by scripts/reference/signal_reference.py (SciPy {scipy.__version__}, NumPy {np.__version__}); do not edit.
// SciPy's answers for the primitives of feedid/numeric/signal.hpp, called with feedid's conventions (see the script).

#include <array>
#include <cstddef>
#include <span>

namespace feedid::signal_reference {{

using Section = std::array<double, 6>;  // b0 b1 b2 a0 a1 a2

/// A filter design; ripple_db 0 for Butterworth.
struct Design {{
    int order;
    double ripple_db;                 // [dB]
    double cutoff_hz;                 // [Hz]
    double sample_rate_hz;            // [Hz]
    std::span<const Section> sos;     // scipy.signal.butter / cheby1(output="sos")
}};

/// sosfiltfilt(sos, signal[:samples], padtype="odd", padlen=padding)
struct FiltfiltCase {{
    Design design;
    std::size_t samples;              // the first `samples` of `signal`
    std::size_t padding;              // reflected samples at each end
    std::span<const double> filtered;
}};

struct SavitzkyGolayCase {{
    int window;
    int polynomial;
    int derivative;
    std::span<const double> coefficients;  // savgol_coeffs(use="dot", delta=sample_time)
    std::span<const double> filtered;      // savgol_filter(signal, mode="interp", delta=sample_time)
}};

struct DecimateCase {{
    int factor;
    std::span<const double> decimated;
}};

/// numpy.arange(samples)[::-1][::factor][::-1]: every factor-th sample, ending on the last
struct IndicesCase {{
    std::size_t samples;
    int factor;
    std::span<const std::size_t> indices;
}};

//! Time between samples [s]
inline constexpr double sample_time = {number(SAMPLE_TIME)};

/// 200 samples: offset, ramp, 5 Hz and 120 Hz sines and white noise (sigma 0.05) at 1 kHz.
{array("signal", x)}

"""]

design_names = []
for i, (d, sos) in enumerate(designs):
    design_names.append(f"design_{i}_sos")
    out.append(sections_array(design_names[-1], sos))
out.append(f"inline constexpr std::array<Design, {len(designs)}> designs{{{{")
out.append(",\n".join(design_literal(d, name) for (d, _), name in zip(designs, design_names)))
out.append("}};\n")

literals = []
for i, (d, sos, samples, filtered, padding) in enumerate(filtfilt_cases):
    out.append(sections_array(f"filtfilt_{i}_sos", sos))
    out.append(array(f"filtfilt_{i}_filtered", filtered))
    literals.append(f"{{{design_literal(d, f'filtfilt_{i}_sos')}, {samples}, {padding}, filtfilt_{i}_filtered}}")
out.append(f"inline constexpr std::array<FiltfiltCase, {len(literals)}> filtfilt_cases{{{{")
out.append(",\n".join(literals))
out.append("}};\n")

out.append("/// numpy.gradient(signal, sample_time, edge_order=1)")
out.append(array("central_difference", derivative) + "\n")

literals = []
for i, (window, polynomial, deriv, coefficients, filtered) in enumerate(savgol_cases):
    out.append(array(f"savitzky_golay_{i}_coefficients", coefficients))
    out.append(array(f"savitzky_golay_{i}_filtered", filtered))
    literals.append(f"{{{window}, {polynomial}, {deriv}, savitzky_golay_{i}_coefficients, savitzky_golay_{i}_filtered}}")
out.append(f"inline constexpr std::array<SavitzkyGolayCase, {len(literals)}> savitzky_golay_cases{{{{")
out.append(",\n".join(literals))
out.append("}};\n")

literals = []
for factor, values in decimate_cases:
    out.append(array(f"decimate_by_{factor}", values))
    literals.append(f"{{{factor}, decimate_by_{factor}}}")
out.append("/// sosfiltfilt(cheby1(8, 0.05, 0.8 / factor, output=\"sos\"), signal, padlen=24) at the kept indices")
out.append(f"inline constexpr std::array<DecimateCase, {len(literals)}> decimate_cases{{{{")
out.append(",\n".join(literals))
out.append("}};\n")

literals = []
for samples, factor in index_cases:
    name = f"indices_{samples}_by_{factor}"
    out.append(array(name, kept_indices(samples, factor), "std::size_t", str))
    literals.append(f"{{{samples}, {factor}, {name}}}")
out.append(f"inline constexpr std::array<IndicesCase, {len(literals)}> index_cases{{{{")
out.append(",\n".join(literals))
out.append("}};\n")

out.append(f"""/// median_abs_deviation(diff(signal), scale="normal") / sqrt(2); 199 differences, so one middle value
inline constexpr double noise_floor = {number(noise_floor_200)};
/// the same with feedid's constant 1.4826 for 1 / Phi^-1(3/4) = 1.482602218505602
inline constexpr double noise_floor_rounded_constant = {number(noise_floor_200_rounded)};

}}  // namespace feedid::signal_reference""")

with open(OUT, "w") as f:
    f.write("\n".join(out) + "\n")
# in the repository's layout (.clang-format), so that a regenerated file differs only where the numbers do
if shutil.which("clang-format"):
    subprocess.run(["clang-format", "-i", OUT], check=True)
print(f"wrote {os.path.normpath(OUT)}")
