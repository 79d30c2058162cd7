#include "store/sqlite_util.h"

#include <gtest/gtest.h>

#include "store/store_test_util.h"
#include <optional>

namespace reconduit {
namespace {

using testing_util::TempDir;

TEST(Statement, BindsAndReadsEveryType) {
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("t.db"));
  db.Exec("CREATE TABLE t (i INTEGER, d REAL, s TEXT, n TEXT)", "create");
  Statement insert(db.get(), "INSERT INTO t VALUES (?1, ?2, ?3, ?4)");
  insert.Bind(1, std::int64_t{1} << 40).Bind(2, 2.5).Bind(3, std::string_view("a\0b", 3));
  insert.Bind(4, std::optional<std::string>()).Run();

  Statement select(db.get(), "SELECT i, d, s, n FROM t");
  ASSERT_TRUE(select.Step());
  EXPECT_EQ(select.Int64(0), std::int64_t{1} << 40);
  EXPECT_DOUBLE_EQ(select.Double(1), 2.5);
  EXPECT_EQ(select.Text(2), std::string("a\0b", 3));  // Embedded NUL survives.
  EXPECT_TRUE(select.IsNull(3));
  EXPECT_EQ(select.OptionalInt64(3), std::nullopt);
  EXPECT_FALSE(select.Step());
}

TEST(Statement, BoundValuesAreNeverSql) {
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("t.db"));
  db.Exec("CREATE TABLE t (s TEXT)", "create");
  const std::string hostile = "x'); DROP TABLE t; --";
  Statement(db.get(), "INSERT INTO t VALUES (?1)").Bind(1, hostile).Run();
  Statement select(db.get(), "SELECT s FROM t");
  ASSERT_TRUE(select.Step());
  EXPECT_EQ(select.Text(0), hostile);
}

TEST(Statement, BadSqlThrowsWithTheStatementInTheMessage) {
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("t.db"));
  try {
    Statement bad(db.get(), "SELEC nonsense");
    FAIL() << "prepare should have thrown";
  } catch (const SqliteError& e) {
    EXPECT_EQ(e.status().code(), StatusCode::kInternal);
    EXPECT_NE(e.status().message().find("SELEC nonsense"), std::string::npos);
  }
}

TEST(Statement, ConstraintViolationIsInvalidArgument) {
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("t.db"));
  db.Exec("CREATE TABLE t (x INTEGER CHECK (x > 0))", "create");
  Statement insert(db.get(), "INSERT INTO t VALUES (?1)");
  insert.Bind(1, -1);
  try {
    insert.Run();
    FAIL() << "insert should have thrown";
  } catch (const SqliteError& e) {
    EXPECT_EQ(e.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(e.status().message().find("CHECK constraint failed"), std::string::npos)
        << e.status();
  }
}

TEST(Transaction, RollsBackUnlessCommitted) {
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("t.db"));
  db.Exec("CREATE TABLE t (x INTEGER)", "create");
  {
    Transaction transaction(db, Transaction::Mode::kImmediate);
    db.Exec("INSERT INTO t VALUES (1)", "insert");
  }
  EXPECT_TRUE(db.InAutocommit());
  EXPECT_EQ(db.QueryInt64("SELECT count(*) FROM t", "count"), 0);
  {
    Transaction transaction(db, Transaction::Mode::kImmediate);
    db.Exec("INSERT INTO t VALUES (1)", "insert");
    transaction.Commit();
  }
  EXPECT_EQ(db.QueryInt64("SELECT count(*) FROM t", "count"), 1);
}

// Two connections to one WAL database with a table t; the first holds the write lock.
struct LockedDatabase {
  LockedDatabase() {
    first.Exec("PRAGMA journal_mode = WAL", "wal");
    first.Exec("CREATE TABLE t (x INTEGER)", "create");
    holder.emplace(first, Transaction::Mode::kImmediate);
  }
  TempDir dir;
  SqliteConnection first = SqliteConnection::Open(dir.File("t.db"));
  SqliteConnection second = SqliteConnection::Open(dir.File("t.db"));
  std::optional<Transaction> holder;
};

// A single-statement write meets another connection's write lock inside Step (autocommit):
// its error says busy, so callers retry it like a busy BEGIN.
TEST(Statement, WriteBehindAnotherWriterIsBusy) {
  LockedDatabase db;
  Statement update(db.second.get(), "UPDATE t SET x = 1");
  try {
    update.Run();
    FAIL() << "the UPDATE should have failed while another connection writes";
  } catch (const SqliteError& e) {
    EXPECT_TRUE(e.busy()) << e.status();
    EXPECT_EQ(e.status().code(), StatusCode::kResourceExhausted) << e.status();
  }
}

TEST(Transaction, SecondWriterWithoutBusyTimeoutGetsResourceExhausted) {
  LockedDatabase db;
  try {
    Transaction blocked(db.second, Transaction::Mode::kImmediate);
    FAIL() << "BEGIN IMMEDIATE should have failed while another connection writes";
  } catch (const SqliteError& e) {
    EXPECT_EQ(e.status().code(), StatusCode::kResourceExhausted) << e.status();
    EXPECT_TRUE(e.busy()) << e.status();
  }
  EXPECT_TRUE(db.second.InAutocommit());
}

TEST(SqliteStatus, MapsCodes) {
  EXPECT_EQ(SqliteStatus(SQLITE_BUSY, nullptr, "x").code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(SqliteStatus(SQLITE_BUSY_SNAPSHOT, nullptr, "x").code(),
            StatusCode::kResourceExhausted);
  EXPECT_EQ(SqliteStatus(SQLITE_CONSTRAINT_UNIQUE, nullptr, "x").code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(SqliteStatus(SQLITE_NOTADB, nullptr, "x").code(), StatusCode::kInternal);
  EXPECT_EQ(SqliteStatus(SQLITE_IOERR, nullptr, "ctx").message().substr(0, 5), "ctx: ");
  EXPECT_TRUE(IsSqliteBusy(SQLITE_LOCKED_SHAREDCACHE));
  EXPECT_FALSE(IsSqliteBusy(SQLITE_CORRUPT));
  // A read-only file or a full disk: a 503 for a client, said plainly, and nothing to retry.
  const Status read_only = SqliteStatus(SQLITE_READONLY_DBMOVED, nullptr, "create job");
  EXPECT_EQ(read_only.code(), StatusCode::kResourceExhausted);
  EXPECT_NE(read_only.message().find("the job database is read-only"), std::string::npos);
  EXPECT_FALSE(IsSqliteBusy(SQLITE_READONLY));
  const Status full = SqliteStatus(SQLITE_FULL, nullptr, "create job");
  EXPECT_EQ(full.code(), StatusCode::kResourceExhausted);
  EXPECT_NE(full.message().find("the disk holding the job database is full"), std::string::npos);
}

TEST(SqliteError, TellsABusyFailureFromOthers) {
  try {
    ThrowIfSqliteError(SQLITE_BUSY, nullptr, "x");
    ADD_FAILURE() << "no throw";
  } catch (const SqliteError& e) {
    EXPECT_TRUE(e.busy());
  }
  try {
    ThrowIfSqliteError(SQLITE_READONLY, nullptr, "x");
    ADD_FAILURE() << "no throw";
  } catch (const SqliteError& e) {
    EXPECT_FALSE(e.busy());
    EXPECT_EQ(e.status().code(), StatusCode::kResourceExhausted);
  }
}

}  // namespace
}  // namespace reconduit
