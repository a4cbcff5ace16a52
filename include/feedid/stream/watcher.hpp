#pragma once
// The heart of `feedid watch`, without the network: messages (topic, payload) in, one online identifier per
// (machine, axis), estimate documents and completed identifications out. The MQTT service (service.hpp) feeds it from
// its queue on one thread; tests feed it directly.
//
// Names: machine and axis come from the topic ('<first level>/<machine>/<axis>/...'), which the broker's access
// control list guards; a payload that names another machine or axis is refused and counted (unless
// trust_payload_names). Names are checked (UTF-8, no control characters, a length limit) before anything is made of
// them.
//
// Time stamps keep the stream honest: a batch that starts before the end of what the axis already has is a repeat
// (a publisher resending after a reconnect, a QoS 1 redelivery) and its old samples are skipped and counted, never
// pushed twice; a batch that starts more than run_gap_s after it is a new recording. A batch that starts after a
// shorter hole is held (with the ones after it, up to reorder_s of stream) until the hole is filled: after a broker
// restart the messages of an axis may come out of order (the client library resends its unacknowledged messages
// before the publisher's replay of those the broker lost). Filled, the stream is pushed in order and the identifier
// sees what it would have seen without the restart; not filled in time (or at flush), the hole is a loss: its
// samples are counted missing, and it ends the identifier's window (flush) so that no window bridges it. An axis's
// first batches are held the same way (reorder_s of stream), since the first to arrive need not be the oldest; a
// batch from before the start that comes later still is a loss, counted missing.
//
// Memory is bounded whatever is sent: an axis is admitted only while the identifiers' memory stays within axes_bytes
// (and their count within max_axes, each window within max_window_samples); held batches take at most held_bytes in
// all, beyond which the axis that has held longest gives up its hole (counted missing), and the count is kept.

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/identify/online_identifier.hpp"
#include "feedid/identify/online_selection.hpp"
#include "feedid/stream/payload.hpp"

namespace feedid::watch {

struct WatchOptions {
    OnlineOptions online;
    /// Force constants [N/A] by "machine/axis" or by axis name alone ("X"); a payload's force_constant wins.
    std::map<std::string, double> force_constants;
    PayloadLimits limits;
    /// false: machine and axis come from the topic only, and a payload naming others is refused; true: a payload's
    /// machine and axis win over the topic's (a broker whose access control does not follow the topics)
    bool trust_payload_names{false};
    std::size_t max_axes{1'000};  ///< more (machine, axis) pairs than this are refused (a runaway publisher)
    /// The identifiers of all axes take at most this much memory [bytes] (SelectingIdentifier::memory_bytes); an axis
    /// beyond is refused. The default holds about 130 axes at 1 kHz with 2 s windows (two identifiers an axis).
    std::size_t axes_bytes{128u << 20};
    /// An axis whose window (and its filter margins) would hold more samples than this is refused (a window of 2 s
    /// at 100 kHz and its margins hold 205,000).
    std::size_t max_window_samples{250'000};
    /// Batches held after a hole, of all axes, take at most this much memory [bytes].
    std::size_t held_bytes{32u << 20};
    /// A completed identification (recorded when the service has a history): this many qualified windows since
    /// the run began (0: not by information) ...
    std::size_t run_windows{0};
    /// ... or this much stream time [s] (0: not by period) ...
    double run_period_s{0.0};
    /// ... or a pause of the stream longer than this [s] before a batch (a new recording).
    double run_gap_s{30.0};
    /// Stream time held after a hole, waiting for the batches that fill it [s]; beyond, the hole is a loss.
    double reorder_s{30.0};

    /// What is wrong ("" when nothing).
    [[nodiscard]] std::string validate() const;
};

/// One completed identification of one axis.
struct CompletedRun {
    std::string machine, axis;
    OnlineEstimate estimate;
    double t_start{0.0}, t_end{0.0};  ///< stream time of its first and past its last sample [s]
    std::size_t samples{0};
    std::size_t sequence{0};  ///< 1, 2, ... per axis
};

struct AxisCounters {
    std::size_t batches{0};
    std::size_t samples{0};            ///< pushed into the identifier
    std::size_t repeated_samples{0};   ///< skipped: their time was already covered
    std::size_t missing_samples{0};    ///< lost: holes in the stream shorter than run_gap_s, or before its start
    std::size_t late_batches{0};       ///< batches that came after later ones, into a lost hole (skipped: too late)
    std::size_t reordered_batches{0};  ///< batches held after a hole that was then filled (pushed in order)
    std::size_t recordings{0};         ///< streams after a pause longer than run_gap_s (1 for one recording)
    std::size_t runs{0};               ///< completed identifications
};

class Watcher {
public:
    explicit Watcher(WatchOptions options);

    /// One message: decodes, converts and pushes it. "" when used (or skipped as a repeat), else what is wrong, in
    /// one line; the message is then dropped and counted (malformed()). Never throws.
    std::string ingest(std::string_view topic, std::span<const std::byte> payload);
    /// Processes the samples buffered in every identifier (end of the stream, SIGTERM); every axis counts as changed.
    void flush();
    /// The completed identifications since the last call.
    std::vector<CompletedRun> take_completed_runs();
    /// (machine, axis) of the axes that received samples since the last call.
    std::vector<std::pair<std::string, std::string>> take_changed();
    /// The estimate document of an axis (null for an unknown one): a result document with identify's keys
    /// ("parameters": value, stderr) plus "kind": "watch", "machine", "axis", "information", "windows",
    /// "stream" (samples, repeats, holes, time span) and "run".
    [[nodiscard]] nlohmann::json estimate_document(const std::string& machine, const std::string& axis) const;
    /// The current estimate of an axis (nullopt for an unknown one).
    [[nodiscard]] std::optional<OnlineEstimate> estimate(const std::string& machine, const std::string& axis) const;

    [[nodiscard]] std::size_t axes() const { return axes_.size(); }
    [[nodiscard]] std::size_t messages() const { return messages_; }
    /// Messages refused (each with its reason): malformed, or refused for the reasons counted below.
    [[nodiscard]] std::size_t malformed() const { return malformed_; }
    /// Messages whose payload named another machine or axis than their topic (refused).
    [[nodiscard]] std::size_t foreign_names() const { return foreign_names_; }
    /// Messages of a new axis refused by max_axes, axes_bytes or max_window_samples.
    [[nodiscard]] std::size_t refused_axes() const { return refused_axes_; }
    /// Holes given up before their time because held batches reached held_bytes.
    [[nodiscard]] std::size_t evicted_holds() const { return evicted_holds_; }
    /// Memory of the held batches [bytes] and budgeted for the identifiers [bytes].
    [[nodiscard]] std::size_t held_bytes() const { return held_bytes_; }
    [[nodiscard]] std::size_t axes_bytes() const { return axes_bytes_; }
    [[nodiscard]] const WatchOptions& options() const { return options_; }

private:
    /// A batch held after a hole: positions [m] then forces [N] in one vector, and when it arrived.
    struct Held {
        std::vector<double> columns;
        std::uint64_t arrival{0};
    };
    struct Axis {
        std::string machine, axis;
        std::unique_ptr<SelectingIdentifier> online;  ///< the windows judged without and with the offset
        std::size_t memory{0};  ///< budgeted for it in axes_bytes_ [bytes]
        double dt{0.0};
        bool started{false};                           ///< false: its first batches are held (see above)
        bool changed{false};                           ///< received samples since the last take_changed
        double first_t{0.0};                           ///< time of its first pushed sample [s]
        double next_t{0.0};                            ///< time of the next expected sample [s]
        double run_start_t{0.0};                       ///< [s]
        double hole_start{0.0}, hole_end{0.0};         ///< the last hole in the stream [s]
        std::vector<std::pair<double, double>> holes;  ///< the first 16 holes: [next expected, next received) [s]
        std::size_t run_samples{0};
        std::size_t checked_windows{0};  ///< window count at the last run check
        AxisCounters counters;
        /// Batches after a hole, by t0, waiting for it to be filled
        std::map<double, Held> held;
        std::size_t held_samples{0};
        std::size_t held_bytes{0};
        std::uint64_t holding_since{0};  ///< when held last became non-empty (its place in holding_)
        std::uint64_t fed_arrival{0};    ///< the latest arrival among the batches pushed
    };
    std::string admit(const std::string& machine, const std::string& axis, double dt);
    std::string names_of(std::string_view topic, std::string& machine, std::string& axis);
    std::string push(Axis& axis, const Batch& batch);
    /// Pushes samples that start at t0, at or before the axis's next expected sample (the part already pushed
    /// skipped and counted as repeated; a part from before the stream's start or in a lost hole: late).
    void feed(Axis& axis, double t0, std::span<const double> position, std::span<const double> force,
              std::uint64_t arrival);
    /// Feeds the held batches that have become contiguous, in order.
    void feed_held(Axis& axis);
    void hold(Axis& axis, double t0, std::span<const double> position, std::span<const double> force);
    /// Starts an axis whose first batches were held: from the earliest of them.
    void start(Axis& axis);
    /// Gives up holes whose reorder_s has passed, then the longest-held holes while held_bytes is exceeded.
    void enforce_holding_limits(Axis& axis);
    /// The first held batch, taken out (its memory counted off).
    std::pair<double, Held> take_first_held(Axis& axis);
    void release_held(Axis& axis);
    /// Gives up on the hole before the first held batch: counted missing, the identifier's window ended there.
    void declare_hole(Axis& axis);
    void complete_run(Axis& axis);
    void mark_changed(Axis& axis);
    [[nodiscard]] double force_constant(const Batch& batch, const std::string& machine, const std::string& axis) const;

    WatchOptions options_;
    std::unordered_map<std::string, std::unique_ptr<Axis>> axes_;
    std::vector<Axis*> changed_;
    std::vector<CompletedRun> completed_;
    std::set<std::pair<std::uint64_t, Axis*>> holding_;  ///< axes with held batches, the longest-held first
    Batch batch_;  ///< the decoded message (storage reused)
    std::vector<double> force_, times_;
    std::size_t messages_{0}, malformed_{0}, foreign_names_{0}, refused_axes_{0}, evicted_holds_{0};
    std::size_t held_bytes_{0}, axes_bytes_{0};
    std::uint64_t arrivals_{0};
};

/// The result document of an online estimate as feedid scan writes it (scan_document: identify's keys, windows,
/// information), "kind": "watch"; symmetric model, the offset when the options estimate it. A value the identifier
/// gives without a standard error is null, with a diagnostic.
nlohmann::json online_result_document(const OnlineEstimate& estimate, const OnlineOptions& options,
                                      const std::string& source, double duration_s);

}  // namespace feedid::watch
