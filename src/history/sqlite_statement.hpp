#pragma once
// The SQLite history store's small wrapper of prepared statements and its errors (internal to src/history).

#include <sqlite3.h>

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "feedid/core/error.hpp"

namespace feedid::history {

/// An error SQLite reported, in words, with its (extended) result code for retry decisions.
class SqliteError : public InputError {
public:
    SqliteError(const std::string& message, int code) : InputError(message), code_(code) {}
    [[nodiscard]] int code() const { return code_; }

private:
    int code_;
};

/// SQLite's result code in words a user can act on.
std::string describe_sqlite_error(int code, sqlite3* db);

class Statement {
public:
    Statement(sqlite3* db, const std::string& sql, const std::string& path) : db_(db), path_(path) {
        if (sqlite3_prepare_v2(db, sql.c_str(), -1, &statement_, nullptr) != SQLITE_OK)
            fail("cannot prepare a statement");
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
    /// The text of a column, valid until the next step (no copy).
    [[nodiscard]] std::string_view view(int column) const {
        const auto* p = sqlite3_column_text(statement_, column);
        return p ? std::string_view(reinterpret_cast<const char*>(p),
                                    static_cast<std::size_t>(sqlite3_column_bytes(statement_, column)))
                 : std::string_view();
    }
    [[nodiscard]] std::string text(int column) const { return std::string(view(column)); }
    [[nodiscard]] std::int64_t integer(int column) const { return sqlite3_column_int64(statement_, column); }
    [[nodiscard]] std::optional<double> real(int column) const {
        if (sqlite3_column_type(statement_, column) == SQLITE_NULL) return std::nullopt;
        return sqlite3_column_double(statement_, column);
    }
    [[noreturn]] void fail(const char* what) const {
        const int code = sqlite3_extended_errcode(db_);
        throw SqliteError(path_ + ": " + what + ": " + describe_sqlite_error(code, db_), code);
    }

private:
    sqlite3* db_;
    sqlite3_stmt* statement_{nullptr};
    const std::string& path_;
};

}  // namespace feedid::history
