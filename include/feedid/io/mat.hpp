#pragma once
// MATLAB .mat files (v5, and v7.3 where libmatio supports it): numeric vectors become channels, numeric scalars
// become constants (for example the EMPS file's gtau, kp, kv).

#include <filesystem>

#include "feedid/core/trace.hpp"

namespace feedid {

/// Reads a .mat file into raw channels (no units: MAT files carry none) and constants. InputError on a file that
/// is not a MAT file, or holds no numeric vector.
Trace read_mat(const std::filesystem::path& path);

}  // namespace feedid
