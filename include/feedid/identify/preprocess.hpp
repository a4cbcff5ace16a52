#pragma once
// Stage 1 of identify: from a trace's position and drive force to velocity and acceleration on the samples that are
// analysed (the paper's section 3: x' and x'' by differentiation of the measured position). Filter, differentiate,
// trim the filter's edges, decimate.

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "feedid/core/trace.hpp"

namespace feedid {

/// The index of an analysed sample (into the Derivatives' columns). 32 bits: the selection's lists of them are the
/// largest of identify's working memory after the columns themselves, 4 bytes per listed sample instead of 8;
/// preprocess() refuses a window of more samples than it can count (max_analysed_samples).
using SampleIndex = std::uint32_t;
using SampleIndices = std::vector<SampleIndex>;
inline constexpr std::size_t max_analysed_samples = std::numeric_limits<SampleIndex>::max();

enum class Differentiation { central, butterworth, savitzky_golay };

/// Where x' comes from: the position (differentiated), or a logged velocity channel (filtered like the position
/// would be; x'' is its derivative). automatic: the logged velocity when the trace has no position, or when the
/// position is too coarse for its derivative (below).
enum class VelocitySource { automatic, position, logged };

struct PreprocessOptions {
    Differentiation differentiation{Differentiation::butterworth};
    VelocitySource velocity_source{VelocitySource::automatic};
    int filter_order{4};                      ///< Butterworth order
    /// [Hz]; default min(max_default_cutoff_hz, default_cutoff_fraction*fs), fs the position signal's native rate
    /// (1 / its native interval: a position held over k samples of a finer grid has 1/k of the grid's rate)
    std::optional<double> cutoff_hz;
    int savitzky_golay_window{0};             ///< [samples], odd; 0 = the odd count spanning savitzky_golay_span_s
    int savitzky_golay_order{3};              ///< polynomial order
    int decimation{0};                        ///< keep every N-th sample after the anti-alias filter; 0 or 1 = none
    std::optional<std::size_t> edge_samples;  ///< dropped at each end; default from the filter (below)
    std::optional<double> from_s;             ///< analysis window start [s]
    std::optional<double> to_s;               ///< analysis window end [s]

    /// Default cut-off ceiling [Hz]: the EMPS/IDIM practice (Janot, Gautier, Brunot 2019 filter position at 100 Hz
    /// for a 1 kHz log before differentiating twice).
    double max_default_cutoff_hz{100.0};
    /// Default cut-off as a fraction of the sample rate (fs/10 keeps the filter well inside the Nyquist band).
    double default_cutoff_fraction{0.1};
    /// Default edge trim after the Butterworth filter, in periods of the cut-off frequency: the forward-backward
    /// filter's start-up transient has decayed by then (EMPS's reference trims 49 samples at 1 kHz / 100 Hz).
    double filter_settling_periods{2.5};
    /// Default Savitzky-Golay window span [s].
    double savitzky_golay_span_s{0.02};
    /// Fewer samples than this in the window (beyond the trimmed edges) cannot identify anything.
    std::size_t minimum_samples{20};
    /// automatic velocity source: a logged velocity replaces the position's derivative when the position's
    /// quantisation step exceeds this fraction of the travel per sample at the typical speed (the 95th percentile of
    /// the logged |v|): the differentiated position would then carry more than this relative quantisation error.
    double coarse_position_fraction{0.1};
    /// A time step longer than this many sample times is a gap (samples the recorder dropped): the stretches on
    /// either side are filtered and differentiated apart (regular steps lie within half a sample time, see TimeBase).
    double gap_factor{1.5};
};

/// What preprocess() did: the values it used, which may differ from the options given (defaults resolved).
struct PreprocessReport {
    std::string differentiation;  ///< "central", "butterworth", "savitzky-golay"
    int filter_order{0};          ///< as given (used only by the Butterworth)
    double cutoff_hz{0.0};        ///< the cut-off used [Hz] (resolved default; reported for every method)
    int decimation{1};            ///< the factor used (1 = none)
    std::size_t edge_samples{0};  ///< the edge trim used, at each end
    std::string velocity_source;  ///< "position" (differentiated) or "velocity" (the logged velocity channel)
    int savitzky_golay_window{0};  ///< [samples], when the Savitzky-Golay differentiation was used
    int savitzky_golay_order{0};
};

/// Velocity, acceleration and force on the analysed samples (after the window, the edge trim and the decimation),
/// all the same length.
struct Derivatives {
    PreprocessReport used;
    bool rotary{false};
    std::string source;            ///< the trace's path, for messages
    std::size_t total{0};          ///< samples in the trace
    std::size_t window{0};         ///< samples inside --from/--to and the edge trim (before decimation)
    double sample_time_s{0.0};     ///< of the trace (before decimation) [s]
    double velocity_noise{0.0};    ///< noise floor of the velocity at the full rate [m/s]
    double position_quantum{0.0};  ///< smallest step of the position signal (its resolution) [m]; 0 without one
    double travel{0.0};            ///< largest minus smallest position in the window (integrated velocity) [m]
    /// The logged velocity and the force over the whole analysis window, unfiltered and untrimmed (empty when x'
    /// comes from the position): steady-speed samples need no filter, so they lose no edge to it [m/s], [N].
    std::vector<double> logged_velocity;
    std::vector<double> logged_force;

    std::vector<double> time;          ///< [s]
    std::vector<double> velocity;      ///< x' [m/s]
    std::vector<double> acceleration;  ///< x'' [m/s^2]
    std::vector<double> force;         ///< F_d [N], through the same low-pass as the position
    /// The commanded velocity (the reference position's derivative, or the velocity command) [m/s]; empty when the
    /// trace has neither. Selection tells a stuck axis from a commanded stop by it.
    std::vector<double> reference_velocity;
    /// The full-rate velocity and acceleration when decimating (empty otherwise): regressor columns are formed at the
    /// full rate and decimated afterwards (IDIM practice: sgn(x') goes through the anti-alias filter like every
    /// column).
    std::vector<double> full_rate_velocity;
    std::vector<double> full_rate_acceleration;

    /// Where each stretch between time-stamp gaps starts in the columns above (the first is 0); the columns are
    /// filtered, differentiated and decimated stretch by stretch. full_rate_segment_starts: the same in the
    /// full-rate columns when decimating.
    std::vector<std::size_t> segment_starts;
    std::vector<std::size_t> full_rate_segment_starts;
    /// Per analysed sample, 1 where it cannot be used: its filtered force reaches a sample where the drive signal
    /// sits at its limit (clipped or saturated). Empty when every sample is usable.
    std::vector<char> unusable;
    /// Over how many analysed samples the low-pass correlates neighbours: the cut-off's period in samples (the
    /// Savitzky-Golay window; 5 for central differences of central differences), after decimation. Residuals of a
    /// fit on these columns are correlated over about this many samples (least_squares.hpp).
    std::size_t correlation_samples{1};
    std::size_t clipped_samples{0};       ///< drive-signal samples at a limit (runs at the extreme)
    std::array<double, 2> clip_levels{};  ///< the drive force's smallest and largest value [N] when clipped

    /// The position signal's native interval, which the rate-dependent defaults come from [s].
    double position_interval_s{0.0};
    /// What the stage chose and why, where a user would not expect it (a position held over several samples).
    std::vector<std::string> notes;

    /// Why nothing can be identified from this trace ("" when the stage succeeded).
    std::string failure;
    [[nodiscard]] bool failed() const { return !failure.empty(); }
    [[nodiscard]] std::size_t size() const { return velocity.size(); }
    [[nodiscard]] bool velocity_from_position() const { return used.velocity_source == "position"; }
};

/// Differentiates the trace's position (or filters and differentiates its logged velocity, see VelocitySource) and
/// lines up `force` (the drive force, one value per trace sample) with it. Throws InputError for impossible options (a
/// cut-off at or above Nyquist) and for a trace with neither position nor velocity; a trace too short or without
/// motion comes back with `failure` set.
Derivatives preprocess(const Trace& trace, std::span<const double> force, const PreprocessOptions& options);

/// The low-pass the drive force went through in preprocess(), applied to a signal given on the full-rate analysed
/// samples (d.full_rate_velocity's when decimating, else d.velocity's), stretch by stretch, then decimated as the
/// regressor columns are. A nonlinear function of x' (sgn x', a friction curve) evaluated on the filtered x' is not
/// the filtered function: through this it becomes comparable with the filtered force (IDIM's parallel filtering
/// filters every column of the regressor, not only the force).
std::vector<double> filter_like_force(std::span<const double> full_rate, const Derivatives& d);
/// The same on a column it may overwrite, unless decimating: filtered in its own storage (no second column when its
/// capacity is at least filter_like_force_capacity()), a trace with gaps stretch by stretch through a workspace of one
/// stretch.
std::vector<double> filter_like_force(std::vector<double>&& full_rate, const Derivatives& d);
/// The capacity a full-rate column of n samples needs for filter_like_force() to filter it in its own storage.
std::size_t filter_like_force_capacity(const Derivatives& d, std::size_t n);

/// decimate() stretch by stretch, divided by the filter's gain at 0 Hz (decimation_dc_gain: a constant stays what it
/// was): `starts` are where the stretches begin in `values` (the first 0).
std::vector<double> decimate_segments(std::span<const double> values, std::span<const std::size_t> starts, int factor);

/// Smallest step the position signal takes (its quantisation), ignoring round-off: the 1st percentile of the nonzero
/// sample-to-sample steps.
double position_quantum(std::span<const double> position);

}  // namespace feedid
