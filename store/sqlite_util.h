// Small RAII wrappers over the SQLite C API: a connection, a prepared statement and a
// transaction.
//
// The wrappers throw SqliteError (which carries a Status) when SQLite reports an error. They are
// an implementation detail of the storage layer: SqliteJobStore catches SqliteError at every
// public method and returns its Status, so no exception leaves the store. Throwing here keeps
// the store's SQL readable and lets a half-done transaction roll back by unwinding.
//
// Values always reach SQL through bound parameters (Statement::Bind); SQL text is built from
// constants only.
//
// Thread-safety: none of these objects may be used from two threads at once. A connection (and
// its statements) may move between threads when it is idle, which is what the store's pool does.
#ifndef RECONDUIT_STORE_SQLITE_UTIL_H_
#define RECONDUIT_STORE_SQLITE_UTIL_H_

#include "core/util/status.h"

#include <sqlite3.h>

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace reconduit {

// An SQLite failure as an exception; status() says what it means for a caller.
class SqliteError : public std::runtime_error {
 public:
  // `busy`: the failure was SQLITE_BUSY / SQLITE_LOCKED (IsSqliteBusy), which a retry may cure.
  explicit SqliteError(Status status, bool busy = false)
      : std::runtime_error(status.ToString()), status_(std::move(status)), busy_(busy) {}
  const Status& status() const { return status_; }
  bool busy() const { return busy_; }

 private:
  Status status_;
  bool busy_;
};

// Maps an SQLite result code to a Status:
//   SQLITE_BUSY / SQLITE_LOCKED            -> kResourceExhausted ("database is busy"; retry later)
//   SQLITE_CONSTRAINT                      -> kInvalidArgument (a CHECK, UNIQUE or FK violation)
//   SQLITE_NOTADB / SQLITE_CORRUPT         -> kInternal, saying the file is not a usable database
//   SQLITE_READONLY / SQLITE_FULL          -> kResourceExhausted, saying the database file is
//                                             read-only or its disk full (a server answers 503
//                                             with Retry-After; nothing to retry within a call)
//   SQLITE_CANTOPEN ...                    -> kInternal with SQLite's message
// @param rc       an extended or primary SQLite result code (not SQLITE_OK).
// @param db       the connection for sqlite3_errmsg, or nullptr.
// @param context  what was being done, e.g. "claim a job"; prefixed to the message.
Status SqliteStatus(int rc, sqlite3* db, std::string_view context);

// True for the codes that a later retry can cure (SQLITE_BUSY, SQLITE_LOCKED and extensions).
bool IsSqliteBusy(int rc);

// Throws SqliteError(SqliteStatus(rc, db, context)) unless rc is SQLITE_OK, SQLITE_ROW or
// SQLITE_DONE.
void ThrowIfSqliteError(int rc, sqlite3* db, std::string_view context);

// An open sqlite3 connection, closed on destruction. Move-only.
class SqliteConnection {
 public:
  // Opens (creating if needed) the database file at `path` read-write, with extended result
  // codes. The handle is opened in SQLite's multi-thread mode (SQLITE_OPEN_NOMUTEX): the caller
  // guarantees one thread at a time. Throws SqliteError.
  static SqliteConnection Open(const std::string& path);

  SqliteConnection() = default;
  SqliteConnection(SqliteConnection&& other) noexcept;
  SqliteConnection& operator=(SqliteConnection&& other) noexcept;
  SqliteConnection(const SqliteConnection&) = delete;
  SqliteConnection& operator=(const SqliteConnection&) = delete;
  ~SqliteConnection();

  sqlite3* get() const { return db_; }

  // Runs one or more SQL statements that take no parameters (schema text, pragmas, BEGIN).
  // Throws SqliteError.
  void Exec(const char* sql, std::string_view context);

  // Runs a statement returning one integer (e.g. "PRAGMA user_version"). Throws SqliteError.
  std::int64_t QueryInt64(const char* sql, std::string_view context);

  // Rows changed by the most recent INSERT, UPDATE or DELETE on this connection.
  std::int64_t Changes() const;

  // True when no transaction is open.
  bool InAutocommit() const;

 private:
  explicit SqliteConnection(sqlite3* db) : db_(db) {}
  sqlite3* db_ = nullptr;
};

// A prepared statement, finalized on destruction. Parameters are 1-based, columns 0-based
// (SQLite's conventions). Move-only.
class Statement {
 public:
  // Prepares `sql` (a single statement) on `db`. Throws SqliteError.
  Statement(sqlite3* db, std::string_view sql);
  Statement(Statement&& other) noexcept;
  Statement& operator=(Statement&& other) = delete;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement();

  // Binders return *this so that calls chain: st.Bind(1, id).Bind(2, now).
  Statement& Bind(int index, std::int64_t value);
  Statement& Bind(int index, int value) { return Bind(index, static_cast<std::int64_t>(value)); }
  Statement& Bind(int index, double value);
  Statement& Bind(int index, bool value) { return Bind(index, std::int64_t{value ? 1 : 0}); }
  // The text is copied (SQLITE_TRANSIENT), so temporaries are fine.
  Statement& Bind(int index, std::string_view value);
  Statement& Bind(int index, const char* value) { return Bind(index, std::string_view(value)); }
  Statement& Bind(int index, const std::string& value) {
    return Bind(index, std::string_view(value));
  }
  Statement& BindNull(int index);
  template <typename T>
  Statement& Bind(int index, const std::optional<T>& value) {
    return value.has_value() ? Bind(index, *value) : BindNull(index);
  }
  // Binds NULL for an empty string, the text otherwise (optional TEXT columns).
  Statement& BindTextOrNull(int index, std::string_view value);

  // Advances the statement: true when a row is ready, false when done. Throws SqliteError.
  bool Step();
  // Steps to completion, ignoring any rows (INSERT, UPDATE, DELETE). Throws SqliteError.
  void Run();
  // Makes the statement runnable again; bindings are kept.
  void Reset();

  bool IsNull(int column) const;
  std::int64_t Int64(int column) const;
  double Double(int column) const;
  // The text of the column; "" for NULL.
  std::string Text(int column) const;
  std::optional<std::int64_t> OptionalInt64(int column) const;
  std::optional<double> OptionalDouble(int column) const;

 private:
  sqlite3* db_ = nullptr;
  sqlite3_stmt* stmt_ = nullptr;
  std::string sql_;  // For error messages.
};

// A transaction that rolls back unless Commit() is called.
//
// kImmediate takes the database write lock at BEGIN (waiting up to busy_timeout). Every
// read-modify-write transaction must use it: a deferred transaction that reads and then writes
// can get SQLITE_BUSY at the write without the busy handler being consulted (SQLite refuses to
// wait there because waiting could deadlock), which is the classic "database is locked" under
// concurrency.
class Transaction {
 public:
  enum class Mode { kDeferred, kImmediate };
  // Begins the transaction. Throws SqliteError.
  Transaction(SqliteConnection& db, Mode mode);
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  // Rolls back when Commit() has not succeeded. Never throws.
  ~Transaction();
  // Throws SqliteError; the destructor then rolls back.
  void Commit();

 private:
  SqliteConnection& db_;
  bool done_ = false;
};

}  // namespace reconduit

#endif  // RECONDUIT_STORE_SQLITE_UTIL_H_
