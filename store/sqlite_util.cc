#include "store/sqlite_util.h"

#include <string>
#include <utility>

namespace reconduit {

Status SqliteStatus(int rc, sqlite3* db, std::string_view context) {
  std::string detail = sqlite3_errstr(rc);
  // sqlite3_errmsg is more specific ("CHECK constraint failed: ...") but only describes the
  // connection's latest error, which is the one at hand when the codes agree.
  if (db != nullptr && sqlite3_extended_errcode(db) == rc) detail = sqlite3_errmsg(db);
  std::string message = std::string(context) + ": " + detail;
  switch (rc & 0xff) {
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      return Status::ResourceExhausted(message + " (database is busy; retry later)");
    case SQLITE_READONLY:
      return Status::ResourceExhausted(
          message +
          " (the job database is read-only: check the file's permissions and its filesystem; "
          "changes are refused until it is writable)");
    case SQLITE_FULL:
      return Status::ResourceExhausted(message + " (the disk holding the job database is full)");
    case SQLITE_CONSTRAINT:
      return Status::InvalidArgument(message);
    case SQLITE_NOTADB:
    case SQLITE_CORRUPT:
      return Status::Internal(message + " (the file is not a usable SQLite database)");
    default:
      return Status::Internal(message);
  }
}

bool IsSqliteBusy(int rc) { return (rc & 0xff) == SQLITE_BUSY || (rc & 0xff) == SQLITE_LOCKED; }

void ThrowIfSqliteError(int rc, sqlite3* db, std::string_view context) {
  if (rc == SQLITE_OK || rc == SQLITE_ROW || rc == SQLITE_DONE) return;
  throw SqliteError(SqliteStatus(rc, db, context), IsSqliteBusy(rc));
}

// ------------------------------------------------------------------------------------------------

SqliteConnection SqliteConnection::Open(const std::string& path) {
  sqlite3* db = nullptr;
  const int flags =
      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX | SQLITE_OPEN_EXRESCODE;
  const int rc = sqlite3_open_v2(path.c_str(), &db, flags, nullptr);
  SqliteConnection connection(db);  // Closes the handle even when opening failed.
  ThrowIfSqliteError(rc, db, "open database '" + path + "'");
  if (db == nullptr) throw SqliteError(Status::Internal("open database '" + path + "': no memory"));
  return connection;
}

SqliteConnection::SqliteConnection(SqliteConnection&& other) noexcept
    : db_(std::exchange(other.db_, nullptr)) {}

SqliteConnection& SqliteConnection::operator=(SqliteConnection&& other) noexcept {
  if (this != &other) {
    if (db_ != nullptr) sqlite3_close_v2(db_);
    db_ = std::exchange(other.db_, nullptr);
  }
  return *this;
}

SqliteConnection::~SqliteConnection() {
  // close_v2 defers the close until outstanding statements are finalized, so the order of
  // destruction between a connection and its statements cannot leak or crash.
  if (db_ != nullptr) sqlite3_close_v2(db_);
}

void SqliteConnection::Exec(const char* sql, std::string_view context) {
  ThrowIfSqliteError(sqlite3_exec(db_, sql, nullptr, nullptr, nullptr), db_, context);
}

std::int64_t SqliteConnection::QueryInt64(const char* sql, std::string_view context) {
  try {
    Statement statement(db_, sql);
    if (!statement.Step()) {
      throw SqliteError(Status::Internal(std::string(context) + ": query returned no row"));
    }
    return statement.Int64(0);
  } catch (const SqliteError& e) {
    const Status& s = e.status();
    throw SqliteError(Status(s.code(), std::string(context) + ": " + s.message()), e.busy());
  }
}

std::int64_t SqliteConnection::Changes() const { return sqlite3_changes64(db_); }

bool SqliteConnection::InAutocommit() const { return sqlite3_get_autocommit(db_) != 0; }

// ------------------------------------------------------------------------------------------------

Statement::Statement(sqlite3* db, std::string_view sql) : db_(db), sql_(sql) {
  const int rc = sqlite3_prepare_v2(db, sql.data(), static_cast<int>(sql.size()), &stmt_, nullptr);
  ThrowIfSqliteError(rc, db, "prepare \"" + sql_ + "\"");
  if (stmt_ == nullptr) {
    throw SqliteError(Status::Internal("prepare \"" + sql_ + "\": empty statement"));
  }
}

Statement::Statement(Statement&& other) noexcept
    : db_(other.db_), stmt_(std::exchange(other.stmt_, nullptr)), sql_(std::move(other.sql_)) {}

Statement::~Statement() {
  if (stmt_ != nullptr) sqlite3_finalize(stmt_);
}

Statement& Statement::Bind(int index, std::int64_t value) {
  ThrowIfSqliteError(sqlite3_bind_int64(stmt_, index, value), db_, "bind " + sql_);
  return *this;
}

Statement& Statement::Bind(int index, double value) {
  ThrowIfSqliteError(sqlite3_bind_double(stmt_, index, value), db_, "bind " + sql_);
  return *this;
}

Statement& Statement::Bind(int index, std::string_view value) {
  ThrowIfSqliteError(
      sqlite3_bind_text64(stmt_, index, value.data(), value.size(), SQLITE_TRANSIENT, SQLITE_UTF8),
      db_, "bind " + sql_);
  return *this;
}

Statement& Statement::BindNull(int index) {
  ThrowIfSqliteError(sqlite3_bind_null(stmt_, index), db_, "bind " + sql_);
  return *this;
}

Statement& Statement::BindTextOrNull(int index, std::string_view value) {
  return value.empty() ? BindNull(index) : Bind(index, value);
}

bool Statement::Step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  // The statement must be reset before the connection reports the specific error code
  // consistently; reset returns the same code.
  sqlite3_reset(stmt_);
  // Marked busy like every other call's SQLITE_BUSY, so SqliteJobStore retries it: an
  // autocommit UPDATE meets the lock here, not at a BEGIN (a worker's progress report behind
  // another process's claim used to fail the worker at once).
  throw SqliteError(SqliteStatus(rc, db_, "run \"" + sql_ + "\""), IsSqliteBusy(rc));
}

void Statement::Run() {
  while (Step()) {
  }
}

void Statement::Reset() { sqlite3_reset(stmt_); }

bool Statement::IsNull(int column) const {
  return sqlite3_column_type(stmt_, column) == SQLITE_NULL;
}

std::int64_t Statement::Int64(int column) const { return sqlite3_column_int64(stmt_, column); }

double Statement::Double(int column) const { return sqlite3_column_double(stmt_, column); }

std::string Statement::Text(int column) const {
  const unsigned char* text = sqlite3_column_text(stmt_, column);
  if (text == nullptr) return {};
  return std::string(reinterpret_cast<const char*>(text),
                     static_cast<std::size_t>(sqlite3_column_bytes(stmt_, column)));
}

std::optional<std::int64_t> Statement::OptionalInt64(int column) const {
  if (IsNull(column)) return std::nullopt;
  return Int64(column);
}

std::optional<double> Statement::OptionalDouble(int column) const {
  if (IsNull(column)) return std::nullopt;
  return Double(column);
}

// ------------------------------------------------------------------------------------------------

Transaction::Transaction(SqliteConnection& db, Mode mode) : db_(db) {
  db_.Exec(mode == Mode::kImmediate ? "BEGIN IMMEDIATE" : "BEGIN DEFERRED", "begin transaction");
}

Transaction::~Transaction() {
  if (done_) return;
  // ROLLBACK can fail only when no transaction is open (SQLite already rolled back after an
  // I/O error or a full disk), which is the state we want anyway.
  sqlite3_exec(db_.get(), "ROLLBACK", nullptr, nullptr, nullptr);
}

void Transaction::Commit() {
  db_.Exec("COMMIT", "commit transaction");
  done_ = true;
}

}  // namespace reconduit
