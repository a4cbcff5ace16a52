// libFuzzer target: SINUMERIK trace XML. Any input must either read or be refused with an InputError; anything else
// (a crash, another exception, a sanitizer report, a hang, unbounded memory) is a bug.
//
// It also checks the reader's two paths against each other: the records of a plain trace are scanned directly, and
// anything unusual goes through pugixml's DOM. A processing instruction put just before </dataFrame> changes nothing
// in the document (checked: pugixml reads both to the same tree) but forces the DOM path, so the input and its copy
// must give the same outcome and the same values. And a document pugixml rejects must be refused.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <pugixml.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/sinumerik_trace.hpp"

namespace {

std::optional<std::vector<feedid::Trace>> read(std::string_view text) {
    try {
        return feedid::parse_sinumerik_trace_axes(text, "fuzz.xml");
    } catch (const feedid::InputError&) {
        return std::nullopt;
    }
}

// The tree pugixml reads (as the reader parses it), printed; nothing when it is not well-formed to pugixml.
std::optional<std::string> tree_of(std::string_view text) {
    pugi::xml_document document;
    if (!document.load_buffer(text.data(), text.size(), pugi::parse_minimal | pugi::parse_escapes,
                              pugi::encoding_utf8)) {
        return std::nullopt;
    }
    std::ostringstream out;
    document.save(out, "", pugi::format_raw);
    return out.str();
}

bool same_values(const std::vector<feedid::Trace>& a, const std::vector<feedid::Trace>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t t = 0; t < a.size(); ++t) {
        if (a[t].channels.size() != b[t].channels.size()) return false;
        for (std::size_t c = 0; c < a[t].channels.size(); ++c) {
            const auto& x = a[t].channels[c];
            const auto& y = b[t].channels[c];
            if (x.name != y.name || x.role != y.role || x.values.size() != y.values.size()) return false;
            for (std::size_t k = 0; k < x.values.size(); ++k) {
                const bool both_nan = std::isnan(x.values[k]) && std::isnan(y.values[k]);
                if (!both_nan && x.values[k] != y.values[k]) return false;
            }
        }
    }
    return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    const auto direct = read(text);
    try {
        (void)feedid::parse_sinumerik_trace(text, "fuzz.xml", "2");
    } catch (const feedid::InputError&) {}
    const auto tree = tree_of(text);
    if (!tree) {
        if (direct) __builtin_trap();  // read although not well-formed
        return 0;
    }
    const auto frame = text.find("<dataFrame");
    const auto end = frame == std::string_view::npos ? frame : text.find("</dataFrame>", frame);
    if (end != std::string_view::npos) {
        std::string copy(text);
        copy.insert(end, "<?feedid?>");
        if (tree_of(copy) != tree) return 0;  // the insertion was not neutral here (inside a comment, ...)
        const auto through_dom = read(copy);
        if (direct.has_value() != through_dom.has_value()) __builtin_trap();
        if (direct && !same_values(*direct, *through_dom)) __builtin_trap();
    }
    return 0;
}
