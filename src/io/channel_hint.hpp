#pragma once
// The --channel option that sets a role to a channel, as a finding prints it: pasted into a shell as printed, it
// assigns that very channel (the name quoted where a shell would split or expand it).
#include <string>
#include <string_view>

#include <fmt/core.h>

namespace feedid::io_detail {

/// "--channel position=x", "--channel 'position=Pos X'", "--channel 'position=it'\''s'".
inline std::string channel_option(std::string_view role, std::string_view channel) {
    const std::string assignment = fmt::format("{}={}", role, channel);
    const bool plain = !channel.empty() && assignment.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstu"
                                                                        "vwxyz0123456789_-.,:/+=@%") == std::string::npos;
    if (plain) return "--channel " + assignment;
    std::string quoted = "'";
    for (const char c : assignment) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return "--channel " + quoted + "'";
}

}  // namespace feedid::io_detail
