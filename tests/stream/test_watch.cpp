// feedid watch without the network (issue 16): the payload formats (JSON and binary, units converted once), the
// malformed messages each refused with a reason while the others go on, and the routing of interleaved messages of
// several machines and axes to one online identifier each, which must give exactly what the identifier gives when
// fed the axis's samples directly, repeats (a publisher resending after a reconnect) included; batches out of order
// held and put back in order; a hole nobody fills counted missing, ending the identifier's window.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include <fmt/core.h>
#include <gtest/gtest.h>

#include "feedid/core/error.hpp"
#include "feedid/core/terminal_text.hpp"
#include "feedid/stream/payload.hpp"
#include "feedid/stream/run_spool.hpp"
#include "feedid/stream/watcher.hpp"
#include "production_traces.hpp"
#include "testing.hpp"

namespace feedid::watch {
namespace {

std::span<const std::byte> bytes(const std::string& text) {
    return std::as_bytes(std::span(text));
}

Batch small_batch() {
    Batch b;
    b.machine = "M1";
    b.axis = "X";
    b.t0 = 12.5;
    b.dt = 1e-3;
    b.position = {-0.1, -0.0999875, -0.0999749, -0.0999623};
    b.drive = {1.5, -2.25, 3.125, 1e-7};
    b.force_constant = 52.5;
    return b;
}

/// small_batch() without names: the topic names machine and axis.
Batch anonymous_batch() {
    Batch b = small_batch();
    b.machine.clear();
    b.axis.clear();
    return b;
}

TEST(WatchPayload, JsonAndBinaryRoundTripExactly) {
    const Batch original = small_batch();
    for (const bool binary : {false, true}) {
        const std::string payload = binary ? encode_binary(original) : encode_json(original);
        Batch decoded;
        ASSERT_EQ(decode_batch(bytes(payload), decoded), "") << (binary ? "binary" : "json");
        EXPECT_EQ(decoded.machine, "M1");
        EXPECT_EQ(decoded.axis, "X");
        EXPECT_EQ(decoded.t0, original.t0);
        EXPECT_EQ(decoded.dt, original.dt);
        EXPECT_EQ(decoded.position, original.position);
        EXPECT_EQ(decoded.drive, original.drive);
        EXPECT_FALSE(decoded.drive_is_force);
        EXPECT_EQ(decoded.force_constant, original.force_constant);
    }
    // binary: 40 header + 4 channel bytes + names + 2 columns of 8-byte samples
    EXPECT_EQ(encode_binary(original).size(), 40u + 4u + 3u + 2u * 8u * original.samples());
}

TEST(WatchPayload, UnitsAreConvertedOnceToSi) {
    const std::string json = R"({"t0": 2000, "dt": 2, "position": [1.5, -3], "force": [0.25, 1],
        "units": {"position": "mm", "force": "kN", "time": "ms"}})";
    Batch b;
    ASSERT_EQ(decode_batch(bytes(json), b), "");
    EXPECT_DOUBLE_EQ(b.t0, 2.0);
    EXPECT_DOUBLE_EQ(b.dt, 0.002);
    EXPECT_DOUBLE_EQ(b.position[0], 1.5e-3);
    EXPECT_DOUBLE_EQ(b.position[1], -3e-3);
    EXPECT_TRUE(b.drive_is_force);
    EXPECT_DOUBLE_EQ(b.drive[0], 250.0);
    const std::string milliamps = R"({"t0": 0, "dt": 0.001, "position": [1], "current": [1500],
        "units": {"position": "um", "current": "mA"}})";
    ASSERT_EQ(decode_batch(bytes(milliamps), b), "");
    EXPECT_DOUBLE_EQ(b.position[0], 1e-6);
    EXPECT_DOUBLE_EQ(b.drive[0], 1.5);
}

/// Malformed payloads of every kind the issue names, and the words their message must contain.
std::vector<std::pair<std::string, std::string>> malformed_payloads() {
    const std::string units = R"("units": {"position": "m", "current": "A"})";
    std::vector<std::pair<std::string, std::string>> cases = {
        {"{\"t0\": 0, \"dt\": ", "not JSON"},
        {"[1, 2, 3]", "not a JSON object"},
        {R"({"t0": 0, "dt": 0.001, "position": [1], "current": [1], "units": {"position": "s", "current": "A"}})",
         "units.position"},
        {R"({"t0": 0, "dt": 0.001, "position": [1], "current": [1], "units": {"position": "furlong", "current": "A"}})",
         "units.position"},
        {R"({"t0": 0, "dt": 0.001, "position": [1], "current": [1], "units": {"position": "m", "current": "N"}})",
         "units.current"},
        {R"({"t0": 0, "dt": 0.001, "position": [1], "current": [1], "units": {"position": "m"}})", "units.current"},
        {R"({"t0": 0, "dt": 0.001, "position": [1], "current": [1]})", "missing key 'units'"},
        {R"({"t0": 0, "dt": 0.001, "position": ["1"], "current": [1], )" + units + "}", "position[0] is not a number"},
        {R"({"t0": 0, "dt": 0.001, "position": 1, "current": [1], )" + units + "}", "'position' is not an array"},
        {R"({"t0": "0", "dt": 0.001, "position": [1], "current": [1], )" + units + "}", "'t0' is not a number"},
        {R"({"t0": 0, "dt": 0, "position": [1], "current": [1], )" + units + "}", "dt"},
        {R"({"t0": 0, "dt": 0.001, "position": [1, 2], "current": [1], )" + units + "}", "samples"},
        {R"({"t0": 0, "dt": 0.001, "position": [1], "current": [1], "curent": [1], )" + units + "}", "unknown key"},
        {R"({"t0": 0, "dt": 0.001, "position": [1], "current": [1], "force": [1], )" + units + "}", "exactly one"},
        {R"({"t0": 0, "dt": 0.001, "position": [NaN], "current": [1], )" + units + "}", "not JSON"},
        {R"({"t0": 0, "dt": 0.001, "position": [1e400], "current": [1], )" + units + "}", "not JSON"},
        {R"({"t0": 0, "dt": 0.001, "position": [], "current": [], )" + units + "}", "no samples"},
        {R"({"t0": 0, "dt": 0.001, "position": [1], "current": [1], "machine": "a/b", )" + units + "}", "machine"},
    };
    // millimetres sent as metres: a 100 mm/s move at 1 kHz would be 100 m/s
    std::string millimetres = R"({"t0": 0, "dt": 0.001, "current": [)";
    std::string positions;
    for (int k = 0; k < 200; ++k) {
        millimetres += (k == 0 ? "" : ",") + std::string("1");
        positions += fmt::format("{}{:.1f}", k == 0 ? "" : ",", 0.1 * k);
    }
    cases.emplace_back(millimetres + "], \"position\": [" + positions + "], " + units + "}",
                       "units.position: the position moves at up to 100 m/s in 199 of 199 steps");
    // a huge array: more samples than the limit (PayloadLimits::max_samples, 1,000,000)
    std::string huge = R"({"t0": 0, "dt": 0.001, "current": [1], )" + units + R"(, "position": [0)";
    for (int k = 0; k < 1'000'000; ++k) huge += ",0";
    cases.emplace_back(huge + "]}", "more than the limit");
    // binary: NaN in a column, truncated, wrong version, unknown unit code
    Batch b = small_batch();
    b.position[2] = std::numeric_limits<double>::quiet_NaN();
    cases.emplace_back(encode_binary(b), "position[2] is not a finite number");
    const std::string good = encode_binary(small_batch());
    cases.emplace_back(good.substr(0, good.size() - 3), "its header says");
    std::string version = good;
    version[4] = 9;
    cases.emplace_back(version, "version 9");
    std::string unit = good;
    unit[41] = 99;
    cases.emplace_back(unit, "unknown unit code 99");
    return cases;
}

TEST(WatchPayload, EachMalformedMessageIsRefusedWithItsReasonAndTheOthersGoOn) {
    WatchOptions options;
    Watcher watcher(options);
    const std::string good = encode_json(small_batch());
    std::size_t refused = 0;
    for (const auto& [payload, words] : malformed_payloads()) {
        const std::string error = watcher.ingest("plant/M1/X/axis", bytes(payload));
        EXPECT_NE(error.find(words), std::string::npos) << "expected '" << words << "' in: " << error;
        ++refused;
        EXPECT_EQ(watcher.ingest("plant/M1/X/axis", bytes(good)), "");
    }
    EXPECT_EQ(watcher.malformed(), refused);
    EXPECT_EQ(watcher.messages(), 2 * refused);
    // a topic without machine and axis and a payload without them; current without a force constant
    Batch anonymous = small_batch();
    anonymous.machine.clear();
    EXPECT_NE(watcher.ingest("plant", bytes(encode_json(anonymous))).find("names no machine"), std::string::npos);
    anonymous.force_constant.reset();
    EXPECT_NE(watcher.ingest("plant/M2/X/axis", bytes(encode_json(anonymous))).find("force constant"),
              std::string::npos);
    EXPECT_EQ(watcher.malformed(), refused + 2);
}

TEST(WatchPayload, TopicLevelsNameMachineAndAxis) {
    EXPECT_EQ(machine_axis_of_topic("plant/M1/X/axis"), (std::pair<std::string, std::string>{"M1", "X"}));
    EXPECT_EQ(machine_axis_of_topic("plant/M1/X"), (std::pair<std::string, std::string>{"M1", "X"}));
    EXPECT_FALSE(machine_axis_of_topic("plant/M1"));
    EXPECT_FALSE(machine_axis_of_topic("plant//X/axis"));
}

struct AxisColumns {
    std::vector<double> t, x, current;
    double force_constant{0.0};
};

/// A production-like trace of the demo drive (tests/support/production_traces.hpp: random moves at many speeds, cutting
/// forces on some), as an NC records it: time, position, current.
AxisColumns axis_columns(std::uint64_t seed, double duration_s = 60.0) {
    testing::ProductionOptions options;
    options.duration_s = duration_s;
    const Trace trace = testing::production_synth(seed, options);
    AxisColumns c;
    const auto t = trace.column(Role::time), x = trace.column(Role::position), i = trace.column(Role::current);
    c.t.assign(t.begin(), t.end());
    c.x.assign(x.begin(), x.end());
    c.current.assign(i.begin(), i.end());
    c.force_constant = demo_spec().force_constant_N_per_A();
    return c;
}

/// The axis's samples pushed straight into an identifier, with the time stamps the watcher makes of batches of
/// `per_message` samples (t0 of the batch + i dt).
OnlineEstimate direct(const AxisColumns& c, std::size_t per_message) {
    SelectingIdentifier online({});
    const double dt = c.t[1] - c.t[0];
    std::vector<double> force(c.current.size()), t(c.t.size());
    for (std::size_t k = 0; k < force.size(); ++k) {
        force[k] = c.force_constant * c.current[k];
        t[k] = c.t[k - k % per_message] + static_cast<double>(k % per_message) * dt;
    }
    online.push(t, c.x, force);
    online.flush();
    return online.estimate();
}

TEST(WatchRouting, InterleavedMachinesAndAxesEachGiveTheDirectIdentifiersEstimateRepeatsIgnored) {
    const std::vector<std::string> axes = {"X", "Y", "Z"};
    const std::size_t machines = 2;
    std::vector<AxisColumns> columns;  // machine m, axis a: columns[3 m + a]
    for (std::uint64_t k = 0; k < 3 * machines; ++k) columns.push_back(axis_columns(k + 1));
    std::size_t n = columns[0].t.size();  // the traces end where their last move does: cut to the shortest
    for (const auto& c : columns) n = std::min(n, c.t.size());
    for (auto& c : columns) {
        c.t.resize(n);
        c.x.resize(n);
        c.current.resize(n);
    }
    Watcher watcher({});
    const std::size_t per_message = 250;
    std::size_t sent = 0;
    for (std::size_t first = 0; first < n; first += per_message) {
        for (std::size_t m = 0; m < machines; ++m) {
            for (std::size_t a = 0; a < axes.size(); ++a) {
                const std::string& axis = axes[a];
                const AxisColumns& c = columns[3 * m + a];
                Batch b;
                b.t0 = c.t[first];
                b.dt = c.t[1] - c.t[0];
                const std::size_t count = std::min(per_message, n - first);
                b.position.assign(c.x.begin() + static_cast<std::ptrdiff_t>(first),
                                  c.x.begin() + static_cast<std::ptrdiff_t>(first + count));
                b.drive.assign(c.current.begin() + static_cast<std::ptrdiff_t>(first),
                               c.current.begin() + static_cast<std::ptrdiff_t>(first + count));
                b.force_constant = c.force_constant;
                const std::string topic = "plant/M" + std::to_string(m + 1) + "/" + axis + "/axis";
                const std::string payload = (sent % 2 == 0) ? encode_binary(b) : encode_json(b);
                ASSERT_EQ(watcher.ingest(topic, bytes(payload)), "");
                if (sent % 7 == 3) {  // a repeat
                    ASSERT_EQ(watcher.ingest(topic, bytes(payload)), "");
                }
                ++sent;
            }
        }
    }
    watcher.flush();
    EXPECT_EQ(watcher.axes(), 6u);
    EXPECT_EQ(watcher.malformed(), 0u);
    std::size_t determined = 0;
    for (std::size_t m = 0; m < machines; ++m) {
        for (std::size_t a = 0; a < axes.size(); ++a) {
            const std::string& axis = axes[a];
            const OnlineEstimate expected = direct(columns[3 * m + a], per_message);
            const auto got = watcher.estimate("M" + std::to_string(m + 1), axis);
            ASSERT_TRUE(got);
            if (expected.coulomb.value) {
                ++determined;
                const AxisModel truth = demo_spec().axis;
                std::cout << "M" << m + 1 << " " << axis << ": M " << 100 * (*expected.mass.value / truth.mass - 1)
                          << " %, B " << 100 * (*expected.viscous.value / truth.friction.forward.viscous - 1)
                          << " %, F_C " << 100 * (*expected.coulomb.value / truth.friction.forward.coulomb - 1)
                          << " % (" << expected.windows.qualified() << " of " << expected.windows.total
                          << " windows)\n";
            } else {
                // no value from the identifier, none from the watcher, for the same reason
                std::cout << "M" << m + 1 << " " << axis << ": " << expected.mass_reason << "\n";
                EXPECT_EQ(got->mass_reason, expected.mass_reason);
            }
            EXPECT_EQ(got->samples, n);
            EXPECT_EQ(got->windows.by_verdict, expected.windows.by_verdict) << "M" << m + 1 << " " << axis;
            // the same numbers to the last bit; the JSON payloads carry doubles exactly (shortest round trip)
            EXPECT_EQ(got->mass.value, expected.mass.value) << "M" << m + 1 << " " << axis;
            EXPECT_EQ(got->coulomb.value, expected.coulomb.value) << "M" << m + 1 << " " << axis;
            EXPECT_EQ(got->viscous.standard_error, expected.viscous.standard_error) << "M" << m + 1 << " " << axis;
            const auto document = watcher.estimate_document("M" + std::to_string(m + 1), axis);
            EXPECT_GT(document["stream"]["repeated_samples"].get<std::size_t>(), 0u);
            EXPECT_EQ(document["windows"]["qualified"].get<std::size_t>(), expected.windows.qualified());
        }
    }
    EXPECT_GE(determined, 5u) << "the comparison needs values";
}

/// The axis's batches of `per_message` samples as the watch's messages, in the order given by `order` (indexes of
/// batches; a repeat sends one again, a missing one is lost).
void send_in_order(Watcher& watcher, const AxisColumns& c, std::size_t per_message,
                   const std::vector<std::size_t>& order) {
    for (const std::size_t k : order) {
        const std::size_t first = k * per_message;
        const std::size_t count = std::min(per_message, c.t.size() - first);
        Batch b;
        b.t0 = c.t[first];
        b.dt = c.t[1] - c.t[0];
        b.position.assign(c.x.begin() + static_cast<std::ptrdiff_t>(first),
                          c.x.begin() + static_cast<std::ptrdiff_t>(first + count));
        b.drive.assign(c.current.begin() + static_cast<std::ptrdiff_t>(first),
                       c.current.begin() + static_cast<std::ptrdiff_t>(first + count));
        b.force_constant = c.force_constant;
        ASSERT_EQ(watcher.ingest("plant/M1/X/axis", bytes(encode_binary(b))), "");
    }
}

// After a broker restart the messages of an axis come out of order: the client library resends its unacknowledged
// (newest) messages first, then the publisher replays the last seconds, among them those the broker lost. The
// watcher holds what comes after a hole until the hole is filled: the identifier sees the uninterrupted stream.
TEST(WatchRouting, BatchesAfterAHoleAreHeldUntilItIsFilledAndPushedInOrder) {
    const AxisColumns c = axis_columns(5);
    const std::size_t per_message = 250, batches = (c.t.size() + per_message - 1) / per_message;
    std::vector<std::size_t> order;
    for (std::size_t k = 0; k < 40; ++k) order.push_back(k);
    for (std::size_t k = 44; k < 47; ++k) order.push_back(k);  // resent by the library: 40 to 43 lost at the broker
    for (std::size_t k = 30; k < 47; ++k) order.push_back(k);  // the publisher's replay
    order.push_back(45);                                       // a QoS 1 redelivery
    for (std::size_t k = 47; k < batches; ++k) order.push_back(k);
    Watcher watcher({});
    send_in_order(watcher, c, per_message, order);
    watcher.flush();
    const OnlineEstimate expected = direct(c, per_message);
    const auto got = watcher.estimate("M1", "X");
    ASSERT_TRUE(got && expected.coulomb.value);
    EXPECT_EQ(got->samples, c.t.size());
    EXPECT_EQ(got->windows.by_verdict, expected.windows.by_verdict);
    EXPECT_EQ(got->mass.value, expected.mass.value);
    EXPECT_EQ(got->coulomb.value, expected.coulomb.value);
    EXPECT_EQ(got->viscous.standard_error, expected.viscous.standard_error);
    const auto stream = watcher.estimate_document("M1", "X")["stream"];
    EXPECT_EQ(stream["missing_samples"].get<std::size_t>(), 0u) << stream.dump();
    EXPECT_EQ(stream["reordered_batches"].get<std::size_t>(), 3u) << stream.dump();  // 44 to 46, after 43
    EXPECT_EQ(stream["repeated_samples"].get<std::size_t>(), (10 + 3 + 1) * per_message) << stream.dump();
    EXPECT_EQ(stream["held_samples"].get<std::size_t>(), 0u);
}

// A hole nobody fills (reorder_s of stream came after it) is a loss: its samples are counted missing and it ends the
// identifier's window, which neither bridges it nor mixes the samples on both sides of it; a batch of the hole that
// comes later still is skipped as late, never pushed out of order.
TEST(WatchRouting, AHoleNotFilledInTimeIsCountedMissingAndEndsTheWindow) {
    const AxisColumns c = axis_columns(7);
    const std::size_t per_message = 250, batches = (c.t.size() + per_message - 1) / per_message;
    std::vector<std::size_t> order;
    for (std::size_t k = 0; k < batches; ++k)
        if (k < 100 || k > 103) order.push_back(k);
    order.insert(order.begin() + 130, 101);  // 30 batches (7.5 s of stream) after the hole: too late
    WatchOptions options;
    options.reorder_s = 5.0;
    Watcher watcher(options);
    send_in_order(watcher, c, per_message, order);
    watcher.flush();
    // the identifier on the samples before the hole, ended there, then on those after it
    SelectingIdentifier online({});
    const double dt = c.t[1] - c.t[0];
    for (std::size_t k = 0; k < c.t.size(); ++k) {
        if (k == 104 * per_message) online.flush();
        if (k >= 100 * per_message && k < 104 * per_message) continue;
        const double t = c.t[k - k % per_message] + static_cast<double>(k % per_message) * dt;
        online.push(t, c.x[k], c.force_constant * c.current[k]);
    }
    online.flush();
    const OnlineEstimate expected = online.estimate();
    const auto got = watcher.estimate("M1", "X");
    // a trace whose windows agree (seed 7: values on both sides of the hole; some seeds' short traces give none)
    ASSERT_TRUE(got && expected.coulomb.value) << expected.mass_reason;
    EXPECT_EQ(got->samples, c.t.size() - 4 * per_message);
    EXPECT_EQ(got->windows.by_verdict, expected.windows.by_verdict);
    EXPECT_EQ(got->windows.count(WindowVerdict::gap), 0u);  // no window across the hole
    EXPECT_EQ(got->mass.value, expected.mass.value);
    EXPECT_EQ(got->coulomb.value, expected.coulomb.value);
    const auto stream = watcher.estimate_document("M1", "X")["stream"];
    EXPECT_EQ(stream["missing_samples"].get<std::size_t>(), 4 * per_message) << stream.dump();
    EXPECT_EQ(stream["late_batches"].get<std::size_t>(), 1u) << stream.dump();
    ASSERT_EQ(stream["holes_s"].size(), 1u);
    EXPECT_DOUBLE_EQ(stream["holes_s"][0][0].get<double>(), c.t[100 * per_message]);
    EXPECT_DOUBLE_EQ(stream["holes_s"][0][1].get<double>(), c.t[104 * per_message]);
}

TEST(WatchRouting, APauseLongerThanTheGapCompletesARun) {
    WatchOptions options;
    options.run_gap_s = 30.0;
    Watcher watcher(options);
    const AxisColumns c = axis_columns(3);
    for (const double offset : {0.0, 3600.0, 7200.0}) {
        Batch b;
        b.t0 = c.t[0] + offset;
        b.dt = c.t[1] - c.t[0];
        b.position = c.x;
        b.drive = c.current;
        b.force_constant = c.force_constant;
        ASSERT_EQ(watcher.ingest("plant/M1/X/axis", bytes(encode_binary(b))), "");
    }
    const auto runs = watcher.take_completed_runs();
    ASSERT_EQ(runs.size(), 2u);  // the third recording is still open
    const OnlineEstimate expected = direct(c, c.t.size());
    for (const auto& run : runs) {
        EXPECT_EQ(run.samples, c.t.size());
        ASSERT_TRUE(run.estimate.coulomb.value && expected.coulomb.value);
        // each run starts from scratch (time stamps shifted by an hour round differently: not to the last bit)
        EXPECT_NEAR(*run.estimate.coulomb.value, *expected.coulomb.value, 1e-9 * *expected.coulomb.value);
    }
    EXPECT_EQ(runs[1].sequence, 2u);
}

// A message that names an axis with bytes a topic level, a terminal or a history cannot take is refused with its
// reason, before anything is made of it; the service goes on (once, one such binary batch stopped it).
TEST(WatchHostile, NamesThatAreNotUtf8OrHoldControlsAreRefusedAndTheWatcherGoesOn) {
    WatchOptions options;
    options.trust_payload_names = true;
    Watcher watcher(options);
    const std::string good = encode_binary(small_batch());
    for (const std::string& name : {std::string("M\xff"), std::string("M\0X", 3), std::string("M\x1b[2J"),
                                    std::string("evil\xe2\x80\xae"), std::string(65, 'M')}) {
        Batch b = small_batch();
        b.machine = name;
        std::vector<std::string> payloads = {encode_binary(b)};
        if (is_storable_text(name)) payloads.push_back(encode_json(b));  // JSON cannot carry bytes that are not UTF-8
        for (const std::string& payload : payloads) {
            const std::string error = watcher.ingest("plant/M1/X/axis", bytes(payload));
            EXPECT_NE(error.find("'machine' is not a name"), std::string::npos) << error;
            EXPECT_TRUE(is_storable_text(error)) << error;
        }
        // from the topic
        const std::string error = watcher.ingest("plant/" + name + "/X/axis", bytes(encode_binary(anonymous_batch())));
        EXPECT_NE(error.find("refused"), std::string::npos) << error;
        EXPECT_TRUE(is_storable_text(error)) << error;
        EXPECT_EQ(watcher.ingest("plant/M1/X/axis", bytes(good)), "");
    }
    EXPECT_EQ(watcher.axes(), 1u);
    const auto document = watcher.estimate_document("M1", "X");
    EXPECT_NO_THROW((void)document.dump());
}

// Machine and axis come from the topic, which the broker's ACL guards: a payload that names another is refused and
// counted; with trust_payload_names the payload's names win, as before.
TEST(WatchHostile, APayloadNamingAnotherMachineIsRefusedUnlessTrusted) {
    Batch other = small_batch();
    other.machine = "M2";
    Watcher strict({});
    EXPECT_EQ(strict.ingest("plant/M1/X/axis", bytes(encode_binary(small_batch()))), "");
    const std::string error = strict.ingest("plant/M1/X/axis", bytes(encode_binary(other)));
    EXPECT_NE(error.find("names machine 'M2' axis 'X', its topic machine 'M1' axis 'X': refused"), std::string::npos)
        << error;
    EXPECT_EQ(strict.foreign_names(), 1u);
    EXPECT_EQ(strict.malformed(), 1u);
    EXPECT_EQ(strict.axes(), 1u);
    EXPECT_NE(strict.ingest("plant", bytes(encode_binary(other))).find("the topic names no machine"),
              std::string::npos);
    WatchOptions options;
    options.trust_payload_names = true;
    Watcher trusting(options);
    EXPECT_EQ(trusting.ingest("plant/M1/X/axis", bytes(encode_binary(other))), "");
    EXPECT_EQ(trusting.ingest("plant", bytes(encode_binary(other))), "");
    trusting.flush();
    EXPECT_TRUE(trusting.estimate("M2", "X"));
    EXPECT_FALSE(trusting.estimate("M1", "X"));
}

/// A batch of `n` samples of a slow sine at `dt`, for the memory tests.
Batch sine_batch(double t0, double dt, std::size_t n) {
    Batch b;
    b.t0 = t0;
    b.dt = dt;
    b.force_constant = 50.0;
    for (std::size_t k = 0; k < n; ++k) {
        b.position.push_back(0.01 * std::sin(t0 + static_cast<double>(k) * dt));
        b.drive.push_back(std::cos(t0 + static_cast<double>(k) * dt));
    }
    return b;
}

// Memory bounded whatever is sent: a sample time of 1e-7 s is refused at decode; one that would make a window
// longer than max_window_samples is refused when the axis comes; axes are admitted while their identifiers fit
// axes_bytes (and max_axes); each refusal counted.
TEST(WatchHostile, SampleTimesWindowsAndAxesAreBounded) {
    Watcher watcher({});
    EXPECT_NE(watcher.ingest("plant/M1/X/axis", bytes(encode_binary(sine_batch(0.0, 1e-7, 2000)))).find("dt = "),
              std::string::npos);
    WatchOptions fine;
    fine.limits.min_dt_s = 1e-7;
    Watcher window(fine);
    const std::string error = window.ingest("plant/M1/X/axis", bytes(encode_binary(sine_batch(0.0, 1e-7, 2000))));
    EXPECT_NE(error.find("more than max_window_samples"), std::string::npos) << error;
    EXPECT_EQ(window.axes(), 0u);
    EXPECT_EQ(window.refused_axes(), 1u);
    // 2,000 axes at 1 kHz: the identifiers' memory stays within axes_bytes, the rest refused and counted (two
    // identifiers an axis, its windows judged without and with the offset: about 1 MB)
    WatchOptions options;
    options.max_axes = 100'000;
    options.axes_bytes = 128u << 20;
    Watcher many(options);
    const std::string payload = encode_binary(sine_batch(0.0, 1e-3, 200));
    std::size_t refused = 0;
    for (int m = 0; m < 2000; ++m) refused += !many.ingest(fmt::format("plant/F{}/X/axis", m), bytes(payload)).empty();
    const std::size_t per_axis = SelectingIdentifier::memory_bytes({}, 1e-3);
    std::cout << fmt::format("{} axes admitted ({:.2f} MB each), {} refused; {:.1f} MB budgeted\n", many.axes(),
                             static_cast<double>(per_axis) / (1 << 20), refused,
                             static_cast<double>(many.axes_bytes()) / (1 << 20));
    EXPECT_LE(many.axes_bytes(), options.axes_bytes);
    EXPECT_GT(many.axes(), 100u);
    EXPECT_EQ(many.axes() + refused, 2000u);
    EXPECT_EQ(many.refused_axes(), refused);
    options.max_axes = 10;
    Watcher counted(options);
    for (int m = 0; m < 12; ++m) (void)counted.ingest(fmt::format("plant/F{}/X/axis", m), bytes(payload));
    EXPECT_EQ(counted.axes(), 10u);
    EXPECT_EQ(counted.refused_axes(), 2u);
}

// Held batches take at most held_bytes: 1,200 batches of 2,000 samples (32 kB each, 38 MB in all) on 80 axes,
// every one of them held (each axis's first 30 s of stream, and after a hole), stay within a budget of 4 MB; the axes
// that held longest give up their holds (counted) and every sample is still accounted for.
TEST(WatchHostile, HeldBatchesStayWithinTheirBudget) {
    WatchOptions options;
    options.held_bytes = 4u << 20;
    Watcher watcher(options);
    std::size_t most = 0;
    const std::size_t per_batch = 2'000;
    const double dt = 1e-3;
    for (int k = 0; k < 1200; ++k) {
        const int axis = k % 80, index = k / 80;
        // each axis: batch 0 at t = 0, then batches 2, 3, ... 15 (batch 1 never comes: a hole)
        const double t0 = (index == 0 ? 0.0 : static_cast<double>(index + 1)) * static_cast<double>(per_batch) * dt;
        ASSERT_EQ(
            watcher.ingest(fmt::format("plant/H{}/X/axis", axis), bytes(encode_binary(sine_batch(t0, dt, per_batch)))),
            "");
        most = std::max(most, watcher.held_bytes());
    }
    std::cout << fmt::format("held at most {:.2f} MB; {} holds given up early\n", static_cast<double>(most) / (1 << 20),
                             watcher.evicted_holds());
    EXPECT_LE(most, options.held_bytes);
    EXPECT_GT(watcher.evicted_holds(), 0u);
    watcher.flush();
    EXPECT_EQ(watcher.held_bytes(), 0u);
    for (int axis = 0; axis < 80; ++axis) {
        const auto stream = watcher.estimate_document(fmt::format("H{}", axis), "X")["stream"];
        EXPECT_EQ(stream["samples"].get<std::size_t>(), 15 * per_batch) << stream.dump();
        EXPECT_EQ(stream["missing_samples"].get<std::size_t>(), per_batch) << stream.dump();  // batch 1
        EXPECT_EQ(stream["repeated_samples"].get<std::size_t>(), 0u) << stream.dump();
    }
}

// The first batch of an axis to arrive need not be its oldest (a QoS 1 redelivery, a publisher's replay after a
// reconnect): it is held like any batch after a hole, and the earlier ones put before it; the identifier sees the
// uninterrupted stream. A batch from before the start that comes too late is a loss, counted missing, never repeated.
TEST(WatchRouting, ALateFirstBatchIsHeldAndPutInItsPlace) {
    const AxisColumns c = axis_columns(5);
    const std::size_t per_message = 250, batches = (c.t.size() + per_message - 1) / per_message;
    std::vector<std::size_t> order = {2, 3, 0, 1};
    for (std::size_t k = 4; k < batches; ++k) order.push_back(k);
    Watcher watcher({});
    send_in_order(watcher, c, per_message, order);
    watcher.flush();
    const OnlineEstimate expected = direct(c, per_message);
    const auto got = watcher.estimate("M1", "X");
    ASSERT_TRUE(got && expected.coulomb.value);
    EXPECT_EQ(got->samples, c.t.size());
    EXPECT_EQ(got->mass.value, expected.mass.value);
    EXPECT_EQ(got->coulomb.value, expected.coulomb.value);
    const auto stream = watcher.estimate_document("M1", "X")["stream"];
    EXPECT_EQ(stream["missing_samples"].get<std::size_t>(), 0u) << stream.dump();
    EXPECT_EQ(stream["repeated_samples"].get<std::size_t>(), 0u) << stream.dump();
    EXPECT_EQ(stream["reordered_batches"].get<std::size_t>(), 2u) << stream.dump();  // 2 and 3, after 0 and 1
    // batch 0 only after reorder_s of stream (30 s = 120 batches): too late, a loss
    std::vector<std::size_t> late;
    for (std::size_t k = 1; k < batches; ++k) late.push_back(k);
    late.insert(late.begin() + 150, 0);
    Watcher too_late({});
    send_in_order(too_late, c, per_message, late);
    too_late.flush();
    const auto lost = too_late.estimate_document("M1", "X")["stream"];
    EXPECT_EQ(lost["samples"].get<std::size_t>(), c.t.size() - per_message) << lost.dump();
    EXPECT_EQ(lost["missing_samples"].get<std::size_t>(), per_message) << lost.dump();
    EXPECT_EQ(lost["repeated_samples"].get<std::size_t>(), 0u) << lost.dump();
    EXPECT_EQ(lost["late_batches"].get<std::size_t>(), 1u) << lost.dump();
}

// The spool of completed runs: on disk before put returns, in order, bounded, kept across a reopen, one process at
// a time; an entry refused for good is set aside with its reason.
TEST(WatchSpool, RunsWaitOnDiskInOrderBoundedAndLocked) {
    const auto folder = testing::temp_dir() / "spool";
    {
        RunSpool spool(folder, 10'000);
        for (int k = 1; k <= 3; ++k) EXPECT_TRUE(spool.put({{"run", k}, {"text", std::string(1000, 'x')}}));
        EXPECT_EQ(spool.size(), 3u);
        EXPECT_THROW(RunSpool(folder, 10'000), InputError);  // locked
        for (int k = 4; k <= 9; ++k) EXPECT_TRUE(spool.put({{"run", k}, {"text", std::string(1000, 'x')}}));
        EXPECT_FALSE(spool.put({{"run", 10}, {"text", std::string(1000, 'x')}}));  // beyond 10,000 bytes
        EXPECT_EQ(spool.size(), 9u);
        const auto first = spool.front();
        ASSERT_TRUE(first);
        EXPECT_EQ(first->entry["run"], 1);
        spool.remove(first->number);
        spool.reject(spool.front()->number, "refused for good");
        EXPECT_EQ(spool.front()->entry["run"], 3);
    }
    RunSpool again(folder, 10'000);  // the lock went with the first; what waited is still there, in order
    EXPECT_EQ(again.size(), 7u);
    EXPECT_EQ(again.front()->entry["run"], 3);
    EXPECT_TRUE(again.put({{"run", 10}}));
    std::vector<int> order;
    while (auto entry = again.front()) {
        order.push_back(entry->entry["run"].get<int>());
        again.remove(entry->number);
    }
    EXPECT_EQ(order, (std::vector<int>{3, 4, 5, 6, 7, 8, 9, 10}));
    EXPECT_TRUE(std::filesystem::exists(folder / "rejected"));
    EXPECT_NE(testing::read_text(folder / "rejected" / "run-000000000002.reason.txt").find("refused for good"),
              std::string::npos);
}

}  // namespace
}  // namespace feedid::watch
