// Starts real reconduit-worker processes on a temporary data folder whose jobs the test inserted
// through the JobStore, and checks what they do to the jobs: normal processing, kill -9 in the
// middle of a stage (the next worker resumes), two workers sharing a queue (each job once), and
// SIGTERM during a job (exit 0 quickly, job back in the queue, finished by the next worker).
#include "server/storage/data_layout.h"
#include "server/storage/job_store.h"
#include "worker/worker_test_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <sys/types.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

#ifndef RECONDUIT_WORKER_BINARY
#error "RECONDUIT_WORKER_BINARY must name the reconduit-worker executable"
#endif

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// Opens a store or throws.
std::unique_ptr<JobStore> OpenOrDie(const std::string& path) {
  Result<std::unique_ptr<JobStore>> store = OpenSqliteJobStore(path);
  if (!store.ok()) throw std::runtime_error(store.status().ToString());
  return std::move(store).value();
}
using namespace std::chrono_literals;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing_util::TempDir;

// Small photos for the quick jobs; larger ones where a test must catch a stage while it runs.
struct PhotoSet {
  int count, width, height;
};
constexpr PhotoSet kSmall{6, 640, 480};
constexpr PhotoSet kLarge{6, 1280, 960};

// Rendered once per test binary and set (rendering is slow), copied into each job.
const fs::path& Photos(const PhotoSet& set) {
  static TempDir small, large;
  static bool small_rendered = false, large_rendered = false;
  const bool is_small = set.width == kSmall.width;
  bool& rendered = is_small ? small_rendered : large_rendered;
  const TempDir& dir = is_small ? small : large;
  if (!rendered) {
    testing_util::WriteBoxRoomPhotos(dir.path(), set.count, set.width, set.height);
    rendered = true;
  }
  return dir.path();
}

// A running reconduit-worker; its stdout and stderr go to a log file. Killed on destruction.
class WorkerProcess {
 public:
  WorkerProcess(const fs::path& data, const std::string& id, std::vector<std::string> extra)
      : log_path_(data / ("worker-" + id + ".log")) {
    std::vector<std::string> args = {RECONDUIT_WORKER_BINARY, "--data", data.string(), "--id", id};
    args.insert(args.end(), extra.begin(), extra.end());
    pid_ = fork();
    THROW_CHECK_GE(pid_, 0) << "fork failed";
    if (pid_ == 0) {
      const int fd = open(log_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd < 0) _exit(127);
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      std::vector<char*> argv;
      for (std::string& arg : args) argv.push_back(arg.data());
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
  }
  WorkerProcess(const WorkerProcess&) = delete;
  WorkerProcess& operator=(const WorkerProcess&) = delete;
  ~WorkerProcess() {
    if (pid_ > 0 && !exited_) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }

  void Signal(int signal) const { kill(pid_, signal); }

  // Waits for the process to end; returns its wait status, or nullopt after `timeout`.
  std::optional<int> Wait(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (true) {
      int status = 0;
      const pid_t done = waitpid(pid_, &status, WNOHANG);
      if (done == pid_) {
        exited_ = true;
        return status;
      }
      if (std::chrono::steady_clock::now() >= deadline) return std::nullopt;
      std::this_thread::sleep_for(20ms);
    }
  }

  std::string Log() const {
    std::ifstream file(log_path_);
    std::stringstream text;
    text << file.rdbuf();
    return text.str();
  }

 private:
  fs::path log_path_;
  pid_t pid_ = -1;
  bool exited_ = false;
};

class WorkerProcessTest : public ::testing::Test {
 protected:
  WorkerProcessTest() : layout_(dir_.path()), store_(OpenOrDie(layout_.DatabasePath().string())) {}

  std::string CreateJob(const PhotoSet& set,
                        nlohmann::json options = {{"num_threads", 1}, {"max_features", 2048}}) {
    NewJob job;
    job.id = NewJobId();
    job.options = std::move(options);
    fs::create_directories(layout_.InputDir(job.id));
    for (int i = 0; i < set.count; ++i) {
      char stored[16];
      std::snprintf(stored, sizeof(stored), "%04d.jpg", i + 1);
      fs::copy_file(Photos(set) / stored, layout_.InputDir(job.id) / stored);
      JobImageRecord image;
      image.index = i;
      image.original_name = "room_" + std::to_string(i) + ".jpg";
      image.stored_name = stored;
      image.bytes = static_cast<std::int64_t>(fs::file_size(layout_.InputDir(job.id) / stored));
      job.images.push_back(std::move(image));
    }
    Result<Job> created = store_->CreateJob(job);
    THROW_CHECK(created.ok()) << created.status();
    return job.id;
  }

  Job Get(const std::string& id) {
    Result<Job> job = store_->GetJob(id);
    THROW_CHECK(job.ok()) << job.status();
    return std::move(job).value();
  }

  std::vector<std::string> Events(const std::string& id) {
    std::vector<std::string> messages;
    std::int64_t after = 0;
    while (true) {
      Result<std::vector<JobEvent>> events = store_->ListEvents(id, after, 1000);
      THROW_CHECK(events.ok()) << events.status();
      if (events->empty()) break;
      for (const JobEvent& event : *events) {
        messages.push_back(event.stage + "|" + event.message);
        after = event.id;
      }
    }
    return messages;
  }

  static long Count(const std::vector<std::string>& events, const std::string& needle) {
    return std::count_if(events.begin(), events.end(), [&](const std::string& event) {
      return event.find(needle) != std::string::npos;
    });
  }

  // Polls `done` every 20 ms until it holds or `timeout` passes.
  static bool WaitUntil(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      if (done()) return true;
      std::this_thread::sleep_for(20ms);
    }
    return done();
  }

  bool WaitForState(const std::string& id, JobState state, std::chrono::milliseconds timeout) {
    return WaitUntil([&] { return Get(id).state == state; }, timeout);
  }

  // Waits until the job's current stage is `stage` and the stage has reported progress.
  bool WaitForStage(const std::string& id,
                    const std::string& stage,
                    std::chrono::milliseconds timeout) {
    return WaitUntil(
        [&] {
          const Job job = Get(id);
          return job.state == JobState::kRunning && job.stage == stage &&
                 job.stage_progress.contains(stage);
        },
        timeout);
  }

  std::string Describe(const std::string& id) {
    const Job job = Get(id);
    return std::string(JobStateName(job.state)) + " stage=" + job.stage + " error=" + job.error +
           "\nevents:\n" + ::testing::PrintToString(Events(id));
  }

  TempDir dir_;
  DataLayout layout_;
  std::unique_ptr<JobStore> store_;
};

TEST_F(WorkerProcessTest, ProcessesQueuedJobsAndWaitsQuietly) {
  const std::string first = CreateJob(kSmall);
  const std::string second = CreateJob(kSmall);
  // --until matching: the stages after it are still being written and do not yet reconstruct
  // these renders; every test here stops there to stay fast and independent of them.
  WorkerProcess worker(layout_.root(), "w1",
                       {"--poll", "0.1", "--lease", "5", "--until", "matching"});
  EXPECT_TRUE(WaitForState(first, JobState::kSucceeded, 50s)) << Describe(first) << worker.Log();
  EXPECT_TRUE(WaitForState(second, JobState::kSucceeded, 30s)) << Describe(second) << worker.Log();
  for (const std::string& id : {first, second}) {
    const Job job = Get(id);
    ASSERT_TRUE(job.result_bytes.has_value());
    EXPECT_EQ(*job.result_bytes, static_cast<std::int64_t>(fs::file_size(layout_.ResultZip(id))));
    EXPECT_EQ(job.counts.value("images", 0), kSmall.count);
    EXPECT_FALSE(fs::exists(layout_.ResultZip(id).string() + ".tmp"));
  }
  // Idle for ~10 polls: "waiting for jobs" is said once, not once per poll.
  std::this_thread::sleep_for(1s);
  worker.Signal(SIGTERM);
  const std::optional<int> status = worker.Wait(5s);
  ASSERT_TRUE(status.has_value()) << "did not exit after SIGTERM\n" << worker.Log();
  EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) == 0) << worker.Log();
  const std::string log = worker.Log();
  std::size_t waiting = 0;
  for (std::size_t pos = log.find("waiting for jobs"); pos != std::string::npos;
       pos = log.find("waiting for jobs", pos + 1)) {
    ++waiting;
  }
  EXPECT_EQ(waiting, 1u) << log;
}

TEST_F(WorkerProcessTest, KillDashNineMidStageThenAnotherWorkerResumes) {
  const std::string id = CreateJob(kLarge);
  {
    WorkerProcess doomed(layout_.root(), "doomed",
                         {"--poll", "0.1", "--lease", "1.5", "--until", "matching"});
    ASSERT_TRUE(WaitForStage(id, "features", 40s)) << Describe(id) << doomed.Log();
    doomed.Signal(SIGKILL);
    ASSERT_TRUE(doomed.Wait(5s).has_value());
  }
  Job job = Get(id);
  ASSERT_EQ(job.state, JobState::kRunning) << "nobody has swept the dead worker's lease yet";
  ASSERT_EQ(job.lease_owner, "doomed");
  ASSERT_EQ(job.finished_stages.front(), "ingest");

  WorkerProcess rescuer(layout_.root(), "rescuer",
                        {"--poll", "0.1", "--lease", "5", "--until", "matching"});
  ASSERT_TRUE(WaitForState(id, JobState::kSucceeded, 55s)) << Describe(id) << rescuer.Log();
  job = Get(id);
  EXPECT_EQ(job.attempts, 1) << "the lost run counts as an attempt";
  EXPECT_THAT(job.finished_stages, ElementsAre("ingest", "features", "pairs", "matching"));
  const std::vector<std::string> events = Events(id);
  // Ingest ran once, in the killed run; the rescuer skipped it.
  EXPECT_EQ(Count(events, "ingest|stage 'ingest' started"), 1) << ::testing::PrintToString(events);
  EXPECT_EQ(Count(events, "stage 'ingest' finished in an earlier run"), 1);
  EXPECT_EQ(Count(events, "started by worker 'rescuer'"), 1);
  // Features was killed mid-way (it takes seconds on these photos): it ran again from scratch.
  EXPECT_EQ(Count(events, "features|stage 'features' started"), 2);
  EXPECT_EQ(Count(events, "stage 'features' finished in an earlier run"), 0);
  EXPECT_EQ(Count(events, "|succeeded"), 1);
  EXPECT_TRUE(fs::exists(layout_.ResultZip(id)));
}

TEST_F(WorkerProcessTest, TwoWorkersProcessEachJobExactlyOnce) {
  std::vector<std::string> ids;
  for (int i = 0; i < 4; ++i) ids.push_back(CreateJob(kSmall));
  WorkerProcess a(layout_.root(), "a",
                  {"--poll", "0.1", "--lease", "5", "--threads", "1", "--until", "matching"});
  WorkerProcess b(layout_.root(), "b",
                  {"--poll", "0.1", "--lease", "5", "--threads", "1", "--until", "matching"});
  for (const std::string& id : ids) {
    EXPECT_TRUE(WaitForState(id, JobState::kSucceeded, 55s)) << Describe(id) << a.Log() << b.Log();
  }
  int by_a = 0, by_b = 0;
  for (const std::string& id : ids) {
    const std::vector<std::string> events = Events(id);
    EXPECT_EQ(Count(events, "started by worker"), 1) << ::testing::PrintToString(events);
    EXPECT_EQ(Count(events, "ingest|stage 'ingest' started"), 1);
    EXPECT_EQ(Count(events, "|succeeded"), 1);
    EXPECT_EQ(Get(id).attempts, 0);
    by_a += static_cast<int>(Count(events, "started by worker 'a'"));
    by_b += static_cast<int>(Count(events, "started by worker 'b'"));
  }
  EXPECT_EQ(by_a + by_b, 4);
  a.Signal(SIGTERM);
  b.Signal(SIGTERM);
  EXPECT_TRUE(a.Wait(5s).has_value());
  EXPECT_TRUE(b.Wait(5s).has_value());
}

TEST_F(WorkerProcessTest, SigtermMidJobReleasesItAndTheNextWorkerFinishesIt) {
  const std::string id = CreateJob(kLarge);
  {
    WorkerProcess stopping(layout_.root(), "stopping",
                           {"--poll", "0.1", "--lease", "30", "--until", "matching"});
    ASSERT_TRUE(WaitForStage(id, "features", 40s)) << Describe(id) << stopping.Log();
    const auto signalled = std::chrono::steady_clock::now();
    stopping.Signal(SIGTERM);
    const std::optional<int> status = stopping.Wait(5s);
    ASSERT_TRUE(status.has_value()) << "no exit within 5 s of SIGTERM\n" << stopping.Log();
    EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) == 0) << stopping.Log();
    EXPECT_LT(std::chrono::steady_clock::now() - signalled, 5s);
  }
  Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kQueued) << Describe(id);
  EXPECT_EQ(job.attempts, 0) << "a clean release spends no attempt";
  EXPECT_TRUE(job.lease_owner.empty());
  EXPECT_EQ(Count(Events(id), "released by worker 'stopping'"), 1);

  // Not waiting for a 30 s lease: the job is claimable at once.
  WorkerProcess next(layout_.root(), "next",
                     {"--poll", "0.1", "--lease", "5", "--once", "--until", "matching"});
  ASSERT_TRUE(WaitForState(id, JobState::kSucceeded, 50s)) << Describe(id) << next.Log();
  const std::optional<int> status = next.Wait(10s);
  ASSERT_TRUE(status.has_value()) << "--once must exit after its job\n" << next.Log();
  EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) == 0);
  const std::vector<std::string> events = Events(id);
  EXPECT_EQ(Count(events, "ingest|stage 'ingest' started"), 1) << ::testing::PrintToString(events);
  EXPECT_EQ(Count(events, "stage 'ingest' finished in an earlier run"), 1);
}

}  // namespace
}  // namespace reconduit
