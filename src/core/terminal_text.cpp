// Escaping text for the terminal (terminal_text.hpp).
#include "feedid/core/terminal_text.hpp"

#include <cstdint>

#include <fmt/core.h>

namespace feedid {
namespace {

/// The length of the valid UTF-8 sequence at the start of `text` and its code point; 0 when it is not one
/// (a stray continuation byte, a truncated sequence, an overlong form, a surrogate, beyond U+10FFFF).
std::size_t utf8_sequence(std::string_view text, std::uint32_t& code_point) {
    const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
    const unsigned char lead = byte(0);
    std::size_t length = 0;
    if (lead < 0x80) {
        code_point = lead;
        return 1;
    }
    if (lead >= 0xC2 && lead <= 0xDF) {
        length = 2;
        code_point = lead & 0x1Fu;
    } else if (lead >= 0xE0 && lead <= 0xEF) {
        length = 3;
        code_point = lead & 0x0Fu;
    } else if (lead >= 0xF0 && lead <= 0xF4) {
        length = 4;
        code_point = lead & 0x07u;
    } else {
        return 0;
    }
    if (text.size() < length) return 0;
    for (std::size_t i = 1; i < length; ++i) {
        if ((byte(i) & 0xC0u) != 0x80u) return 0;
        code_point = (code_point << 6) | (byte(i) & 0x3Fu);
    }
    const bool overlong = (length == 3 && code_point < 0x800) || (length == 4 && code_point < 0x10000);
    const bool surrogate = code_point >= 0xD800 && code_point <= 0xDFFF;
    if (overlong || surrogate || code_point > 0x10FFFF) return 0;
    return length;
}

bool bidirectional_control(std::uint32_t c) {
    return (c >= 0x202A && c <= 0x202E) || (c >= 0x2066 && c <= 0x2069) || c == 0x200E || c == 0x200F;
}

std::string escaped(std::string_view text, bool keep_newlines) {
    std::string out;
    out.reserve(text.size());
    while (!text.empty()) {
        std::uint32_t c = 0;
        const std::size_t length = utf8_sequence(text, c);
        if (length == 0) {
            out += fmt::format("\\x{:02x}", static_cast<unsigned char>(text[0]));
            text.remove_prefix(1);
            continue;
        }
        if (c == '\n' && keep_newlines) {
            out += '\n';
        } else if (c < 0x20 || c == 0x7F) {
            out += fmt::format("\\x{:02x}", c);
        } else if ((c >= 0x80 && c <= 0x9F) || bidirectional_control(c)) {
            out += fmt::format("\\u{:04x}", c);
        } else {
            out.append(text.substr(0, length));
        }
        text.remove_prefix(length);
    }
    return out;
}

}  // namespace

std::string terminal_text(std::string_view text) {
    return escaped(text, false);
}

std::string terminal_message(std::string_view text) {
    return escaped(text, true);
}

bool is_storable_text(std::string_view text) {
    while (!text.empty()) {
        std::uint32_t c = 0;
        const std::size_t length = utf8_sequence(text, c);
        if (length == 0 || c == 0) return false;
        text.remove_prefix(length);
    }
    return true;
}

std::string name_problem(std::string_view name, std::size_t max_bytes) {
    if (name.empty()) return "empty";
    if (name.size() > max_bytes) return fmt::format("longer than {} bytes", max_bytes);
    while (!name.empty()) {
        std::uint32_t c = 0;
        const std::size_t length = utf8_sequence(name, c);
        if (length == 0) return "not UTF-8";
        if (c < 0x20 || c == 0x7F || (c >= 0x80 && c <= 0x9F)) return "a control character";
        if (bidirectional_control(c)) return "a bidirectional override";
        name.remove_prefix(length);
    }
    return "";
}

}  // namespace feedid
