// libFuzzer target: LinuxCNC halscope exports (both layouts) and halsampler output. Read or InputError; anything
// else is a bug.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "feedid/core/error.hpp"
#include "feedid/io/halscope.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    (void)feedid::looks_like_halsampler(text);
    try {
        (void)feedid::parse_halscope(text, "fuzz.txt");
    } catch (const feedid::InputError&) {}
    try {
        (void)feedid::parse_halscope(text, "fuzz.txt", 0.001);
    } catch (const feedid::InputError&) {}
    return 0;
}
