// The history store (store.hpp): its SQLite implementation.
//
// Durability: the file runs in WAL journal mode; a run is written inside one BEGIN IMMEDIATE ... COMMIT, so a process
// killed anywhere leaves either the whole run or none of it (SQLite's atomic commit: the commit frame in the WAL is
// the single point where the transaction becomes visible). Concurrency: BEGIN IMMEDIATE takes the write lock up
// front, so two writers never deadlock on a lock upgrade; a writer that finds the lock taken waits (busy timeout) and,
// should SQLite still report SQLITE_BUSY, retries the whole transaction.
//
// Safety of foreign files: before anything is written the file is checked (header, integrity_check for a writer,
// quick_check for a reader, application_id, schema version). A file that fails a check is closed untouched, so a
// failed command never modifies it.
//
// Layout (schema 6; 6 added fingerprint runs, told by their model): `runs` holds one narrow row per run with typed columns (names, times, status, options, the fit's
// figures); `parameters` one row per run and key (value, stderr, systematic, uncertainty); `documents` the bulky
// result document and diagnostics, read only for the run that needs them. Listings and the trend never touch it.

#include "feedid/history/store.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdlib>
#include <thread>
#include <unordered_map>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/io/json_input.hpp"
#include "sqlite_access.hpp"
#include "sqlite_statement.hpp"
#include "store_parts.hpp"

namespace feedid::history {
namespace {

// "FEID": marks the file as a feedid history (PRAGMA application_id, bytes 68-71 of the header).
constexpr int application_id = 0x46454944;

// A number of the fit object of schema < 5 (the JSON text of fit_json), NULL where it is not one.
#define FEEDID_FIT_NUMBER(column, key)                                              \
    "CASE WHEN json_valid(" column ") THEN CASE WHEN json_type(" column ", '$." key \
    "') IN ('real', 'integer') "                                                    \
    "THEN json_extract(" column ", '$." key "') END END"

// One migration per schema version: migrations[v - 1] takes the file from version v - 1 to v.
const char* const migrations[] = {
    // 1: runs and their parameters
    "CREATE TABLE runs ("
    "  id INTEGER PRIMARY KEY AUTOINCREMENT,"
    "  machine TEXT NOT NULL, axis TEXT NOT NULL, location TEXT NOT NULL DEFAULT '',"
    "  recorded_at TEXT NOT NULL, trace_path TEXT NOT NULL, trace_sha256 TEXT NOT NULL,"
    "  feedid_version TEXT NOT NULL, model TEXT NOT NULL, status TEXT NOT NULL DEFAULT '',"
    "  options_json TEXT NOT NULL, fit_json TEXT NOT NULL, diagnostics_json TEXT NOT NULL,"
    "  stored_at TEXT NOT NULL,"
    "  UNIQUE (trace_sha256, options_json));"
    "CREATE INDEX runs_by_axis ON runs (machine, axis, recorded_at);"
    "CREATE TABLE parameters ("
    "  run_id INTEGER NOT NULL REFERENCES runs (id) ON DELETE CASCADE, key TEXT NOT NULL,"
    "  value REAL, stderr REAL, PRIMARY KEY (run_id, key)) WITHOUT ROWID;",
    // 2: pinned baselines for the trend
    "CREATE TABLE baselines ("
    "  machine TEXT NOT NULL, axis TEXT NOT NULL, run_id INTEGER NOT NULL REFERENCES runs (id),"
    "  pinned_at TEXT NOT NULL, PRIMARY KEY (machine, axis));",
    // 3: the result document (without the RLS history) for the report's friction curve
    "ALTER TABLE runs ADD COLUMN result_json TEXT NOT NULL DEFAULT '{}';",
    // 4: the axis kind of each run; earlier runs' from their mass key (a rotary axis's result has inertia_kgm2)
    "ALTER TABLE runs ADD COLUMN axis_kind TEXT NOT NULL DEFAULT '';"
    "UPDATE runs SET axis_kind = CASE WHEN EXISTS (SELECT 1 FROM parameters p WHERE p.run_id = runs.id AND "
    "p.key = 'inertia_kgm2') THEN 'rotary' ELSE 'linear' END;",
    // 5: the bulky documents move out of the runs table (a listing reads narrow rows); the fit's figures become
    // typed columns; each parameter gets its systematic error and combined uncertainty
    "CREATE TABLE documents ("
    "  run_id INTEGER PRIMARY KEY REFERENCES runs (id) ON DELETE CASCADE,"
    "  result_json TEXT NOT NULL, diagnostics_json TEXT NOT NULL);"
    "INSERT INTO documents (run_id, result_json, diagnostics_json) SELECT id, result_json, diagnostics_json FROM runs;"
    "ALTER TABLE runs DROP COLUMN result_json;"
    "ALTER TABLE runs DROP COLUMN diagnostics_json;"
    "ALTER TABLE runs ADD COLUMN relative_error_pct REAL;"
    "ALTER TABLE runs ADD COLUMN condition_number REAL;"
    "ALTER TABLE runs ADD COLUMN samples_used INTEGER;"
    "UPDATE runs SET relative_error_pct = " FEEDID_FIT_NUMBER("fit_json", "relative_error_pct") ","
    " condition_number = " FEEDID_FIT_NUMBER("fit_json", "condition_number") ","
    " samples_used = " FEEDID_FIT_NUMBER("fit_json", "samples_used") ";"
    "ALTER TABLE parameters ADD COLUMN systematic REAL;"
    "ALTER TABLE parameters ADD COLUMN uncertainty REAL;",
    // 6: fingerprint runs (model 'fingerprint') beside the identifications, each kind its own trend; a build of
    // schema 5 would take them for identifications, so the version keeps it out
    "CREATE INDEX IF NOT EXISTS runs_by_kind ON runs (machine, axis, model);",
};
static_assert(std::size(migrations) == sqlite_schema_version);

// The FEEDID_TEST_ABORT_AFTER_STATEMENT hook (see store.hpp).
void count_write_statement() {
    static const long abort_after = [] {
        const char* text = std::getenv("FEEDID_TEST_ABORT_AFTER_STATEMENT");
        return text ? std::strtol(text, nullptr, 10) : 0L;
    }();
    static long executed = 0;
    if (abort_after > 0 && ++executed == abort_after) std::abort();
}

/// The columns that differ between schema versions, as SQL expressions over `runs r` (and `documents d`).
struct Columns {
    std::string axis_kind;
    std::string fit_figures;  // three columns
    std::string diagnostics;
    std::string result;
    std::string documents_join;
    std::string parameter_errors;  // systematic, uncertainty of `parameters p`
};

Columns columns_of(int version) {
    Columns c;
    c.axis_kind = version >= 4 ? "r.axis_kind" : "''";
    c.fit_figures = version >= 5
                        ? "r.relative_error_pct, r.condition_number, r.samples_used"
                        : FEEDID_FIT_NUMBER("r.fit_json", "relative_error_pct") ", " FEEDID_FIT_NUMBER(
                              "r.fit_json", "condition_number") ", " FEEDID_FIT_NUMBER("r.fit_json", "samples_used");
    c.diagnostics = version >= 5 ? "d.diagnostics_json" : "r.diagnostics_json";
    c.result = version >= 5 ? "d.result_json" : version >= 3 ? "r.result_json" : "'{}'";
    c.documents_join = version >= 5 ? " LEFT JOIN documents d ON d.run_id = r.id" : "";
    c.parameter_errors = version >= 5 ? "p.systematic, p.uncertainty" : "NULL, NULL";
    return c;
}

const char* const filter_clause =
    " WHERE (?1 = '' OR r.machine = ?1) AND (?2 = '' OR r.axis = ?2) AND (?3 = '' OR r.location = ?3)";

class SqliteStore final : public HistoryStore {
public:
    SqliteStore(const std::filesystem::path& path, const SqliteOpenOptions& options)
        : path_(path.string()), read_only_(options.read_only) {
        const OpenPlan plan = plan_open(path, options);
        const int code = sqlite3_open_v2(plan.name.c_str(), &db_, plan.flags | SQLITE_OPEN_NOMUTEX, nullptr);
        if (code != SQLITE_OK) {
            const std::string message = describe_sqlite_error(code, db_);
            sqlite3_close(db_);
            db_ = nullptr;
            throw InputError(fmt::format("{}: cannot open the history database: {}", path_, message));
        }
        try {
            sqlite3_busy_timeout(db_, options.busy_timeout_ms);
            if (read_only_) exec("PRAGMA query_only = ON");
            check_and_migrate(options.target_schema_version);
        } catch (...) {
            sqlite3_close(db_);
            db_ = nullptr;
            throw;
        }
    }
    SqliteStore(const SqliteStore&) = delete;
    SqliteStore& operator=(const SqliteStore&) = delete;
    ~SqliteStore() override { sqlite3_close(db_); }

    AddOutcome add_run(const RunRecord& run) override {
        require_writable();
        const StoredText text = stored_text_of(run, path_);
        return write_transaction([&] {
            Statement existing(db_, "SELECT id FROM runs WHERE trace_sha256 = ?1 AND options_json = ?2", path_);
            existing.bind(1, run.trace_sha256).bind(2, text.options_json);
            if (existing.step()) return AddOutcome{existing.integer(0), false};

            const std::string axis_kind = run.axis_kind.empty() ? axis_kind_of(run.parameters) : run.axis_kind;
            require_same_axis_kind(run, axis_kind);
            insert_run(run, axis_kind, text);
            const std::int64_t id = sqlite3_last_insert_rowid(db_);
            if (schema_version_ >= 5) insert_documents(id, text);
            insert_parameters(id, run);
            return AddOutcome{id, true};
        });
    }

    std::vector<RunRecord> runs(const RunFilter& filter, RunDetail detail) const override {
        std::vector<RunRecord> result;
        snapshot([&] {  // one snapshot for both queries
            std::unordered_map<std::int64_t, std::size_t> index;
            read_run_rows(
                std::string(filter_clause) + " ORDER BY r.recorded_at, r.id",
                [&](Statement& select) {
                    select.bind(1, filter.machine).bind(2, filter.axis).bind(3, filter.location);
                },
                detail, result, index);
            read_parameters(filter, [&](std::int64_t id, std::string_view key, const StoredEstimate& estimate) {
                if (const auto found = index.find(id); found != index.end())
                    result[found->second].parameters.emplace(std::string(key), estimate);
            });
        });
        return result;
    }

    std::vector<RunRecord> runs_in_storage_order(std::int64_t after_id, std::size_t limit) const override {
        std::vector<RunRecord> result;
        snapshot([&] {  // one snapshot for both queries
            std::unordered_map<std::int64_t, std::size_t> index;
            read_run_rows(
                " WHERE r.id > ?1 ORDER BY r.id LIMIT ?2",
                [&](Statement& select) { select.bind(1, after_id).bind(2, static_cast<std::int64_t>(limit)); },
                RunDetail::documents, result, index);
            if (!result.empty()) {
                const Columns c = columns_of(schema_version_);
                Statement select(db_,
                                 fmt::format("SELECT p.run_id, p.key, p.value, p.stderr, {} FROM parameters p WHERE "
                                             "p.run_id > ?1 AND p.run_id <= ?2",
                                             c.parameter_errors),
                                 path_);
                select.bind(1, after_id).bind(2, result.back().id);
                while (select.step())
                    result[index.at(select.integer(0))].parameters.emplace(
                        select.text(1), StoredEstimate{select.real(2), select.real(3), select.real(4), select.real(5)});
            }
        });
        return result;
    }

    std::vector<SeriesRuns> series(const RunFilter& filter) const override {
        std::vector<SeriesRuns> result;
        snapshot([&] {  // one snapshot for both queries
            // where each run lives: (series, position)
            std::unordered_map<std::int64_t, std::pair<std::uint32_t, std::uint32_t>> where;
            read_series_rows(filter, result, where);
            std::vector<std::unordered_map<std::string, std::size_t>> key_index(result.size());
            read_parameters(filter, [&](std::int64_t id, std::string_view key, const StoredEstimate& estimate) {
                const auto found = where.find(id);
                if (found == where.end()) return;
                auto& series = result[found->second.first];
                auto& keys = key_index[found->second.first];
                auto slot = keys.find(std::string(key));
                if (slot == keys.end()) {
                    slot = keys.emplace(std::string(key), series.keys.size()).first;
                    series.keys.emplace_back(key);
                    series.estimates.emplace_back(series.size());
                }
                series.estimates[slot->second][found->second.second] = estimate;
            });
        });
        for (auto& series : result) sort_keys(series);
        return result;
    }

    nlohmann::json result_document(std::int64_t run_id) const override {
        const Columns c = columns_of(schema_version_);
        Statement select(db_, fmt::format("SELECT {} FROM runs r{} WHERE r.id = ?1", c.result, c.documents_join),
                         path_);
        select.bind(1, run_id);
        if (!select.step()) throw InputError(fmt::format("{}: there is no run #{}", path_, run_id));
        const auto text = select.view(0);
        return text.empty() ? nlohmann::json::object() : parse_stored_json(text, run_id, "result document");
    }

    std::vector<std::string> verify() const override;

    void pin_baseline(const std::string& machine, const std::string& axis, std::int64_t run_id) override {
        require_writable();
        write_transaction([&] {
            Statement find(db_, "SELECT machine, axis FROM runs WHERE id = ?1", path_);
            find.bind(1, run_id);
            if (!find.step()) throw InputError(fmt::format("{}: there is no run #{}", path_, run_id));
            if (find.text(0) != machine || find.text(1) != axis)
                throw InputError(fmt::format("{}: run #{} belongs to machine '{}' axis '{}', not '{}' '{}'", path_,
                                             run_id, find.text(0), find.text(1), machine, axis));
            Statement pin(db_,
                          "INSERT INTO baselines (machine, axis, run_id, pinned_at) VALUES (?1, ?2, ?3, ?4) "
                          "ON CONFLICT (machine, axis) DO UPDATE SET run_id = excluded.run_id, "
                          "pinned_at = excluded.pinned_at",
                          path_);
            pin.bind(1, machine).bind(2, axis).bind(3, run_id).bind(4, now_utc());
            pin.step();
            count_write_statement();
            return 0;
        });
    }

    std::vector<BaselinePin> pins() const override {
        std::vector<BaselinePin> result;
        if (schema_version_ < 2) return result;
        Statement select(db_, "SELECT machine, axis, run_id FROM baselines ORDER BY machine, axis", path_);
        while (select.step()) result.push_back({select.text(0), select.text(1), select.integer(2)});
        return result;
    }

    int schema_version() const override { return schema_version_; }

private:
    /// Runs `read` in one read transaction, so that its queries see one snapshot of the file.
    template <typename Read>
    void snapshot(Read&& read) const {
        exec("BEGIN");
        try {
            read();
            exec("COMMIT");
        } catch (...) {
            sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
            throw;
        }
    }

    /// One axis holds runs of one kind: a rotary run on an axis of linear runs (or the reverse) is refused. Since
    /// every run of an axis is of its kind, one run (the first the index gives) tells it: a search for a run of the
    /// other kind would read every run of the axis, each time a run is recorded.
    void require_same_axis_kind(const RunRecord& run, const std::string& axis_kind) const {
        if (schema_version_ < 4) return;
        Statement any(db_,
                      "SELECT id, axis_kind FROM runs WHERE machine = ?1 AND axis = ?2 AND axis_kind != '' LIMIT 1",
                      path_);
        any.bind(1, run.machine).bind(2, run.axis);
        if (!any.step() || any.view(1) == axis_kind) return;
        throw InputError(
            fmt::format("{}: machine '{}' axis '{}' is a {} axis (run #{}), this run is of a {} axis: "
                        "record it under another machine or axis name",
                        path_, run.machine, run.axis, any.text(1), any.integer(0), axis_kind));
    }

    void insert_run(const RunRecord& run, const std::string& axis_kind, const StoredText& text) {
        // A file kept at an older schema (tests of the migrations) has the columns of its version.
        std::vector<std::string> columns{"machine",      "axis",         "location",       "recorded_at",
                                         "trace_path",   "trace_sha256", "model",          "status",
                                         "options_json", "fit_json",     "feedid_version", "stored_at"};
        if (schema_version_ < 5) columns.push_back("diagnostics_json");
        if (schema_version_ >= 3 && schema_version_ < 5) columns.push_back("result_json");
        if (schema_version_ >= 4) columns.push_back("axis_kind");
        if (schema_version_ >= 5)
            for (const char* c : {"relative_error_pct", "condition_number", "samples_used"}) columns.push_back(c);
        std::string names;
        std::string placeholders;
        for (std::size_t i = 0; i < columns.size(); ++i) {
            names += (i == 0 ? "" : ", ") + columns[i];
            placeholders += fmt::format("{}?{}", i == 0 ? "" : ", ", i + 1);
        }
        Statement insert(db_, fmt::format("INSERT INTO runs ({}) VALUES ({})", names, placeholders), path_);
        insert.bind(1, run.machine).bind(2, run.axis).bind(3, run.location).bind(4, run.recorded_at);
        insert.bind(5, run.trace_path).bind(6, run.trace_sha256).bind(7, run.model).bind(8, run.status);
        insert.bind(9, text.options_json).bind(10, text.fit_json).bind(11, run.feedid_version);
        insert.bind(12, text.stored_at);
        int next = 13;
        if (schema_version_ < 5) insert.bind(next++, text.diagnostics_json);
        if (schema_version_ >= 3 && schema_version_ < 5) insert.bind(next++, text.result_json);
        if (schema_version_ >= 4) insert.bind(next++, axis_kind);
        if (schema_version_ >= 5) {
            const FitFigures figures = fit_figures_of(run);
            insert.bind(next, figures.relative_error_pct).bind(next + 1, figures.condition_number);
            insert.bind(next + 2, figures.samples_used);
        }
        insert.step();
        count_write_statement();
    }

    void insert_documents(std::int64_t id, const StoredText& text) {
        Statement insert(db_, "INSERT INTO documents (run_id, result_json, diagnostics_json) VALUES (?1, ?2, ?3)",
                         path_);
        insert.bind(1, id).bind(2, text.result_json).bind(3, text.diagnostics_json);
        insert.step();
        count_write_statement();
    }

    void insert_parameters(std::int64_t id, const RunRecord& run) {
        Statement parameter(db_,
                            schema_version_ >= 5
                                ? "INSERT INTO parameters (run_id, key, value, stderr, systematic, uncertainty) "
                                  "VALUES (?1, ?2, ?3, ?4, ?5, ?6)"
                                : "INSERT INTO parameters (run_id, key, value, stderr) VALUES (?1, ?2, ?3, ?4)",
                            path_);
        for (const auto& [key, estimate] : run.parameters) {
            parameter.reset();
            parameter.bind(1, id).bind(2, key).bind(3, estimate.value).bind(4, estimate.standard_error);
            if (schema_version_ >= 5) parameter.bind(5, estimate.systematic).bind(6, estimate.uncertainty);
            parameter.step();
            count_write_statement();
        }
    }

    /// The runs `clause` (WHERE ... ORDER BY ..., its parameters bound by `bind`) selects, in its order.
    template <class Bind>
    void read_run_rows(const std::string& clause, Bind&& bind, RunDetail detail, std::vector<RunRecord>& result,
                       std::unordered_map<std::int64_t, std::size_t>& index) const {
        const Columns c = columns_of(schema_version_);
        const bool documents = detail == RunDetail::documents;
        Statement select(db_,
                         fmt::format("SELECT r.id, r.machine, r.axis, r.location, r.recorded_at, r.trace_path, "
                                     "r.trace_sha256, r.feedid_version, r.model, r.status, r.options_json, "
                                     "r.stored_at, {}, {}, {}, {}, {} FROM runs r{}{}",
                                     c.axis_kind, c.fit_figures, documents ? "r.fit_json" : "NULL",
                                     documents ? c.diagnostics : "NULL", documents ? c.result : "NULL",
                                     documents ? c.documents_join : "", clause),
                         path_);
        bind(select);
        OptionsGroups groups;
        while (select.step()) {
            RunRecord run;
            run.id = select.integer(0);
            run.machine = select.text(1);
            run.axis = select.text(2);
            run.location = select.text(3);
            run.recorded_at = select.text(4);
            run.trace_path = select.text(5);
            run.trace_sha256 = select.text(6);
            run.feedid_version = select.text(7);
            run.model = select.text(8);
            run.status = select.text(9);
            run.options_group = groups.of(select.view(10));
            run.stored_at = select.text(11);
            run.axis_kind = select.text(12);
            run.fit_figures = {select.real(13), select.real(14), select.real(15)};
            if (documents) {
                run.options = parse_stored_json(select.view(10), run.id, "options");
                run.fit = parse_stored_json(select.view(16), run.id, "fit");
                for (const auto& line : parse_stored_json(select.view(17), run.id, "diagnostics"))
                    if (line.is_string()) run.diagnostics.push_back(line.get<std::string>());
                run.result = parse_stored_json(select.view(18), run.id, "result document");
            } else {
                run.options = nullptr;
                run.fit = nullptr;
                run.result = nullptr;
            }
            index[run.id] = result.size();
            result.push_back(std::move(run));
        }
    }

    void read_series_rows(const RunFilter& filter, std::vector<SeriesRuns>& result,
                          std::unordered_map<std::int64_t, std::pair<std::uint32_t, std::uint32_t>>& where) const {
        Statement select(db_,
                         fmt::format("SELECT r.id, r.machine, r.axis, r.recorded_at, r.options_json, r.model "
                                     "FROM runs r{} "
                                     "ORDER BY r.machine, r.axis, r.recorded_at, r.id",
                                     filter_clause),
                         path_);
        select.bind(1, filter.machine).bind(2, filter.axis).bind(3, filter.location);
        OptionsGroups groups;
        while (select.step()) {
            if (result.empty() || result.back().machine != select.view(1) || result.back().axis != select.view(2)) {
                result.emplace_back();
                result.back().machine = select.text(1);
                result.back().axis = select.text(2);
            }
            auto& series = result.back();
            const std::int64_t id = select.integer(0);
            where[id] = {static_cast<std::uint32_t>(result.size() - 1), static_cast<std::uint32_t>(series.size())};
            series.run_ids.push_back(id);
            series.recorded_at.push_back(select.text(3));
            series.options_groups.push_back(groups.of(select.view(4)));
            note_kind(series, select.view(5) == fingerprint_model);
        }
    }

    /// Calls `take(run id, key, estimate)` for every parameter row of the runs matching the filter.
    template <class Take>
    void read_parameters(const RunFilter& filter, Take&& take) const {
        const Columns c = columns_of(schema_version_);
        const bool all = filter.machine.empty() && filter.axis.empty() && filter.location.empty();
        Statement select(
            db_,
            all ? fmt::format("SELECT p.run_id, p.key, p.value, p.stderr, {} FROM parameters p", c.parameter_errors)
                : fmt::format("SELECT p.run_id, p.key, p.value, p.stderr, {} FROM parameters p "
                              "JOIN runs r ON r.id = p.run_id{}",
                              c.parameter_errors, filter_clause),
            path_);
        if (!all) select.bind(1, filter.machine).bind(2, filter.axis).bind(3, filter.location);
        while (select.step())
            take(select.integer(0), select.view(1),
                 StoredEstimate{select.real(2), select.real(3), select.real(4), select.real(5)});
    }

    static void sort_keys(SeriesRuns& series) {
        std::vector<std::size_t> order(series.keys.size());
        for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
        std::sort(order.begin(), order.end(), [&](auto a, auto b) { return series.keys[a] < series.keys[b]; });
        std::vector<std::string> keys;
        std::vector<std::vector<StoredEstimate>> estimates;
        for (const auto k : order) {
            keys.push_back(std::move(series.keys[k]));
            estimates.push_back(std::move(series.estimates[k]));
        }
        series.keys = std::move(keys);
        series.estimates = std::move(estimates);
    }

    void exec(const char* sql) const {
        char* message = nullptr;
        const int code = sqlite3_exec(db_, sql, nullptr, nullptr, &message);
        if (code != SQLITE_OK) {
            sqlite3_free(message);
            const int extended = sqlite3_extended_errcode(db_);
            throw SqliteError(
                fmt::format("{}: cannot read or write the database: {}", path_, describe_sqlite_error(extended, db_)),
                extended);
        }
    }

    int pragma_integer(const char* sql) const {
        Statement statement(db_, sql, path_);
        return statement.step() ? static_cast<int>(statement.integer(0)) : 0;
    }

    void require_writable() const {
        if (read_only_) throw InputError(fmt::format("{}: opened read-only", path_));
    }

    nlohmann::json parse_stored_json(std::string_view text, std::int64_t id, const char* what) const {
        try {
            return parse_json(text, fmt::format("{}: run #{}'s {}", path_, id, what));
        } catch (const InputError& e) {
            throw InputError(
                fmt::format("{} (the file is damaged; feedid history {} --verify checks it)", e.what(), path_));
        }
    }

    /// Runs `body` inside BEGIN IMMEDIATE ... COMMIT; retries the whole transaction when SQLite reports the database
    /// busy after the busy timeout (a long transaction of another process), up to a bounded number of attempts.
    template <class Body>
    auto write_transaction(Body&& body) -> decltype(body()) {
        constexpr int attempts = 20;
        for (int attempt = 1;; ++attempt) {
            try {
                exec("BEGIN IMMEDIATE");
                count_write_statement();
            } catch (const SqliteError& e) {
                const int primary = e.code() & 0xff;
                if ((primary == SQLITE_BUSY || primary == SQLITE_LOCKED) && attempt < attempts) {
                    std::this_thread::sleep_for(std::chrono::milliseconds(50 * attempt));
                    continue;
                }
                throw;
            }
            try {
                auto result = body();
                exec("COMMIT");
                count_write_statement();
                return result;
            } catch (...) {
                sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
                throw;
            }
        }
    }

    /// Runs `step` (statements that read the file), turning SQLite's word for a damaged file into "corrupt".
    template <class Step>
    auto reading_the_file(Step&& step) const -> decltype(step()) {
        try {
            return step();
        } catch (const SqliteError& e) {
            const int primary = e.code() & 0xff;
            if (primary == SQLITE_CORRUPT || primary == SQLITE_NOTADB)
                throw InputError(
                    fmt::format("{}: the history database is corrupt (not a readable SQLite file)", path_));
            throw;  // not the file's fault: a lock, the disk, a permission, named as such
        }
    }

    /// SQLite's check of the tables the listings and the trend read, and of their indexes (quick_check for a reader;
    /// integrity_check for a writer: only the full check compares every index with its table). The bulky documents
    /// table is left to --verify: checking it reads every stored document, hundreds of MB in a large history, and
    /// a damaged page there is reported as corrupt when it is read. The first finding; "ok" when there is none.
    std::string check_tables(const char* pragma) const {
        return reading_the_file([&] {
            Statement tables(db_,
                             "SELECT name FROM sqlite_master WHERE type = 'table' AND name IN ('runs', 'parameters', "
                             "'baselines') ORDER BY name",
                             path_);
            std::vector<std::string> names;
            while (tables.step()) names.push_back(tables.text(0));
            if (names.empty()) names.emplace_back();  // a file without them: the whole (small) file
            for (const auto& name : names) {
                Statement check(db_, name.empty() ? std::string(pragma) : fmt::format("{}({})", pragma, name), path_);
                if (check.step() && check.view(0) != "ok") return check.text(0);
            }
            return std::string("ok");
        });
    }

    void check_and_migrate(int target_version);

    std::string path_;
    bool read_only_;
    sqlite3* db_{nullptr};
    int schema_version_{0};
};

void SqliteStore::check_and_migrate(int target_version) {
    // Read-only checks first: nothing below writes until the file is known to be a feedid history (or empty).
    // One snapshot for the three: another process may be creating the tables right now.
    const auto [found_application, version, tables] = reading_the_file([&] {
        std::array<int, 3> header{};
        snapshot([&] {
            header = {pragma_integer("PRAGMA application_id"), pragma_integer("PRAGMA user_version"),
                      pragma_integer("SELECT count(*) FROM sqlite_master")};
        });
        return header;
    });
    schema_version_ = version;
    std::string check = check_tables(read_only_ ? "PRAGMA quick_check" : "PRAGMA integrity_check");
    if (check != "ok") {
        // One line: SQLite lists its findings on several.
        for (auto& c : check)
            if (c == '\n') c = ' ';
        if (check.size() > 200) check = check.substr(0, 200) + "...";
        throw InputError(fmt::format("{}: the history database is corrupt (SQLite's check: {})", path_, check));
    }
    const bool empty = found_application == 0 && schema_version_ == 0 && tables == 0;
    if (!empty && found_application != application_id)
        throw InputError(
            fmt::format("{}: not a feedid history database (a SQLite file of another application)", path_));
    if (schema_version_ > sqlite_schema_version)
        throw InputError(
            fmt::format("{}: the history database has schema version {}, newer than this feedid "
                        "understands ({}); use a newer feedid",
                        path_, schema_version_, sqlite_schema_version));
    if (read_only_) {
        if (empty) throw InputError(fmt::format("{}: the history database is empty (no run recorded yet)", path_));
        return;
    }
    // WAL lets readers go on while one process writes; the mode is stored in the file. Switching needs a moment
    // of exclusive access, so it is retried while another process is busy with the file.
    for (int attempt = 1;; ++attempt) {
        try {
            exec("PRAGMA journal_mode = WAL");
            break;
        } catch (const SqliteError& e) {
            const int primary = e.code() & 0xff;
            if ((primary != SQLITE_BUSY && primary != SQLITE_LOCKED) || attempt >= 20) throw;
            std::this_thread::sleep_for(std::chrono::milliseconds(50 * attempt));
        }
    }
    if (schema_version_ >= target_version) return;
    write_transaction([&] {
        // Re-read inside the write lock: another process may have migrated meanwhile.
        int version = pragma_integer("PRAGMA user_version");
        if (version == 0) exec(fmt::format("PRAGMA application_id = {}", application_id).c_str());
        for (; version < target_version; ++version) {
            exec(migrations[version]);
            exec(fmt::format("PRAGMA user_version = {}", version + 1).c_str());
        }
        schema_version_ = version;
        return 0;
    });
}

std::vector<std::string> SqliteStore::verify() const {
    std::vector<std::string> problems;
    {
        Statement check(db_, "PRAGMA integrity_check", path_);
        while (check.step())
            if (check.view(0) != "ok") problems.push_back("SQLite's integrity check: " + check.text(0));
    }
    if (!problems.empty()) return problems;  // the tables are not to be trusted for the next check
    const Columns c = columns_of(schema_version_);
    Statement documents(db_,
                        fmt::format("SELECT r.id, json_valid(r.options_json), json_valid(r.fit_json), "
                                    "json_valid(COALESCE({}, '[]')), json_valid(COALESCE({}, '{{}}')) FROM runs r{} "
                                    "ORDER BY r.id",
                                    c.diagnostics, c.result, c.documents_join),
                        path_);
    const std::array<const char*, 4> names{"options", "fit", "diagnostics", "result document"};
    while (documents.step())
        for (int k = 0; k < 4; ++k)
            if (documents.integer(k + 1) == 0)
                problems.push_back(fmt::format("run #{}: its {} is not readable JSON", documents.integer(0),
                                               names[static_cast<std::size_t>(k)]));
    return problems;
}

}  // namespace

std::unique_ptr<HistoryStore> open_sqlite_store(const std::filesystem::path& path, const SqliteOpenOptions& options) {
    return std::make_unique<SqliteStore>(path, options);
}

}  // namespace feedid::history
