#pragma once
// Part programs (G-code) of a test plan for three controls: ISO (Fanuc-style), SINUMERIK 840D and LinuxCNC. The
// plan itself (moves, passes, reference trajectory) comes from test_plan.hpp; this header only writes it out.

#include <optional>
#include <string>
#include <string_view>

#include "feedid/plan/test_plan.hpp"

namespace feedid {

enum class Dialect { iso, sinumerik, linuxcnc };

/// "iso", "sinumerik", "linuxcnc".
std::string_view dialect_name(Dialect dialect);
/// The inverse of dialect_name; nullopt for an unknown name.
std::optional<Dialect> parse_dialect(std::string_view name);

/// The part program in a dialect: absolute positions (G90), mm and mm/min (G94), exact stop, G4 dwells, and a header
/// comment with the plan's parameters and the feedid version. SINUMERIK gets servo-trace start/stop lines the user
/// can enable. InputError when the axis name is not an axis letter of the dialect (X1 is SINUMERIK only).
std::string emit_part_program(const TestPlan& plan, Dialect dialect);

}  // namespace feedid
