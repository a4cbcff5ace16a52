// SINUMERIK Solution Line servo trace XML. See the header for the time-base and unit rules.
//
// Layout (as written by "SINUMERIK Solution Line Trace", traceSession version 01.00.03.02):
//   <traceSession>
//     <traceCaptureSetup[_V20]> <signalSettings> <signal key= name= unitsType= description=/> ...
//     <traceDisplaySetup[_V20]> <signals> <signal key= unitsType= description=/> ...
//     <traceData> <dataFrame>
//         <dataSignal key= id="f1" name="/Nck/!SD/nckServoDataActPos2ndEnc64 [u1, 1]" interval="0.002"
//                     unitsType="posn" datapointCount= description=/>
//         <rec time="0.000000" f1=".." f2=".."/>   (sparse: an attribute only when the value changed)
#include "feedid/io/sinumerik_trace.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include <fmt/core.h>
#include <pugixml.hpp>

#include "feedid/core/error.hpp"
#include "text_scan.hpp"
#include "channel_hint.hpp"

namespace feedid {

namespace {

constexpr double not_a_number = std::numeric_limits<double>::quiet_NaN();

struct Signal {
    std::string id;
    std::string key;
    std::string variable;     // NC variable without path and axis suffix: "nckServoDataActPos2ndEnc64"
    std::string axis;         // from "[u1, 1]": "1"; empty when the name carries none
    std::string units_type;   // "posn", "velo", ...
    std::string description;  // "Position actual value meas.system 2 (64 bit)"
    double interval_s{not_a_number};
    long long datapoint_count{-1};
    std::vector<double> times;   // sparse events: when the value was written [s]
    std::vector<double> values;  // ... and the value, in the source unit
};

struct Session {
    std::vector<Signal> signals;
    double first_time{not_a_number};
    double last_time{not_a_number};
    std::size_t input_bytes{0};
    std::vector<std::string> findings;
    std::map<std::string, double> constants;  // the cycles the setup states (read_sample_rates())
};

bool contains_ci(std::string_view text, std::string_view pattern) {
    if (pattern.size() > text.size()) return false;
    for (std::size_t i = 0; i + pattern.size() <= text.size(); ++i) {
        std::size_t k = 0;
        while (k < pattern.size() && std::tolower(static_cast<unsigned char>(text[i + k])) ==
                                         std::tolower(static_cast<unsigned char>(pattern[k]))) {
            ++k;
        }
        if (k == pattern.size()) return true;
    }
    return false;
}

bool equals_ci(std::string_view a, std::string_view b) {
    return a.size() == b.size() && contains_ci(a, b);
}

// "/Nck/!SD/nckServoDataActPos2ndEnc64 [u1, 1]" -> variable "nckServoDataActPos2ndEnc64", axis "1".
void split_signal_name(std::string_view name, std::string& variable, std::string& axis) {
    name = scan::trim(name);
    axis.clear();
    if (const auto open = name.rfind('['); open != std::string_view::npos && name.back() == ']') {
        std::string_view inside = name.substr(open + 1, name.size() - open - 2);
        if (const auto comma = inside.find(','); comma != std::string_view::npos) inside = inside.substr(comma + 1);
        axis = std::string(scan::trim(inside));
        name = scan::trim(name.substr(0, open));
    }
    if (const auto slash = name.rfind('/'); slash != std::string_view::npos) name = name.substr(slash + 1);
    while (!name.empty() && (name.front() == '$' || name.front() == '!')) name.remove_prefix(1);
    variable = std::string(name);
}

// SINUMERIK unitsType names -> unit strings parse_unit() knows. posn/velo are the NC's basic length system
// (metric: mm, mm/min); a rotary axis writes deg and deg/min (rev/min for a spindle) - the file does not say which,
// so a linear metric axis is assumed and said (see read_axis).
std::optional<std::string> unit_of(std::string_view units_type) {
    struct Entry {
        std::string_view type;
        std::string_view unit;
    };
    static constexpr Entry table[] = {
        {"posn", "mm"}, {"velo", "mm/min"}, {"current", "A"}, {"torque", "N*m"}, {"percent", "%"}, {"accel", "m/s^2"},
        {"time", "s"},  {"voltage", "V"},   {"force", "N"},   {"freq", "Hz"},    {"angle", "deg"}, {"speed", "rpm"},
    };
    for (const auto& entry : table) {
        if (equals_ci(units_type, entry.type)) return std::string(entry.unit);
    }
    return std::nullopt;
}

std::size_t line_of_node(std::string_view xml, const pugi::xml_node& node) {
    const auto offset = node.offset_debug();
    return offset < 0 ? 0 : scan::line_of(xml, static_cast<std::size_t>(offset));
}

// Signal ids are "f1", "f2", ...: a direct index for those, a map for anything else.
class SignalLookup {
public:
    explicit SignalLookup(const std::vector<Signal>& signals) {
        for (std::size_t k = 0; k < signals.size(); ++k) {
            const auto& id = signals[k].id;
            if (const auto number = f_number(id); number && *number < 4096) {
                if (by_number_.size() <= *number) by_number_.resize(*number + 1, -1);
                by_number_[*number] = static_cast<int>(k);
            } else {
                by_name_[id] = static_cast<int>(k);
            }
        }
    }
    [[nodiscard]] int find(std::string_view id) const {
        if (const auto number = f_number(id); number && *number < by_number_.size()) {
            if (by_number_[*number] >= 0) return by_number_[*number];
        }
        const auto it = by_name_.find(std::string(id));
        return it == by_name_.end() ? -1 : it->second;
    }

private:
    static std::optional<std::size_t> f_number(std::string_view id) {
        if (id.size() < 2 || id.size() > 6 || id.front() != 'f') return std::nullopt;
        std::size_t number = 0;
        for (std::size_t k = 1; k < id.size(); ++k) {
            if (id[k] < '0' || id[k] > '9') return std::nullopt;
            number = number * 10 + static_cast<std::size_t>(id[k] - '0');
        }
        return number;
    }
    std::vector<int> by_number_;
    std::unordered_map<std::string, int> by_name_;
};

double parse_attribute_number(std::string_view xml, const std::string& source, const pugi::xml_node& node,
                              const pugi::xml_attribute& attribute) {
    double value = 0.0;
    if (!scan::parse_number(attribute.value(), value) || !std::isfinite(value)) {
        throw InputError(fmt::format("{}: line {}: <{} {}=\"{}\">: not a finite number", source,
                                     line_of_node(xml, node), node.name(), attribute.name(), attribute.value()));
    }
    return value;
}

// The first <dataFrame> of <traceSession><traceData>; a missing level is refused, naming its line.
pugi::xml_node first_data_frame(const pugi::xml_document& document, std::string_view xml, const std::string& source) {
    const auto session_node = document.child("traceSession");
    if (!session_node) {
        const auto root = document.document_element();
        if (!root) throw InputError(fmt::format("{}: no <traceSession> element: not a SINUMERIK trace", source));
        throw InputError(fmt::format("{}: line {}: the root element is <{}>, not <traceSession>: not a SINUMERIK trace",
                                     source, line_of_node(xml, root), root.name()));
    }
    const auto data = session_node.child("traceData");
    if (!data) {
        throw InputError(fmt::format("{}: line {}: <traceSession> holds no <traceData> element", source,
                                     line_of_node(xml, session_node)));
    }
    const auto frame = data.child("dataFrame");
    if (!frame)
        throw InputError(fmt::format("{}: line {}: <traceData> holds no <dataFrame>", source, line_of_node(xml, data)));
    return frame;
}

using SetupBySignalKey =
    std::map<std::string, std::pair<std::string, std::string>, std::less<>>;  // (unitsType, description)

// Descriptions and unit types from the setup sections, by signal key: the dataSignal's own unitsType is not always a
// unit (the reference file writes "611DTime1" for the torque setpoint that the display setup calls "torque").
SetupBySignalKey read_setup(const pugi::xml_node& session_node) {
    SetupBySignalKey setup;
    for (const auto& section : session_node.children()) {
        const std::string_view name = section.name();
        pugi::xml_node list;
        if (name.starts_with("traceDisplaySetup"))
            list = section.child("signals");
        else if (name.starts_with("traceCaptureSetup"))
            list = section.child("signalSettings");
        if (!list) continue;
        for (const auto& signal : list.children("signal")) {
            auto& entry = setup[signal.attribute("key").value()];
            if (entry.first.empty() || !unit_of(entry.first)) entry.first = signal.attribute("unitsType").value();
            if (entry.second.empty()) entry.second = signal.attribute("description").value();
        }
    }
    return setup;
}

// The cycles the capture setup's <sampleRateSettings> states [s]: driveSampleRate1, the drive's cycle for its signals
// (its speed controller's, 125 us on a SINAMICS drive), as servo_cycle_s, the cycle `feedid gains` fits the velocity
// loop at; servoSampleRate, the NC's position-control cycle, as position_cycle_s.
void read_sample_rates(const pugi::xml_node& session_node, Session& session) {
    for (const auto& section : session_node.children()) {
        if (!std::string_view(section.name()).starts_with("traceCaptureSetup")) continue;
        const auto rates = section.child("sampleRateSettings");
        for (const auto& [attribute, key] :
             {std::pair{"driveSampleRate1", "servo_cycle_s"}, std::pair{"servoSampleRate", "position_cycle_s"}}) {
            const double value = rates.attribute(attribute).as_double(0.0);
            if (value > 0.0 && std::isfinite(value)) session.constants[key] = value;
        }
    }
}

// One <dataSignal>: its id, NC variable and axis, unit type and description (from the setup where its own are
// missing), and its interval.
Signal read_data_signal(const pugi::xml_node& node, const SetupBySignalKey& setup, std::string_view xml,
                        const std::string& source) {
    Signal signal;
    auto line = [&] { return line_of_node(xml, node); };  // only on the error path: it counts lines
    signal.id = node.attribute("id").value();
    signal.key = node.attribute("key").value();
    if (signal.id.empty()) {
        throw InputError(fmt::format("{}: line {}: <dataSignal> without an id", source, line()));
    }
    split_signal_name(node.attribute("name").value(), signal.variable, signal.axis);
    if (signal.variable.empty()) signal.variable = signal.key.empty() ? signal.id : signal.key;
    signal.units_type = node.attribute("unitsType").value();
    signal.description = node.attribute("description").value();
    if (const auto it = setup.find(signal.key); it != setup.end()) {
        if (!unit_of(signal.units_type) && unit_of(it->second.first)) signal.units_type = it->second.first;
        if (signal.description.empty()) signal.description = it->second.second;
    }
    const auto interval = node.attribute("interval");
    if (!interval) {
        throw InputError(fmt::format("{}: line {}: <dataSignal id=\"{}\"> has no interval", source, line(), signal.id));
    }
    signal.interval_s = parse_attribute_number(xml, source, node, interval);
    if (!(signal.interval_s > 0.0)) {
        throw InputError(fmt::format("{}: line {}: <dataSignal id=\"{}\">: interval {} is not positive", source, line(),
                                     signal.id, interval.value()));
    }
    if (const auto count = node.attribute("datapointCount")) signal.datapoint_count = count.as_llong(-1);
    return signal;
}

// Everything but the records: the root, the setup sections' unit types and descriptions, the dataSignals. `frame`
// receives the (first) <dataFrame>.
Session read_declarations(const pugi::xml_document& document, std::string_view xml, const std::string& source,
                          pugi::xml_node& frame) {
    frame = first_data_frame(document, xml, source);
    Session session;
    session.input_bytes = xml.size();
    if (frame.next_sibling("dataFrame")) {
        session.findings.push_back("the trace holds several data frames; only the first is read");
    }
    const auto setup = read_setup(document.child("traceSession"));
    read_sample_rates(document.child("traceSession"), session);
    std::unordered_set<std::string> ids;
    for (const auto& node : frame.children("dataSignal")) {
        Signal signal = read_data_signal(node, setup, xml, source);
        if (!ids.insert(signal.id).second) {
            throw InputError(fmt::format("{}: line {}: <dataSignal id=\"{}\"> is declared twice", source,
                                         line_of_node(xml, node), signal.id));
        }
        session.signals.push_back(std::move(signal));
    }
    if (session.signals.empty()) {
        throw InputError(
            fmt::format("{}: line {}: <dataFrame> declares no <dataSignal>", source, line_of_node(xml, frame)));
    }
    return session;
}

// A record's value of a signal, as the signal's next event; the same instant written twice: the later value counts.
void record_value(Signal& signal, double time, double value) {
    if (!signal.times.empty() && signal.times.back() == time) {
        signal.values.back() = value;
    } else {
        signal.times.push_back(time);
        signal.values.push_back(value);
    }
}

void note_unknown_attributes(Session& session, std::size_t unknown_attributes) {
    if (unknown_attributes > 0) {
        session.findings.push_back(
            fmt::format("{} record values belong to no declared <dataSignal> and were ignored", unknown_attributes));
    }
}

// The records as pugixml's DOM holds them; every problem is an InputError naming its line.
void read_dom_records(Session& session, const pugi::xml_node& frame, std::string_view xml, const std::string& source) {
    const SignalLookup lookup(session.signals);
    std::size_t unknown_attributes = 0;
    double previous = -std::numeric_limits<double>::infinity();
    for (const auto& rec : frame.children()) {
        if (std::string_view(rec.name()) != "rec") continue;
        const auto time_attribute = rec.attribute("time");
        if (!time_attribute) {
            throw InputError(fmt::format("{}: line {}: <rec> without a time", source, line_of_node(xml, rec)));
        }
        const double time = parse_attribute_number(xml, source, rec, time_attribute);
        if (time < previous) {
            throw InputError(
                fmt::format("{}: line {}: <rec time=\"{}\"> goes back in time (the record before is at "
                            "{} s)",
                            source, line_of_node(xml, rec), time_attribute.value(), previous));
        }
        previous = time;
        if (std::isnan(session.first_time)) session.first_time = time;
        session.last_time = time;
        for (auto attribute = rec.first_attribute(); attribute; attribute = attribute.next_attribute()) {
            const std::string_view name = attribute.name();
            if (name == "time") continue;
            const int index = lookup.find(name);
            if (index < 0) {
                ++unknown_attributes;
                continue;
            }
            const double value = parse_attribute_number(xml, source, rec, attribute);
            record_value(session.signals[static_cast<std::size_t>(index)], time, value);
        }
    }
    if (std::isnan(session.first_time)) {
        throw InputError(
            fmt::format("{}: line {}: <dataFrame> holds no <rec> records", source, line_of_node(xml, frame)));
    }
    note_unknown_attributes(session, unknown_attributes);
}

// ---- The fast path for the records --------------------------------------------------------------------------------
// A trace is almost all <rec .../> elements; building pugixml's DOM for them costs more than reading them. So the
// run of records is scanned directly when it is plain (empty <rec> elements whose attributes hold no entity, no '<'
// and no control character), and only the rest of the document, with the run replaced by a placeholder element, goes
// through pugixml. Anything else - a comment or another element among the records, an entity, a record that does not
// parse, any error at all - sends the whole file down the DOM path, which gives the canonical result and messages.

constexpr std::string_view records_placeholder = "<feedidRecords/>";

bool is_blank(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n';
}
bool is_name_start(char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '_' || c == ':';
}
bool is_name_char(char c) {
    return is_name_start(c) || (c >= '0' && c <= '9') || c == '.' || c == '-';
}

struct RawAttribute {
    std::string_view name;
    std::string_view value;
};

// Reads one plain "<rec ... />" at `position` (which points at '<'); fills `attributes` and returns the position
// after it, or npos when it is not a plain record.
std::size_t scan_record(std::string_view xml, std::size_t position, std::vector<RawAttribute>& attributes) {
    attributes.clear();
    std::size_t p = position + 4;  // past "<rec"
    const std::size_t n = xml.size();
    while (true) {
        const std::size_t before = p;
        while (p < n && is_blank(xml[p])) ++p;
        if (p >= n) return std::string_view::npos;
        if (xml[p] == '/') return p + 1 < n && xml[p + 1] == '>' ? p + 2 : std::string_view::npos;
        if (p == before || !is_name_start(xml[p])) return std::string_view::npos;  // attributes are blank-separated
        const std::size_t name_start = p;
        while (p < n && is_name_char(xml[p])) ++p;
        const std::string_view name = xml.substr(name_start, p - name_start);
        while (p < n && is_blank(xml[p])) ++p;
        if (p >= n || xml[p] != '=') return std::string_view::npos;
        ++p;
        while (p < n && is_blank(xml[p])) ++p;
        if (p >= n || (xml[p] != '"' && xml[p] != '\'')) return std::string_view::npos;
        const char quote = xml[p++];
        const std::size_t value_start = p;
        while (p < n && xml[p] != quote) {
            const auto c = static_cast<unsigned char>(xml[p]);
            if (c == '<' || c == '&' || (c < 0x20 && c != '\t') || c == 0x7F) return std::string_view::npos;
            ++p;
        }
        if (p >= n) return std::string_view::npos;
        attributes.push_back({name, xml.substr(value_start, p - value_start)});
        ++p;  // the closing quote
    }
}

bool starts_record(std::string_view xml, std::size_t p) {
    return xml.size() > p + 4 && xml.compare(p, 4, "<rec") == 0 && (is_blank(xml[p + 4]) || xml[p + 4] == '/');
}

// Reads the run of records into the session; false at the first thing the DOM path must judge.
bool read_plain_records(Session& session, std::string_view records) {
    const SignalLookup lookup(session.signals);
    std::vector<RawAttribute> attributes;
    std::size_t unknown_attributes = 0;
    double previous = -std::numeric_limits<double>::infinity();
    std::size_t p = 0;
    while (true) {
        while (p < records.size() && is_blank(records[p])) ++p;
        if (p >= records.size()) break;
        if (!starts_record(records, p)) return false;
        p = scan_record(records, p, attributes);
        if (p == std::string_view::npos) return false;
        const auto time_attribute =
            std::find_if(attributes.begin(), attributes.end(), [](const RawAttribute& a) { return a.name == "time"; });
        double time = 0.0;
        if (time_attribute == attributes.end() || !scan::parse_number(time_attribute->value, time) ||
            !std::isfinite(time) || time < previous) {
            return false;
        }
        previous = time;
        if (std::isnan(session.first_time)) session.first_time = time;
        session.last_time = time;
        for (const auto& attribute : attributes) {
            if (attribute.name == "time") continue;
            const int index = lookup.find(attribute.name);
            if (index < 0) {
                ++unknown_attributes;
                continue;
            }
            double value = 0.0;
            if (!scan::parse_number(attribute.value, value) || !std::isfinite(value)) return false;
            record_value(session.signals[static_cast<std::size_t>(index)], time, value);
        }
    }
    if (std::isnan(session.first_time)) return false;
    note_unknown_attributes(session, unknown_attributes);
    return true;
}

std::optional<Session> read_session_fast(std::string_view xml, const std::string& source) {
    const std::size_t frame_at = xml.find("<dataFrame");
    if (frame_at == std::string_view::npos) return std::nullopt;
    std::size_t begin = xml.find("<rec", frame_at);
    while (begin != std::string_view::npos && !starts_record(xml, begin)) begin = xml.find("<rec", begin + 1);
    if (begin == std::string_view::npos) return std::nullopt;
    // The run ends where its frame does; that nothing but records lies between is checked while reading them (a
    // '<' cannot hide inside a plain record's value).
    const std::size_t end = xml.find("</dataFrame>", begin);
    if (end == std::string_view::npos) return std::nullopt;
    std::string rest;
    rest.reserve(begin + records_placeholder.size() + (xml.size() - end));
    rest.append(xml.substr(0, begin)).append(records_placeholder).append(xml.substr(end));
    pugi::xml_document document;
    if (!document.load_buffer(rest.data(), rest.size(), pugi::parse_minimal | pugi::parse_escapes,
                              pugi::encoding_utf8)) {
        return std::nullopt;
    }
    try {
        pugi::xml_node frame;
        Session session = read_declarations(document, rest, source, frame);
        // The run must be element content of the frame that is read (the placeholder, found where it was put, is
        // one of its children; a run inside a comment or CDATA is not), and all of its records.
        bool placed = false;
        for (const auto& child : frame.children("feedidRecords")) {
            placed = placed || child.offset_debug() == static_cast<std::ptrdiff_t>(begin + 1);
        }
        if (!placed || frame.child("rec")) return std::nullopt;
        session.input_bytes = xml.size();
        if (!read_plain_records(session, xml.substr(begin, end - begin))) return std::nullopt;
        return session;
    } catch (const InputError&) {
        return std::nullopt;
    }
}

Session read_session(std::string_view xml, const std::string& source) {
    if (auto session = read_session_fast(xml, source)) return std::move(*session);
    pugi::xml_document document;
    const auto parsed =
        document.load_buffer(xml.data(), xml.size(), pugi::parse_minimal | pugi::parse_escapes, pugi::encoding_utf8);
    if (!parsed) {
        throw InputError(
            fmt::format("{}: line {}: not well-formed XML ({})", source,
                        scan::line_of(xml, static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, parsed.offset))),
                        parsed.description()));
    }
    pugi::xml_node frame;
    Session session = read_declarations(document, xml, source, frame);
    read_dom_records(session, frame, xml, source);
    return session;
}

struct RoleGuess {
    std::size_t signal;
    Role role;
};

// Roles from the NC variable names (see the header). The position comes from the direct measuring system (2nd
// encoder, the linear scale) when the trace has it: that is what the position loop closes on and what the table
// really does; velocity is taken from the same measuring system so that the two agree.
std::vector<RoleGuess> guess_roles(const std::vector<Signal>& signals, const std::vector<std::size_t>& members) {
    auto find = [&](std::initializer_list<std::string_view> patterns, std::string_view units_type,
                    std::string_view prefer = {}) -> std::optional<std::size_t> {
        std::optional<std::size_t> any;
        for (const auto index : members) {
            const auto& signal = signals[index];
            if (!equals_ci(signal.units_type, units_type)) continue;
            for (const auto pattern : patterns) {
                if (!contains_ci(signal.variable, pattern)) continue;
                if (prefer.empty() || contains_ci(signal.variable, prefer)) return index;
                if (!any) any = index;
            }
        }
        return any;
    };
    std::vector<RoleGuess> guesses;
    const auto direct = find({"ActPos2ndEnc", "measPos2"}, "posn");
    const auto motor = find({"ActPos1stEnc", "measPos1"}, "posn");
    const std::string_view encoder = direct ? "2nd" : "1st";
    if (const auto position = direct ? direct : motor) guesses.push_back({*position, Role::position});
    if (direct && motor) guesses.push_back({*motor, Role::motor_position});  // both systems: the fingerprint's pair
    if (const auto reference = find({"CmdPos", "PosSetpoint", "SetPos"}, "posn", encoder)) {
        guesses.push_back({*reference, Role::reference_position});
    }
    if (const auto command = find({"CmdVel", "VelSetpoint", "SetVel"}, "velo")) {
        guesses.push_back({*command, Role::velocity_command});
    }
    if (const auto velocity = find({"ActVel", "measVel"}, "velo", encoder))
        guesses.push_back({*velocity, Role::velocity});
    if (const auto current = find({"ActCurr", "CurrAct", "iqAct"}, "current"))
        guesses.push_back({*current, Role::current});
    return guesses;
}

// What a few bytes of a hostile file may make us compute and allocate, in cells (samples x channels, plus one per
// signal scanned for each axis): a real trace writes a record for nearly every fine sample, so cells far beyond the
// file size mean a broken time or interval attribute, or a flood of axes.
double cell_budget(const Session& session) {
    return std::max(16.0e6, 2.0 * static_cast<double>(session.input_bytes));
}

// The signals of an axis (and those that name none) that have samples; each one left out is said.
std::vector<std::size_t> signals_with_samples(const std::vector<Signal>& signals, const std::string& axis,
                                              const std::string& source, std::vector<std::string>& findings) {
    std::vector<std::size_t> kept;
    for (std::size_t k = 0; k < signals.size(); ++k) {
        if (signals[k].axis != axis && !signals[k].axis.empty()) continue;
        if (signals[k].times.empty()) {
            findings.push_back(fmt::format("signal '{}' has no samples in the records; left out", signals[k].variable));
        } else {
            kept.push_back(k);
        }
    }
    if (kept.empty()) {
        throw InputError(fmt::format("{}: no signal of axis {} has any sample in the records", source,
                                     axis.empty() ? std::string("(none)") : axis));
    }
    return kept;
}

// The number of samples on the fine time base (the finest interval over the records' span), taken from the budget;
// a count far beyond what the file holds records for means a broken time or interval attribute.
std::size_t fine_sample_count(const Session& session, double step, std::size_t channels, const std::string& source,
                              double& budget) {
    const double span = session.last_time - session.first_time;
    const double count_real = std::floor(span / step + 1e-6) + 1.0;
    const double cells = count_real * static_cast<double>(channels + 1);
    if (!(count_real >= 1.0) || !(cells <= budget)) {
        throw InputError(
            fmt::format("{}: records from {} s to {} s at an interval of {} s would make {:.0f} samples, "
                        "far more than the file holds records for",
                        source, session.first_time, session.last_time, step, count_real));
    }
    budget -= cells;
    return static_cast<std::size_t>(count_real);
}

// Forward-fill on the signal's own grid (origin: its first sample, spacing: its interval), then read the grid at each
// fine time: the latest grid value at or before it; NaN before the first sample.
std::vector<double> held_on_time_base(const Signal& signal, const std::vector<double>& time) {
    const double origin = signal.times.front();
    const double interval = signal.interval_s;
    std::vector<double> values(time.size(), not_a_number);
    std::size_t event = 0;
    double held = not_a_number;
    for (std::size_t j = 0; j < time.size(); ++j) {
        const double position = (time[j] - origin) / interval;
        if (position < -1e-6) continue;
        const double cell = std::floor(position + 1e-6);
        while (event < signal.times.size() && std::round((signal.times[event] - origin) / interval) <= cell) {
            held = signal.values[event];
            ++event;
        }
        values[j] = held;
    }
    return values;
}

// A channel per kept signal, named after its NC variable (and its key when two share a variable).
std::vector<Channel> axis_channels(const std::vector<Signal>& signals, const std::vector<std::size_t>& kept,
                                   const std::vector<double>& time) {
    std::vector<Channel> channels;
    std::map<std::string, int> name_use;
    for (const auto index : kept) ++name_use[signals[index].variable];
    for (const auto index : kept) {
        const auto& signal = signals[index];
        Channel channel;
        channel.name = name_use[signal.variable] > 1 ? signal.variable + "_" + signal.key : signal.variable;
        channel.source_unit = unit_of(signal.units_type).value_or(signal.units_type);
        channel.values = held_on_time_base(signal, time);
        channel.native_interval_s = signal.interval_s;
        channel.interval_source = IntervalSource::format;
        channels.push_back(std::move(channel));
    }
    return channels;
}

// Roles, each guess said.
void assign_roles(const std::vector<Signal>& signals, const std::vector<std::size_t>& kept,
                  std::vector<Channel>& channels, std::vector<std::string>& findings) {
    const auto guesses = guess_roles(signals, kept);
    for (const auto& guess : guesses) {
        const auto position =
            static_cast<std::size_t>(std::find(kept.begin(), kept.end(), guess.signal) - kept.begin());
        auto& channel = channels[position];
        channel.role = guess.role;
        const auto& description = signals[guess.signal].description;
        findings.push_back(
            fmt::format("channel '{}'{} taken as {} (guessed from the NC variable name; set it with {})",
                        channel.name, description.empty() ? "" : " (" + description + ")", role_name(guess.role),
                        io_detail::channel_option(role_name(guess.role), channel.name)));
    }
    if (!guesses.empty()) {
        findings.push_back(
            fmt::format("{}: posn in mm, velo in mm/min (a rotary axis: --rotary, or --unit position=deg; every posn "
                        "signal is then in deg and every velo signal in rpm)",
                        sinumerik_linear_units_finding));
    }
}

// Where every role channel has a value (sparse signals on coarser grids may start later).
std::size_t first_complete_sample(const std::vector<Channel>& channels, std::size_t n, const std::string& source) {
    std::size_t first = 0;
    for (const auto& channel : channels) {
        if (channel.role == Role::other) continue;
        std::size_t k = 0;
        while (k < n && std::isnan(channel.values[k])) ++k;
        first = std::max(first, k);
    }
    if (first >= n) throw InputError(fmt::format("{}: no sample where all role channels have values", source));
    return first;
}

// Said once: a signal on the fine interval whose declared count of data points differs from the samples made.
void note_datapoint_mismatch(const std::vector<Signal>& signals, const std::vector<std::size_t>& kept, std::size_t n,
                             double step, std::vector<std::string>& findings) {
    for (const auto index : kept) {
        const auto& signal = signals[index];
        if (signal.datapoint_count > 0 && static_cast<std::size_t>(signal.datapoint_count) != n &&
            signal.interval_s == step) {
            findings.push_back(fmt::format("signal '{}' declares {} data points; the records span {}", signal.variable,
                                           signal.datapoint_count, n));
            return;
        }
    }
}

Trace build_axis(const Session& session, const std::string& axis, const std::string& source, double& budget) {
    const auto& signals = session.signals;
    budget -= static_cast<double>(signals.size());
    if (budget < 0.0) {
        throw InputError(
            fmt::format("{}: the trace declares more axes and signals than its records could fill "
                        "({} signals)",
                        source, signals.size()));
    }
    Trace trace;
    trace.format = "sinumerik-trace";
    trace.findings = session.findings;
    trace.constants = session.constants;
    const auto kept = signals_with_samples(signals, axis, source, trace.findings);
    double step = std::numeric_limits<double>::infinity();
    for (const auto index : kept) step = std::min(step, signals[index].interval_s);
    const std::size_t n = fine_sample_count(session, step, kept.size(), source, budget);

    std::vector<double> time(n);
    for (std::size_t j = 0; j < n; ++j) time[j] = session.first_time + static_cast<double>(j) * step;
    auto channels = axis_channels(signals, kept, time);
    assign_roles(signals, kept, channels, trace.findings);
    const std::size_t first = first_complete_sample(channels, n, source);
    if (first > 0) {
        trace.findings.push_back(
            fmt::format("the first {} samples were dropped: not every role channel had a value yet", first));
    }
    note_datapoint_mismatch(signals, kept, n, step, trace.findings);

    auto cut = [first](std::vector<double>& values) {
        values.erase(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(first));
    };
    cut(time);
    trace.channels.push_back(Channel{"time", Role::time, "", "s", std::move(time)});
    for (auto& channel : channels) {
        cut(channel.values);
        trace.channels.push_back(std::move(channel));
    }
    return trace;
}

// "1, 2, 3" (the first twenty, then how many more).
std::string list_of(const std::vector<std::string>& axes) {
    std::string list;
    const std::size_t shown = std::min<std::size_t>(axes.size(), 20);
    for (std::size_t k = 0; k < shown; ++k) list += (k == 0 ? "" : ", ") + axes[k];
    if (axes.size() > shown) list += fmt::format(" and {} more", axes.size() - shown);
    return list;
}

std::vector<std::string> axes_of(const Session& session) {
    std::vector<std::string> axes;
    std::unordered_set<std::string> seen;
    for (const auto& signal : session.signals) {
        if (!signal.axis.empty() && seen.insert(signal.axis).second) axes.push_back(signal.axis);
    }
    if (axes.empty()) axes.emplace_back();
    return axes;
}

}  // namespace

Trace parse_sinumerik_trace(std::string_view xml, const std::string& source, const std::string& axis) {
    const Session session = read_session(xml, source);
    const auto axes = axes_of(session);
    std::string chosen;
    if (axis.empty()) {
        chosen = axes.front();
    } else {
        for (const auto& candidate : axes) {
            if (equals_ci(candidate, axis)) chosen = candidate;
        }
        if (chosen.empty()) {
            throw InputError(fmt::format("{}: --axis {}: the trace holds no such axis (it holds: {})", source, axis,
                                         axes.front().empty() ? std::string("none named") : list_of(axes)));
        }
    }
    double budget = cell_budget(session);
    Trace trace = build_axis(session, chosen, source, budget);
    if (axes.size() > 1) {
        trace.axes = axes;
        trace.findings.insert(trace.findings.begin(), fmt::format("the trace holds axes {}; read axis {} (choose with "
                                                                  "--axis)",
                                                                  list_of(axes), chosen));
    }
    return trace;
}

std::vector<Trace> parse_sinumerik_trace_axes(std::string_view xml, const std::string& source) {
    const Session session = read_session(xml, source);
    std::vector<Trace> traces;
    double budget = cell_budget(session);  // shared by all axes
    for (const auto& axis : axes_of(session)) traces.push_back(build_axis(session, axis, source, budget));
    return traces;
}

}  // namespace feedid
