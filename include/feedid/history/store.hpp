#pragma once
// The parameter history: one record per test run of an axis (machine, axis, location, when it was recorded, a content
// hash of the trace, the options and feedid version that produced the result, every parameter with its standard
// error, the fit metrics and diagnostics). Callers see only the HistoryStore interface; SQLite (one file, no server)
// is the implementation today, and a server database can be added behind the same interface.
//
// Guarantees of the SQLite store (tested in tests/test_history_store.cpp):
//   - a run is written in one transaction: after a crash it is either whole or absent;
//   - re-recording the same trace with the same options (same SHA-256 of the trace file, same options) adds nothing;
//   - two processes writing at once lose nothing (WAL journal, busy timeout, BEGIN IMMEDIATE with retry);
//   - a file that is not a feedid history (corrupt, another application's SQLite file, a newer schema) is rejected
//     with an InputError before anything is written: a failed command never modifies the file.

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/estimate.hpp"

namespace feedid::history {

/// A value with its standard error, in the SI unit its key names; both absent when the data could not determine it.
/// A stored parameter: the result document's {value, stderr}.
using StoredEstimate = Estimate;

/// One test run of one axis.
struct RunRecord {
    std::int64_t id{0};          ///< assigned by the store (increasing in insertion order)
    std::string machine;         ///< e.g. "DMU-50 #3"
    std::string axis;            ///< e.g. "X"
    std::string location;        ///< site, for multi-centre tests ("" when not given)
    std::string recorded_at;     ///< when the trace was recorded, ISO 8601 UTC ("2026-11-23T09:30:21.250Z")
    std::string trace_path;      ///< the trace file as given when recorded
    std::string trace_sha256;    ///< lower-case hex SHA-256 of the trace file's bytes
    std::string feedid_version;  ///< version that produced the result
    std::string model;           ///< "symmetric", "asymmetric", ...
    /// "linear" or "rotary" (from the result; runs stored before schema version 4 get it from their parameter keys).
    /// One axis of one machine holds runs of one kind: add_run refuses the other with an InputError.
    std::string axis_kind;
    std::string status;  ///< the result's status ("ok", "partial", ...), "" when it had none
    nlohmann::json options = nlohmann::json::object();  ///< identification options used (canonical key order)
    std::map<std::string, StoredEstimate> parameters;   ///< keys as in the result document ("coulomb_N", ...)
    nlohmann::json fit = nlohmann::json::object();      ///< {relative_error_pct, condition_number, samples_used}
    std::vector<std::string> diagnostics;
    std::string stored_at;  ///< when the store wrote it, ISO 8601 UTC
    /// The result document as recorded, without the bulky RLS history (keeps the friction curve, selection and
    /// Stribeck fit for the report); an empty object for runs stored before schema version 3.
    nlohmann::json result = nlohmann::json::object();
};

/// Which runs to list; empty fields match everything.
struct RunFilter {
    std::string machine;
    std::string axis;
    std::string location;
};

/// What add_run did.
struct AddOutcome {
    std::int64_t id{0};    ///< the new run, or the existing one it duplicates
    bool inserted{false};  ///< false: the same trace with the same options was already recorded
};

/// A pinned baseline: trends of (machine, axis) are measured against runs from this one on.
struct BaselinePin {
    std::string machine;
    std::string axis;
    std::int64_t run_id{0};
};

/// The storage interface the CLI and the report use.
class HistoryStore {
public:
    virtual ~HistoryStore() = default;
    /// Adds a run in one transaction. Duplicate (same trace hash and options): returns the existing id, adds nothing.
    /// InputError naming machine, axis and both kinds when the axis holds runs of the other axis kind.
    virtual AddOutcome add_run(const RunRecord& run) = 0;
    /// Runs matching the filter, ordered by recording time, then id.
    [[nodiscard]] virtual std::vector<RunRecord> runs(const RunFilter& filter = {}) const = 0;
    /// Pins the baseline of (machine, axis) to a run (replacing an earlier pin). InputError if the run does not exist
    /// or belongs to another machine or axis.
    virtual void pin_baseline(const std::string& machine, const std::string& axis, std::int64_t run_id) = 0;
    /// Every pinned baseline.
    [[nodiscard]] virtual std::vector<BaselinePin> pins() const = 0;
    /// The schema version of the open store.
    [[nodiscard]] virtual int schema_version() const = 0;
};

/// The newest schema this build writes (PRAGMA user_version of the SQLite file).
inline constexpr int sqlite_schema_version = 4;

struct SqliteOpenOptions {
    bool read_only{false};  ///< open for reading only; the file must exist and is never written
    bool create{true};      ///< create the file when missing (ignored when read_only)
    /// Migrate no further than this schema version (tests of the migrations create older files with it).
    int target_schema_version{sqlite_schema_version};
    int busy_timeout_ms{30000};  ///< how long a writer waits for another process's transaction [ms]
};

/// Opens (or creates) a SQLite history file. InputError, naming the file, when it is not a feedid history, is
/// corrupt, or has a newer schema than this build understands; the file is not modified in those cases.
///
/// Test hook: when the environment variable FEEDID_TEST_ABORT_AFTER_STATEMENT=N is set, the store calls std::abort()
/// right after executing its N-th write statement of the process (counting from 1), to test that an interrupted
/// write leaves the file whole. Never set it outside tests.
std::unique_ptr<HistoryStore> open_sqlite_store(const std::filesystem::path& path,
                                                const SqliteOpenOptions& options = {});

/// True when the file starts with the SQLite 3 header ("SQLite format 3\0").
bool looks_like_sqlite(const std::filesystem::path& path);

/// ISO 8601 UTC with milliseconds ("2026-11-23T09:30:21.250Z") of a file's modification time.
std::string file_modification_time_utc(const std::filesystem::path& path);
/// The current time, ISO 8601 UTC with milliseconds.
std::string now_utc();

/// Builds a run record from an identify result document (DESIGN.md, "result document"), copying every parameter key
/// it holds. InputError naming `source` when the document is not an identify result (no "parameters" object, no
/// "model"). Machine, axis, location, recorded_at, trace hash and options are left for the caller to fill in
/// (prepare_run in record.hpp does it).
RunRecord run_from_result(const nlohmann::json& result, const std::string& source);

/// The run as JSON (the `feedid history --json` element).
nlohmann::json to_json(const RunRecord& run);

}  // namespace feedid::history
