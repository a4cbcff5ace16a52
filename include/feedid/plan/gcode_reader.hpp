#pragma once
// Reads the part programs a job shop runs on LinuxCNC, in the subset that 3-axis milling and drilling use: G0 G1 G2 G3
// (arcs in the XY plane with I J centre offsets, helical with Z), G4 P dwell, G17, G20/G21, G90/G91, G94, F, S,
// M3/M4/M5, M2/M30, comments `( )` and `;`, N words and `%` lines. T, M6 and the coolant words M7/M8/M9 are read and
// ignored (a note says so); G40 G49 G54 G61 G80, which select the state this reader assumes anyway, are accepted.
// Anything else is an InputError naming the line and the word. gcode_writer.hpp writes programs; this header reads them.

#include <array>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace feedid {

enum class BlockKind { rapid, linear, arc_cw, arc_ccw, dwell };

/// "rapid", "linear", "arc_cw", "arc_ccw", "dwell".
std::string_view block_kind_name(BlockKind kind);

/// One motion (or dwell) of a program, in SI and absolute machine coordinates.
struct GcodeBlock {
    BlockKind kind{BlockKind::rapid};
    std::array<double, 3> start{};   ///< X, Y, Z where the block starts [m]
    std::array<double, 3> end{};     ///< X, Y, Z where it ends [m]
    std::array<double, 2> center{};  ///< arc centre X, Y [m] (arcs only; the XY plane, G17)
    double feed_m_per_s{0.0};        ///< programmed feed [m/s] (feed moves; 0 for rapids and dwells)
    double dwell_s{0.0};             ///< G4 P [s] (dwells only)
    double spindle_rpm{0.0};         ///< programmed S [rpm], whether or not the spindle turns
    bool spindle_on{false};          ///< M3 or M4 in effect
    int line{0};                     ///< 1-based line of the program
};

struct GcodeProgram {
    std::vector<GcodeBlock> blocks;
    std::vector<std::string> notes;  ///< what was read and ignored (tool changes, coolant), with its line
};

/// Parses program text. `source` names it in messages. InputError naming `source:line` and the word for an
/// unsupported word or G/M code, a feed move without a feed rate, an arc whose end is not on its circle (radius
/// difference over 0.01 mm and 0.1 %), and a program that ends without M2, M30 or a closing `%`. Reading stops at
/// M2/M30 or the closing `%`, as LinuxCNC's does.
GcodeProgram read_gcode(std::string_view text, const std::string& source);
/// Reads a program file.
GcodeProgram read_gcode_file(const std::filesystem::path& path);

}  // namespace feedid
