#pragma once
// The payloads `feedid watch` reads and `feedid publish` writes: one batch of samples of one axis, as JSON or as a
// little-endian binary record with the same fields. Units are converted once, here, with feedid's unit parser
// (units.hpp); what comes out is SI: t0, dt [s], position [m], current [A] or force [N], force constant [N/A].
//
// JSON (README, "feedid watch"):
//   {"machine": "M1", "axis": "X", "t0": 12.5, "dt": 0.001, "position": [...], "current": [...],
//    "units": {"position": "mm", "current": "A", "time": "s"}, "force_constant": 52.0}
// machine, axis, force_constant and units.time ("s" when absent) are optional; exactly one of current / force;
// every other key is an error. Names are 1 to max_name_bytes of UTF-8 without control characters, '/', '+' or '#';
// dt lies in [min_dt_s, 10 s].
//
// Binary (all little-endian; offsets in bytes):
//   0 magic "FDIB" | 4 u16 version (1) | 6 u8 channels (2) | 7 u8 flags (bit 0: force constant given)
//   8 u32 samples | 12 u8 machine length | 13 u8 axis length | 14 u16 reserved (0)
//   16 f64 t0 [s] | 24 f64 dt [s] | 32 f64 force constant [N/A] (NaN when not given)
//   40 per channel: u8 role (1 position, 2 current, 3 force), u8 unit code (binary_unit_codes)
//   then the machine and axis names (UTF-8, no terminator), then one f64 column per channel, in channel order.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace feedid::watch {

/// One batch of one axis, in SI.
struct Batch {
    std::string machine;  ///< from the payload ("" when it names none: the topic names it)
    std::string axis;
    double t0{0.0};                ///< time of the first sample [s]
    double dt{0.0};                ///< sample time [s]
    std::vector<double> position;  ///< [m]
    std::vector<double> drive;     ///< current [A] or force [N], as drive_is_force says
    bool drive_is_force{false};
    std::optional<double> force_constant;  ///< [N/A], when the payload gives one

    [[nodiscard]] std::size_t samples() const { return position.size(); }
};

struct PayloadLimits {
    std::size_t max_samples{1'000'000};  ///< per message and channel
    std::size_t max_name_bytes{64};      ///< machine and axis names
    /// [s] the shortest sample time taken (100 kHz: beyond a feed drive's current loop); a shorter one is refused
    double min_dt_s{1e-5};
};

/// The unit codes of the binary format and the unit each stands for.
inline constexpr std::pair<std::uint8_t, std::string_view> binary_unit_codes[] = {
    {1, "m"}, {2, "mm"}, {3, "um"}, {4, "in"}, {16, "A"}, {17, "mA"}, {32, "N"}, {33, "kN"},
};
/// The code of a unit string (nullopt when the binary format has none for it).
std::optional<std::uint8_t> binary_unit_code(std::string_view unit);

inline constexpr std::uint16_t binary_version = 1;
inline constexpr char binary_magic[4] = {'F', 'D', 'I', 'B'};

/// Decodes a payload (binary when it starts with the magic, JSON otherwise) into `batch`, reusing its storage.
/// Returns "" on success, else what is wrong in one line of valid UTF-8 ("position[17] is not a finite number",
/// "unknown key 'curent'", "units.position: 'furlong' is not a length unit"); never throws.
std::string decode_batch(std::span<const std::byte> payload, Batch& batch, const PayloadLimits& limits = {});

/// JSON payload of a batch in SI units (position in m, current in A or force in N).
std::string encode_json(const Batch& batch);
/// Binary payload of a batch in SI units.
std::string encode_binary(const Batch& batch);

/// Machine and axis from a data topic 'plant/<machine>/<axis>/...': its second and third levels. nullopt when the
/// topic has fewer than three levels or an empty one there.
std::optional<std::pair<std::string, std::string>> machine_axis_of_topic(std::string_view topic);

}  // namespace feedid::watch
