#pragma once
// Delimited text traces: a header row of `name [unit]` (also `name (unit)` and `name/unit`), comma, semicolon or
// tab separated, `#` comment lines, decimal comma with `;`. Values are parsed with fast_float; missing cells (empty,
// NaN, NA, -) are NaN, left for Trace::validate() to refuse in a role channel. A separator at the end of each line is
// accepted; quoted header cells may hold the separator, and quoted numbers are read.
//
// What real exports add, each said in a finding rather than refused: a row of units directly under the header (every
// cell a known unit or empty, at least one a unit); repeated column names (numbered `name`, `name#2`, ...); columns of
// text (a process step, a tool condition: a column whose first value is not a number) left out; an unnamed first
// column counting 0, 1, 2, ... (the index pandas writes) left out. A column of numbers with a cell that is not one is
// still an error naming the line and the cell.

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "feedid/core/trace.hpp"

namespace feedid {

struct CsvOptions {
    /// Lines skipped at the top of the file before anything is read (a preamble no reader knows) [lines].
    std::size_t skip_rows{0};
    /// Columns that must hold numbers (the channels given with --channel): one of them holding text is an error
    /// naming it, not a column left out.
    std::vector<std::string> numeric_columns;
    /// What an unnamed first column (the index pandas writes) holds in the first data row: 0 for a whole file, the
    /// rows before it for a block of a file read in blocks.
    std::size_t first_index{0};
};

/// Parses CSV text into raw channels (values in the source units, roles unassigned). Comment lines before the header
/// of the form `# name = number` become trace constants. `source` names the file in error messages. Throws InputError
/// with the line number on a malformed file.
Trace parse_csv(std::string_view text, const std::string& source, const CsvOptions& options = {});

/// Reads a CSV file as parse_csv does, with memory bounded by the columns it produces: the file is mapped, not
/// copied, and the pages already parsed are handed back as parsing goes. InputError naming the file on failure.
Trace read_csv(const std::filesystem::path& path, const CsvOptions& options = {});

/// Splits a header cell into name and unit: "x [mm]" -> {"x", "mm"}, "v (mm/min)" -> {"v", "mm/min"},
/// "i/A" -> {"i", "A"}, "time" -> {"time", ""}.
std::pair<std::string, std::string> split_name_unit(std::string_view header_cell);

/// Writes a trace as CSV: its constants as `# name = value` lines, then `name [unit]` headers (SI units), then the
/// values in the shortest form that reads back exactly.
std::string write_csv(const Trace& trace);

}  // namespace feedid
