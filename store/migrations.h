// Schema migrations: the numbered SQL files in schema/sql/, embedded in the binary at build time
// and applied when a job database is opened.
//
// A database records the number of the last migration applied in `PRAGMA user_version` (0 for
// a new file) and carries Reconduit's `PRAGMA application_id`, so a file that belongs to some
// other program is refused rather than silently extended with our tables.
#ifndef RECONDUIT_STORE_MIGRATIONS_H_
#define RECONDUIT_STORE_MIGRATIONS_H_

#include "core/util/status.h"

#include "store/sqlite_util.h"
#include <cstdint>
#include <span>
#include <string_view>

namespace reconduit {

// One schema step: the file schema/sql/<NNN>_<name>.sql.
struct Migration {
  // The NNN prefix; migrations are numbered 1, 2, 3, ... without gaps.
  int version = 0;
  // File name, e.g. "001_init.sql", for messages.
  std::string_view name;
  // The file's SQL text, possibly several statements.
  std::string_view sql;
};

// The migrations compiled into this binary, in version order. Generated at build time by
// store/embed_migrations.cmake from schema/sql/*.sql: the program does not read the
// source tree at run time.
std::span<const Migration> EmbeddedMigrations();

// "RCND" — written to the database header (PRAGMA application_id) by the first migration.
inline constexpr std::int32_t kReconduitApplicationId = 0x52434e44;

// Brings the database on `db` up to the latest of `migrations`.
//
// Runs in one BEGIN IMMEDIATE transaction, so concurrent openers (a server and several workers
// starting together) serialise: the first applies the pending migrations, the others then find
// nothing to do. Each pending migration's SQL runs in order, then user_version is set to the
// last version; any failure rolls everything back and leaves the file as it was.
//
// Refuses (kFailedPrecondition) a database whose user_version is newer than the newest
// migration this binary knows — an older binary must not write to a schema it does not
// understand — and a database that carries another program's application_id or has tables but
// no Reconduit version. A file that is not an SQLite database gives kInternal naming the problem.
//
// @param migrations  ordered, numbered 1..N without gaps (checked: kInternal otherwise).
// @return OK, or why the database cannot be used.
Status ApplyMigrations(SqliteConnection& db, std::span<const Migration> migrations);

// The user_version of the database on `db` (0 for a new file).
Result<int> SchemaVersion(SqliteConnection& db);

}  // namespace reconduit

#endif  // RECONDUIT_STORE_MIGRATIONS_H_
