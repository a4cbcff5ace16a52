#pragma once
// How an analysis ended. Written to documents as "ok", "partial", "failed" (json_adapters.hpp).

namespace feedid {

enum class Status {
    ok,       ///< every parameter determined
    partial,  ///< some parameters null, each with a diagnostic saying why
    failed,   ///< nothing usable; the diagnostics say why and what data would help
};

/// "ok", "partial" or "failed".
[[nodiscard]] inline const char* to_string(Status status) {
    switch (status) {
        case Status::ok: return "ok";
        case Status::partial: return "partial";
        case Status::failed: return "failed";
    }
    return "failed";
}

}  // namespace feedid
