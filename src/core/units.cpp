#include "feedid/core/units.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <numbers>
#include <system_error>

#include <fast_float/fast_float.h>
#include <fmt/core.h>

#include "feedid/core/error.hpp"

namespace feedid {

std::string_view axis_kind_name(AxisKind kind) {
    return kind == AxisKind::rotary ? "rotary" : "linear";
}

std::optional<AxisKind> axis_kind_of(Quantity quantity) {
    switch (quantity) {
        case Quantity::length:
        case Quantity::velocity:
        case Quantity::acceleration:
        case Quantity::force: return AxisKind::linear;
        case Quantity::angle:
        case Quantity::angular_velocity:
        case Quantity::angular_acceleration:
        case Quantity::torque: return AxisKind::rotary;
        default: return std::nullopt;
    }
}

std::string_view si_symbol(Quantity quantity) {
    switch (quantity) {
        case Quantity::dimensionless: return "";
        case Quantity::length: return "m";
        case Quantity::angle: return "rad";
        case Quantity::time: return "s";
        case Quantity::velocity: return "m/s";
        case Quantity::angular_velocity: return "rad/s";
        case Quantity::acceleration: return "m/s^2";
        case Quantity::angular_acceleration: return "rad/s^2";
        case Quantity::current: return "A";
        case Quantity::voltage: return "V";
        case Quantity::force: return "N";
        case Quantity::torque: return "N*m";
        case Quantity::frequency: return "1/s";
    }
    return "";
}

namespace {

struct KnownUnit {
    std::string_view symbol;
    Quantity quantity;
    double scale;
};

constexpr double pi = std::numbers::pi;
constexpr double deg = pi / 180.0;

// Spellings are compared after normalisation (see normalise()): lower case except where case matters is not
// needed here, since no two units in this table differ by case only once 'M' (mega) is excluded.
constexpr std::array known_units{
    // length
    KnownUnit{"m", Quantity::length, 1.0},
    KnownUnit{"mm", Quantity::length, 1e-3},
    KnownUnit{"cm", Quantity::length, 1e-2},
    KnownUnit{"um", Quantity::length, 1e-6},
    KnownUnit{"nm", Quantity::length, 1e-9},
    KnownUnit{"in", Quantity::length, 0.0254},
    KnownUnit{"inch", Quantity::length, 0.0254},
    // angle
    KnownUnit{"rad", Quantity::angle, 1.0},
    KnownUnit{"mrad", Quantity::angle, 1e-3},
    KnownUnit{"deg", Quantity::angle, deg},
    KnownUnit{"degree", Quantity::angle, deg},
    KnownUnit{"degrees", Quantity::angle, deg},
    KnownUnit{"°", Quantity::angle, deg},
    KnownUnit{"rev", Quantity::angle, 2.0 * pi},
    // time
    KnownUnit{"s", Quantity::time, 1.0},
    KnownUnit{"sec", Quantity::time, 1.0},
    KnownUnit{"ms", Quantity::time, 1e-3},
    KnownUnit{"us", Quantity::time, 1e-6},
    KnownUnit{"ns", Quantity::time, 1e-9},
    KnownUnit{"min", Quantity::time, 60.0},
    // velocity
    KnownUnit{"m/s", Quantity::velocity, 1.0},
    KnownUnit{"mm/s", Quantity::velocity, 1e-3},
    KnownUnit{"um/s", Quantity::velocity, 1e-6},
    KnownUnit{"mm/min", Quantity::velocity, 1e-3 / 60.0},
    KnownUnit{"m/min", Quantity::velocity, 1.0 / 60.0},
    KnownUnit{"in/min", Quantity::velocity, 0.0254 / 60.0},
    KnownUnit{"in/s", Quantity::velocity, 0.0254},
    KnownUnit{"rad/s", Quantity::angular_velocity, 1.0},
    KnownUnit{"deg/s", Quantity::angular_velocity, deg},
    KnownUnit{"deg/min", Quantity::angular_velocity, deg / 60.0},
    // acceleration
    KnownUnit{"m/s^2", Quantity::acceleration, 1.0},
    KnownUnit{"m/s2", Quantity::acceleration, 1.0},
    KnownUnit{"mm/s^2", Quantity::acceleration, 1e-3},
    KnownUnit{"mm/s2", Quantity::acceleration, 1e-3},
    KnownUnit{"rad/s^2", Quantity::angular_acceleration, 1.0},
    KnownUnit{"rad/s2", Quantity::angular_acceleration, 1.0},
    KnownUnit{"deg/s^2", Quantity::angular_acceleration, deg},
    // current, voltage
    KnownUnit{"a", Quantity::current, 1.0},
    KnownUnit{"ma", Quantity::current, 1e-3},
    KnownUnit{"arms", Quantity::current, 1.0},
    KnownUnit{"v", Quantity::voltage, 1.0},
    KnownUnit{"mv", Quantity::voltage, 1e-3},
    // force, torque
    KnownUnit{"n", Quantity::force, 1.0},
    KnownUnit{"kn", Quantity::force, 1e3},
    KnownUnit{"n*m", Quantity::torque, 1.0},
    KnownUnit{"kn*m", Quantity::torque, 1e3},
    KnownUnit{"mn*m", Quantity::torque, 1e-3},
    // frequency
    KnownUnit{"hz", Quantity::frequency, 1.0},
    KnownUnit{"1/s", Quantity::frequency, 1.0},
};

// Normalises a unit string: trims, drops surrounding brackets, maps micro signs to 'u', middle dots and spaces
// between factors to '*', and lower-cases. Case matters in exactly two places, kept apart before lower-casing:
// "Nm" / "N.m" / "N m" (newton metre) versus "nm" (nanometre), and "mN" versus "MN" (not supported).
std::string normalise(std::string_view unit) {
    std::string out;
    out.reserve(unit.size());
    std::size_t i = 0;
    while (i < unit.size()) {
        const unsigned char c = static_cast<unsigned char>(unit[i]);
        // UTF-8 micro sign U+00B5 (C2 B5) and Greek mu U+03BC (CE BC)
        if (c == 0xC2 && i + 1 < unit.size() && static_cast<unsigned char>(unit[i + 1]) == 0xB5) {
            out += 'u';
            i += 2;
            continue;
        }
        if (c == 0xCE && i + 1 < unit.size() && static_cast<unsigned char>(unit[i + 1]) == 0xBC) {
            out += 'u';
            i += 2;
            continue;
        }
        // middle dot U+00B7 (C2 B7)
        if (c == 0xC2 && i + 1 < unit.size() && static_cast<unsigned char>(unit[i + 1]) == 0xB7) {
            out += '*';
            i += 2;
            continue;
        }
        // degree sign U+00B0 (C2 B0)
        if (c == 0xC2 && i + 1 < unit.size() && static_cast<unsigned char>(unit[i + 1]) == 0xB0) {
            out += "deg";
            i += 2;
            continue;
        }
        out += static_cast<char>(c);
        ++i;
    }
    // trim and strip one level of brackets
    auto trim = [](std::string& s) {
        const auto first = s.find_first_not_of(" \t\r\n\"'");
        const auto last = s.find_last_not_of(" \t\r\n\"'");
        s = first == std::string::npos ? std::string{} : s.substr(first, last - first + 1);
    };
    trim(out);
    if (out.size() >= 2 && ((out.front() == '[' && out.back() == ']') || (out.front() == '(' && out.back() == ')'))) {
        out = out.substr(1, out.size() - 2);
        trim(out);
    }
    // Newton metre spellings, decided before lower-casing: "Nm", "N.m", "N m", "N*m", "kNm", "mNm".
    for (std::string_view newton_metre : {"N.m", "N m", "N*m", "Nm"}) {
        if (const auto pos = out.find(newton_metre);
            pos != std::string::npos && pos + newton_metre.size() == out.size()) {
            out = out.substr(0, pos) + "n*m";
            break;
        }
    }
    std::string lowered;
    lowered.reserve(out.size());
    for (const char ch : out) {
        if (ch == ' ') continue;
        lowered += static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    }
    // common alternative spellings
    if (lowered == "mm/sec") return "mm/s";
    if (lowered == "m/sec") return "m/s";
    if (lowered == "1/min" || lowered == "min^-1" || lowered == "min-1" || lowered == "u/min" || lowered == "r/min" ||
        lowered == "rev/min" || lowered == "revs/min" || lowered == "rpm")
        return "rpm";
    if (lowered == "rev/s" || lowered == "r/s" || lowered == "rps") return "rps";
    if (lowered == "deg/sec") return "deg/s";
    if (lowered == "grad") return "deg";  // German "Grad" (degree) as some controls write it
    return lowered;
}

}  // namespace

bool is_revolution_speed(std::string_view unit) {
    const std::string key = normalise(unit);
    return key == "rpm" || key == "rps";
}

std::optional<UnitConversion> parse_unit(std::string_view unit, const UnitContext& context) {
    const std::string key = normalise(unit);
    if (key.empty() || key == "-" || key == "1") return UnitConversion{Quantity::dimensionless, 1.0, 0.0, ""};
    if (key == "rpm" || key == "rps") {
        const double revolutions_per_second = key == "rpm" ? 1.0 / 60.0 : 1.0;
        if (!context.lead_m) {
            return UnitConversion{Quantity::angular_velocity, revolutions_per_second * 2.0 * pi, 0.0, "rad/s"};
        }
        // Motor revolutions -> screw revolutions (the gear ratio) -> table travel (the lead).
        const double gear_ratio = context.gear_ratio.value_or(1.0);
        return UnitConversion{Quantity::velocity, revolutions_per_second / gear_ratio * *context.lead_m, 0.0, "m/s"};
    }
    if (key == "%") {
        if (!context.rated_value_si || !context.rated_quantity) return std::nullopt;
        return UnitConversion{*context.rated_quantity, *context.rated_value_si / 100.0, 0.0,
                              std::string(si_symbol(*context.rated_quantity))};
    }
    for (const auto& known : known_units) {
        if (known.symbol == key) {
            return UnitConversion{known.quantity, known.scale, 0.0, std::string(si_symbol(known.quantity))};
        }
    }
    return std::nullopt;
}

UnitConversion parse_unit_or_throw(std::string_view unit, std::string_view channel, const UnitContext& context) {
    if (auto conversion = parse_unit(unit, context)) return *conversion;
    const std::string key = normalise(unit);
    if (key == "%") {
        throw InputError(
            fmt::format("channel '{}': unit '%' needs the rated value it is a percentage of "
                        "(--rated VALUE with its unit, e.g. --rated 18A or --rated 2.4Nm)",
                        channel));
    }
    throw InputError(fmt::format("channel '{}': unknown unit '{}'", channel, unit));
}

Rating parse_rating(std::string_view text) {
    const auto fail = [&](std::string_view why) {
        return InputError(
            fmt::format("--rated {}: {} (give the value 100 % stands for with its unit, e.g. "
                        "--rated 18A for a current, --rated 2.4Nm for a torque)",
                        text, why));
    };
    std::string_view rest = text;
    while (!rest.empty() && rest.front() == ' ') rest.remove_prefix(1);
    double value = 0.0;
    const auto [end, error] = fast_float::from_chars(rest.data(), rest.data() + rest.size(), value);
    if (error != std::errc() || end == rest.data()) throw fail("expected a number");
    // From 1 uA (uN*m, ...) to 1e7 (10 MN): past any drive, short of nonsense.
    if (!(value >= 1e-6 && value <= 1e7))
        throw fail("the rated value must be a positive number from 1e-06 to 1e+07 in its unit");
    const std::string_view unit = rest.substr(static_cast<std::size_t>(end - rest.data()));
    if (normalise(unit).empty()) return Rating{value, Quantity::current};  // a bare number: amperes, as before
    const auto conversion = parse_unit(unit);
    if (!conversion) throw fail(fmt::format("unknown unit '{}'", unit));
    switch (conversion->quantity) {
        case Quantity::current:
        case Quantity::torque:
        case Quantity::force:
        case Quantity::voltage: return Rating{conversion->scale * value, conversion->quantity};
        default: throw fail(fmt::format("'{}' is not a unit of a current, torque, force or voltage", unit));
    }
}

}  // namespace feedid
