#pragma once
// A thin layer over the SQLite C API, shared by the BLE store (libble) and the run database (libcampaign):
// statements that finalize themselves and transactions that roll back unless committed. Every failure is an
// InputError naming the database file and what was being done, so a user sees which file is locked, full or not
// a database. Header only: the libraries that include it link SQLite themselves.
#include <sqlite3.h>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "blt/core/error.hpp"

namespace blt::sql {

[[noreturn]] inline void fail(sqlite3* db, const std::string& file, const std::string& doing) {
  throw InputError(InputLocation::file(file), "SQLite error while " + doing + ": " + sqlite3_errmsg(db));
}

inline void exec(sqlite3* db, const std::string& file, const std::string& sql, const std::string& doing) {
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) fail(db, file, doing);
}

// A prepared statement. Parameters count from 1 and columns from 0, as in SQLite. `file` must outlive it.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& file, std::string_view sql, std::string doing)
      : db_(db), file_(file), doing_(std::move(doing)) {
    if (sqlite3_prepare_v2(db, sql.data(), static_cast<int>(sql.size()), &stmt_, nullptr) != SQLITE_OK)
      fail(db_, file_, doing_);
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& bind(int i, double v) { return ok(sqlite3_bind_double(stmt_, i, v)); }
  Statement& bind(int i, std::int64_t v) { return ok(sqlite3_bind_int64(stmt_, i, v)); }
  Statement& bind(int i, int v) { return ok(sqlite3_bind_int(stmt_, i, v)); }
  Statement& bind(int i, bool v) { return ok(sqlite3_bind_int(stmt_, i, v ? 1 : 0)); }
  Statement& bind(int i, const std::string& v) {
    return ok(sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
  }
  Statement& bind(int i, const char* v) { return bind(i, std::string(v)); }
  // NULL for nullopt (and for NaN, which SQLite would store as NULL anyway).
  Statement& bind(int i, const std::optional<double>& v) {
    return v && *v == *v ? bind(i, *v) : ok(sqlite3_bind_null(stmt_, i));
  }
  Statement& bindBlob(int i, const std::string& bytes) {
    return ok(sqlite3_bind_blob(stmt_, i, bytes.data(), static_cast<int>(bytes.size()), SQLITE_TRANSIENT));
  }

  // Advances; true while there is a row to read.
  bool step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    fail(db_, file_, doing_);
  }
  void run() {
    while (step()) {
    }
  }
  // For running the statement again with other parameters.
  void reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  int changes() const { return sqlite3_changes(db_); }

  bool isNull(int c) const { return sqlite3_column_type(stmt_, c) == SQLITE_NULL; }
  double real(int c) const { return sqlite3_column_double(stmt_, c); }
  std::optional<double> optionalReal(int c) const { return isNull(c) ? std::nullopt : std::optional<double>(real(c)); }
  std::int64_t integer(int c) const { return sqlite3_column_int64(stmt_, c); }
  std::string text(int c) const {
    const auto* p = sqlite3_column_text(stmt_, c);
    return p ? std::string(reinterpret_cast<const char*>(p), static_cast<std::size_t>(sqlite3_column_bytes(stmt_, c)))
             : std::string();
  }
  std::string blob(int c) const {
    const auto* p = static_cast<const char*>(sqlite3_column_blob(stmt_, c));
    return p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(stmt_, c))) : std::string();
  }

 private:
  Statement& ok(int rc) {
    if (rc != SQLITE_OK) fail(db_, file_, doing_);
    return *this;
  }
  sqlite3* db_;
  const std::string& file_;
  std::string doing_;
  sqlite3_stmt* stmt_ = nullptr;
};

// BEGIN IMMEDIATE: the write lock is taken first (waiting out other writers under the busy timeout), so a
// transaction cannot fail halfway for want of it. Without commit() the destructor rolls back, which is how every
// exception leaves the file as it was.
class WriteTransaction {
 public:
  WriteTransaction(sqlite3* db, const std::string& file) : db_(db), file_(file) {
    exec(db_, file_, "BEGIN IMMEDIATE", "starting a transaction");
  }
  ~WriteTransaction() {
    if (!done_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
  WriteTransaction(const WriteTransaction&) = delete;
  WriteTransaction& operator=(const WriteTransaction&) = delete;
  void commit() {
    exec(db_, file_, "COMMIT", "committing");
    done_ = true;
  }

 private:
  sqlite3* db_;
  const std::string& file_;
  bool done_ = false;
};

// BEGIN (deferred): the reads inside see one snapshot of the file, so values read one after another cannot
// straddle another connection's commit. Ends with the object; it writes nothing.
class ReadTransaction {
 public:
  ReadTransaction(sqlite3* db, const std::string& file) : db_(db) { exec(db_, file, "BEGIN", "starting a read"); }
  ~ReadTransaction() { sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr); }
  ReadTransaction(const ReadTransaction&) = delete;
  ReadTransaction& operator=(const ReadTransaction&) = delete;

 private:
  sqlite3* db_;
};

// The integer value of PRAGMA `name` (user_version, application_id, ...); 0 where it has none.
inline int pragmaInt(sqlite3* db, const std::string& file, const std::string& name) {
  Statement s(db, file, "PRAGMA " + name, "reading PRAGMA " + name);
  return s.step() ? static_cast<int>(s.integer(0)) : 0;
}

}  // namespace blt::sql
