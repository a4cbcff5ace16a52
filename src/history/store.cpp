// The history store (store.hpp): its SQLite implementation, the run records it keeps, and their time stamps.
//
// Durability: the file runs in WAL journal mode; a run is written inside one BEGIN IMMEDIATE ... COMMIT, so a process
// killed anywhere leaves either the whole run or none of it (SQLite's atomic commit: the commit frame in the WAL is
// the single point where the transaction becomes visible). Concurrency: BEGIN IMMEDIATE takes the write lock up
// front, so two writers never deadlock on a lock upgrade; a writer that finds the lock taken waits (busy timeout) and,
// should SQLite still report SQLITE_BUSY, retries the whole transaction.
//
// Safety of foreign files: before anything is written the file is checked (header, quick_check, application_id,
// schema version). A file that fails a check is closed untouched, so a failed command never modifies it.

#include "feedid/history/store.hpp"

#include <sqlite3.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <thread>

#include <fmt/core.h>

#include "feedid/error.hpp"
#include "feedid/parameters.hpp"

namespace feedid::history {
namespace {

// "FEID": marks the file as a feedid history (PRAGMA application_id, bytes 68-71 of the header).
constexpr int application_id = 0x46454944;

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

class Statement {
public:
    Statement(sqlite3* db, const char* sql, const std::string& path) : db_(db), path_(path) {
        if (sqlite3_prepare_v2(db, sql, -1, &statement_, nullptr) != SQLITE_OK) fail("cannot prepare a statement");
    }
    Statement(const Statement&) = delete;
    Statement& operator=(const Statement&) = delete;
    ~Statement() { sqlite3_finalize(statement_); }

    Statement& bind(int index, const std::string& text) {
        sqlite3_bind_text(statement_, index, text.c_str(), static_cast<int>(text.size()), SQLITE_TRANSIENT);
        return *this;
    }
    Statement& bind(int index, std::int64_t value) {
        sqlite3_bind_int64(statement_, index, value);
        return *this;
    }
    Statement& bind(int index, const std::optional<double>& value) {
        if (value && std::isfinite(*value))
            sqlite3_bind_double(statement_, index, *value);
        else
            sqlite3_bind_null(statement_, index);
        return *this;
    }
    /// True while a row is available.
    bool step() {
        const int code = sqlite3_step(statement_);
        if (code == SQLITE_ROW) return true;
        if (code == SQLITE_DONE) return false;
        fail("cannot read or write the database");
    }
    void reset() {
        sqlite3_reset(statement_);
        sqlite3_clear_bindings(statement_);
    }
    [[nodiscard]] std::string text(int column) const {
        const auto* p = sqlite3_column_text(statement_, column);
        return p ? std::string(reinterpret_cast<const char*>(p),
                               static_cast<std::size_t>(sqlite3_column_bytes(statement_, column)))
                 : std::string();
    }
    [[nodiscard]] std::int64_t integer(int column) const { return sqlite3_column_int64(statement_, column); }
    [[nodiscard]] std::optional<double> real(int column) const {
        if (sqlite3_column_type(statement_, column) == SQLITE_NULL) return std::nullopt;
        return sqlite3_column_double(statement_, column);
    }
    [[noreturn]] void fail(const char* what) const;

private:
    sqlite3* db_;
    sqlite3_stmt* statement_{nullptr};
    const std::string& path_;
};

class SqliteError : public InputError {
public:
    SqliteError(const std::string& message, int code) : InputError(message), code_(code) {}
    [[nodiscard]] int code() const { return code_; }

private:
    int code_;
};

std::string describe(int code, sqlite3* db) {
    const int primary = code & 0xff;
    if (primary == SQLITE_CORRUPT || primary == SQLITE_NOTADB) return "the file is corrupt or not a SQLite database";
    if (primary == SQLITE_READONLY) return "the file is read-only";
    if (primary == SQLITE_FULL) return "the disk is full";
    if (primary == SQLITE_BUSY || primary == SQLITE_LOCKED) return "another process holds the database locked";
    return db ? sqlite3_errmsg(db) : sqlite3_errstr(code);
}

void Statement::fail(const char* what) const {
    const int code = sqlite3_extended_errcode(db_);
    throw SqliteError(fmt::format("{}: {}: {}", path_, what, describe(code, db_)), code);
}

// The axis kind a run's parameter keys name: "rotary" for inertia_kgm2, viscous_Nms_per_rad, ...
std::string axis_kind_of(const std::map<std::string, StoredEstimate>& parameters) {
    for (const auto& [key, estimate] : parameters) {
        if (const auto parsed = parse_parameter_key(key); parsed && parsed->rotary) return "rotary";
    }
    return "linear";
}

class SqliteStore final : public HistoryStore {
public:
    SqliteStore(const std::filesystem::path& path, const SqliteOpenOptions& options)
        : path_(path.string()), read_only_(options.read_only) {
        const bool exists = std::filesystem::exists(path);
        if (!exists && (options.read_only || !options.create))
            throw InputError(fmt::format("{}: no such history database", path_));
        if (exists && std::filesystem::is_directory(path))
            throw InputError(fmt::format("{}: is a folder, not a history database", path_));
        if (exists && std::filesystem::file_size(path) > 0 && !looks_like_sqlite(path))
            throw InputError(fmt::format("{}: not a feedid history database (not a SQLite file)", path_));

        // A reader opens read-write too (query_only below keeps it from writing): in WAL mode a connection opened
        // with SQLITE_OPEN_READONLY creates the -wal and -shm files beside the database but may not delete them when
        // it closes, so read-only commands left two stray files behind. A read-write connection that closes last
        // deletes them, as a writer does. SQLite falls back to reading only where the file is write-protected.
        const int flags = SQLITE_OPEN_READWRITE | (exists || options.read_only ? 0 : SQLITE_OPEN_CREATE);
        const int code = sqlite3_open_v2(path_.c_str(), &db_, flags | SQLITE_OPEN_NOMUTEX, nullptr);
        if (code != SQLITE_OK) {
            const std::string message = describe(code, db_);
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
        const std::string options_json = run.options.dump();
        const std::string fit_json = run.fit.dump();
        const std::string diagnostics_json = nlohmann::json(run.diagnostics).dump();
        const std::string result_json = run.result.is_object() ? run.result.dump() : std::string("{}");
        const std::string stored_at = run.stored_at.empty() ? now_utc() : run.stored_at;
        return write_transaction([&] {
            Statement existing(db_, "SELECT id FROM runs WHERE trace_sha256 = ?1 AND options_json = ?2", path_);
            existing.bind(1, run.trace_sha256).bind(2, options_json);
            if (existing.step()) return AddOutcome{existing.integer(0), false};

            const std::string axis_kind = run.axis_kind.empty() ? axis_kind_of(run.parameters) : run.axis_kind;
            require_same_axis_kind(run, axis_kind);
            insert_run(run, axis_kind, {options_json, fit_json, diagnostics_json, result_json, stored_at});
            const std::int64_t id = sqlite3_last_insert_rowid(db_);

            Statement parameter(db_, "INSERT INTO parameters (run_id, key, value, stderr) VALUES (?1, ?2, ?3, ?4)",
                                path_);
            for (const auto& [key, estimate] : run.parameters) {
                parameter.reset();
                parameter.bind(1, id).bind(2, key).bind(3, estimate.value).bind(4, estimate.standard_error);
                parameter.step();
                count_write_statement();
            }
            return AddOutcome{id, true};
        });
    }

    std::vector<RunRecord> runs(const RunFilter& filter) const override {
        std::vector<RunRecord> result;
        exec("BEGIN");  // one snapshot for both queries
        try {
            const char* where =
                " WHERE (?1 = '' OR r.machine = ?1) AND (?2 = '' OR r.axis = ?2) "
                "AND (?3 = '' OR r.location = ?3)";
            Statement select(
                db_,
                (std::string("SELECT r.id, r.machine, r.axis, r.location, r.recorded_at, r.trace_path, "
                             "r.trace_sha256, r.feedid_version, r.model, r.status, r.options_json, "
                             "r.fit_json, r.diagnostics_json, r.stored_at, ") +
                 (schema_version_ >= 3 ? "r.result_json" : "'{}'") + (schema_version_ >= 4 ? ", r.axis_kind" : ", ''") +
                 " FROM runs r" + where + " ORDER BY r.recorded_at, r.id")
                    .c_str(),
                path_);
            select.bind(1, filter.machine).bind(2, filter.axis).bind(3, filter.location);
            std::map<std::int64_t, std::size_t> index;
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
                run.options = parse_stored_json(select.text(10), run.id);
                run.fit = parse_stored_json(select.text(11), run.id);
                const auto diagnostics = parse_stored_json(select.text(12), run.id);
                if (diagnostics.is_array())
                    for (const auto& line : diagnostics)
                        if (line.is_string()) run.diagnostics.push_back(line.get<std::string>());
                run.stored_at = select.text(13);
                run.result = parse_stored_json(select.text(14), run.id);
                run.axis_kind = select.text(15);
                index[run.id] = result.size();
                result.push_back(std::move(run));
            }
            Statement parameters(db_,
                                 (std::string("SELECT p.run_id, p.key, p.value, p.stderr FROM parameters p "
                                              "JOIN runs r ON r.id = p.run_id") +
                                  where)
                                     .c_str(),
                                 path_);
            parameters.bind(1, filter.machine).bind(2, filter.axis).bind(3, filter.location);
            while (parameters.step()) {
                const auto found = index.find(parameters.integer(0));
                if (found == index.end()) continue;
                result[found->second].parameters[parameters.text(1)] = {parameters.real(2), parameters.real(3)};
            }
            exec("COMMIT");
        } catch (...) {
            sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
            throw;
        }
        return result;
    }

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
    /// One axis holds runs of one kind: a rotary run on an axis of linear runs (or the reverse) is refused.
    void require_same_axis_kind(const RunRecord& run, const std::string& axis_kind) const {
        if (schema_version_ < 4) return;
        Statement other(db_,
                        "SELECT id, axis_kind FROM runs WHERE machine = ?1 AND axis = ?2 AND axis_kind != ?3 AND "
                        "axis_kind != '' ORDER BY id LIMIT 1",
                        path_);
        other.bind(1, run.machine).bind(2, run.axis).bind(3, axis_kind);
        if (!other.step()) return;
        throw InputError(
            fmt::format("{}: machine '{}' axis '{}' is a {} axis (run #{}), this run is of a {} axis: "
                        "record it under another machine or axis name",
                        path_, run.machine, run.axis, other.text(1), other.integer(0), axis_kind));
    }

    /// A run's JSON columns and its storage time, as written.
    struct StoredText {
        const std::string& options_json;
        const std::string& fit_json;
        const std::string& diagnostics_json;
        const std::string& result_json;
        const std::string& stored_at;
    };

    void insert_run(const RunRecord& run, const std::string& axis_kind, const StoredText& text) {
        // A file kept at an older schema (tests of the migrations) lacks the later columns.
        std::string columns =
            "machine, axis, location, recorded_at, trace_path, trace_sha256, feedid_version, model, status, "
            "options_json, fit_json, diagnostics_json, stored_at";
        int count = 13;
        if (schema_version_ >= 3) columns += ", result_json";
        if (schema_version_ >= 3) ++count;
        if (schema_version_ >= 4) columns += ", axis_kind";
        if (schema_version_ >= 4) ++count;
        std::string placeholders;
        for (int i = 1; i <= count; ++i) placeholders += fmt::format("{}?{}", i == 1 ? "" : ", ", i);
        Statement insert(db_, fmt::format("INSERT INTO runs ({}) VALUES ({})", columns, placeholders).c_str(), path_);
        insert.bind(1, run.machine).bind(2, run.axis).bind(3, run.location).bind(4, run.recorded_at);
        insert.bind(5, run.trace_path).bind(6, run.trace_sha256).bind(7, run.feedid_version).bind(8, run.model);
        insert.bind(9, run.status).bind(10, text.options_json).bind(11, text.fit_json);
        insert.bind(12, text.diagnostics_json).bind(13, text.stored_at);
        if (schema_version_ >= 3) insert.bind(14, text.result_json);
        if (schema_version_ >= 4) insert.bind(15, axis_kind);
        insert.step();
        count_write_statement();
    }

    void exec(const char* sql) const {
        char* message = nullptr;
        const int code = sqlite3_exec(db_, sql, nullptr, nullptr, &message);
        if (code != SQLITE_OK) {
            sqlite3_free(message);
            const int extended = sqlite3_extended_errcode(db_);
            throw SqliteError(fmt::format("{}: cannot read or write the database: {}", path_, describe(extended, db_)),
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

    nlohmann::json parse_stored_json(const std::string& text, std::int64_t id) const {
        try {
            return nlohmann::json::parse(text);
        } catch (const nlohmann::json::parse_error&) {
            throw InputError(fmt::format("{}: run #{} holds malformed JSON (the file is corrupt)", path_, id));
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

    void check_and_migrate(int target_version) {
        // Read-only checks first: nothing below writes until the file is known to be a feedid history (or empty).
        std::string check;
        try {
            Statement quick_check(db_, "PRAGMA quick_check", path_);
            if (quick_check.step()) check = quick_check.text(0);
        } catch (const SqliteError&) {
            throw InputError(fmt::format("{}: the history database is corrupt (not a readable SQLite file)", path_));
        }
        if (check != "ok") {
            // One line: SQLite lists its findings on several.
            for (auto& c : check)
                if (c == '\n') c = ' ';
            if (check.size() > 200) check = check.substr(0, 200) + "...";
            throw InputError(fmt::format("{}: the history database is corrupt (SQLite's check: {})", path_, check));
        }
        const int found_application = pragma_integer("PRAGMA application_id");
        schema_version_ = pragma_integer("PRAGMA user_version");
        const int tables = pragma_integer("SELECT count(*) FROM sqlite_master");
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

    std::string path_;
    bool read_only_;
    sqlite3* db_{nullptr};
    int schema_version_{0};
};

}  // namespace

std::unique_ptr<HistoryStore> open_sqlite_store(const std::filesystem::path& path, const SqliteOpenOptions& options) {
    return std::make_unique<SqliteStore>(path, options);
}

bool looks_like_sqlite(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    char header[16] = {};
    in.read(header, sizeof header);
    return in.gcount() == sizeof header &&
           std::string_view(header, sizeof header) == std::string_view("SQLite format 3\0", 16);
}

std::string file_modification_time_utc(const std::filesystem::path& path) {
    std::error_code error;
    const auto file_time = std::filesystem::last_write_time(path, error);
    if (error) throw InputError(fmt::format("{}: cannot read the file's modification time", path.string()));
    const auto system_time = std::chrono::file_clock::to_sys(file_time);
    const auto milliseconds =
        std::chrono::duration_cast<std::chrono::milliseconds>(system_time.time_since_epoch()).count();
    const std::time_t seconds = static_cast<std::time_t>(milliseconds / 1000);
    std::tm utc{};
    gmtime_r(&seconds, &utc);
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z", utc.tm_year + 1900, utc.tm_mon + 1, utc.tm_mday,
                       utc.tm_hour, utc.tm_min, utc.tm_sec, static_cast<int>(milliseconds % 1000));
}

std::string now_utc() {
    const auto milliseconds =
        std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count();
    const std::time_t seconds = static_cast<std::time_t>(milliseconds / 1000);
    std::tm utc{};
    gmtime_r(&seconds, &utc);
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z", utc.tm_year + 1900, utc.tm_mon + 1, utc.tm_mday,
                       utc.tm_hour, utc.tm_min, utc.tm_sec, static_cast<int>(milliseconds % 1000));
}

RunRecord run_from_result(const nlohmann::json& result, const std::string& source) {
    const auto not_a_result = [&](const std::string& why) {
        return InputError(fmt::format("{}: not a feedid identify result document ({})", source, why));
    };
    if (!result.is_object()) throw not_a_result("it is not a JSON object");
    if (!result.contains("parameters") || !result["parameters"].is_object())
        throw not_a_result("it has no \"parameters\" object");
    if (!result.contains("model") || !result["model"].is_string()) throw not_a_result("it has no \"model\"");
    RunRecord run;
    run.model = result["model"].get<std::string>();

    for (const auto& [key, entry] : result["parameters"].items()) {
        if (!entry.is_object() || !entry.contains("value"))
            throw not_a_result(fmt::format("parameter \"{}\" has no \"value\"", key));
        try {
            run.parameters[key] = entry.get<Estimate>();
        } catch (const nlohmann::json::exception&) {
            throw not_a_result(fmt::format("parameter \"{}\" is not a number or null", key));
        }
    }
    if (result.contains("feedid_version") && result["feedid_version"].is_string())
        run.feedid_version = result["feedid_version"].get<std::string>();
    if (result.contains("status") && result["status"].is_string()) run.status = result["status"].get<std::string>();
    if (result.contains("trace") && result["trace"].is_object() && result["trace"].contains("path") &&
        result["trace"]["path"].is_string())
        run.trace_path = result["trace"]["path"].get<std::string>();
    if (result.contains("fit") && result["fit"].is_object()) run.fit = result["fit"];
    if (result.contains("diagnostics") && result["diagnostics"].is_array())
        for (const auto& line : result["diagnostics"])
            if (line.is_string()) run.diagnostics.push_back(line.get<std::string>());
    // The axis kind as the result states it; older results without "rotary" by their keys.
    run.axis_kind = result.contains("rotary") && result["rotary"].is_boolean()
                        ? ParameterNaming{result["rotary"].get<bool>()}.axis_kind()
                        : axis_kind_of(run.parameters);
    run.result = result;
    if (run.result.contains("rls") && run.result["rls"].is_object()) run.result["rls"].erase("history");
    return run;
}

nlohmann::json to_json(const RunRecord& run) {
    const nlohmann::json parameters(run.parameters);
    return {{"id", run.id},
            {"machine", run.machine},
            {"axis", run.axis},
            {"location", run.location},
            {"recorded_at", run.recorded_at},
            {"trace", {{"path", run.trace_path}, {"sha256", run.trace_sha256}}},
            {"feedid_version", run.feedid_version},
            {"model", run.model},
            {"axis_kind", run.axis_kind},
            {"status", run.status},
            {"options", run.options},
            {"parameters", parameters},
            {"fit", run.fit},
            {"diagnostics", run.diagnostics},
            {"stored_at", run.stored_at}};
}

}  // namespace feedid::history
