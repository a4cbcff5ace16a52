// libFuzzer target: SINUMERIK trace XML. Any input must either read or be refused with an InputError; anything else
// (a crash, another exception, a sanitizer report, a hang, unbounded memory) is a bug.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "feedid/error.hpp"
#include "feedid/io/sinumerik_trace.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    try {
        (void)feedid::parse_sinumerik_trace_axes(text, "fuzz.xml");
    } catch (const feedid::InputError&) {
    }
    try {
        (void)feedid::parse_sinumerik_trace(text, "fuzz.xml", "2");
    } catch (const feedid::InputError&) {
    }
    return 0;
}
