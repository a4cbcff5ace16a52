#include "feedid/plan/gcode_reader.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/io/import.hpp"

namespace feedid {

namespace {

constexpr double metres_per_mm = 1e-3;
constexpr double metres_per_inch = 0.0254;
// LinuxCNC rejects an arc whose end radius differs from its start radius by more than an absolute and a relative
// tolerance (both must be exceeded); these are of its order, in SI.
constexpr double arc_radius_tolerance_m = 1e-5;
constexpr double arc_radius_tolerance_relative = 1e-3;

// A G or M number in tenths (G61.1 -> 611), so that decimal codes compare exactly.
int code_tenths(double value) {
    return static_cast<int>(std::lround(value * 10.0));
}

struct Word {
    char letter;
    double value;
    std::string text;  // as written, for messages ("G33", "K2")
};

// The words of one line, comments removed; InputError for a letter without a number.
std::vector<Word> words_of(std::string_view line, const std::string& where) {
    std::vector<Word> words;
    std::size_t k = 0;
    while (k < line.size()) {
        const char c = line[k];
        if (c == ';') break;  // comment to the end of the line
        if (c == '(') {
            const auto close = line.find(')', k);
            if (close == std::string_view::npos) throw InputError(fmt::format("{}: comment '(' not closed", where));
            k = close + 1;
            continue;
        }
        if (std::isspace(static_cast<unsigned char>(c))) {
            ++k;
            continue;
        }
        if (!std::isalpha(static_cast<unsigned char>(c)))
            throw InputError(fmt::format("{}: unexpected '{}'", where, c));
        const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
        std::size_t j = k + 1;
        while (j < line.size() && std::isspace(static_cast<unsigned char>(line[j]))) ++j;
        std::size_t end = j;
        while (end < line.size() && (std::isdigit(static_cast<unsigned char>(line[end])) || line[end] == '.' ||
                                     line[end] == '-' || line[end] == '+'))
            ++end;
        double value = 0.0;
        std::string_view number = line.substr(j, end - j);
        if (number.starts_with('+')) number.remove_prefix(1);
        const auto [last, error] = std::from_chars(number.data(), number.data() + number.size(), value);
        if (number.empty() || error != std::errc() || last != number.data() + number.size())
            throw InputError(fmt::format("{}: word '{}' has no number", where, line.substr(k, end - k)));
        words.push_back({letter, value, std::string(line.substr(k, end - k))});
        k = end;
    }
    return words;
}

// The modal state of the interpreter, in SI.
struct State {
    std::array<double, 3> position{};
    double length_scale{metres_per_mm};  // G21 by default here, as the programs say explicitly
    bool incremental{false};
    int motion{-1};  // 0, 1, 2, 3; -1 = none yet
    double feed_m_per_s{0.0};
    double spindle_rpm{0.0};
    bool spindle_on{false};
};

// What one line asks for, before it is applied.
struct Line {
    std::optional<int> motion;
    bool dwell{false};
    std::map<char, double> values;  // X Y Z I J F S P
    std::vector<int> m_codes;
};

void read_g_code(const Word& word, Line& line, State& state, const std::string& where) {
    switch (code_tenths(word.value)) {
        case 0: line.motion = 0; break;
        case 10: line.motion = 1; break;
        case 20: line.motion = 2; break;
        case 30: line.motion = 3; break;
        case 40: line.dwell = true; break;
        case 170: break;  // XY plane: the only one read
        case 200: state.length_scale = metres_per_inch; break;
        case 210: state.length_scale = metres_per_mm; break;
        case 900: state.incremental = false; break;
        case 910: state.incremental = true; break;
        case 940:
            break;  // units per minute: the only feed mode read
        // cancel cutter compensation, tool length offset and canned cycles, first work offset, exact stop: the
        // state this reader assumes anyway
        case 400:
        case 490:
        case 540:
        case 610:
        case 800: break;
        default: throw InputError(fmt::format("{}: {} is not supported (unsupported word)", where, word.text));
    }
}

Line parse_line(const std::vector<Word>& words, State& state, GcodeProgram& program, const std::string& where) {
    Line line;
    for (const auto& word : words) {
        switch (word.letter) {
            case 'N': break;
            case 'G': read_g_code(word, line, state, where); break;
            case 'M': line.m_codes.push_back(code_tenths(word.value)); break;
            case 'T': program.notes.push_back(fmt::format("{}: {} (tool selection) ignored", where, word.text)); break;
            case 'X':
            case 'Y':
            case 'Z':
            case 'I':
            case 'J':
            case 'F':
            case 'S':
            case 'P':
                if (line.values.contains(word.letter))
                    throw InputError(fmt::format("{}: {} given twice", where, word.letter));
                line.values[word.letter] = word.value;
                break;
            default: throw InputError(fmt::format("{}: {} is not supported (unsupported word)", where, word.text));
        }
    }
    return line;
}

// M codes: spindle, program end (returns true), and those read and ignored.
bool apply_m_codes(const Line& line, State& state, GcodeProgram& program, const std::string& where) {
    bool end = false;
    for (const int code : line.m_codes) {
        switch (code) {
            case 30:
            case 40: state.spindle_on = true; break;
            case 50: state.spindle_on = false; break;
            case 20:
            case 300: end = true; break;  // executed last, after the line's motion
            case 60: program.notes.push_back(fmt::format("{}: M6 (tool change) ignored", where)); break;
            case 70:
            case 80:
            case 90: program.notes.push_back(fmt::format("{}: M{} (coolant) ignored", where, code / 10)); break;
            default: throw InputError(fmt::format("{}: M{:g} is not supported (unsupported word)", where, code / 10.0));
        }
    }
    return end;
}

std::array<double, 3> target_of(const Line& line, const State& state) {
    std::array<double, 3> target = state.position;
    for (int axis = 0; axis < 3; ++axis) {
        const auto found = line.values.find("XYZ"[axis]);
        if (found == line.values.end()) continue;
        const double value = found->second * state.length_scale;
        target[axis] = state.incremental ? state.position[axis] + value : value;
    }
    return target;
}

void check_arc(const GcodeBlock& block, const std::string& where) {
    const double r0 = std::hypot(block.start[0] - block.center[0], block.start[1] - block.center[1]);
    const double r1 = std::hypot(block.end[0] - block.center[0], block.end[1] - block.center[1]);
    if (r0 == 0.0) throw InputError(fmt::format("{}: the arc has radius 0 (I and J both 0)", where));
    const double difference = std::abs(r1 - r0);
    if (difference > arc_radius_tolerance_m && difference > arc_radius_tolerance_relative * r0) {
        throw InputError(
            fmt::format("{}: the arc's end is not on its circle (radius {:.4f} mm at the start, {:.4f} mm "
                        "at the end)",
                        where, r0 * 1e3, r1 * 1e3));
    }
}

// The block a motion line makes (nullopt when it moves nothing: no axis words).
std::optional<GcodeBlock> motion_block(const Line& line, State& state, const std::string& where, int number) {
    const bool has_axis = line.values.contains('X') || line.values.contains('Y') || line.values.contains('Z');
    if (line.motion) state.motion = *line.motion;
    const bool has_offset = line.values.contains('I') || line.values.contains('J');
    if (!has_axis) {
        if (has_offset) throw InputError(fmt::format("{}: I or J without an arc's end point", where));
        return std::nullopt;
    }
    if (state.motion < 0) throw InputError(fmt::format("{}: axis words without a motion mode (G0, G1, G2, G3)", where));
    GcodeBlock block;
    block.line = number;
    block.start = state.position;
    block.end = target_of(line, state);
    block.spindle_rpm = state.spindle_rpm;
    block.spindle_on = state.spindle_on;
    if (state.motion == 0) {
        block.kind = BlockKind::rapid;
    } else {
        if (!(state.feed_m_per_s > 0.0))
            throw InputError(fmt::format("{}: G{} without a feed rate (F)", where, state.motion));
        block.feed_m_per_s = state.feed_m_per_s;
        block.kind = state.motion == 1 ? BlockKind::linear : state.motion == 2 ? BlockKind::arc_cw : BlockKind::arc_ccw;
    }
    if (state.motion >= 2) {
        if (!has_offset) throw InputError(fmt::format("{}: G{} needs I and/or J (the centre)", where, state.motion));
        const auto offset = [&](char letter) {
            const auto found = line.values.find(letter);
            return found == line.values.end() ? 0.0 : found->second * state.length_scale;
        };
        block.center = {block.start[0] + offset('I'), block.start[1] + offset('J')};
        check_arc(block, where);
    } else if (has_offset) {
        throw InputError(fmt::format("{}: I or J on a straight move", where));
    }
    state.position = block.end;
    return block;
}

// Applies one line to the state and the program; returns true at the program's end.
bool apply_line(const Line& line, State& state, GcodeProgram& program, const std::string& where, int number) {
    if (const auto f = line.values.find('F'); f != line.values.end()) {
        if (!(f->second > 0.0)) throw InputError(fmt::format("{}: F must be positive", where));
        state.feed_m_per_s = f->second * state.length_scale / 60.0;
    }
    if (const auto s = line.values.find('S'); s != line.values.end()) {
        if (s->second < 0.0) throw InputError(fmt::format("{}: S must be >= 0", where));
        state.spindle_rpm = s->second;
    }
    // LinuxCNC's order of execution: feed and speed, then spindle on/off, then dwell, then motion, then stop.
    const bool end = apply_m_codes(line, state, program, where);
    if (line.dwell) {
        const auto p = line.values.find('P');
        if (p == line.values.end() || p->second < 0.0)
            throw InputError(fmt::format("{}: G4 needs P, the dwell time >= 0 [s]", where));
        GcodeBlock block;
        block.kind = BlockKind::dwell;
        block.start = block.end = state.position;
        block.dwell_s = p->second;
        block.spindle_rpm = state.spindle_rpm;
        block.spindle_on = state.spindle_on;
        block.line = number;
        program.blocks.push_back(block);
    } else if (line.values.contains('P')) {
        throw InputError(fmt::format("{}: P without G4", where));
    }
    if (auto block = motion_block(line, state, where, number)) program.blocks.push_back(*block);
    if (end) state.spindle_on = false;
    return end;
}

}  // namespace

std::string_view block_kind_name(BlockKind kind) {
    switch (kind) {
        case BlockKind::rapid: return "rapid";
        case BlockKind::linear: return "linear";
        case BlockKind::arc_cw: return "arc_cw";
        case BlockKind::arc_ccw: return "arc_ccw";
        case BlockKind::dwell: return "dwell";
    }
    return "?";
}

GcodeProgram read_gcode(std::string_view text, const std::string& source) {
    GcodeProgram program;
    State state;
    int number = 0;
    bool opened = false;  // a first `%` line was seen
    while (!text.empty()) {
        const auto newline = text.find('\n');
        std::string_view line = text.substr(0, newline);
        text = newline == std::string_view::npos ? std::string_view() : text.substr(newline + 1);
        ++number;
        if (line.ends_with('\r')) line.remove_suffix(1);
        const std::string where = fmt::format("{}:{}", source, number);
        const auto first = line.find_first_not_of(" \t");
        if (first != std::string_view::npos && line[first] == '%') {
            if (opened) return program;
            opened = true;
            continue;
        }
        if (line.find_first_not_of(" \t") == std::string_view::npos) continue;
        const auto words = words_of(line, where);
        if (words.empty()) continue;
        if (apply_line(parse_line(words, state, program, where), state, program, where, number)) return program;
    }
    throw InputError(fmt::format("{}: the program ends without M2, M30 or a closing %", source));
}

GcodeProgram read_gcode_file(const std::filesystem::path& path) {
    return read_gcode(read_file_bytes(path), path.string());
}

}  // namespace feedid
