// Several threads and several processes claiming from one database: every job is claimed
// exactly once and no "database is locked" error reaches a caller.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sqlite3.h>

#include "store/job_store.h"
#include "store/store_test_util.h"
#include <chrono>
#include <fstream>
#include <map>
#include <signal.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace reconduit {
namespace {

using namespace std::chrono_literals;
using testing_util::MakeNewJob;
using testing_util::OpenOrDie;
using testing_util::TempDir;

constexpr int kJobs = 200;
constexpr int kWorkers = 4;
const std::string kSha(64, '0');

std::vector<std::string> CreateJobs(JobStore& store, int count) {
  std::vector<std::string> ids;
  for (int i = 0; i < count; ++i) {
    Result<Job> job = store.CreateJob(MakeNewJob(1));
    THROW_CHECK(job.ok()) << job.status();
    ids.push_back(job->id);
  }
  return ids;
}

// Claims until the queue is empty, finishing each job; returns the ids claimed, or the first
// error as text (so that a thread or a child process can report it).
std::vector<std::string> ClaimUntilEmpty(JobStore& store,
                                         const std::string& worker,
                                         std::string* error) {
  std::vector<std::string> claimed;
  for (;;) {
    Result<std::optional<Job>> job = store.ClaimNextJob(worker, 60s);
    if (!job.ok()) {
      *error = job.status().ToString();
      return claimed;
    }
    if (!job->has_value()) return claimed;
    const std::string id = (*job)->id;
    claimed.push_back(id);
    // A little traffic between claims, as a real worker makes.
    Status status = store.RecordProgress(id, worker, {.stage = "ingest", .progress = 0.5});
    if (status.ok()) status = store.AppendEvent(id, {.message = "working"}).status();
    if (status.ok()) status = store.FinishSucceeded(id, worker, {.result_sha256 = kSha});
    if (!status.ok()) {
      *error = status.ToString();
      return claimed;
    }
  }
}

void ExpectEachClaimedOnce(const std::vector<std::string>& created,
                           const std::vector<std::vector<std::string>>& claims) {
  std::map<std::string, int> times;
  for (const auto& worker_claims : claims) {
    for (const std::string& id : worker_claims) ++times[id];
  }
  EXPECT_EQ(times.size(), created.size());
  for (const std::string& id : created) EXPECT_EQ(times[id], 1) << id;
}

void ExpectAllSucceeded(JobStore& store, std::int64_t count) {
  Result<QueueStats> stats = store.GetQueueStats();
  ASSERT_TRUE(stats.ok()) << stats.status();
  EXPECT_EQ(stats->Count(JobState::kSucceeded), count);
  EXPECT_EQ(stats->QueueLength(), 0);
  EXPECT_EQ(stats->Count(JobState::kRunning), 0);
}

TEST(JobStoreConcurrency, ThreadsSharingOneStoreClaimEachJobOnce) {
  TempDir dir;
  std::unique_ptr<JobStore> store = OpenOrDie(dir.File("jobs.db"));
  const std::vector<std::string> created = CreateJobs(*store, kJobs);

  std::vector<std::vector<std::string>> claims(kWorkers);
  std::vector<std::string> errors(kWorkers);
  std::vector<std::thread> threads;
  for (int w = 0; w < kWorkers; ++w) {
    threads.emplace_back(
        [&, w] { claims[w] = ClaimUntilEmpty(*store, "thread-" + std::to_string(w), &errors[w]); });
  }
  for (std::thread& thread : threads) thread.join();

  for (const std::string& error : errors) EXPECT_EQ(error, "");
  ExpectEachClaimedOnce(created, claims);
  ExpectAllSucceeded(*store, kJobs);
}

TEST(JobStoreConcurrency, ThreadsWithTheirOwnStoresClaimEachJobOnce) {
  TempDir dir;
  const std::string path = dir.File("jobs.db");
  std::unique_ptr<JobStore> creator = OpenOrDie(path);
  const std::vector<std::string> created = CreateJobs(*creator, kJobs);

  std::vector<std::vector<std::string>> claims(kWorkers);
  std::vector<std::string> errors(kWorkers);
  std::vector<std::thread> threads;
  for (int w = 0; w < kWorkers; ++w) {
    threads.emplace_back([&, w] {
      Result<std::unique_ptr<JobStore>> store = OpenSqliteJobStore(path);
      if (!store.ok()) {
        errors[w] = store.status().ToString();
        return;
      }
      claims[w] = ClaimUntilEmpty(**store, "store-" + std::to_string(w), &errors[w]);
    });
  }
  // Meanwhile the "server" keeps reading, as status pages do.
  for (int i = 0; i < 50; ++i) ASSERT_TRUE(creator->ListJobs({.limit = 20}).ok());
  for (std::thread& thread : threads) thread.join();

  for (const std::string& error : errors) EXPECT_EQ(error, "");
  ExpectEachClaimedOnce(created, claims);
  ExpectAllSucceeded(*creator, kJobs);
}

// Runs `body` in a child process; the child exits with body's return value and never returns
// into the test (no gtest state, no destructors of the parent's objects).
pid_t Spawn(const std::function<int()>& body) {
  const pid_t pid = fork();
  THROW_CHECK(pid >= 0) << "fork failed";
  if (pid == 0) {
    int code = 3;
    try {
      code = body();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "child %d: %s\n", getpid(), e.what());
    }
    std::fflush(stderr);
    _exit(code);
  }
  return pid;
}

int WaitExitCode(pid_t pid) {
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

std::vector<std::string> ReadLines(const std::string& path) {
  std::vector<std::string> lines;
  std::ifstream file(path);
  for (std::string line; std::getline(file, line);) lines.push_back(line);
  return lines;
}

TEST(JobStoreConcurrency, ProcessesClaimEachJobOnceWithoutBusyErrors) {
  TempDir dir;
  const std::string path = dir.File("jobs.db");
  std::vector<std::string> created;
  {
    // Close every connection before fork(): SQLite handles must not cross into a child.
    std::unique_ptr<JobStore> store = OpenOrDie(path);
    created = CreateJobs(*store, kJobs);
  }
  std::vector<pid_t> children;
  for (int w = 0; w < kWorkers; ++w) {
    const std::string claims_file = dir.File("claims-" + std::to_string(w));
    children.push_back(Spawn([&path, claims_file, w] {
      Result<std::unique_ptr<JobStore>> store = OpenSqliteJobStore(path);
      if (!store.ok()) {
        std::fprintf(stderr, "open: %s\n", store.status().ToString().c_str());
        return 1;
      }
      std::string error;
      const std::vector<std::string> claimed =
          ClaimUntilEmpty(**store, "process-" + std::to_string(w), &error);
      std::ofstream out(claims_file);
      for (const std::string& id : claimed) out << id << '\n';
      if (!error.empty()) {
        std::fprintf(stderr, "process-%d: %s\n", w, error.c_str());
        return 2;
      }
      return 0;
    }));
  }
  std::vector<std::vector<std::string>> claims;
  for (int w = 0; w < kWorkers; ++w) {
    EXPECT_EQ(WaitExitCode(children[w]), 0) << "worker process " << w;
    claims.push_back(ReadLines(dir.File("claims-" + std::to_string(w))));
  }
  ExpectEachClaimedOnce(created, claims);
  std::unique_ptr<JobStore> store = OpenOrDie(path);
  ExpectAllSucceeded(*store, kJobs);
}

TEST(JobStoreConcurrency, ProcessesOpeningANewDatabaseAtOnceMigrateItOnce) {
  TempDir dir;
  const std::string path = dir.File("fresh.db");
  constexpr int kPerProcess = 10;
  std::vector<pid_t> children;
  for (int w = 0; w < kWorkers; ++w) {
    children.push_back(Spawn([&path] {
      Result<std::unique_ptr<JobStore>> store = OpenSqliteJobStore(path);
      if (!store.ok()) {
        std::fprintf(stderr, "open: %s\n", store.status().ToString().c_str());
        return 1;
      }
      for (int i = 0; i < kPerProcess; ++i) {
        Result<Job> job = (*store)->CreateJob(MakeNewJob(1));
        if (!job.ok()) {
          std::fprintf(stderr, "create: %s\n", job.status().ToString().c_str());
          return 2;
        }
      }
      return 0;
    }));
  }
  for (int w = 0; w < kWorkers; ++w) EXPECT_EQ(WaitExitCode(children[w]), 0);
  std::unique_ptr<JobStore> store = OpenOrDie(path);
  Result<JobPage> page = store->ListJobs({});
  ASSERT_TRUE(page.ok()) << page.status();
  EXPECT_EQ(page->total, kWorkers * kPerProcess);
}

TEST(JobStoreConcurrency, AJobOfAKilledWorkerProcessIsResumedByAnother) {
  TempDir dir;
  const std::string path = dir.File("jobs.db");
  std::string id;
  {
    std::unique_ptr<JobStore> store = OpenOrDie(path);
    id = CreateJobs(*store, 1)[0];
  }
  const pid_t child = Spawn([&path, &id] {
    std::unique_ptr<JobStore> store = OpenOrDie(path);
    Result<std::optional<Job>> job = store->ClaimNextJob("doomed", 200ms);
    if (!job.ok() || !job->has_value()) return 1;
    if (!store->MarkStageFinished(id, "doomed", "ingest", 0.1).ok()) return 2;
    kill(getpid(), SIGKILL);  // Dies holding the lease, like kill -9 mid-stage.
    return 3;
  });
  EXPECT_EQ(WaitExitCode(child), 128 + SIGKILL);

  std::unique_ptr<JobStore> store = OpenOrDie(path);
  Result<std::optional<Job>> early = store->ClaimNextJob("rescuer", 60s);
  ASSERT_TRUE(early.ok()) << early.status();
  EXPECT_FALSE(early->has_value());  // The lease has not run out yet.
  std::this_thread::sleep_for(300ms);
  Result<std::optional<Job>> job = store->ClaimNextJob("rescuer", 60s);
  ASSERT_TRUE(job.ok()) << job.status();
  ASSERT_TRUE(job->has_value());
  EXPECT_EQ((*job)->id, id);
  EXPECT_EQ((*job)->attempts, 1);
  EXPECT_THAT((*job)->finished_stages, ::testing::ElementsAre("ingest"));
  EXPECT_TRUE(store->FinishSucceeded(id, "rescuer", {.result_sha256 = kSha}).ok());
}

// Another process holds the database's write lock (here: another connection in BEGIN
// EXCLUSIVE). A write gives up with kResourceExhausted after its tries (each waiting the busy
// timeout), saying the database is busy; reads go on (WAL); once the lock is gone, writes go
// through.
TEST(JobStoreConcurrency, AWriteBehindALockGivesUpSayingSo) {
  TempDir dir;
  const std::string path = dir.File("jobs.db");
  std::unique_ptr<JobStore> store = OpenOrDie(path, {.busy_timeout_ms = 200});
  const std::string before = CreateJobs(*store, 1)[0];
  sqlite3* other = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &other), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(other, "BEGIN EXCLUSIVE", nullptr, nullptr, nullptr), SQLITE_OK);
  const auto start = std::chrono::steady_clock::now();
  const Result<Job> blocked = store->CreateJob(MakeNewJob(1));
  const auto waited = std::chrono::steady_clock::now() - start;
  EXPECT_EQ(blocked.status().code(), StatusCode::kResourceExhausted) << blocked.status();
  EXPECT_THAT(blocked.status().message(), ::testing::HasSubstr("busy"));
  EXPECT_GE(waited, 190ms);
  EXPECT_LT(waited, 4 * 200ms + 1s) << "at most four tries of one busy timeout each";
  EXPECT_TRUE(store->GetJob(before).ok());
  ASSERT_EQ(sqlite3_exec(other, "ROLLBACK", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(other);
  EXPECT_TRUE(store->CreateJob(MakeNewJob(1)).ok());
}

}  // namespace
}  // namespace reconduit
