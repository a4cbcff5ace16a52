#pragma once
// Text that came from input files or the command line (machine and axis names, channel names, paths, messages
// quoting a file) made safe to show on a terminal: a name such as "M\e]0;T\a\e[2J" must not retitle or clear the
// user's terminal, and bytes that are not UTF-8 must not garble it. Documents (JSON, CSV, HTML) keep the text as it
// is; their own escaping applies there.

#include <cstddef>
#include <string>
#include <string_view>

namespace feedid {

/// `text` with every control character (C0 including newline and tab, DEL, C1), every Unicode bidirectional
/// override and every byte that is not part of valid UTF-8 written as an escape: \x1b for a byte, \u202e for a
/// character. Valid UTF-8 otherwise passes unchanged ("±", "µm", "Δ").
std::string terminal_text(std::string_view text);

/// terminal_text() for a message that may span lines: newlines pass, everything else is escaped.
std::string terminal_message(std::string_view text);

/// True when `text` is valid UTF-8 (no stray or truncated sequence, no overlong form, no surrogate) without a NUL:
/// what every history backend stores as text (PostgreSQL refuses the rest).
bool is_storable_text(std::string_view text);

/// What is wrong with a name (a machine, an axis) that comes from outside: "" when it is 1 to `max_bytes` bytes of
/// valid UTF-8 without control characters (C0 including NUL, DEL, C1) or bidirectional overrides, else what is wrong
/// in a few words ("not UTF-8", "a control character", "longer than 64 bytes").
std::string name_problem(std::string_view name, std::size_t max_bytes);

}  // namespace feedid
