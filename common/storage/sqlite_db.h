// Thin RAII wrappers around the sqlite3 C API, for the SQLite landmark store: a connection that
// closes itself, prepared statements with bound (never formatted) values, and transactions that
// roll back unless committed. Calls return SQLite result codes; callers turn them into Status with
// SqliteMessage. Nothing here is thread-safe: the store serialises use of a connection.
#pragma once

#include <sqlite3.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>

#include "common/util/status.h"

namespace placerec {

struct SqliteConnectionCloser {
  // close_v2 also copes with statements that are still alive (it defers the close).
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
using SqliteConnection = std::unique_ptr<sqlite3, SqliteConnectionCloser>;

// The connection's last error message (or, without a connection, the text of `rc`) followed by
// " (sqlite code <rc>)".
std::string SqliteMessage(sqlite3* db, int rc);

// Opens the database at `path` with `flags` (SQLITE_OPEN_*), extended result codes on and a busy
// timeout of `busy_timeout_ms`; IoError "cannot open map <path>: ..." when SQLite cannot.
StatusOr<SqliteConnection> OpenSqliteDatabase(const std::string& path, int flags,
                                              int busy_timeout_ms);

// Whether another process has the database at `path` (a symbolic link is followed, as SQLite
// follows it) open in WAL mode: every such connection holds a read lock on the database's
// shared-memory file (`path`-shm) for as long as it is open, even when idle. False when there is
// no -shm file or nobody locks it; IoError when the file cannot be examined. Linux
// (open-file-description locks: it sees connections of this process too). Examining the file drops
// this process's own POSIX locks on it, as closing any descriptor of a file does: ask before this
// process opens the map, or while holding it in exclusive locking mode (which keeps no lock there).
StatusOr<bool> SqliteOpenElsewhere(const std::string& path);

// Runs constant SQL without results; the error names the SQL and `path` (for messages only).
Status SqliteExec(sqlite3* db, const char* sql, const std::string& path);

// A prepared statement. Values are always bound, never formatted into the SQL. A failed bind is
// remembered and reported by the next Step().
class SqliteStatement {
 public:
  SqliteStatement() = default;
  SqliteStatement(const SqliteStatement&) = delete;
  SqliteStatement& operator=(const SqliteStatement&) = delete;
  SqliteStatement(SqliteStatement&& other) noexcept
      : stmt_(std::exchange(other.stmt_, nullptr)), bind_rc_(other.bind_rc_) {}
  SqliteStatement& operator=(SqliteStatement&& other) noexcept;
  ~SqliteStatement() { sqlite3_finalize(stmt_); }

  // Compiles one SQL statement into `out`; `persistent` hints that it is kept and reused.
  static int Prepare(sqlite3* db, const char* sql, bool persistent, SqliteStatement* out);

  // Parameters are numbered from 1. Bound text and blobs must outlive the next Step().
  void BindInt(int index, int64_t value) { Note(sqlite3_bind_int64(stmt_, index, value)); }
  void BindDouble(int index, double value) { Note(sqlite3_bind_double(stmt_, index, value)); }
  void BindNull(int index) { Note(sqlite3_bind_null(stmt_, index)); }
  void BindText(int index, const std::string& text) { BindText(index, text.data(), text.size()); }
  void BindText(int index, const char* text);
  // SQLite keeps a pointer to bound text until the step: a temporary would dangle.
  void BindText(int index, std::string&& text) = delete;
  // A zero-length blob, not NULL, when `size` is 0.
  void BindBlob(int index, const void* data, size_t size);

  // SQLITE_ROW when a row is ready, SQLITE_DONE at the end, or an error code.
  int Step() { return bind_rc_ != SQLITE_OK ? bind_rc_ : sqlite3_step(stmt_); }

  // Makes a kept statement ready for the next use and drops references to bound buffers.
  void Reset();

  // Columns are numbered from 0.
  int ColumnType(int column) const { return sqlite3_column_type(stmt_, column); }
  int64_t ColumnInt(int column) const { return sqlite3_column_int64(stmt_, column); }
  double ColumnDouble(int column) const { return sqlite3_column_double(stmt_, column); }
  std::string ColumnText(int column) const;
  // Valid until the next Step() or Reset(); {nullptr, 0} for NULL and empty blobs.
  std::pair<const uint8_t*, size_t> ColumnBlob(int column) const;

 private:
  void BindText(int index, const char* text, size_t size);
  void Note(int rc) {
    if (bind_rc_ == SQLITE_OK) bind_rc_ = rc;
  }

  sqlite3_stmt* stmt_ = nullptr;
  int bind_rc_ = SQLITE_OK;
};

// Resets a kept statement when the scope ends, whichever way it ends.
class ScopedStatementReset {
 public:
  explicit ScopedStatementReset(SqliteStatement* statement) : statement_(statement) {}
  ScopedStatementReset(const ScopedStatementReset&) = delete;
  ScopedStatementReset& operator=(const ScopedStatementReset&) = delete;
  ~ScopedStatementReset() { statement_->Reset(); }

 private:
  SqliteStatement* statement_;
};

// A transaction that rolls back unless Commit() succeeded. IMMEDIATE takes the write lock at
// BEGIN, so a writer never fails half-way on a lock held by another connection.
class SqliteTransaction {
 public:
  explicit SqliteTransaction(sqlite3* db) : db_(db) {}
  SqliteTransaction(const SqliteTransaction&) = delete;
  SqliteTransaction& operator=(const SqliteTransaction&) = delete;
  ~SqliteTransaction();

  int Begin(bool immediate);
  int Commit();

 private:
  sqlite3* db_;
  bool active_ = false;
};

}  // namespace placerec
