// libFuzzer target: TwinCAT Scope View CSV exports. Read or InputError; anything else is a bug.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "feedid/core/error.hpp"
#include "feedid/io/twincat_scope.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    try {
        (void)feedid::parse_twincat_scope(text, "fuzz.csv");
    } catch (const feedid::InputError&) {}
    return 0;
}
