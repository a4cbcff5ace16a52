// Part-program emitters for the test plan: ISO (Fanuc-style), SINUMERIK 840D and LinuxCNC.
//
// Dialect differences that matter here:
//   dwell       ISO: G04 X<s> (X with a decimal point is seconds; P would be milliseconds)
//               SINUMERIK: G4 F<s>        LinuxCNC: G4 P<s> (seconds)
//   exact stop  ISO: G61   SINUMERIK: G60 (modal exact stop)   LinuxCNC: G61 (exact path)
//               Every move must end at rest: the reversals are the test, and consecutive moves in one direction
//               must not blend, or the NC would not follow the reference trajectory.
//   metric      ISO, LinuxCNC: G21   SINUMERIK: G71
//   jerk        SINUMERIK: SOFT (jerk-limited) or BRISK (trapezoidal); ISO and LinuxCNC program no jerk.
//   comments    ISO, LinuxCNC: ( ... ) without nested parentheses; SINUMERIK: ; to the end of the line
//   end         ISO, SINUMERIK: M30; LinuxCNC: M2
// Positions are written with a decimal point always (a Fanuc control without decimal-point programming reads X10 as
// 10 increments, not 10 mm). A rotary axis (A, B, C) is programmed in degrees and deg/min: with G94 a block that
// moves a rotary axis alone runs at F degrees per minute on all three controls.
#include "feedid/plan/gcode_writer.hpp"

#include <cctype>
#include <cmath>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/version.hpp"

namespace feedid {

namespace {

// Precision of the blocks' words. Positions to 0.1 um (0.0001 deg), four decimals in mm: the input increment of the
// finest ISO increment system (IS-C; a coarser control rounds), and exact for the plan's centres and 0.01 mm strokes.
// Feedrates to 0.001 mm/min, so that the log-spaced slow feeds keep their two significant digits down to
// 0.1 mm/min. Dwells to 1 ms.
constexpr int position_decimals = 4;
constexpr int feed_decimals = 3;
constexpr double feed_steps_per_unit = 1000.0;  // 10^feed_decimals
constexpr int dwell_decimals = 3;

// Fixed-point with up to `decimals` decimals, trailing zeros trimmed but one decimal kept ("1250.0", "21.5").
std::string number(double value, int decimals) {
    std::string text = fmt::format("{:.{}f}", value, decimals);
    if (text == fmt::format("-{:.{}f}", 0.0, decimals)) text.erase(0, 1);
    const auto point = text.find('.');
    if (point == std::string::npos) return text + ".0";
    std::size_t last = text.find_last_not_of('0');
    if (last == point) ++last;
    text.erase(last + 1);
    return text;
}

std::string position_word(double si, const PlanUnits& units) {
    static const std::string negative_zero = fmt::format("-{:.{}f}", 0.0, position_decimals);
    std::string text = fmt::format("{:.{}f}", si / units.length(), position_decimals);
    if (text == negative_zero) text.erase(0, 1);
    return text;
}

std::string feed_list(const std::vector<double>& feeds, const PlanUnits& units) {
    if (feeds.empty()) return "none";
    std::string text;
    for (const double feed : feeds) text += (text.empty() ? "" : ", ") + number(feed / units.feed(), 3);
    return text + " " + units.feed_unit();
}

std::vector<std::string> header_lines(const TestPlan& plan, Dialect dialect) {
    const auto& o = plan.options;
    const PlanUnits u = o.units();
    const auto length = [&](double si) { return number(si / u.length(), 3); };
    const char* l = u.length_unit();
    std::vector<std::string> lines;
    if (!plan.description.empty()) {
        lines.push_back(fmt::format("feedid {} {} for {} axis {} ({} dialect)", version, plan.description.front(),
                                    u.rotary ? "rotary" : "linear", o.axis, dialect_name(dialect)));
        lines.insert(lines.end(), plan.description.begin() + 1, plan.description.end());
        lines.push_back(fmt::format("trace sample time {} ms; predicted duration {} s; {} blocks",
                                    number(o.sample_time * 1e3, 4), number(plan.duration, 1), plan.moves.size()));
        return lines;
    }
    lines.push_back(fmt::format("feedid {} axis test for {} axis {} ({} dialect)", version,
                                u.rotary ? "rotary" : "linear", o.axis, dialect_name(dialect)));
    lines.push_back("constant-velocity back-and-forth strokes at rising feedrates, every move ends at rest");
    lines.push_back(fmt::format("travel {} .. {} {}", length(o.travel_min), length(o.travel_max), l));
    std::string centers;
    for (const double c : o.centers) centers += (centers.empty() ? "" : ", ") + length(c);
    lines.push_back(fmt::format("centres {} {}", centers, l));
    lines.push_back(fmt::format("stroke {} {}, slow passes shortened to at most {} s each", length(o.stroke), l,
                                number(o.max_pass_time, 3)));
    lines.push_back(fmt::format("ladder feeds {}", feed_list(o.feeds, u)));
    lines.push_back(fmt::format("slow feeds {}", feed_list(o.slow_feeds, u)));
    lines.push_back(fmt::format("cycles per feedrate {}, dwell at reversals {} s", o.cycles, number(o.dwell, 3)));
    lines.push_back(fmt::format("positioning feed {} {}", number(o.positioning_feed / u.feed(), 3), u.feed_unit()));
    lines.push_back(
        fmt::format("acceleration {} {} and jerk {} as set in the machine data; the reference trajectory "
                    "assumes them",
                    number(o.acceleration / u.acceleration(), 4), u.acceleration_unit(),
                    o.jerk ? number(*o.jerk / u.acceleration(), 3) + " " + u.jerk_unit() : "unlimited"));
    lines.push_back(fmt::format("trace sample time {} ms; predicted duration {} s; {} blocks",
                                number(o.sample_time * 1e3, 4), number(plan.duration, 1), plan.moves.size()));
    return lines;
}

std::string sanitize_parenthesised(std::string text) {
    for (auto& c : text) {
        if (c == '(') c = '[';
        if (c == ')') c = ']';
    }
    return text;
}

bool is_single_letter_axis(const std::string& axis) {
    static const std::string letters = "XYZABCUVW";
    return axis.size() == 1 &&
           letters.find(static_cast<char>(std::toupper(static_cast<unsigned char>(axis[0])))) != std::string::npos;
}

}  // namespace

std::string_view dialect_name(Dialect dialect) {
    switch (dialect) {
        case Dialect::iso: return "iso";
        case Dialect::sinumerik: return "sinumerik";
        case Dialect::linuxcnc: return "linuxcnc";
    }
    return "iso";
}

std::optional<Dialect> parse_dialect(std::string_view name) {
    for (const auto dialect : {Dialect::iso, Dialect::sinumerik, Dialect::linuxcnc}) {
        if (dialect_name(dialect) == name) return dialect;
    }
    return std::nullopt;
}

std::string emit_part_program(const TestPlan& plan, Dialect dialect) {
    const auto& o = plan.options;
    const PlanUnits u = o.units();
    if (dialect != Dialect::sinumerik && !is_single_letter_axis(o.axis)) {
        throw InputError(
            fmt::format("part program: axis '{}' is not an axis letter of the {} dialect (X, Y, Z, A, B, "
                        "C, U, V, W).",
                        o.axis, dialect_name(dialect)));
    }
    const bool semicolon_comments = dialect == Dialect::sinumerik;
    std::string out;
    const auto comment = [&](const std::string& text) {
        out += semicolon_comments ? fmt::format("; {}\n", text) : fmt::format("({})\n", sanitize_parenthesised(text));
    };
    // SINUMERIK needs "=" between an axis name with digits and its value (X1=10.0).
    const std::string axis_word =
        dialect == Dialect::sinumerik && o.axis.find_first_of("0123456789") != std::string::npos ? o.axis + "="
                                                                                                 : o.axis;

    if (dialect == Dialect::iso) out += "%\nO1000\n";
    for (const auto& line : header_lines(plan, dialect)) comment(line);
    switch (dialect) {
        case Dialect::iso: out += "G21 G90 G94 G61\n"; break;
        case Dialect::linuxcnc: out += "G21 G90 G94 G17 G40 G49 G61\n"; break;
        case Dialect::sinumerik: out += fmt::format("G71 G90 G94 G60 {}\n", o.jerk ? "SOFT" : "BRISK"); break;
    }
    if (dialect == Dialect::sinumerik) {
        comment(
            "servo trace: in HMI Diagnostics > Trace, record actual position, position setpoint and actual current");
        comment(
            fmt::format("every {} ms, start trigger R99 == 1, stop trigger R99 == 0; then remove the ';' before "
                        "the STOPRE and R99 lines",
                        number(o.sample_time * 1e3, 4)));
        out += ";STOPRE\n;R99=1 ; servo trace start\n";
    }

    int last_pass = -2;
    double last_feed = -1.0;
    for (const auto& move : plan.moves) {
        if (move.pass != last_pass && move.pass >= 0) {
            const auto& pass = plan.passes[static_cast<std::size_t>(move.pass)];
            comment(fmt::format("pass {}: centre {} at {} {}, {} {}, stroke {} {}, {} cycles{}", move.pass + 1,
                                pass.center + 1, number(pass.center_position / u.length(), 3), u.length_unit(),
                                number(pass.feed / u.feed(), 3), u.feed_unit(), number(pass.stroke / u.length(), 3),
                                u.length_unit(), o.cycles, pass.slow ? " (slow pass)" : ""));
        }
        last_pass = move.pass;
        if (move.kind == MoveKind::dwell) {
            switch (dialect) {
                case Dialect::iso: out += fmt::format("G04 X{}\n", number(move.dwell, dwell_decimals)); break;
                case Dialect::sinumerik: out += fmt::format("G4 F{}\n", number(move.dwell, dwell_decimals)); break;
                case Dialect::linuxcnc: out += fmt::format("G4 P{}\n", number(move.dwell, dwell_decimals)); break;
            }
            continue;
        }
        std::string block = fmt::format("G1 {}{}", axis_word, position_word(move.target, u));
        const double feed_per_min = std::round(move.feed / u.feed() * feed_steps_per_unit) / feed_steps_per_unit;
        if (feed_per_min != last_feed) {
            block += " F" + number(feed_per_min, feed_decimals);
            last_feed = feed_per_min;
        }
        out += block + "\n";
    }

    if (dialect == Dialect::sinumerik) out += ";STOPRE\n;R99=0 ; servo trace stop\n";
    comment("end of the feedid axis test");
    out += dialect == Dialect::linuxcnc ? "M2\n" : "M30\n";
    if (dialect == Dialect::iso) out += "%\n";
    return out;
}

}  // namespace feedid
