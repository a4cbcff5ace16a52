// libFuzzer target: the MQTT payload decoder of feedid watch (JSON and binary batches) and the watcher behind it.
// Any input must either decode or be refused with a one-line reason; never a crash, another exception, a sanitizer
// report, a hang or unbounded memory. What decodes must be what the decoder promises (names that a topic level and a
// history take, a sample time within the limits, finite samples of equal count), must survive the binary encoding
// unchanged, and must go through a watcher (held, fed, flushed) without an exception.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "feedid/core/terminal_text.hpp"
#include "feedid/stream/payload.hpp"
#include "feedid/stream/watcher.hpp"

namespace {

using feedid::watch::Batch;

bool valid_name(const std::string& name, const feedid::watch::PayloadLimits& limits) {
    return name.empty() || (feedid::name_problem(name, limits.max_name_bytes).empty() &&
                            name.find_first_of("/+#") == std::string::npos);
}

bool same(const Batch& a, const Batch& b) {
    return a.machine == b.machine && a.axis == b.axis && a.t0 == b.t0 && a.dt == b.dt && a.position == b.position &&
           a.drive == b.drive && a.drive_is_force == b.drive_is_force && a.force_constant == b.force_constant;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const auto payload = std::as_bytes(std::span(data, size));
    feedid::watch::PayloadLimits limits;
    limits.max_samples = 4096;
    Batch batch;
    const std::string error = feedid::watch::decode_batch(payload, batch, limits);
    if (!error.empty()) {
        // a reason in one line of valid UTF-8 (it is published as JSON and printed)
        if (error.find('\n') != std::string::npos || !feedid::is_storable_text(error)) __builtin_trap();
    } else {
        if (!valid_name(batch.machine, limits) || !valid_name(batch.axis, limits)) __builtin_trap();
        if (!(batch.dt >= limits.min_dt_s && batch.dt <= 10.0) || !std::isfinite(batch.t0)) __builtin_trap();
        if (batch.position.empty() || batch.position.size() != batch.drive.size()) __builtin_trap();
        if (batch.position.size() > limits.max_samples) __builtin_trap();
        for (std::size_t k = 0; k < batch.samples(); ++k)
            if (!std::isfinite(batch.position[k]) || !std::isfinite(batch.drive[k])) __builtin_trap();
        Batch again;
        const std::string binary = feedid::watch::encode_binary(batch);
        if (!feedid::watch::decode_batch(std::as_bytes(std::span(binary)), again, limits).empty() ||
            !same(batch, again))
            __builtin_trap();
    }
    // the watcher: small budgets, so that what it holds and admits is bounded here too
    feedid::watch::WatchOptions options;
    options.limits = limits;
    options.max_axes = 4;
    options.axes_bytes = 64u << 20;
    options.held_bytes = 1u << 20;
    options.trust_payload_names = size % 2 == 1;
    feedid::watch::Watcher watcher(options);
    for (const char* topic : {"plant/M1/X/axis", "plant/M1/X/axis", "plant", "plant/\xff/X/axis"}) {
        const std::string reason = watcher.ingest(topic, payload);
        if (!feedid::is_storable_text(reason)) __builtin_trap();
    }
    watcher.flush();
    for (const auto& [machine, axis] : watcher.take_changed()) (void)watcher.estimate_document(machine, axis).dump();
    return 0;
}
