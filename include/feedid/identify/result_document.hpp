#pragma once
// The identify result document (docs/documents.md): the one place where its keys are spelled. Keys carry their SI unit
// ("mass_kg", "coulomb_forward_N"; rotary "inertia_kgm2", ...); a value the data cannot determine is null.
//   nlohmann::json document = result;               // to_json
//   auto result = document.get<IdentifyResult>();   // from_json: what simulate, report, history, plan read back

#include <nlohmann/json.hpp>

#include "feedid/identify/identify.hpp"

namespace feedid {

void to_json(nlohmann::json& document, const IdentifyResult& result);
/// Reads a result document back. Throws InputError when it is not one (no "parameters" object, a parameter key that
/// is not of feedid's model, a value that is not a number or null).
void from_json(const nlohmann::json& document, IdentifyResult& result);

/// The options that shape an identify result, as stored with it: the same trace with other options is another run
/// in the history. `command_line` holds what only the command line knows (channel and unit assignments, the drive's
/// constants as given); it is merged in under its own keys.
nlohmann::json identify_options_document(const IdentifyOptions& options, const nlohmann::json& command_line);

}  // namespace feedid
