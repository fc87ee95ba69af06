#include "common/storage/sqlite_db.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "common/util/logging.h"

namespace placerec {

std::string SqliteMessage(sqlite3* db, int rc) {
  std::string message = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  return message + " (sqlite code " + std::to_string(rc) + ")";
}

StatusOr<SqliteConnection> OpenSqliteDatabase(const std::string& path, int flags,
                                              int busy_timeout_ms) {
  sqlite3* raw = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &raw, flags, nullptr);
  SqliteConnection db(raw);
  if (rc != SQLITE_OK) {
    return Status::IoError("cannot open map " + path + ": " + SqliteMessage(raw, rc));
  }
  sqlite3_extended_result_codes(db.get(), 1);
  sqlite3_busy_timeout(db.get(), busy_timeout_ms);
  return StatusOr<SqliteConnection>(std::move(db));
}

Status SqliteExec(sqlite3* db, const char* sql, const std::string& path) {
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) {
    return Status::IoError(std::string(sql) + " failed on " + path + ": " + SqliteMessage(db, rc));
  }
  return Status::Ok();
}

SqliteStatement& SqliteStatement::operator=(SqliteStatement&& other) noexcept {
  if (this != &other) {
    sqlite3_finalize(stmt_);
    stmt_ = std::exchange(other.stmt_, nullptr);
    bind_rc_ = other.bind_rc_;
  }
  return *this;
}

int SqliteStatement::Prepare(sqlite3* db, const char* sql, bool persistent, SqliteStatement* out) {
  sqlite3_stmt* stmt = nullptr;
  const int rc =
      sqlite3_prepare_v3(db, sql, -1, persistent ? SQLITE_PREPARE_PERSISTENT : 0, &stmt, nullptr);
  *out = SqliteStatement();
  out->stmt_ = stmt;
  return rc;
}

void SqliteStatement::BindText(int index, const char* text) {
  BindText(index, text, std::strlen(text));
}

void SqliteStatement::BindText(int index, const char* text, size_t size) {
  Note(sqlite3_bind_text64(stmt_, index, text, size, SQLITE_STATIC, SQLITE_UTF8));
}

void SqliteStatement::BindBlob(int index, const void* data, size_t size) {
  Note(size == 0 ? sqlite3_bind_zeroblob(stmt_, index, 0)
                 : sqlite3_bind_blob64(stmt_, index, data, size, SQLITE_STATIC));
}

void SqliteStatement::Reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
  bind_rc_ = SQLITE_OK;
}

std::string SqliteStatement::ColumnText(int column) const {
  const unsigned char* text = sqlite3_column_text(stmt_, column);
  const int size = sqlite3_column_bytes(stmt_, column);
  return text == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(text), size);
}

std::pair<const uint8_t*, size_t> SqliteStatement::ColumnBlob(int column) const {
  const void* data = sqlite3_column_blob(stmt_, column);
  const int size = sqlite3_column_bytes(stmt_, column);
  return {static_cast<const uint8_t*>(data), static_cast<size_t>(size)};
}

SqliteTransaction::~SqliteTransaction() {
  // SQLite may already have rolled back by itself after an I/O error.
  if (active_ && sqlite3_get_autocommit(db_) == 0) {
    const int rc = sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    LOG_IF(ERROR, rc != SQLITE_OK) << "sqlite rollback failed: " << SqliteMessage(db_, rc);
  }
}

int SqliteTransaction::Begin(bool immediate) {
  const int rc =
      sqlite3_exec(db_, immediate ? "BEGIN IMMEDIATE" : "BEGIN", nullptr, nullptr, nullptr);
  active_ = rc == SQLITE_OK;
  return rc;
}

int SqliteTransaction::Commit() {
  const int rc = sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr);
  if (rc == SQLITE_OK) active_ = false;
  return rc;
}

StatusOr<bool> SqliteOpenElsewhere(const std::string& path) {
  // SQLite keeps the -shm file beside the file a link names.
  std::error_code error_code;
  const std::filesystem::path target = std::filesystem::canonical(path, error_code);
  const std::string shm = (error_code ? path : target.string()) + "-shm";
  const int fd = open(shm.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return false;
    return Status::IoError("cannot examine " + shm + ": " + std::strerror(errno));
  }
  // Would a write lock over the whole file conflict with anybody's lock? F_OFD_GETLK reports
  // conflicts with every other lock holder, this process's ordinary (POSIX) locks included.
  struct flock probe = {};
  probe.l_type = F_WRLCK;
  probe.l_whence = SEEK_SET;
  probe.l_start = 0;
  probe.l_len = 0;  // to the end
  const int rc = fcntl(fd, F_OFD_GETLK, &probe);
  const int error = errno;
  // Closing a descriptor drops this process's POSIX locks on the file: those of a connection of
  // this process to the same map (seen above, so the caller refuses the map; that connection's
  // next transactions take their locks anew). A connection in SQLite's exclusive locking mode
  // holds none there.
  close(fd);
  if (rc != 0)
    return Status::IoError("cannot examine the locks of " + shm + ": " + std::strerror(error));
  return probe.l_type != F_UNLCK;
}

}  // namespace placerec
