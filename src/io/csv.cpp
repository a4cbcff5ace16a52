#include "feedid/io/csv.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <map>
#include <unordered_set>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fast_float/fast_float.h>
#include <fmt/core.h>
#include <fmt/format.h>

#include "feedid/core/error.hpp"
#include "feedid/core/large_columns.hpp"
#include "feedid/io/import.hpp"
#include "feedid/core/units.hpp"
#include "text_scan.hpp"

namespace feedid {

namespace {

constexpr double missing = std::numeric_limits<double>::quiet_NaN();

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
    return s;
}

std::string_view unquote(std::string_view s) {
    s = trim(s);
    if (s.size() >= 2 && s.front() == '"' && s.back() == '"') s = s.substr(1, s.size() - 2);
    return trim(s);
}

// Splits a header line on the separator, honouring double quotes (a quoted header may contain the separator).
std::vector<std::string> split_header(std::string_view line, char separator) {
    std::vector<std::string> cells;
    std::string cell;
    bool quoted = false;
    for (const char c : line) {
        if (c == '"') {
            quoted = !quoted;
            cell += c;
        } else if (c == separator && !quoted) {
            cells.emplace_back(unquote(cell));
            cell.clear();
        } else {
            cell += c;
        }
    }
    cells.emplace_back(unquote(cell));
    return cells;
}

char detect_separator(std::string_view header) {
    // The separator is the candidate that occurs most often outside quotes; a single column has none.
    std::size_t best_count = 0;
    char best = ',';
    for (const char candidate : {'\t', ';', ','}) {
        std::size_t count = 0;
        bool quoted = false;
        for (const char c : header) {
            if (c == '"')
                quoted = !quoted;
            else if (c == candidate && !quoted)
                ++count;
        }
        if (count > best_count) {
            best_count = count;
            best = candidate;
        }
    }
    return best;
}

// A cell as it may appear in a one-line message: control bytes escaped, at most 40 characters.
std::string printable(std::string_view cell) {
    std::string out;
    for (const char c : cell.substr(0, 40)) {
        const auto byte = static_cast<unsigned char>(c);
        if (byte < 0x20 || byte == 0x7F)
            out += fmt::format("\\x{:02X}", byte);
        else
            out += c;
    }
    if (cell.size() > 40) out += "...";
    return out;
}

// Text exports never hold control bytes other than tab, CR, LF and form feed; anything else in the first 64 KiB
// means the file is binary (an image, a compressed archive, a binary scope format) and not a CSV at all.
void reject_binary(std::string_view text, const std::string& source) {
    if (text.starts_with("\xFF\xFE") || text.starts_with("\xFE\xFF")) {
        throw InputError(
            fmt::format("{}: UTF-16 text (as Excel's \"Unicode text\" writes it); save it as UTF-8 CSV", source));
    }
    const auto head = text.substr(0, 65536);
    for (std::size_t k = 0; k < head.size(); ++k) {
        const auto byte = static_cast<unsigned char>(head[k]);
        if ((byte < 0x20 && byte != '\t' && byte != '\n' && byte != '\r' && byte != '\f') || byte == 0x7F) {
            throw InputError(
                fmt::format("{}: not a text file (byte {} is the control character 0x{:02X}); a CSV "
                            "trace is text with a header row like 'time [s],x [mm],i [A]'",
                            source, k + 1, byte));
        }
    }
}

// The '\n' bytes in `part`, counted in 32 one-byte counters that the compiler keeps in vector registers (a compare
// and a subtract per 16 bytes), summed before they can overflow: about 1.5 ms for the 42 MB of a million rows, where
// one counter of 8 bytes took 9 ms (each comparison's result widened to 8 bytes before it was added).
std::size_t count_newlines(std::string_view part) {
    constexpr std::size_t lanes = 32;
    constexpr std::size_t rounds = 255;  // the most a one-byte counter takes
    const std::size_t whole = part.size() / lanes * lanes;
    std::size_t count = 0;
    std::size_t k = 0;
    while (k < whole) {
        const std::size_t stop = std::min(whole, k + lanes * rounds);
        std::array<std::uint8_t, lanes> in_lane{};
        for (; k < stop; k += lanes) {
            for (std::size_t lane = 0; lane < lanes; ++lane)
                in_lane[lane] = static_cast<std::uint8_t>(in_lane[lane] + (part[k + lane] == '\n' ? 1 : 0));
        }
        for (const std::uint8_t n : in_lane) count += n;
    }
    for (; k < part.size(); ++k) count += static_cast<std::size_t>(part[k] == '\n');
    return count;
}

// The line ends in `rest`, counted a block at a time. `release` hands each counted block's pages back, so that
// counting a mapped file of gigabytes does not hold it in memory; the parse reads them back from the page cache.
std::size_t count_line_ends(std::string_view rest, const std::function<void(const char*)>& release) {
    constexpr std::size_t block = std::size_t{8} << 20;
    std::size_t lines = 0;
    for (std::size_t start = 0; start < rest.size(); start += block) {
        const auto part = rest.substr(start, block);
        lines += count_newlines(part);
        if (part.size() == block) release(part.data() + part.size());
    }
    return lines;
}

// Appends with a growth of 25 % instead of doubling, should the rows counted ever fall short: the columns are the largest
// thing import holds, and doubling them all at once would double peak memory.
inline void append(std::vector<double>& column, double value) {
    if (column.size() == column.capacity()) column.reserve(column.capacity() + column.capacity() / 4 + 64);
    column.push_back(value);
}

// A quoted number ("1.5"), as some exports write every cell.
bool parse_quoted(std::string_view cell, const fast_float::parse_options& options, double& value) {
    if (cell.size() < 3 || cell.front() != '"' || cell.back() != '"') return false;
    cell = trim(cell.substr(1, cell.size() - 2));
    if (!cell.empty() && cell.front() == '+') cell.remove_prefix(1);
    if (cell.empty()) {
        value = missing;
        return true;
    }
    const auto parsed = fast_float::from_chars_advanced(cell.data(), cell.data() + cell.size(), value, options);
    return parsed.ec == std::errc() && parsed.ptr == cell.data() + cell.size();
}

bool is_comment_or_blank(std::string_view line) {
    line = trim(line);
    return line.empty() || line.front() == '#';
}

// A comment line `# name = number` carries a scalar constant (a drive constant, say) along with the trace.
void read_constant(std::string_view line, std::map<std::string, double>& constants) {
    line = trim(line);
    if (line.empty() || line.front() != '#') return;
    line.remove_prefix(1);
    const auto equals = line.find('=');
    if (equals == std::string_view::npos) return;
    const auto name = trim(line.substr(0, equals));
    auto value_text = trim(line.substr(equals + 1));
    if (name.empty() || name.find_first_of(" \t") != std::string_view::npos) return;
    if (!value_text.empty() && value_text.front() == '+') value_text.remove_prefix(1);
    // the decimal mark is not known yet (the separator comes with the header): a point, else a comma
    for (const char decimal_point : {'.', ','}) {
        double value = 0.0;
        const fast_float::parse_options options{fast_float::chars_format::general, decimal_point};
        const auto parsed =
            fast_float::from_chars_advanced(value_text.data(), value_text.data() + value_text.size(), value, options);
        if (parsed.ec == std::errc() && parsed.ptr == value_text.data() + value_text.size()) {
            constants[std::string(name)] = value;
            return;
        }
    }
}

}  // namespace

std::pair<std::string, std::string> split_name_unit(std::string_view cell) {
    cell = unquote(cell);
    if (!cell.empty() && (cell.back() == ']' || cell.back() == ')')) {
        const char open = cell.back() == ']' ? '[' : '(';
        if (const auto pos = cell.rfind(open); pos != std::string_view::npos && pos > 0) {
            return {std::string(trim(cell.substr(0, pos))),
                    std::string(trim(cell.substr(pos + 1, cell.size() - pos - 2)))};
        }
    }
    // "name/unit": only when what follows the first slash looks like a unit (the name part must not be empty).
    if (const auto pos = cell.find('/'); pos != std::string_view::npos && pos > 0 && pos + 1 < cell.size()) {
        return {std::string(trim(cell.substr(0, pos))), std::string(trim(cell.substr(pos + 1)))};
    }
    return {std::string(cell), ""};
}

namespace {

// The text without a UTF-8 byte-order mark; refused when it is empty or binary.
std::string_view checked_text(std::string_view text, const std::string& source) {
    if (text.size() >= 3 && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) {
        throw InputError(fmt::format("{}: empty file", source));
    }
    reject_binary(text, source);
    return text;
}

// The text read line by line (a line keeps a trailing '\r'), with the number of the line last read.
struct TextLines {
    std::string_view text;
    std::size_t position{0};
    std::size_t number{0};

    bool next(std::string_view& line) {
        if (position >= text.size()) return false;
        const auto end = text.find('\n', position);
        const auto stop = end == std::string_view::npos ? text.size() : end;
        line = text.substr(position, stop - position);
        position = stop + 1;
        ++number;
        return true;
    }
};

// What comes before the header row: comments (some carrying constants), blank lines, Excel's "sep=;" line.
struct Preamble {
    std::string_view header_row;
    char stated_separator{'\0'};
    std::map<std::string, double> constants;
};

Preamble read_preamble(TextLines& lines, const std::string& source) {
    Preamble preamble;
    std::string_view line;
    while (lines.next(line)) {
        // Excel's "sep=;" line states the separator
        if (const auto stated = trim(line); stated.size() == 5 && stated.starts_with("sep=") && lines.number == 1) {
            preamble.stated_separator = stated[4];
            continue;
        }
        if (!is_comment_or_blank(line)) {
            preamble.header_row = line;
            return preamble;
        }
        read_constant(line, preamble.constants);
    }
    throw InputError(fmt::format("{}: no header row (only comments or blank lines)", source));
}

std::vector<std::string> header_cells(std::string_view header_row, char separator) {
    auto cells = split_header(header_row, separator);
    // A separator at the end of every line (some exports write one) makes an empty last column: not a channel.
    if (cells.size() > 1 && cells.back().empty()) cells.pop_back();
    return cells;
}

// A channel per header cell, its unit taken from the cell (split_name_unit). Repeated names are numbered, and a
// finding says so; an unnamed first column is kept with an empty name for drop_index_column to judge.
void add_header_channels(Trace& trace, const std::vector<std::string>& header, const std::string& source,
                         std::size_t header_line) {
    const std::size_t columns = header.size();
    std::vector<std::string> names;
    std::vector<std::string> units;
    names.reserve(columns);
    units.reserve(columns);
    for (std::size_t c = 0; c < columns; ++c) {
        auto [name, unit] = split_name_unit(header[c]);
        if (c == 0 && (name.empty() || name.starts_with("Unnamed: "))) {
            name.clear();  // pandas writes its index unnamed (read back and written again: "Unnamed: 0")
        } else if (name.empty()) {
            throw InputError(fmt::format("{}:{}: column {} has no name in the header", source, header_line, c + 1));
        }
        // a header whose "names" are all numbers is data, not a header
        double probe = 0.0;
        const auto* first = name.data();
        if (!name.empty() && fast_float::from_chars(first, first + name.size(), probe).ptr == first + name.size() &&
            unit.empty()) {
            throw InputError(
                fmt::format("{}:{}: the first row holds numbers, not a header of channel names "
                            "(write one like 'time [s],x [mm],i [A]')",
                            source, header_line));
        }
        names.push_back(std::move(name));
        units.push_back(std::move(unit));
    }
    for (const auto& name : scan::number_repeated_names(names)) {
        trace.findings.push_back(
            fmt::format("column name '{}' appears more than once in the header (line {}): the "
                        "repeats are named {}#2, ...",
                        name, header_line, name));
    }
    trace.channels.reserve(columns);
    for (std::size_t c = 0; c < columns; ++c)
        trace.channels.push_back(Channel{std::move(names[c]), Role::other, "", std::move(units[c]), {}});
}

enum class UnitCell { empty, unit, number, other };

// A cell of a possible unit row: empty (or "-"), a unit (one that may need context, such as rpm or %), a number, or
// other text.
UnitCell classify_unit_cell(std::string_view cell) {
    cell = unquote(cell);
    if (cell.empty() || cell == "-") return UnitCell::empty;
    double number = 0.0;
    if (fast_float::from_chars(cell.data(), cell.data() + cell.size(), number).ptr == cell.data() + cell.size())
        return UnitCell::number;
    const UnitContext any_context{
        .lead_m = 1.0, .gear_ratio = std::nullopt, .rated_value_si = 1.0, .rated_quantity = Quantity::current};
    const auto conversion = parse_unit(cell, any_context);
    if (!conversion) return UnitCell::other;
    return conversion->quantity == Quantity::dimensionless ? UnitCell::empty : UnitCell::unit;
}

// A row of units directly under the header gives the columns their units: no cell a number, and more than half of
// the cells that are not empty known units (so that one vendor unit, "pulse" or "inc", does not turn the row into
// data and every column into text; such a unit is kept as the column's, for import to judge). A column whose header
// states another unit is an error naming both. Otherwise the line is left unread.
void read_unit_row(TextLines& lines, Trace& trace, char separator, const std::string& source) {
    const TextLines before = lines;
    std::string_view line;
    if (!lines.next(line) || is_comment_or_blank(line)) {
        lines = before;
        return;
    }
    auto cells = split_header(line, separator);
    if (cells.size() == trace.channels.size() + 1 && cells.back().empty()) cells.pop_back();  // a trailing separator
    std::size_t units = 0;
    std::size_t others = 0;
    for (const auto& cell : cells) {
        const UnitCell kind = classify_unit_cell(cell);
        if (kind == UnitCell::number) {
            lines = before;
            return;
        }
        units += kind == UnitCell::unit;
        others += kind == UnitCell::other;
    }
    if (units <= others || cells.size() != trace.channels.size()) {
        lines = before;
        return;
    }
    for (std::size_t c = 0; c < cells.size(); ++c) {
        const auto unit = std::string(unquote(cells[c]));
        auto& channel = trace.channels[c];
        if (classify_unit_cell(unit) == UnitCell::empty) continue;
        if (!channel.source_unit.empty() && channel.source_unit != unit) {
            throw InputError(
                fmt::format("{}:{}: column {} ('{}') has the unit '{}' in the header and '{}' in the "
                            "row of units under it",
                            source, lines.number, c + 1, channel.name, channel.source_unit, unit));
        }
        channel.source_unit = unit;
    }
    trace.findings.push_back(fmt::format("units taken from the row under the header (line {})", lines.number));
}

// The rows the rest of the text can hold, counted before reading, so that every column is allocated once at its
// final size (no growth, no copy, nothing to give back): one row per line, and a row of n cells takes at least n
// bytes (n - 1 separators and a line end), which bounds the rows however the lines are counted: reserving for blank
// lines under a wide header would otherwise claim columns x lines values, gigabytes for a file of kilobytes.
void reserve_rows(std::vector<Channel>& channels, std::string_view text, std::size_t position,
                  const std::function<void(const char*)>& release) {
    const std::string_view rest = text.substr(std::min(position, text.size()));
    const std::size_t rows = std::min(count_line_ends(rest, release) + 1, rest.size() / channels.size() + 1);
    for (auto& channel : channels) {
        channel.values.reserve(rows);
        prefer_huge_pages(channel.values);
    }
}

// Columns found to hold text: per column a flag, and where its first text cell was (for the finding).
struct TextColumns {
    std::vector<char> is_text;
    std::vector<std::pair<std::size_t, std::string>> first_cell;
};

// What the data rows are read into and checked against.
struct DataRows {
    const std::string& source;
    char separator;
    std::size_t columns;
    std::vector<Channel>& channels;
    TextColumns& text;
};

// A cell that is not a number in column c: skipped when the column holds text (a column whose cells so far were all
// missing or text becomes one here); returns where the cell ends, or nullptr when the column holds numbers.
const char* skip_text_cell(const DataRows& rows, std::size_t c, std::size_t line_number, const char* cell_start,
                           const char* end) {
    if (c >= rows.columns) return nullptr;
    if (rows.text.is_text[c] == 0) {
        const auto& values = rows.channels[c].values;
        if (std::any_of(values.begin(), values.end(), [](double v) { return !std::isnan(v); })) return nullptr;
        rows.text.is_text[c] = 1;
        const char* stop = std::find(cell_start, end, rows.separator);
        rows.text.first_cell[c] = {
            line_number, printable(trim(std::string_view(cell_start, static_cast<std::size_t>(stop - cell_start))))};
    }
    const char* cell_end =
        *cell_start == '"' ? std::find(cell_start + 1, end, '"') + 1 : std::find(cell_start, end, rows.separator);
    return std::min(cell_end, end);
}

InputError not_a_number(const DataRows& rows, std::size_t line_number, std::size_t c, const char* cell_start,
                        const char* end) {
    const char* cell_end = std::find(cell_start, end, rows.separator);
    const auto cell = trim(std::string_view(cell_start, static_cast<std::size_t>(cell_end - cell_start)));
    if (c >= rows.columns) {
        return InputError(fmt::format("{}:{}: row has more cells than the header's {} columns", rows.source,
                                      line_number, rows.columns));
    }
    return InputError(fmt::format("{}:{}: column {} ('{}') holds '{}', which is not a number", rows.source, line_number,
                                  c + 1, rows.channels[c].name, printable(cell)));
}

// The slow path for a cell that does not start with a number: a quoted number or a spelled-out missing value. Returns
// where the cell ends, or nullptr when it is neither.
const char* read_unusual_cell(const char* cell_start, const char* end, char separator,
                              const fast_float::parse_options& options, double& value) {
    const char* cell_end =
        *cell_start == '"' ? std::find(cell_start + 1, end, '"') + 1 : std::find(cell_start, end, separator);
    cell_end = std::min(cell_end, end);
    const auto cell = trim(std::string_view(cell_start, static_cast<std::size_t>(cell_end - cell_start)));
    if (cell == "NA" || cell == "N/A" || cell == "n/a" || cell == "-" || cell == "\"\"") {
        value = missing;
    } else if (!parse_quoted(cell, options, value)) {
        return nullptr;
    }
    return cell_end;
}

// One data row, a value appended to every column (an empty cell is missing: NaN).
void read_row(std::string_view line, std::size_t line_number, const fast_float::parse_options& options,
              const DataRows& rows) {
    const char separator = rows.separator;
    const std::size_t columns = rows.columns;
    const char* p = line.data();
    const char* const end = line.data() + line.size();
    std::size_t c = 0;
    while (true) {
        while (p < end && (*p == ' ' || *p == '\t') && *p != separator) ++p;
        double value = missing;
        const char* cell_start = p;
        if (p < end && *p == '+') ++p;
        if (p < end && *p != separator && *p != '\r') {
            const auto parsed = fast_float::from_chars_advanced(p, end, value, options);
            if (parsed.ec != std::errc() || parsed.ptr == p) {
                p = read_unusual_cell(cell_start, end, separator, options, value);
            } else {
                p = parsed.ptr;
                while (p < end && (*p == ' ' || *p == '\t' || *p == '\r') && *p != separator) ++p;
                if (p < end && *p != separator) p = nullptr;  // a number followed by more: "1.5mm"
            }
            if (p == nullptr) {
                value = missing;
                p = skip_text_cell(rows, c, line_number, cell_start, end);
                if (p == nullptr) throw not_a_number(rows, line_number, c, cell_start, end);
            }
        }
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\r') && *p != separator) ++p;
        if (c >= columns) {
            // one empty cell after a trailing separator is no extra column
            const bool empty_cell =
                std::isnan(value) &&
                trim(std::string_view(cell_start, static_cast<std::size_t>(p - cell_start))).empty();
            if (!(c == columns && empty_cell && p >= end)) {
                throw InputError(fmt::format("{}:{}: row has more cells than the header's {} columns", rows.source,
                                             line_number, columns));
            }
            break;
        }
        append(rows.channels[c].values, value);
        ++c;
        if (p >= end) break;
        if (*p != separator) throw not_a_number(rows, line_number, c - 1, cell_start, end);
        ++p;  // past the separator
    }
    if (c != columns) {
        throw InputError(
            fmt::format("{}:{}: row has {} cells, the header has {} columns", rows.source, line_number, c, columns));
    }
}

// The data rows to the end of the text; returns how many there were. `release` as for parse_csv_text.
std::size_t read_data_rows(TextLines& lines, const DataRows& rows, const std::function<void(const char*)>& release) {
    // Decimal comma: only with ';' or tab separators, decided on the first data line holding a ',' in a number.
    char decimal_point = '.';
    bool decided = rows.separator == ',';
    const fast_float::parse_options dot_options{fast_float::chars_format::general, '.'};
    const fast_float::parse_options comma_options{fast_float::chars_format::general, ','};

    constexpr std::size_t release_every = std::size_t{8} << 20;
    std::size_t next_release = release_every;
    std::size_t data_rows = 0;
    std::string_view line;
    while (lines.next(line)) {
        if (lines.position >= next_release) {
            release(line.data());
            next_release = lines.position + release_every;
        }
        // only a line starting with a blank can be blank after trimming: the others skip the trim
        if (line.empty() || line.front() == '#') continue;
        if ((line.front() == ' ' || line.front() == '\t' || line.front() == '\r') && is_comment_or_blank(line)) continue;
        if (!decided) {
            if (line.find(',') != std::string_view::npos) {
                decimal_point = ',';
                decided = true;
            } else if (line.find('.') != std::string_view::npos) {
                decided = true;
            }
        }
        read_row(line, lines.number, decimal_point == ',' ? comma_options : dot_options, rows);
        ++data_rows;
    }
    return data_rows;
}

// Gives back what an estimate of the rows reserved too much.
void shrink_columns(std::vector<Channel>& channels) {
    for (auto& channel : channels) {
        if (channel.values.capacity() > channel.values.size() + channel.values.size() / 4)
            channel.values.shrink_to_fit();
    }
}

// Leaves out the columns found to hold text, with one finding naming them; one given with --channel is an error.
void drop_text_columns(Trace& trace, const TextColumns& text, const CsvOptions& options, const std::string& source) {
    if (std::find(text.is_text.begin(), text.is_text.end(), 1) == text.is_text.end()) return;
    std::string dropped;
    std::vector<Channel> kept;
    kept.reserve(trace.channels.size());
    for (std::size_t c = 0; c < trace.channels.size(); ++c) {
        auto& channel = trace.channels[c];
        if (text.is_text[c] == 0) {
            kept.push_back(std::move(channel));
            continue;
        }
        const auto& [line, cell] = text.first_cell[c];
        if (std::find(options.numeric_columns.begin(), options.numeric_columns.end(), channel.name) !=
            options.numeric_columns.end()) {
            throw InputError(
                fmt::format("{}:{}: column {} ('{}') holds '{}', text, not numbers: it cannot be used "
                            "for a role (--channel)",
                            source, line, c + 1, channel.name, cell));
        }
        dropped += fmt::format("{}'{}' ('{}' at line {})", dropped.empty() ? "" : ", ", channel.name, cell, line);
    }
    if (kept.empty()) throw InputError(fmt::format("{}: no column holds numbers (text in {})", source, dropped));
    trace.channels = std::move(kept);
    trace.findings.push_back(fmt::format("columns holding text, not numbers, left out: {}", dropped));
}

// An unnamed first column counting 0, 1, 2, ... is the index pandas writes: left out, with a finding. Unnamed and
// counting anything else, it is a column without a name: an error.
void drop_index_column(Trace& trace, const std::string& source, std::size_t header_line, std::size_t first) {
    if (trace.channels.empty() || !trace.channels.front().name.empty()) return;
    const auto& values = trace.channels.front().values;
    for (std::size_t k = 0; k < values.size(); ++k) {
        if (values[k] != static_cast<double>(first + k)) {
            throw InputError(
                fmt::format("{}:{}: column 1 has no name in the header, and it does not count 0, 1, 2, "
                            "... like an index (it holds {} in row {})",
                            source, header_line, values[k], k + 1));
        }
    }
    if (trace.channels.size() == 1) throw InputError(fmt::format("{}: the only column is an unnamed index", source));
    trace.channels.erase(trace.channels.begin());
    trace.findings.push_back("the unnamed first column counts 0, 1, 2, ... (an index, as pandas writes one): left out");
}

// Skips the lines --skip-rows names; the file must hold more.
void skip_rows(TextLines& lines, std::size_t count, const std::string& source) {
    std::string_view line;
    for (std::size_t k = 0; k < count; ++k) {
        if (!lines.next(line)) {
            throw InputError(fmt::format("{}: --skip-rows {} skips the whole file ({} lines)", source, count, k));
        }
    }
}

// The parser proper. `release(upto)` is called now and then with a pointer below which the text is no longer read,
// so a memory-mapped file can hand those pages back (read_csv); parse_csv passes a no-op.
Trace parse_csv_text(std::string_view text, const std::string& source, const CsvOptions& options,
                     const std::function<void(const char*)>& release) {
    text = checked_text(text, source);
    TextLines lines{text};
    skip_rows(lines, options.skip_rows, source);
    Preamble preamble = read_preamble(lines, source);
    const std::size_t header_line = lines.number;
    const char separator =
        preamble.stated_separator != '\0' ? preamble.stated_separator : detect_separator(preamble.header_row);

    Trace trace;
    trace.source_path = source;
    trace.format = "csv";
    trace.constants = std::move(preamble.constants);
    add_header_channels(trace, header_cells(preamble.header_row, separator), source, header_line);
    read_unit_row(lines, trace, separator, source);
    reserve_rows(trace.channels, text, lines.position, release);
    TextColumns text_columns{std::vector<char>(trace.channels.size(), 0),
                             std::vector<std::pair<std::size_t, std::string>>(trace.channels.size())};
    const DataRows rows{source, separator, trace.channels.size(), trace.channels, text_columns};
    if (read_data_rows(lines, rows, release) == 0) {
        throw InputError(fmt::format("{}: the file has a header but no data rows", source));
    }
    drop_text_columns(trace, text_columns, options, source);
    drop_index_column(trace, source, header_line, options.first_index);
    shrink_columns(trace.channels);
    return trace;
}

class MappedFile {
public:
    explicit MappedFile(const std::filesystem::path& path) {
        descriptor_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
        if (descriptor_ < 0) return;
        struct stat status {};
        if (::fstat(descriptor_, &status) != 0 || !S_ISREG(status.st_mode) || status.st_size <= 0) return;
        size_ = static_cast<std::size_t>(status.st_size);
        void* address = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, descriptor_, 0);
        if (address == MAP_FAILED) {
            size_ = 0;
            return;
        }
        data_ = static_cast<const char*>(address);
        ::madvise(address, size_, MADV_SEQUENTIAL);
    }
    MappedFile(const MappedFile&) = delete;
    MappedFile& operator=(const MappedFile&) = delete;
    ~MappedFile() {
        if (data_ != nullptr) ::munmap(const_cast<char*>(data_), size_);
        if (descriptor_ >= 0) ::close(descriptor_);
    }
    [[nodiscard]] bool mapped() const { return data_ != nullptr; }
    [[nodiscard]] std::string_view text() const { return {data_, size_}; }
    /// Drops the pages below `upto` from memory (they read back from the file should they be touched again).
    void release(const char* upto) const {
        static const auto page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
        const std::size_t length = static_cast<std::size_t>(upto - data_) / page * page;
        if (length > 0) ::madvise(const_cast<char*>(data_), length, MADV_DONTNEED);
    }

private:
    int descriptor_{-1};
    const char* data_{nullptr};
    std::size_t size_{0};
};

}  // namespace

Trace parse_csv(std::string_view text, const std::string& source, const CsvOptions& options) {
    return parse_csv_text(text, source, options, [](const char*) {});
}

Trace read_csv(const std::filesystem::path& path, const CsvOptions& options) {
    const std::string source = path.string();
    const MappedFile file(path);
    if (file.mapped()) {
        return parse_csv_text(file.text(), source, options, [&file](const char* upto) { file.release(upto); });
    }
    // Not a regular file that can be mapped (a pipe, an empty file): read it whole.
    const std::string bytes = read_file_bytes(path);
    return parse_csv(bytes, source, options);
}

std::string write_csv(const Trace& trace) {
    fmt::memory_buffer out;
    for (const auto& [name, value] : trace.constants)
        fmt::format_to(std::back_inserter(out), "# {} = {}\n", name, value);
    for (std::size_t c = 0; c < trace.channels.size(); ++c) {
        const auto& channel = trace.channels[c];
        if (c > 0) out.push_back(',');
        // a name holding the separator is quoted so that it reads back as one column
        const char* quote = channel.name.find(',') != std::string::npos ? "\"" : "";
        if (channel.unit.empty())
            fmt::format_to(std::back_inserter(out), "{}{}{}", quote, channel.name, quote);
        else
            fmt::format_to(std::back_inserter(out), "{}{} [{}]{}", quote, channel.name, channel.unit, quote);
    }
    out.push_back('\n');
    const std::size_t n = trace.samples();
    for (std::size_t k = 0; k < n; ++k) {
        for (std::size_t c = 0; c < trace.channels.size(); ++c) {
            if (c > 0) out.push_back(',');
            // "{}" is the shortest text that reads back to the same double; a shorter column leaves its cell empty
            const auto& values = trace.channels[c].values;
            if (k < values.size()) fmt::format_to(std::back_inserter(out), "{}", values[k]);
        }
        out.push_back('\n');
    }
    return fmt::to_string(out);
}

}  // namespace feedid
