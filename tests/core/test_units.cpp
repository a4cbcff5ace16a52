// The unit layer: every unit family the import has to understand, each checked against SI values computed by hand
// from the unit's definition (1 in = 25.4 mm exactly, 1 deg = pi/180 rad, 1 min = 60 s, ...).
#include "feedid/core/units.hpp"

#include <gtest/gtest.h>

#include <numbers>
#include <string>

#include "feedid/core/error.hpp"

using namespace feedid;

namespace {

constexpr double pi = std::numbers::pi;

// Converts `value` given in `unit` to SI and checks quantity, SI symbol and the value (relative 1e-15: one or two
// rounding steps of the scale multiplication).
void expect_si(std::string_view unit, double value, Quantity quantity, std::string_view si_unit, double expected,
               const UnitContext& context = {}) {
    SCOPED_TRACE(std::string("unit '") + std::string(unit) + "'");
    const auto conversion = parse_unit(unit, context);
    ASSERT_TRUE(conversion.has_value());
    EXPECT_EQ(conversion->quantity, quantity);
    EXPECT_EQ(conversion->si_unit, si_unit);
    const double si = conversion->scale * value + conversion->offset;
    EXPECT_NEAR(si, expected, 1e-15 * std::abs(expected) + 1e-300);
}

std::string message_of(std::string_view unit, std::string_view channel, const UnitContext& context = {}) {
    try {
        (void)parse_unit_or_throw(unit, channel, context);
    } catch (const InputError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no InputError for unit '" << unit << "'";
    return {};
}

}  // namespace

TEST(Units, Length) {
    expect_si("m", 2.5, Quantity::length, "m", 2.5);
    expect_si("mm", 1234.0, Quantity::length, "m", 1.234);
    expect_si("um", 250.0, Quantity::length, "m", 0.000250);
    expect_si("\xC2\xB5m", 250.0, Quantity::length, "m", 0.000250);  // U+00B5 MICRO SIGN
    expect_si("\xCE\xBCm", 250.0, Quantity::length, "m", 0.000250);  // U+03BC GREEK SMALL LETTER MU
    expect_si("in", 10.0, Quantity::length, "m", 0.254);             // 1 in = 25.4 mm exactly
    expect_si("[mm]", 5.0, Quantity::length, "m", 0.005);            // brackets left on by a caller
    expect_si(" mm ", 5.0, Quantity::length, "m", 0.005);
}

TEST(Units, Angle) {
    expect_si("deg", 180.0, Quantity::angle, "rad", pi);
    expect_si("deg", 90.0, Quantity::angle, "rad", 1.5707963267948966);
    expect_si("\xC2\xB0", 45.0, Quantity::angle, "rad", 0.7853981633974483);  // U+00B0 DEGREE SIGN
    expect_si("rad", 1.25, Quantity::angle, "rad", 1.25);
}

TEST(Units, Time) {
    expect_si("s", 3.0, Quantity::time, "s", 3.0);
    expect_si("ms", 1.0, Quantity::time, "s", 0.001);
    expect_si("ms", 24840.0, Quantity::time, "s", 24.84);
    expect_si("us", 125.0, Quantity::time, "s", 0.000125);
    expect_si("\xC2\xB5s", 125.0, Quantity::time, "s", 0.000125);
}

TEST(Units, LinearVelocity) {
    expect_si("m/s", 0.2, Quantity::velocity, "m/s", 0.2);
    expect_si("mm/s", 200.0, Quantity::velocity, "m/s", 0.2);
    expect_si("mm/min", 1500.0, Quantity::velocity, "m/s", 0.025);  // 1.5 m per 60 s
    expect_si("mm/min", 6000.0, Quantity::velocity, "m/s", 0.1);
    expect_si("m/min", 12.0, Quantity::velocity, "m/s", 0.2);
}

TEST(Units, AngularVelocity) {
    expect_si("deg/s", 360.0, Quantity::angular_velocity, "rad/s", 2.0 * pi);
    expect_si("deg/s", 30.0, Quantity::angular_velocity, "rad/s", 0.5235987755982988);
    expect_si("rad/s", 7.0, Quantity::angular_velocity, "rad/s", 7.0);
}

TEST(Units, RpmBecomesTableVelocityThroughTheLead) {
    UnitContext context;
    context.lead_m = 0.010;  // 10 mm per motor revolution
    // 3000 rpm = 50 rev/s; 50 * 10 mm = 0.5 m/s
    expect_si("rpm", 3000.0, Quantity::velocity, "m/s", 0.5, context);
    expect_si("1/min", 3000.0, Quantity::velocity, "m/s", 0.5, context);
    expect_si("min^-1", 600.0, Quantity::velocity, "m/s", 0.1, context);
    context.lead_m = 0.005;
    expect_si("rpm", 1200.0, Quantity::velocity, "m/s", 0.1, context);  // 20 rev/s * 5 mm
}

TEST(Units, RevolutionSpeedsWithoutALeadAreAngularVelocities) {
    // 1 rev = 2*pi rad: 60 rpm = 1 rev/s = 2*pi rad/s; SINUMERIK logs rotary speeds in rpm, Mitsubishi in r/min
    for (const char* spelling : {"rpm", "r/min", "rev/min", "1/min", "min^-1", "U/min", "RPM"}) {
        expect_si(spelling, 60.0, Quantity::angular_velocity, "rad/s", 2.0 * pi);
    }
    expect_si("rpm", 1500.0, Quantity::angular_velocity, "rad/s", 157.07963267948966);  // 25 rev/s
    expect_si("rev/s", 2.0, Quantity::angular_velocity, "rad/s", 4.0 * pi);
    expect_si("rps", 0.5, Quantity::angular_velocity, "rad/s", pi);
    // deg/s for an rpm channel would be 6x wrong: 1 rpm = 6 deg/s
    const auto rpm = parse_unit("rpm");
    const auto deg_per_s = parse_unit("deg/s");
    ASSERT_TRUE(rpm && deg_per_s);
    EXPECT_NEAR(rpm->scale / deg_per_s->scale, 6.0, 1e-14);
    EXPECT_TRUE(is_revolution_speed("r/min"));
    EXPECT_TRUE(is_revolution_speed("rev/min"));
    EXPECT_FALSE(is_revolution_speed("deg/s"));
    EXPECT_FALSE(is_revolution_speed("rev"));
}

TEST(Units, RpmWithALeadAndAGearRatioIsATableVelocity) {
    UnitContext context;
    context.lead_m = 0.020;    // 20 mm per screw revolution
    context.gear_ratio = 4.0;  // 4 motor revolutions per screw revolution
    // 3000 motor rpm = 50 motor rev/s = 12.5 screw rev/s; * 20 mm = 0.25 m/s
    expect_si("rpm", 3000.0, Quantity::velocity, "m/s", 0.25, context);
    expect_si("rev/min", -1200.0, Quantity::velocity, "m/s", -0.1, context);
    expect_si("rev/s", 10.0, Quantity::velocity, "m/s", 0.05, context);
}

TEST(Units, RotaryPositions) {
    expect_si("rev", 1.5, Quantity::angle, "rad", 3.0 * pi);
    expect_si("deg", 720.0, Quantity::angle, "rad", 4.0 * pi);
    expect_si("rad", -0.5, Quantity::angle, "rad", -0.5);
}

TEST(Units, AxisKindOfEachQuantity) {
    EXPECT_EQ(axis_kind_of(Quantity::length), AxisKind::linear);
    EXPECT_EQ(axis_kind_of(Quantity::velocity), AxisKind::linear);
    EXPECT_EQ(axis_kind_of(Quantity::force), AxisKind::linear);
    EXPECT_EQ(axis_kind_of(Quantity::angle), AxisKind::rotary);
    EXPECT_EQ(axis_kind_of(Quantity::angular_velocity), AxisKind::rotary);
    EXPECT_EQ(axis_kind_of(Quantity::torque), AxisKind::rotary);
    EXPECT_FALSE(axis_kind_of(Quantity::current).has_value());
    EXPECT_FALSE(axis_kind_of(Quantity::voltage).has_value());
    EXPECT_FALSE(axis_kind_of(Quantity::time).has_value());
    EXPECT_EQ(axis_kind_name(AxisKind::rotary), "rotary");
    EXPECT_EQ(axis_kind_name(AxisKind::linear), "linear");
}

TEST(Units, RatedValueWithItsUnit) {
    const auto expect_rating = [](std::string_view text, Quantity quantity, double value_si) {
        SCOPED_TRACE(std::string("--rated ") + std::string(text));
        const Rating rating = parse_rating(text);
        EXPECT_EQ(rating.quantity, quantity);
        EXPECT_NEAR(rating.value_si, value_si, 1e-15 * value_si);
    };
    expect_rating("18", Quantity::current, 18.0);  // a bare number keeps meaning amperes
    expect_rating("18A", Quantity::current, 18.0);
    expect_rating("18 A", Quantity::current, 18.0);
    expect_rating("2.4Nm", Quantity::torque, 2.4);
    expect_rating("2.4 N*m", Quantity::torque, 2.4);
    expect_rating("2400mNm", Quantity::torque, 2.4);
    expect_rating("500N", Quantity::force, 500.0);
    expect_rating("1.2kN", Quantity::force, 1200.0);
    expect_rating("10V", Quantity::voltage, 10.0);
    // what a rating gives a % channel: 50 % of 2.4 N*m is 1.2 N*m
    const Rating torque = parse_rating("2.4Nm");
    UnitContext context;
    context.rated_value_si = torque.value_si;
    context.rated_quantity = torque.quantity;
    expect_si("%", 50.0, Quantity::torque, "N*m", 1.2, context);
}

TEST(Units, RatedValueRefusals) {
    for (const char* text : {"", "Nm", "abc", "-5A", "0", "2.4furlong", "3mm", "10rpm", "nan"}) {
        SCOPED_TRACE(text);
        try {
            (void)parse_rating(text);
            ADD_FAILURE() << "no InputError for --rated " << text;
        } catch (const InputError& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find("--rated"), std::string::npos) << message;
            EXPECT_NE(message.find(text), std::string::npos) << message;
            EXPECT_EQ(message.find('\n'), std::string::npos) << message;
        }
    }
}

TEST(Units, Current) {
    expect_si("A", 2.5, Quantity::current, "A", 2.5);
    expect_si("mA", 2500.0, Quantity::current, "A", 2.5);
}

TEST(Units, ForceAndTorque) {
    expect_si("N", 742.8, Quantity::force, "N", 742.8);
    expect_si("kN", 0.9462, Quantity::force, "N", 946.2);
    for (const char* spelling : {"Nm", "N.m", "N m", "N*m", "N\xC2\xB7m"}) {  // the last with U+00B7 MIDDLE DOT
        expect_si(spelling, 1.45, Quantity::torque, "N*m", 1.45);
    }
    expect_si("kNm", 1.2, Quantity::torque, "N*m", 1200.0);
    // "nm" is a nanometre, not a newton metre: the capital N decides
    expect_si("nm", 500.0, Quantity::length, "m", 5e-7);
}

TEST(Units, PercentOfARatedValue) {
    UnitContext context;
    context.rated_value_si = 18.0;  // rated current 18 A
    context.rated_quantity = Quantity::current;
    expect_si("%", 50.0, Quantity::current, "A", 9.0, context);
    expect_si("%", -12.5, Quantity::current, "A", -2.25, context);
    context.rated_value_si = 8.0;  // rated torque 8 N*m
    context.rated_quantity = Quantity::torque;
    expect_si("%", 25.0, Quantity::torque, "N*m", 2.0, context);
}

TEST(Units, PercentWithoutARatingIsRefused) {
    EXPECT_FALSE(parse_unit("%").has_value());
    const std::string message = message_of("%", "load");
    EXPECT_NE(message.find("load"), std::string::npos) << message;
    EXPECT_NE(message.find("%"), std::string::npos) << message;
    EXPECT_NE(message.find("rated"), std::string::npos) << message;
    EXPECT_NE(message.find("--rated 2.4Nm"), std::string::npos) << message;
}

TEST(Units, EmptyUnitIsDimensionless) {
    const auto conversion = parse_unit("");
    ASSERT_TRUE(conversion.has_value());
    EXPECT_EQ(conversion->quantity, Quantity::dimensionless);
    EXPECT_EQ(conversion->scale, 1.0);
}

TEST(Units, UnknownUnitNamesTheChannelAndTheUnit) {
    for (const char* unit : {"furlong", "mm/fortnight", "kg", "MN"}) {
        EXPECT_FALSE(parse_unit(unit).has_value()) << unit;
        const std::string message = message_of(unit, "x_act");
        EXPECT_NE(message.find("'x_act'"), std::string::npos) << message;
        EXPECT_NE(message.find(std::string("'") + unit + "'"), std::string::npos) << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << "one line: " << message;
    }
}

TEST(Units, SiSymbols) {
    EXPECT_EQ(si_symbol(Quantity::length), "m");
    EXPECT_EQ(si_symbol(Quantity::velocity), "m/s");
    EXPECT_EQ(si_symbol(Quantity::angular_velocity), "rad/s");
    EXPECT_EQ(si_symbol(Quantity::torque), "N*m");
    EXPECT_EQ(si_symbol(Quantity::current), "A");
}
