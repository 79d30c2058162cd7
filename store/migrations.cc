#include "store/migrations.h"

#include <string>

namespace reconduit {
namespace {

Status CheckMigrationList(std::span<const Migration> migrations) {
  for (std::size_t i = 0; i < migrations.size(); ++i) {
    if (migrations[i].version != static_cast<int>(i) + 1) {
      return Status::Internal("schema migration " + std::string(migrations[i].name) +
                              " has version " + std::to_string(migrations[i].version) +
                              ", expected " + std::to_string(i + 1) +
                              " (migrations must be numbered 1, 2, ... without gaps)");
    }
  }
  return Status::Ok();
}

}  // namespace

Result<int> SchemaVersion(SqliteConnection& db) {
  try {
    return static_cast<int>(db.QueryInt64("PRAGMA user_version", "read schema version"));
  } catch (const SqliteError& e) {
    return e.status();
  }
}

Status ApplyMigrations(SqliteConnection& db, std::span<const Migration> migrations) {
  if (Status s = CheckMigrationList(migrations); !s.ok()) return s;
  const int latest = static_cast<int>(migrations.size());
  try {
    // The usual case, a database already at the latest version: confirmed with reads only. In
    // WAL mode readers never wait for the write lock, which processes that claim and finish jobs
    // keep taking; several of them busy on two cores kept an opening process from the write
    // lock beyond the busy timeout (JobStoreConcurrency under the sanitizers).
    if (db.QueryInt64("PRAGMA application_id", "read application id") == kReconduitApplicationId &&
        db.QueryInt64("PRAGMA user_version", "read schema version") == latest) {
      return Status::Ok();
    }
    // IMMEDIATE: read the version and write the schema under the same write lock, so two
    // processes opening a new file at once cannot both apply migration 1.
    Transaction transaction(db, Transaction::Mode::kImmediate);
    const std::int64_t version = db.QueryInt64("PRAGMA user_version", "read schema version");
    const std::int64_t application_id =
        db.QueryInt64("PRAGMA application_id", "read application id");
    if (application_id != 0 && application_id != kReconduitApplicationId) {
      return Status::FailedPrecondition("not a Reconduit job database (application_id " +
                                        std::to_string(application_id) +
                                        "); refusing to modify it");
    }
    if (version > latest) {
      return Status::FailedPrecondition(
          "job database schema version " + std::to_string(version) +
          " is newer than this program supports (" + std::to_string(latest) +
          "); run a newer Reconduit, or restore a backup made before the upgrade");
    }
    if (version == 0) {
      const std::int64_t objects =
          db.QueryInt64("SELECT count(*) FROM sqlite_schema", "inspect database");
      if (objects != 0) {
        return Status::FailedPrecondition(
            "not a Reconduit job database (it has tables but no schema version); refusing to "
            "modify it");
      }
    }
    if (version == latest) return Status::Ok();  // Rolls back the empty transaction.

    for (const Migration& migration : migrations.subspan(static_cast<std::size_t>(version))) {
      const std::string sql(migration.sql);  // Exec needs a terminating NUL.
      db.Exec(sql.c_str(), "apply schema migration " + std::string(migration.name));
    }
    // PRAGMAs take no bound parameters; both values are integers from this code, not input.
    db.Exec(("PRAGMA application_id = " + std::to_string(kReconduitApplicationId)).c_str(),
            "set application id");
    db.Exec(("PRAGMA user_version = " + std::to_string(latest)).c_str(), "set schema version");
    transaction.Commit();
    return Status::Ok();
  } catch (const SqliteError& e) {
    return e.status();
  }
}

}  // namespace reconduit
