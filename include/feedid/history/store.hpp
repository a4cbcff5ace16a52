#pragma once
// The parameter history: one record per test run of an axis (machine, axis, location, when it was recorded, a content
// hash of the trace, the options and feedid version that produced the result, every parameter with its standard
// error, the fit metrics and diagnostics). Callers see only the HistoryStore interface, opened by open_store from a
// location: a SQLite file (one file, no server; the default) or a PostgreSQL database (a plant's shared history,
// written by many machines at once and read by dashboards).
//
// Guarantees of the SQLite store (tested in tests/history/test_history_store.cpp):
//   - a run is written in one transaction: after a crash it is either whole or absent;
//   - re-recording the same trace with the same options (same SHA-256 of the trace file, same options) adds nothing;
//   - two processes writing at once lose nothing (WAL journal, busy timeout, BEGIN IMMEDIATE with retry);
//   - a file that is not a feedid history (corrupt, another application's SQLite file, a newer schema) is rejected
//     with an InputError before anything is written: a failed command never modifies the file;
//   - reading never writes: a reader that may write the file and its folder opens it as a writer does (so that the
//     last one to close removes DB-wal and DB-shm) but with query_only; one that may not opens it read-only
//     (mode=ro, or immutable when no DB-wal is there) and creates no file; permission and read-only mounts are
//     named as such;
//   - listings and the trend read typed columns (names, times, each parameter's value, standard error, systematic
//     error and uncertainty, the fit's figures); the stored JSON documents are parsed only for the run they are
//     needed for (history --json, the report's friction curve).

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/core/estimate.hpp"

namespace feedid::history {

/// A stored parameter: the result document's {value, stderr, systematic, uncertainty}, in the SI unit its key
/// names; absent (null) where the data could not determine it or the document did not give it.
struct StoredEstimate {
    StoredEstimate() = default;
    StoredEstimate(std::optional<double> value_, std::optional<double> standard_error_,
                   std::optional<double> systematic_ = {}, std::optional<double> uncertainty_ = {})
        : value(value_), standard_error(standard_error_), systematic(systematic_), uncertainty(uncertainty_) {}

    std::optional<double> value;
    std::optional<double> standard_error;
    std::optional<double> systematic;   ///< bound of the systematic error, when the result gives one
    std::optional<double> uncertainty;  ///< combined uncertainty, when the result gives one
};

/// The fit's figures of a run ("fit" of the result document) as typed columns.
struct FitFigures {
    std::optional<double> relative_error_pct;
    std::optional<double> condition_number;
    std::optional<double> samples_used;
};

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
    /// "symmetric", "asymmetric", ... for an identification; fingerprint_model for a fingerprint run (feedid
    /// fingerprint --record), whose parameters are the fingerprint's figures and whose trend is its own.
    std::string model;
    /// "linear" or "rotary" (from the result; runs stored before schema version 4 get it from their parameter keys).
    /// One axis of one machine holds runs of one kind: add_run refuses the other with an InputError.
    std::string axis_kind;
    std::string status;  ///< the result's status ("ok", "partial", ...), "" when it had none
    /// Identification options used (canonical key order); null in a RunDetail::summary listing.
    nlohmann::json options = nlohmann::json::object();
    /// Equal for runs identified with equal options within one answer of the store (0: compare `options`).
    std::int64_t options_group{0};
    std::map<std::string, StoredEstimate> parameters;  ///< keys as in the result document ("coulomb_N", ...)
    FitFigures fit_figures;                            ///< from "fit", in every listing
    /// The result's "fit" object as recorded; null in a RunDetail::summary listing.
    nlohmann::json fit = nlohmann::json::object();
    std::vector<std::string> diagnostics;  ///< empty in a RunDetail::summary listing
    std::string stored_at;                 ///< when the store wrote it, ISO 8601 UTC
    /// The result document as recorded, without the bulky RLS history (keeps the friction curve, selection and
    /// Stribeck fit for the report); an empty object for runs stored before schema version 3, null in a summary.
    nlohmann::json result = nlohmann::json::object();
    /// What recording changed (text cut to the store's limits): for the recording command to print, not stored.
    std::vector<std::string> recording_findings;
};

/// How much of each run a listing reads.
enum class RunDetail {
    summary,    ///< the typed columns only: names, times, status, parameters, fit figures, options_group
    documents,  ///< also the stored documents, parsed: options, fit, diagnostics, result
};

/// One axis's runs in recording order as the trend reads them: compact columns, no documents.
struct SeriesRuns {
    std::string machine;
    std::string axis;
    std::vector<std::int64_t> run_ids;
    std::vector<std::string> recorded_at;
    std::vector<std::int64_t> options_groups;  ///< equal for runs identified with equal options
    std::vector<std::string> keys;             ///< every parameter key of these runs, sorted
    /// estimates[k][i]: parameter keys[k] of run i (all null where the run lacks it).
    std::vector<std::vector<StoredEstimate>> estimates;
    /// fingerprint[i]: 1 when run i is a fingerprint run (model fingerprint_model); empty when none is.
    std::vector<char> fingerprint;

    [[nodiscard]] std::size_t size() const { return run_ids.size(); }
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
    /// InputError naming machine, axis and both kinds when the axis holds runs of the other axis kind, and naming the
    /// field when a text of the run is not one every backend stores (is_storable_text: valid UTF-8 without NUL), so
    /// that a SQLite file and a PostgreSQL database accept the same runs.
    virtual AddOutcome add_run(const RunRecord& run) = 0;
    /// Runs matching the filter, ordered by recording time, then id.
    [[nodiscard]] virtual std::vector<RunRecord> runs(const RunFilter& filter = {},
                                                      RunDetail detail = RunDetail::documents) const = 0;
    /// The runs matching the filter as the trend reads them, one series per (machine, axis), ordered by machine,
    /// then axis; each in recording order (time, then id).
    [[nodiscard]] virtual std::vector<SeriesRuns> series(const RunFilter& filter = {}) const = 0;
    /// A page of the runs in the order the store added them (by id): at most `limit` runs with an id above
    /// `after_id`, with their documents (RunDetail::documents); empty after the last. For reading a large history in
    /// bounded memory (copy_history).
    [[nodiscard]] virtual std::vector<RunRecord> runs_in_storage_order(std::int64_t after_id,
                                                                       std::size_t limit) const = 0;
    /// The stored result document of a run (without its RLS history); an empty object when none was stored.
    /// InputError when there is no such run or its document is not readable JSON.
    [[nodiscard]] virtual nlohmann::json result_document(std::int64_t run_id) const = 0;
    /// A full check of the file: every page, every index against its table (SQLite's integrity_check), and every
    /// stored document readable as JSON. The problems found, in words; empty when there are none.
    [[nodiscard]] virtual std::vector<std::string> verify() const = 0;
    /// Pins the baseline of (machine, axis) to a run (replacing an earlier pin). InputError if the run does not exist
    /// or belongs to another machine or axis.
    virtual void pin_baseline(const std::string& machine, const std::string& axis, std::int64_t run_id) = 0;
    /// Every pinned baseline.
    [[nodiscard]] virtual std::vector<BaselinePin> pins() const = 0;
    /// The schema version of the open store.
    [[nodiscard]] virtual int schema_version() const = 0;
};

/// The model of a fingerprint run: lost motion, backlash, stiffness and reversal error of an axis
/// (fingerprint.hpp), recorded beside its identifications.
inline constexpr std::string_view fingerprint_model = "fingerprint";

/// True for a run of feedid fingerprint (its model is fingerprint_model).
bool is_fingerprint_run(const RunRecord& run);

/// The newest schema this build writes (PRAGMA user_version of the SQLite file). Schema 6: fingerprint runs beside
/// the identifications (a build of schema 5 would read them as identifications, so it refuses the file as newer).
inline constexpr int sqlite_schema_version = 6;

/// Limits of the text a run stores; longer text is cut (at a character boundary, with a mark) and a finding says so.
struct StoredTextLimits {
    std::size_t line_bytes{4096};         ///< one diagnostic, note or other string of the stored documents
    std::size_t diagnostics{200};         ///< diagnostics kept (the first ones)
    std::size_t document_bytes{1 << 20};  ///< the stored result document; larger is refused (InputError)
    std::size_t options_bytes{1 << 16};   ///< the identification options; larger are refused (InputError)
};

struct SqliteOpenOptions {
    bool read_only{false};  ///< open for reading only; the file must exist and is never written
    bool create{true};      ///< create the file when missing (ignored when read_only)
    /// Migrate no further than this schema version (tests of the migrations create older files with it).
    int target_schema_version{sqlite_schema_version};
    int busy_timeout_ms{30000};  ///< how long a writer waits for another process's transaction [ms]
};

/// Opens (or creates) a SQLite history file. InputError, naming the file, when it is not a feedid history, is
/// corrupt, has a newer schema than this build understands, or cannot be opened as asked (permission, a read-only
/// file system, a folder where a writer must create DB-wal, not a regular file); the file is not modified in those
/// cases. A file that is missing is created only when `create` is set and `read_only` is not.
///
/// Test hook: when the environment variable FEEDID_TEST_ABORT_AFTER_STATEMENT=N is set, the store calls std::abort()
/// right after executing its N-th write statement of the process (counting from 1), to test that an interrupted
/// write leaves the file whole. Never set it outside tests.
std::unique_ptr<HistoryStore> open_sqlite_store(const std::filesystem::path& path,
                                                const SqliteOpenOptions& options = {});

/// How a history is opened, whatever holds it.
struct OpenOptions {
    bool read_only{false};  ///< open for reading only; nothing is ever written
    bool create{true};      ///< a SQLite file: create it when missing (ignored when read_only)
    /// A database server: a connection lost after the history was opened (a restart, a network cut) is tried again
    /// with backoff (0.1 s doubling to 5 s) for this long [s] before the call gives up with Unavailable.
    double retry_s{300.0};
    /// When set (to true, by another thread), the retries stop at once with Unavailable (a service shutting down).
    const std::atomic<bool>* cancel{nullptr};
};

/// The history's server went away and did not come back within OpenOptions::retry_s (or the retry was cancelled):
/// nothing was written by the call that throws it; the same call may be made again later.
class Unavailable : public InputError {
public:
    using InputError::InputError;
};

/// The newest schema of the PostgreSQL backend (the highest version in its feedid_schema table). Schema 3:
/// fingerprint runs, and a series_<key> view per fingerprint figure.
inline constexpr int postgres_schema_version = 3;

/// True when `location` names a PostgreSQL database (a URI starting postgresql:// or postgres://) rather than a
/// SQLite file.
bool is_postgresql_location(std::string_view location);

/// True when this build has the PostgreSQL backend (libpq was found when feedid was built).
bool postgresql_supported();

/// The location as messages show it: a PostgreSQL URI without a password (neither user:password@ nor a password=
/// parameter); a path as it is.
std::string shown_location(const std::string& location);

/// True when a PostgreSQL URI holds a password (user:password@ or a password= parameter). open_store refuses such a
/// location: a password on the command line shows in `ps` and in logs; libpq reads it from ~/.pgpass, PGPASSFILE, a
/// service file (PGSERVICEFILE) or PGPASSWORD instead.
bool location_has_password(const std::string& location);

/// Opens the history at `location`: a PostgreSQL URI (is_postgresql_location; libpq's environment variables PGHOST,
/// PGUSER, PGPASSWORD, ... and service files fill in what the URI leaves out, e.g. postgresql:///?service=plant)
/// opens the PostgreSQL backend, anything else is a SQLite file (open_sqlite_store). InputError naming the location
/// (never a password) when it cannot be opened as asked, when it holds a password (location_has_password), and when
/// a PostgreSQL location is given to a build without the PostgreSQL backend.
std::unique_ptr<HistoryStore> open_store(const std::string& location, const OpenOptions& options = {});

/// Opens the history held in a PostgreSQL database (postgresql://user@host:port/db). A writer creates the schema, or
/// migrates it, in one transaction (serialised between processes by an advisory lock); a reader writes nothing (its
/// session is read-only). InputError, one line naming user, host, port and database, when the server is unreachable,
/// refuses the authentication or the user lacks a permission; when the database holds another application's tables
/// of the same names, or a newer feedid schema.
///
/// A run is written in one transaction; a run already stored (same trace hash, same options) is found inside it and,
/// should two writers race, the unique index keeps one (INSERT ... ON CONFLICT DO NOTHING). A call whose connection
/// is lost is retried on a new connection, with backoff, for OpenOptions::retry_s, without duplicates; then
/// Unavailable.
///
/// Test hooks (never set them outside tests): FEEDID_TEST_ABORT_AFTER_STATEMENT=N as for SQLite (BEGIN, the run,
/// its documents, its parameters and COMMIT are the write statements); FEEDID_TEST_DROP_CONNECTION_AT_STATEMENT=N
/// ends the store's own server session just before its N-th write statement, once, to test the retry;
/// FEEDID_TEST_PAUSE_AFTER_STATEMENT=N sleeps two minutes right after the N-th, so that a test can kill the process
/// in the middle of a write.
std::unique_ptr<HistoryStore> open_postgres_store(const std::string& location, const OpenOptions& options = {});

/// What copy_history did.
struct CopyOutcome {
    std::size_t copied{0};         ///< runs added to the destination
    std::size_t already_there{0};  ///< runs the destination held already (same trace, same options)
    std::size_t pins{0};           ///< baselines pinned in the destination (those not already pinned there)
};

/// Copies every run of `from` into `to` in the order `from` stored them (each in its own transaction, skipping those
/// `to` holds already; read a page of runs at a time), then its pinned baselines, mapped to the runs' ids in `to`.
/// Copying again adds nothing.
CopyOutcome copy_history(const HistoryStore& from, HistoryStore& to);

/// True when the file starts with the SQLite 3 header ("SQLite format 3\0").
bool looks_like_sqlite(const std::filesystem::path& path);

/// ISO 8601 UTC with milliseconds ("2026-11-23T09:30:21.250Z") of a file's modification time.
std::string file_modification_time_utc(const std::filesystem::path& path);
/// The current time, ISO 8601 UTC with milliseconds.
std::string now_utc();

/// Builds a run record from an identify result document (docs/documents.md), copying every parameter key
/// it holds; a fingerprint document (one with a "fingerprint" object) goes to run_from_fingerprint. InputError naming `source` and the key when the document is not an identify result: every value is
/// checked against the result document's schema (result_document.hpp's from_json), so a document that could not be
/// read back later is never stored. Text beyond `limits` is cut, with a finding in recording_findings and in the
/// stored diagnostics. Machine, axis, location, recorded_at, trace hash and options are left for the caller to fill
/// in (prepare_run in record.hpp does it).
RunRecord run_from_result(const nlohmann::json& result, const std::string& source, const StoredTextLimits& limits = {});

/// Builds a run record from a fingerprint document (feedid fingerprint --json; fingerprint.hpp): model
/// fingerprint_model, the figures of "fingerprint" as its parameters (lost motion, backlash, stiffness and reversal
/// error, each per direction where the document has it; not the breakaway force, whose keys are the identification's
/// breakaway friction and which the identification runs track), samples_used as the fit's figure, the document
/// without its "curves" as the stored result. InputError naming `source` and the key when it is not a fingerprint
/// document. Machine, axis and the rest are left for the caller (prepare_run).
RunRecord run_from_fingerprint(const nlohmann::json& document, const std::string& source,
                               const StoredTextLimits& limits = {});

/// The parameter keys a fingerprint run stores (linear and rotary).
std::vector<std::string> fingerprint_parameter_keys();

/// "rotary" when a parameter key is of a rotary axis (inertia_kgm2, viscous_Nms_per_rad, ...), else "linear".
std::string axis_kind_of(const std::map<std::string, StoredEstimate>& parameters);

/// The run as JSON (the `feedid history --json` element).
nlohmann::json to_json(const RunRecord& run);

}  // namespace feedid::history
