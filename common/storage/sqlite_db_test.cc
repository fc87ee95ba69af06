#include "common/storage/sqlite_db.h"

#include <gtest/gtest.h>

#include <string>

namespace placerec {
namespace {

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

SqliteConnection OpenMemory() {
  sqlite3* raw = nullptr;
  EXPECT_EQ(sqlite3_open_v2(":memory:", &raw, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr),
            SQLITE_OK);
  SqliteConnection db(raw);
  sqlite3_extended_result_codes(db.get(), 1);
  EXPECT_TRUE(SqliteExec(db.get(), "CREATE TABLE t(x)", ":memory:").ok());
  return db;
}

int64_t CountRows(sqlite3* db) {
  SqliteStatement count;
  EXPECT_EQ(SqliteStatement::Prepare(db, "SELECT COUNT(*) FROM t", false, &count), SQLITE_OK);
  EXPECT_EQ(count.Step(), SQLITE_ROW);
  return count.ColumnInt(0);
}

TEST(SqliteDbTest, MessagesNameTheCode) {
  SqliteConnection db = OpenMemory();
  SqliteStatement statement;
  const int rc = SqliteStatement::Prepare(db.get(), "SELEC 1", false, &statement);
  EXPECT_EQ(rc, SQLITE_ERROR);
  const std::string message = SqliteMessage(db.get(), rc);
  EXPECT_TRUE(Contains(message, "syntax error")) << message;
  EXPECT_TRUE(Contains(message, "(sqlite code 1)")) << message;
  // Without a connection (opening failed), the text of the code.
  EXPECT_EQ(SqliteMessage(nullptr, SQLITE_NOTADB),
            std::string(sqlite3_errstr(SQLITE_NOTADB)) + " (sqlite code 26)");
}

TEST(SqliteDbTest, ExecErrorNamesTheSqlAndThePath) {
  SqliteConnection db = OpenMemory();
  EXPECT_TRUE(SqliteExec(db.get(), "INSERT INTO t VALUES(1)", "x.db").ok());
  const Status status = SqliteExec(db.get(), "INSERT INTO nowhere VALUES(1)", "x.db");
  EXPECT_EQ(status.code(), StatusCode::kIoError);
  EXPECT_TRUE(Contains(status.message(), "INSERT INTO nowhere VALUES(1) failed on x.db: "))
      << status.message();
  EXPECT_TRUE(Contains(status.message(), "no such table")) << status.message();
}

TEST(SqliteDbTest, FailedBindIsReportedByStepAndClearedByReset) {
  SqliteConnection db = OpenMemory();
  SqliteStatement insert;
  ASSERT_EQ(SqliteStatement::Prepare(db.get(), "INSERT INTO t VALUES(?)", true, &insert),
            SQLITE_OK);
  insert.BindInt(2, 5);  // there is one parameter only
  insert.BindInt(1, 5);  // a later good bind does not hide the first error
  EXPECT_EQ(insert.Step(), SQLITE_RANGE);
  EXPECT_EQ(CountRows(db.get()), 0);  // nothing ran
  insert.Reset();
  insert.BindInt(1, 5);
  EXPECT_EQ(insert.Step(), SQLITE_DONE);
  EXPECT_EQ(CountRows(db.get()), 1);
}

TEST(SqliteDbTest, ValuesRoundTripAndEmptyBlobIsNotNull) {
  SqliteConnection db = OpenMemory();
  const std::string text("a\0b", 3);
  const uint8_t bytes[] = {1, 2, 3};
  {
    SqliteStatement insert;
    ASSERT_EQ(SqliteStatement::Prepare(db.get(), "INSERT INTO t VALUES(?)", true, &insert),
              SQLITE_OK);
    for (int row = 0; row < 5; ++row) {
      ScopedStatementReset reset(&insert);
      if (row == 0) insert.BindInt(1, -7);
      if (row == 1) insert.BindText(1, text);
      if (row == 2) insert.BindBlob(1, bytes, sizeof(bytes));
      if (row == 3) insert.BindBlob(1, nullptr, 0);
      // Row 4 binds nothing: the reset of row 3 cleared the binding, so it stores NULL.
      ASSERT_EQ(insert.Step(), SQLITE_DONE) << row;
    }
  }
  SqliteStatement select;
  ASSERT_EQ(SqliteStatement::Prepare(db.get(), "SELECT x FROM t ORDER BY rowid", false, &select),
            SQLITE_OK);
  ASSERT_EQ(select.Step(), SQLITE_ROW);
  EXPECT_EQ(select.ColumnInt(0), -7);
  ASSERT_EQ(select.Step(), SQLITE_ROW);
  EXPECT_EQ(select.ColumnText(0), text);
  ASSERT_EQ(select.Step(), SQLITE_ROW);
  const auto [data, size] = select.ColumnBlob(0);
  ASSERT_EQ(size, 3u);
  EXPECT_EQ(data[2], 3);
  ASSERT_EQ(select.Step(), SQLITE_ROW);
  EXPECT_EQ(select.ColumnType(0), SQLITE_BLOB);
  EXPECT_EQ(select.ColumnBlob(0).second, 0u);
  ASSERT_EQ(select.Step(), SQLITE_ROW);
  EXPECT_EQ(select.ColumnType(0), SQLITE_NULL);
  EXPECT_EQ(select.ColumnText(0), "");
  EXPECT_EQ(select.ColumnBlob(0).first, nullptr);
  EXPECT_EQ(select.Step(), SQLITE_DONE);
}

TEST(SqliteDbTest, MovedStatementKeepsItsPreparedQuery) {
  SqliteConnection db = OpenMemory();
  SqliteStatement first;
  ASSERT_EQ(SqliteStatement::Prepare(db.get(), "SELECT 42", false, &first), SQLITE_OK);
  SqliteStatement second(std::move(first));
  SqliteStatement third;
  third = std::move(second);
  ASSERT_EQ(third.Step(), SQLITE_ROW);
  EXPECT_EQ(third.ColumnInt(0), 42);
}

TEST(SqliteDbTest, TransactionRollsBackUnlessCommitted) {
  SqliteConnection db = OpenMemory();
  {
    SqliteTransaction transaction(db.get());
    ASSERT_EQ(transaction.Begin(/*immediate=*/true), SQLITE_OK);
    ASSERT_TRUE(SqliteExec(db.get(), "INSERT INTO t VALUES(1)", ":memory:").ok());
    EXPECT_EQ(CountRows(db.get()), 1);
  }
  EXPECT_EQ(CountRows(db.get()), 0);
  EXPECT_NE(sqlite3_get_autocommit(db.get()), 0);  // no transaction left open
  {
    SqliteTransaction transaction(db.get());
    ASSERT_EQ(transaction.Begin(/*immediate=*/false), SQLITE_OK);
    ASSERT_TRUE(SqliteExec(db.get(), "INSERT INTO t VALUES(1)", ":memory:").ok());
    ASSERT_EQ(transaction.Commit(), SQLITE_OK);
  }
  EXPECT_EQ(CountRows(db.get()), 1);
}

TEST(SqliteDbTest, FailedBeginLeavesTheOuterTransactionAlone) {
  SqliteConnection db = OpenMemory();
  SqliteTransaction outer(db.get());
  ASSERT_EQ(outer.Begin(/*immediate=*/true), SQLITE_OK);
  ASSERT_TRUE(SqliteExec(db.get(), "INSERT INTO t VALUES(1)", ":memory:").ok());
  {
    SqliteTransaction inner(db.get());
    EXPECT_EQ(inner.Begin(/*immediate=*/false), SQLITE_ERROR);  // no nested BEGIN in SQLite
  }  // the inner one did not begin, so it must not roll back the outer one
  EXPECT_EQ(CountRows(db.get()), 1);
  EXPECT_EQ(outer.Commit(), SQLITE_OK);
  EXPECT_EQ(CountRows(db.get()), 1);
}

}  // namespace
}  // namespace placerec
