#pragma once
// SHA-256 content hashes: the history store recognises a trace recorded twice by its bytes, whatever its name.

#include <filesystem>
#include <string>
#include <string_view>

namespace feedid::history {

/// Lower-case hex SHA-256 of a file's bytes (streamed). InputError naming the file when it cannot be read.
std::string sha256_file(const std::filesystem::path& path);
/// Lower-case hex SHA-256 of a byte string.
std::string sha256_hex(std::string_view bytes);

}  // namespace feedid::history
