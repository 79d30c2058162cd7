#include "store/migrations.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "store/job_store.h"
#include "store/store_test_util.h"
#include <fstream>
#include <vector>

namespace reconduit {
namespace {

using ::testing::HasSubstr;
using testing_util::MakeNewJob;
using testing_util::OpenOrDie;
using testing_util::TempDir;

// Two toy migrations: the second inserts a row, so running it twice would show.
constexpr Migration kToyMigrations[] = {
    {1, "001_a.sql", "CREATE TABLE a (x INTEGER); CREATE TABLE log (what TEXT);"},
    {2, "002_b.sql", "INSERT INTO log VALUES ('2 applied'); CREATE TABLE b (y INTEGER);"},
};

std::int64_t Count(SqliteConnection& db, const char* sql) { return db.QueryInt64(sql, "count"); }

std::int64_t TableCount(SqliteConnection& db) {
  return Count(db, "SELECT count(*) FROM sqlite_schema WHERE type = 'table'");
}

TEST(EmbeddedMigrations, AreNumberedFromOneAndCreateTheTables) {
  const std::span<const Migration> migrations = EmbeddedMigrations();
  ASSERT_FALSE(migrations.empty());
  for (std::size_t i = 0; i < migrations.size(); ++i) {
    EXPECT_EQ(migrations[i].version, static_cast<int>(i) + 1);
    EXPECT_FALSE(migrations[i].sql.empty());
  }
  EXPECT_EQ(migrations[0].name, "001_init.sql");
  EXPECT_THAT(std::string(migrations[0].sql), HasSubstr("CREATE TABLE jobs"));
  EXPECT_THAT(std::string(migrations[0].sql), HasSubstr("CREATE TABLE job_events"));
  EXPECT_THAT(std::string(migrations[0].sql), HasSubstr("CREATE TABLE images"));
}

TEST(ApplyMigrations, AppliesOnceAndReapplyingIsANoOp) {
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("m.db"));
  ASSERT_TRUE(ApplyMigrations(db, kToyMigrations).ok());
  EXPECT_EQ(SchemaVersion(db).value(), 2);
  EXPECT_EQ(Count(db, "PRAGMA application_id"), kReconduitApplicationId);
  EXPECT_EQ(Count(db, "SELECT count(*) FROM log"), 1);

  ASSERT_TRUE(ApplyMigrations(db, kToyMigrations).ok());
  SqliteConnection reopened = SqliteConnection::Open(dir.File("m.db"));
  ASSERT_TRUE(ApplyMigrations(reopened, kToyMigrations).ok());
  EXPECT_EQ(Count(reopened, "SELECT count(*) FROM log"), 1);
  EXPECT_EQ(SchemaVersion(reopened).value(), 2);
}

TEST(ApplyMigrations, AppliesOnlyTheNewOnes) {
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("m.db"));
  ASSERT_TRUE(ApplyMigrations(db, std::span(kToyMigrations).first(1)).ok());
  EXPECT_EQ(SchemaVersion(db).value(), 1);
  EXPECT_EQ(Count(db, "SELECT count(*) FROM log"), 0);
  ASSERT_TRUE(ApplyMigrations(db, kToyMigrations).ok());
  EXPECT_EQ(SchemaVersion(db).value(), 2);
  EXPECT_EQ(Count(db, "SELECT count(*) FROM log"), 1);
}

TEST(ApplyMigrations, FailureRollsEverythingBack) {
  constexpr Migration kBroken[] = {
      {1, "001_a.sql", "CREATE TABLE a (x INTEGER);"},
      {2, "002_bad.sql", "CREATE TABLE b (y INTEGER); THIS IS NOT SQL;"},
  };
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("m.db"));
  const Status status = ApplyMigrations(db, kBroken);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), HasSubstr("002_bad.sql"));
  EXPECT_EQ(SchemaVersion(db).value(), 0);
  EXPECT_EQ(TableCount(db), 0);  // Not even migration 1's table.
  EXPECT_TRUE(db.InAutocommit());
}

TEST(ApplyMigrations, RefusesANewerSchema) {
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("m.db"));
  ASSERT_TRUE(ApplyMigrations(db, kToyMigrations).ok());
  db.Exec("PRAGMA user_version = 7", "bump");
  const Status status = ApplyMigrations(db, kToyMigrations);
  EXPECT_EQ(status.code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(), HasSubstr("schema version 7 is newer"));
  EXPECT_EQ(SchemaVersion(db).value(), 7);  // Untouched.
}

TEST(ApplyMigrations, RefusesAnotherProgramsDatabase) {
  TempDir dir;
  SqliteConnection with_tables = SqliteConnection::Open(dir.File("a.db"));
  with_tables.Exec("CREATE TABLE customers (name TEXT)", "create");
  Status status = ApplyMigrations(with_tables, kToyMigrations);
  EXPECT_EQ(status.code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(), HasSubstr("not a Reconduit job database"));
  EXPECT_EQ(TableCount(with_tables), 1);

  SqliteConnection with_id = SqliteConnection::Open(dir.File("b.db"));
  with_id.Exec("PRAGMA application_id = 42", "set id");
  status = ApplyMigrations(with_id, kToyMigrations);
  EXPECT_EQ(status.code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(), HasSubstr("application_id 42"));
}

TEST(ApplyMigrations, RejectsAGapInTheNumbering) {
  constexpr Migration kGap[] = {{1, "001_a.sql", "SELECT 1;"}, {3, "003_c.sql", "SELECT 1;"}};
  TempDir dir;
  SqliteConnection db = SqliteConnection::Open(dir.File("m.db"));
  const Status status = ApplyMigrations(db, kGap);
  EXPECT_EQ(status.code(), StatusCode::kInternal);
  EXPECT_THAT(status.message(), HasSubstr("003_c.sql"));
}

TEST(OpenSqliteJobStore, CreatesTheSchemaInWalModeAndReopens) {
  TempDir dir;
  const std::string path = dir.File("jobs.db");
  std::string id;
  {
    std::unique_ptr<JobStore> store = OpenOrDie(path);
    Result<Job> job = store->CreateJob(MakeNewJob());
    ASSERT_TRUE(job.ok()) << job.status();
    id = job->id;
  }
  std::unique_ptr<JobStore> store = OpenOrDie(path);  // Reopening migrates nothing.
  EXPECT_TRUE(store->GetJob(id).ok());
  SqliteConnection db = SqliteConnection::Open(path);
  EXPECT_EQ(SchemaVersion(db).value(), static_cast<int>(EmbeddedMigrations().size()));
  Statement mode(db.get(), "PRAGMA journal_mode");
  ASSERT_TRUE(mode.Step());
  EXPECT_EQ(mode.Text(0), "wal");
}

TEST(OpenSqliteJobStore, RefusesANewerSchemaWithAClearError) {
  TempDir dir;
  const std::string path = dir.File("jobs.db");
  OpenOrDie(path);
  {
    SqliteConnection db = SqliteConnection::Open(path);
    db.Exec("PRAGMA user_version = 999", "bump");
  }
  Result<std::unique_ptr<JobStore>> store = OpenSqliteJobStore(path);
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(store.status().message(), HasSubstr(path));
  EXPECT_THAT(store.status().message(), HasSubstr("999 is newer than this program supports"));
}

TEST(OpenSqliteJobStore, AFileThatIsNotADatabaseGivesAClearError) {
  TempDir dir;
  const std::string path = dir.File("jobs.db");
  {
    std::ofstream file(path, std::ios::binary);
    for (int i = 0; i < 200; ++i) file << "this is a text file, not a database\n";
  }
  Result<std::unique_ptr<JobStore>> store = OpenSqliteJobStore(path);
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.status().code(), StatusCode::kInternal);
  EXPECT_THAT(store.status().message(), HasSubstr(path));
  EXPECT_THAT(store.status().message(), HasSubstr("not a usable SQLite database"));
}

TEST(OpenSqliteJobStore, ACorruptDatabaseGivesErrorsNotACrash) {
  TempDir dir;
  const std::string path = dir.File("jobs.db");
  {
    std::unique_ptr<JobStore> store = OpenOrDie(path);
    for (int i = 0; i < 50; ++i) ASSERT_TRUE(store->CreateJob(MakeNewJob(20)).ok());
  }  // The last connection checkpoints the WAL into the main file.
  const auto size = std::filesystem::file_size(path);
  ASSERT_GT(size, 8192u);
  {
    // Keep the header page, overwrite every other page with garbage.
    std::fstream file(path, std::ios::in | std::ios::out | std::ios::binary);
    file.seekp(4096);
    for (std::uintmax_t i = 4096; i < size; ++i) file.put(static_cast<char>((i * 131) & 0xff));
  }
  Result<std::unique_ptr<JobStore>> store = OpenSqliteJobStore(path);
  if (!store.ok()) {
    EXPECT_EQ(store.status().code(), StatusCode::kInternal) << store.status();
    return;
  }
  Result<JobPage> page = (*store)->ListJobs({});
  ASSERT_FALSE(page.ok());
  EXPECT_EQ(page.status().code(), StatusCode::kInternal);
  EXPECT_THAT(page.status().message(), HasSubstr("not a usable SQLite database")) << page.status();
}

TEST(OpenSqliteJobStore, RefusesInMemoryAndUriNames) {
  EXPECT_EQ(OpenSqliteJobStore(":memory:").status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(OpenSqliteJobStore("").status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(OpenSqliteJobStore("file:x.db?mode=memory").status().code(),
            StatusCode::kInvalidArgument);
}

TEST(OpenSqliteJobStore, AnUnopenablePathGivesAnError) {
  TempDir dir;
  Result<std::unique_ptr<JobStore>> store = OpenSqliteJobStore(dir.File("missing/dir/jobs.db"));
  ASSERT_FALSE(store.ok());
  EXPECT_THAT(store.status().message(), HasSubstr("unable to open"));
}

}  // namespace
}  // namespace reconduit
