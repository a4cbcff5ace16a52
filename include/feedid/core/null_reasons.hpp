#pragma once
// Nulls in the documents feedid writes, and why each is there. JSON has no NaN or infinity (nlohmann writes them as
// null without a word), and a null a reader cannot explain is a silent gap: every document that may hold nulls
// replaces its non-finite numbers by null and names every null in a diagnostic with its reason.

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace feedid {

/// Replaces every number in `document` that is not finite by null, and returns the paths of all nulls in it, in
/// document order: "gains.velocity_feedforward.value", "series.time_s[3]" (arrays by index).
std::vector<std::string> null_paths(nlohmann::json& document);

/// Why the value at a path is null ("" = not known: said as "not a finite number").
using NullReason = std::function<std::string(std::string_view path)>;

/// Makes `document` free of NaN and infinity (null_paths()) and appends to its "diagnostics" array one line per reason
/// that names the nulls it explains: "gains.velocity_feedforward.value, gains.velocity_feedforward.stderr: null, no
/// velocity feed-forward fitted (--feedforward not given)". The nulls of one array are named once, with their count
/// ("series.tracking_error_model_m[] (1700 of 2000 values)"). Nulls inside "diagnostics" are left alone.
void explain_nulls(nlohmann::json& document, const NullReason& reason_of);

}  // namespace feedid
