#pragma once
// An identification in a few lines of text for a person (as Ceres' Summary::BriefReport): what the terminal shows after
// feedid identify and what Python shows for a result. The result document (result_document.hpp) is for programs.

#include <string>

#include "feedid/identify/identify.hpp"

namespace feedid {

/// The parameter table: a heading row, then one row per parameter in document order with its symbol, value,
/// standard error (statistical), combined uncertainty (with the preprocessing's systematic part) and unit; "—" where a
/// figure is null. Every line is indented by two spaces and ends in a newline.
[[nodiscard]] std::string parameter_table_text(const IdentifyResult& result);

/// The drive signal's delay behind the position where it was applied ("timing: the drive signal lags the position by
/// 0.5 ms +/- 0.01 (estimated): read that much later", and a newline); "" where none was.
[[nodiscard]] std::string timing_line(const IdentifyResult& result);

/// The trace (path, samples, duration [s]), the model and the status on two lines, an empty line, then
/// parameter_table_text(). Text from input files (the path) passes through terminal_text().
[[nodiscard]] std::string brief_report(const IdentifyResult& result);

}  // namespace feedid
