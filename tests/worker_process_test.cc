// Starts real reconduit-worker processes on a temporary data folder whose jobs the test inserted
// through the JobStore, and checks what they do to the jobs: normal processing, kill -9 in the
// middle of a stage (the next worker resumes), kill -9 at eleven moments of a job's life (every job
// finishes once, with a valid result.zip), two workers sharing a queue (each job once), SIGTERM
// during a job (exit 0 quickly, job back in the queue, finished by the next worker), and the
// configuration file.
#include "core/io/file_util.h"
#include "tests/long_test_util.h"
#include "worker/worker_test_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "store/data_layout.h"
#include "store/job_store.h"
#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <sys/types.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

extern char** environ;

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

// The stages a run can resume, in pipeline order (export and packaging always run again).
const std::vector<std::string> kResumableStages = {"ingest", "features", "pairs", "matching",
                                                   "sparse", "dense",    "mesh",  "texture"};

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
// Started with --data `data` and --id `id` (none when empty), then `extra`; `env` adds
// "NAME=value" entries to the inherited environment; `wrapper` (a program and its arguments,
// e.g. unshare) runs the worker command line as its own last arguments.
class WorkerProcess {
 public:
  WorkerProcess(const fs::path& data,
                const std::string& id,
                std::vector<std::string> extra,
                const std::vector<std::string>& env = {},
                const std::vector<std::string>& wrapper = {})
      : log_path_(data / ("worker-" + (id.empty() ? std::string("anonymous") : id) + ".log")) {
    std::vector<std::string> args = wrapper;
    args.insert(args.end(), {RECONDUIT_WORKER_BINARY, "--data", data.string()});
    if (!id.empty()) args.insert(args.end(), {"--id", id});
    args.insert(args.end(), extra.begin(), extra.end());
    std::vector<std::string> env_strings;
    for (char** e = environ; *e != nullptr; ++e) env_strings.emplace_back(*e);
    env_strings.insert(env_strings.end(), env.begin(), env.end());
    std::vector<char*> envp;
    for (std::string& entry : env_strings) envp.push_back(entry.data());
    envp.push_back(nullptr);
    std::vector<char*> argv;
    for (std::string& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    pid_ = fork();
    THROW_CHECK_GE(pid_, 0) << "fork failed";
    if (pid_ == 0) {
      const int fd = open(log_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd < 0) _exit(127);
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      execve(argv[0], argv.data(), envp.data());
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

  static nlohmann::json SmallJobOptions() {
    return {{"num_threads", 1}, {"max_features", 2048}, {"dense_max_image_side", 256}};
  }

  std::string CreateJob(const PhotoSet& set,
                        nlohmann::json options = SmallJobOptions(),
                        int max_attempts = 3) {
    NewJob job;
    job.id = NewJobId();
    job.options = std::move(options);
    job.max_attempts = max_attempts;
    fs::create_directories(layout_.InputDir(job.id));
    for (int i = 0; i < set.count; ++i) {
      char stored[16];
      std::snprintf(stored, sizeof(stored), "%04d.jpg", i + 1);
      fs::copy_file(Photos(set) / stored, layout_.InputDir(job.id) / stored);
      JobImageRecord image;
      image.index = i;
      image.original_name = "room_" + std::to_string(i) + ".jpg";
      image.stored_name = stored;
      image.photo.bytes =
          static_cast<std::int64_t>(fs::file_size(layout_.InputDir(job.id) / stored));
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

  // Depth maps the dense stage of job `id` has finished on disk.
  int KeptDepthMaps(const std::string& id) {
    std::error_code ec;
    int n = 0;
    for (fs::directory_iterator it(layout_.WorkDir(id) / "dense" / "maps", ec), end;
         !ec && it != end; it.increment(ec)) {
      n += it->path().extension() == ".rcdm";
    }
    return n;
  }

  std::string Describe(const std::string& id) {
    const Job job = Get(id);
    return std::string(JobStateName(job.state)) + " stage=" + job.stage + " error=" + job.error +
           "\nevents:\n" + ::testing::PrintToString(Events(id));
  }

  // One result.zip, the one the store describes for succeeded job `id`, whose manifest matches
  // its entries and the output folder, with nothing left over from a killed run, holding the
  // deliverables and a report of every stage.
  void ExpectResultVerifies(const std::string& id, const Job& job) {
    const fs::path zip = layout_.ResultZip(id);
    ASSERT_TRUE(fs::exists(zip));
    EXPECT_FALSE(fs::exists(zip.string() + ".tmp"));
    ASSERT_TRUE(job.result_bytes.has_value());
    EXPECT_EQ(*job.result_bytes, static_cast<std::int64_t>(fs::file_size(zip)));
    const Result<std::string> sha = Sha256OfFile(zip);
    ASSERT_TRUE(sha.ok());
    EXPECT_EQ(job.result_sha256, *sha);
    const std::map<std::string, std::string> entries = testing_util::ReadZipEntries(zip);
    ASSERT_TRUE(entries.count("manifest.json"));
    const nlohmann::json manifest = nlohmann::json::parse(entries.at("manifest.json"));
    std::set<std::string> listed = {"manifest.json"};
    for (const nlohmann::json& file : manifest.at("files")) {
      const std::string name = file.at("name");
      listed.insert(name);
      ASSERT_TRUE(entries.count(name)) << name;
      EXPECT_EQ(file.at("bytes").get<std::size_t>(), entries.at(name).size()) << name;
      EXPECT_EQ(file.at("sha256").get<std::string>(), Sha256Hex(entries.at(name))) << name;
    }
    std::set<std::string> in_zip, in_output;
    for (const auto& [name, bytes] : entries) in_zip.insert(name);
    for (const auto& entry : fs::recursive_directory_iterator(layout_.OutputDir(id))) {
      if (entry.is_regular_file()) {
        in_output.insert(fs::relative(entry.path(), layout_.OutputDir(id)).generic_string());
      }
    }
    EXPECT_EQ(in_zip, listed);
    EXPECT_EQ(in_output, listed);
    for (const std::string& name : listed) {
      EXPECT_EQ(name.find(".tmp"), std::string::npos) << "a leftover of the killed run: " << name;
    }
    for (const char* expected : {"report.json", "cameras.json", "sparse.ply", "model.glb",
                                 "report/similarity.png", "report/match_graph.png"}) {
      EXPECT_TRUE(listed.count(expected)) << expected;
    }
    const nlohmann::json report = nlohmann::json::parse(entries.at("report.json"));
    std::vector<std::string> reported;
    for (const nlohmann::json& stage : report.at("stages")) reported.push_back(stage.at("name"));
    std::vector<std::string> expected_stages = kResumableStages;
    expected_stages.push_back("export");  // Not resumable: it runs again, before packaging.
    EXPECT_EQ(reported, expected_stages);
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
    EXPECT_EQ(job.counts.images.value_or(0), kSmall.count);
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

// One moment of a job's life at which its worker dies by SIGKILL.
struct KillMoment {
  std::string name;
  // RECONDUIT_WORKER_CRASH_AT: the worker kills itself there, for moments an outside kill
  // cannot aim at (between two lines of the runner). Empty: the test sends SIGKILL itself
  // once `stage` has run for `after`.
  std::string crash_at;
  std::string stage;
  std::chrono::milliseconds after{0};
  // What the dead worker leaves: the first `finished_on_disk` resumable stages have their
  // stage.json marker (so the next run skips them), and whether result.zip is in place.
  int finished_on_disk = 0;
  bool result_zip = false;
};

// Kills a worker at eleven moments spread over a job's life, one job per moment (a job may run
// max_attempts = 3 times, so each job dies once): right after the claim; between a stage's
// marker on disk and the store hearing of it (ingest, features, matching); in the middle of
// features, matching and sparse; in dense once a depth map is finished (the next worker takes
// the finished maps over); when packaging starts; after result.zip is renamed into place
// but before the store knows; just before FinishSucceeded. Each time a new worker takes the job
// over once the dead worker's lease runs out, and the job must end succeeded exactly once:
// claimed by the rescuer, attempts 1, the finished stages skipped and the others run once,
// every stage recorded, one result.zip whose manifest matches its entries and the output
// folder, and no job lost or duplicated across the queue.
TEST_F(WorkerProcessTest, KillDashNineAtElevenMomentsEveryJobFinishesOnce) {
  const std::vector<KillMoment> moments = {
      {"right after the claim", "claimed", "", 0ms, 0, false},
      {"ingest's marker written, store not told", "stage-done:ingest", "", 0ms, 1, false},
      {"in the middle of features", "", "features", 400ms, 1, false},
      {"features' marker written, store not told", "stage-done:features", "", 0ms, 2, false},
      {"in the middle of matching", "", "matching", 250ms, 3, false},
      {"matching's marker written, store not told", "stage-done:matching", "", 0ms, 4, false},
      {"in the middle of sparse", "", "sparse", 100ms, 4, false},
      {"in the middle of dense, a depth map finished", "", "dense", 0ms, 5, false},
      {"packaging started", "stage-started:package", "", 0ms, 8, false},
      {"result.zip renamed into place, store not told", "stage-done:package", "", 0ms, 8, true},
      {"result.zip checked, FinishSucceeded not called", "before-finish", "", 0ms, 8, true},
  };
  // All jobs queued from the start: each doomed worker and each rescuer takes the oldest queued
  // job, and nothing may take a job that is not its turn.
  std::vector<std::string> ids;
  for (std::size_t i = 0; i < moments.size(); ++i) ids.push_back(CreateJob(kSmall));

  for (std::size_t i = 0; i < moments.size(); ++i) {
    const KillMoment& moment = moments[i];
    const std::string& id = ids[i];
    SCOPED_TRACE("moment " + std::to_string(i) + ": " + moment.name);
    const std::string doomed_id = "doomed-" + std::to_string(i);
    const std::string rescuer_id = "rescuer-" + std::to_string(i);
    std::vector<std::string> env;
    if (!moment.crash_at.empty()) env.push_back("RECONDUIT_WORKER_CRASH_AT=" + moment.crash_at);
    {
      WorkerProcess doomed(layout_.root(), doomed_id, {"--poll", "0.1", "--lease", "1"}, env);
      if (moment.crash_at.empty()) {
        ASSERT_TRUE(WaitForStage(id, moment.stage, 40s)) << Describe(id) << doomed.Log();
        if (moment.stage == "dense") {
          ASSERT_TRUE(WaitUntil([&] { return KeptDepthMaps(id) >= 1; }, 40s)) << doomed.Log();
        }
        std::this_thread::sleep_for(moment.after);
        doomed.Signal(SIGKILL);
      }
      const std::optional<int> status = doomed.Wait(40s);
      ASSERT_TRUE(status.has_value()) << Describe(id) << doomed.Log();
      ASSERT_TRUE(WIFSIGNALED(*status) && WTERMSIG(*status) == SIGKILL) << doomed.Log();
      if (!moment.crash_at.empty()) {
        ASSERT_THAT(doomed.Log(),
                    HasSubstr("RECONDUIT_WORKER_CRASH_AT=" + moment.crash_at + " reached"));
      }
    }
    // The kill landed where it was meant to: the job is still the dead worker's, with exactly
    // the expected stages finished on disk.
    Job job = Get(id);
    ASSERT_EQ(job.state, JobState::kRunning) << Describe(id);
    ASSERT_EQ(job.lease_owner, doomed_id);
    for (int s = 0; s < static_cast<int>(kResumableStages.size()); ++s) {
      const fs::path marker = layout_.WorkDir(id) / kResumableStages[s] / "stage.json";
      EXPECT_EQ(fs::exists(marker), s < moment.finished_on_disk) << marker;
    }
    EXPECT_EQ(fs::exists(layout_.ResultZip(id)), moment.result_zip);
    const int kept_maps = moment.stage == "dense" ? KeptDepthMaps(id) : 0;
    if (moment.stage == "sparse") {
      // What a kill inside an atomic write of a deliverable leaves (core/io writes
      // "<file>.tmp-<pid>-<random>", then renames it): it must not reach result.zip.
      std::ofstream(layout_.OutputDir(id) / "sparse.ply.tmp-4242-17") << "ply\nformat ascii";
    }
    for (std::size_t later = i + 1; later < ids.size(); ++later) {
      ASSERT_EQ(Get(ids[later]).state, JobState::kQueued) << "the doomed worker took another job";
    }

    // The rescuer starts once the dead worker's lease has run out: its first sweep requeues the
    // job, which keeps its place at the head of the queue. --once: exactly one job.
    ASSERT_TRUE(job.lease_until_ms.has_value());
    const auto lease_end =
        std::chrono::system_clock::time_point(std::chrono::milliseconds(*job.lease_until_ms));
    std::this_thread::sleep_until(lease_end + 50ms);
    WorkerProcess rescuer(layout_.root(), rescuer_id, {"--poll", "0.1", "--lease", "5", "--once"});
    const std::optional<int> rescuer_status = rescuer.Wait(60s);
    ASSERT_TRUE(rescuer_status.has_value()) << Describe(id) << rescuer.Log();
    EXPECT_TRUE(WIFEXITED(*rescuer_status) && WEXITSTATUS(*rescuer_status) == 0) << rescuer.Log();

    job = Get(id);
    ASSERT_EQ(job.state, JobState::kSucceeded) << Describe(id) << rescuer.Log();
    EXPECT_EQ(job.attempts, 1) << "the killed run is one lost attempt";
    EXPECT_TRUE(job.lease_owner.empty());
    EXPECT_TRUE(job.error.empty()) << job.error;
    EXPECT_EQ(job.finished_stages, kResumableStages);
    EXPECT_EQ(job.counts.images.value_or(0), kSmall.count);
    EXPECT_EQ(job.counts.registered.value_or(0), kSmall.count);

    // The rescuer's run: after its "started by" line, the stages finished on disk are skipped
    // and every other stage (and export and packaging) runs exactly once.
    const std::vector<std::string> events = Events(id);
    const std::string all = ::testing::PrintToString(events);
    EXPECT_EQ(Count(events, "started by worker"), 2) << all;
    EXPECT_EQ(Count(events, "started by worker '" + doomed_id + "'"), 1) << all;
    EXPECT_EQ(Count(events, "(lease expired); requeued for run 2"), 1) << all;
    EXPECT_EQ(Count(events, "|succeeded"), 1) << all;
    const auto rescue_start =
        std::find_if(events.begin(), events.end(), [&](const std::string& event) {
          return event.find("started by worker '" + rescuer_id + "'") != std::string::npos;
        });
    ASSERT_NE(rescue_start, events.end()) << all;
    const std::vector<std::string> rescue(rescue_start, events.end());
    for (int s = 0; s < static_cast<int>(kResumableStages.size()); ++s) {
      const std::string& stage = kResumableStages[s];
      const bool skipped = s < moment.finished_on_disk;
      EXPECT_EQ(Count(rescue, "stage '" + stage + "' finished in an earlier run"), skipped ? 1 : 0)
          << stage << "\n"
          << all;
      EXPECT_EQ(Count(rescue, stage + "|stage '" + stage + "' started"), skipped ? 0 : 1)
          << stage << "\n"
          << all;
    }
    EXPECT_EQ(Count(rescue, "export|stage 'export' started"), 1) << all;
    if (moment.stage == "dense") {
      // The rescuer took over the depth maps the dead worker finished and computed the rest.
      const nlohmann::json report =
          nlohmann::json::parse(*ReadFile(layout_.OutputDir(id) / "report.json"));
      int resumed = 0, maps = 0;
      for (const nlohmann::json& stage : report.at("stages")) {
        if (stage.at("name") != "dense") continue;
        for (const nlohmann::json& map : stage.at("summary").at("maps")) {
          ++maps;
          resumed += map.value("resumed", false);
        }
      }
      EXPECT_EQ(resumed, kept_maps);
      EXPECT_EQ(maps, kSmall.count);
    }
    EXPECT_EQ(Count(rescue, "package|stage 'package' started"), 1) << all;

    ExpectResultVerifies(id, job);
  }

  // Nothing lost, nothing duplicated: the same ten jobs, all succeeded, each started by its
  // doomed worker and its rescuer only.
  JobListQuery query;
  query.limit = 100;
  const Result<JobPage> page = store_->ListJobs(query);
  ASSERT_TRUE(page.ok());
  EXPECT_EQ(page->total, static_cast<std::int64_t>(ids.size()));
  std::set<std::string> listed_ids;
  for (const Job& job : page->jobs) {
    listed_ids.insert(job.id);
    EXPECT_EQ(job.state, JobState::kSucceeded) << job.id;
  }
  EXPECT_EQ(listed_ids, std::set<std::string>(ids.begin(), ids.end()));
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const std::vector<std::string> events = Events(ids[i]);
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const long expected = k == i ? 1 : 0;
      EXPECT_EQ(Count(events, "started by worker 'doomed-" + std::to_string(k) + "'"), expected);
      EXPECT_EQ(Count(events, "started by worker 'rescuer-" + std::to_string(k) + "'"), expected);
    }
  }
}

// The long random kill test (issue 12; ctest entry tests/worker_random_kill_test, label long,
// which sets RECONDUIT_LONG_TESTS=1; skipped in the regular run). Workers are killed by SIGKILL
// at random moments, RECONDUIT_RANDOM_KILLS times (default 50), each after a uniform random
// 0.1-5 s of life, while the queue is kept busy (a new job whenever fewer than two wait or
// run), and two jobs are canceled on the way. Then one worker that is not killed finishes the
// queue. Every job must end succeeded, or canceled when asked; none lost, none run to the end
// twice; every succeeded job's result.zip verifies; every run of a job is accounted for (its
// runs are its lost attempts plus the last). RECONDUIT_RANDOM_SEED repeats a run (the seed
// is printed).
TEST_F(WorkerProcessTest, RandomKillsLoseNoJob) {
  if (!testing_util::LongTestsEnabled()) {
    GTEST_SKIP() << "a long test: ctest -L long -R worker_random_kill (RECONDUIT_LONG_TESTS=1)";
  }
  const int kills = static_cast<int>(testing_util::EnvLong("RECONDUIT_RANDOM_KILLS", 50));
  const auto seed =
      static_cast<unsigned>(testing_util::EnvLong("RECONDUIT_RANDOM_SEED", std::random_device()()));
  std::printf("random kills: %d, seed %u (RECONDUIT_RANDOM_SEED repeats it)\n", kills, seed);
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> life_ms(100, 5000);
  std::set<int> cancel_at;
  while (cancel_at.size() < 2 && kills >= 4) {
    cancel_at.insert(std::uniform_int_distribution<int>(1, kills - 2)(random));
  }

  std::vector<std::string> ids;
  std::set<std::string> cancel_asked;
  // A job may die on every run: no attempt limit gets in the way.
  const auto add_job = [&] { ids.push_back(CreateJob(kSmall, SmallJobOptions(), kills + 2)); };
  const auto open_jobs = [&] {
    int open = 0;
    for (const std::string& id : ids) {
      const JobState state = Get(id).state;
      open += state == JobState::kQueued || state == JobState::kRunning;
    }
    return open;
  };
  std::map<std::string, int> killed_in;  // The running job's stage at each kill.
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < kills; ++k) {
    while (open_jobs() < 2) add_job();
    const std::string worker_id = "w" + std::to_string(k);
    WorkerProcess worker(layout_.root(), worker_id, {"--poll", "0.1", "--lease", "1"});
    std::this_thread::sleep_for(std::chrono::milliseconds(life_ms(random)));
    if (cancel_at.count(k) > 0) {
      // The job this worker runs (or the oldest open one): canceled by a client.
      for (const std::string& id : ids) {
        const Job job = Get(id);
        if ((job.state == JobState::kRunning && job.lease_owner == worker_id) ||
            (job.state == JobState::kQueued && cancel_asked.empty())) {
          ASSERT_TRUE(store_->RequestCancel(id).ok());
          cancel_asked.insert(id);
          break;
        }
      }
    }
    std::string stage = "idle";
    for (const std::string& id : ids) {
      const Job job = Get(id);
      if (job.state == JobState::kRunning && job.lease_owner == worker_id) stage = job.stage;
    }
    worker.Signal(SIGKILL);
    const std::optional<int> status = worker.Wait(10s);
    ASSERT_TRUE(status.has_value()) << worker.Log();
    ASSERT_TRUE(WIFSIGNALED(*status) && WTERMSIG(*status) == SIGKILL)
        << "the worker died before its kill\n"
        << worker.Log();
    ++killed_in[stage.empty() ? "claimed" : stage];
  }
  // The survivor finishes the queue (it sweeps the last dead worker's lease first).
  WorkerProcess survivor(layout_.root(), "survivor", {"--poll", "0.1", "--lease", "5"});
  ASSERT_TRUE(WaitUntil([&] { return open_jobs() == 0; }, 600s)) << survivor.Log();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  int succeeded = 0, canceled = 0, runs = 0, lost_runs = 0;
  for (const std::string& id : ids) {
    SCOPED_TRACE("job " + id);
    const Job job = Get(id);
    const std::vector<std::string> events = Events(id);
    const std::string all = ::testing::PrintToString(events);
    const long started = Count(events, "started by worker");
    const long requeued = Count(events, "(lease expired); requeued for run");
    runs += static_cast<int>(started);
    lost_runs += job.attempts;
    // Every run but the last was lost to a kill and requeued once; a canceled job's last run
    // may itself be a lost one (canceled when its lease was swept) or never have started.
    EXPECT_EQ(job.attempts, requeued) << all;
    EXPECT_TRUE(job.lease_owner.empty());
    if (job.state == JobState::kCanceled) {
      ++canceled;
      EXPECT_TRUE(cancel_asked.count(id)) << "canceled without being asked\n" << all;
      EXPECT_FALSE(fs::exists(layout_.ResultZip(id)));
      continue;
    }
    ASSERT_EQ(job.state, JobState::kSucceeded) << Describe(id);
    ++succeeded;
    EXPECT_EQ(started, job.attempts + 1) << all;
    EXPECT_EQ(Count(events, "|succeeded"), 1) << all;
    EXPECT_TRUE(job.error.empty()) << job.error;
    EXPECT_EQ(job.finished_stages, kResumableStages);
    EXPECT_EQ(job.counts.registered.value_or(0), kSmall.count);
    ExpectResultVerifies(id, job);
  }
  // Nothing lost or added: the store lists exactly the jobs made here.
  JobListQuery query;
  query.limit = 1000;
  const Result<JobPage> page = store_->ListJobs(query);
  ASSERT_TRUE(page.ok());
  std::set<std::string> listed;
  for (const Job& job : page->jobs) listed.insert(job.id);
  EXPECT_EQ(listed, std::set<std::string>(ids.begin(), ids.end()));

  std::string where;
  for (const auto& [stage, n] : killed_in) where += " " + stage + " " + std::to_string(n);
  std::printf(
      "random kills: %d workers killed (running job's stage at the kill:%s); %zu jobs: %d "
      "succeeded, %d canceled as asked (%zu asked), %d runs of which %d lost; %.0f s\n",
      kills, where.c_str(), ids.size(), succeeded, canceled, cancel_asked.size(), runs, lost_runs,
      seconds);
}

// True when this process may make mount namespaces and mount in them (root with unshare, as on
// the project's machines and CI); the fault-injection tests that need a small filesystem of
// their own skip otherwise.
bool CanMountPrivately() {
  return ::geteuid() == 0 &&
         std::system("/usr/bin/unshare -m --propagation private true >/dev/null 2>&1") == 0;
}

// Issue 12's fault injection: the disk fills while the worker writes a job's results. The
// worker runs in a mount namespace of its own where that job's output folder is a 64 KiB tmpfs,
// so the deliverables cannot be written. The job fails in the stage that met the full disk, with
// a message that says so; nothing of it is packaged; its photos stay; the worker lives on and
// the next job (on the roomy disk) succeeds; restarted once there is room, the failed job
// succeeds too.
TEST_F(WorkerProcessTest, DiskFullWhileWritingResultsFailsTheJobCleanly) {
  if (!CanMountPrivately()) GTEST_SKIP() << "needs root and unshare -m (util-linux)";
  const std::string full = CreateJob(kSmall);
  const std::string next = CreateJob(kSmall);
  fs::create_directories(layout_.OutputDir(full));
  const std::string mount = "mount -t tmpfs -o size=64k reconduit-full '" +
                            layout_.OutputDir(full).string() + "' && exec \"$@\"";
  {
    WorkerProcess worker(
        layout_.root(), "w-full", {"--poll", "0.1", "--lease", "5"}, {},
        {"/usr/bin/unshare", "-m", "--propagation", "private", "/bin/sh", "-c", mount, "sh"});
    ASSERT_TRUE(WaitForState(full, JobState::kFailed, 90s)) << Describe(full) << worker.Log();
    ASSERT_TRUE(WaitForState(next, JobState::kSucceeded, 90s)) << Describe(next) << worker.Log();
    EXPECT_FALSE(worker.Wait(0ms).has_value()) << "the worker must live on\n" << worker.Log();
  }
  const Job failed = Get(full);
  std::printf("disk full while writing results: failed in stage '%s': %s\n",
              failed.error_stage.c_str(), failed.error.c_str());
  EXPECT_FALSE(failed.error_stage.empty());
  EXPECT_THAT(failed.error,
              HasSubstr("out of disk space: cannot write '" + layout_.OutputDir(full).string()));
  EXPECT_THAT(failed.error, HasSubstr("then restart the job"));
  EXPECT_FALSE(fs::exists(layout_.ResultZip(full)));
  for (int i = 0; i < kSmall.count; ++i) {
    char stored[16];
    std::snprintf(stored, sizeof(stored), "%04d.jpg", i + 1);
    EXPECT_TRUE(fs::exists(layout_.InputDir(full) / stored)) << stored;
  }
  ExpectResultVerifies(next, Get(next));

  // With room again, the restarted job runs to the end. What its stages wrote to the small
  // filesystem went with the worker's namespace (a real disk keeps it, and the restart resumes
  // after the finished stages): here the job starts over.
  fs::remove_all(layout_.WorkDir(full));
  fs::remove_all(layout_.OutputDir(full));
  ASSERT_TRUE(store_->RestartJob(full).ok());
  WorkerProcess worker(layout_.root(), "w-room", {"--poll", "0.1", "--lease", "5", "--once"});
  ASSERT_TRUE(WaitForState(full, JobState::kSucceeded, 90s)) << Describe(full) << worker.Log();
  ExpectResultVerifies(full, Get(full));
}

// A job over --memory-budget fails in the stage that went over it, saying so; the worker lives
// on and runs the next job, which fits.
TEST_F(WorkerProcessTest, JobOverTheMemoryBudgetFailsAndTheWorkerTakesTheNext) {
  // Features at full size: one SIFT pass over 1280 x 960 holds about 300 MiB.
  const std::string big = CreateJob(kLarge, {{"num_threads", 1}, {"max_features", 2048}});
  // Features on 320 px copies: a few MiB.
  const std::string small =
      CreateJob(kSmall, {{"num_threads", 1}, {"max_features", 512}, {"max_image_side", 320}});
  WorkerProcess worker(
      layout_.root(), "w-budget",
      {"--poll", "0.1", "--lease", "5", "--until", "features", "--memory-budget", "200"});
  ASSERT_TRUE(WaitForState(big, JobState::kFailed, 60s)) << Describe(big) << worker.Log();
  const Job failed = Get(big);
  EXPECT_EQ(failed.error_stage, "features");
  EXPECT_THAT(failed.error, HasSubstr("stage features needed more memory than this worker allows"));
  EXPECT_THAT(failed.error, HasSubstr("over the budget of 200 MiB"));
  EXPECT_TRUE(WaitForState(small, JobState::kSucceeded, 60s)) << Describe(small) << worker.Log();
  EXPECT_FALSE(worker.Wait(0ms).has_value()) << "the worker must live on\n" << worker.Log();
  EXPECT_THAT(worker.Log(), HasSubstr("memory budget 200 MiB"));
}

TEST_F(WorkerProcessTest, ConfigFileSettingsUnderTheEnvironmentAndFlags) {
  const fs::path config = dir_.path() / "worker.conf";
  std::ofstream(config) << "# reconduit-worker settings\n"
                        << "id = from-file\n"
                        << "lease = 2.5\n"
                        << "poll = 0.1   # seconds\n"
                        << "until = ingest\n"
                        << "once = true\n";
  // The file alone (no --id): its id, lease, --until and --once apply to a real job.
  const std::string id = CreateJob(kSmall);
  {
    WorkerProcess worker(layout_.root(), "", {"--config", config.string()});
    const std::optional<int> status = worker.Wait(30s);
    ASSERT_TRUE(status.has_value()) << "once = true must make it exit\n" << worker.Log();
    EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) == 0) << worker.Log();
    EXPECT_THAT(worker.Log(), HasSubstr("reconduit-worker from-file: data folder"));
    EXPECT_THAT(worker.Log(), HasSubstr("lease 2.5 s, stages up to ingest"));
    const Job job = Get(id);
    EXPECT_EQ(job.state, JobState::kSucceeded) << Describe(id);
    EXPECT_THAT(job.finished_stages, ElementsAre("ingest"));
    EXPECT_EQ(Count(Events(id), "started by worker 'from-file'"), 1);
  }
  // RECONDUIT_CONFIG names the file; the environment wins over it and a flag over both.
  {
    WorkerProcess worker(layout_.root(), "flag-id", {"--lease", "4"},
                         {"RECONDUIT_CONFIG=" + config.string(), "RECONDUIT_LEASE_SECONDS=3",
                          "RECONDUIT_UNTIL_STAGE=features"});
    const std::optional<int> status = worker.Wait(10s);
    ASSERT_TRUE(status.has_value()) << worker.Log();
    EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) == 0) << worker.Log();
    EXPECT_THAT(worker.Log(), HasSubstr("reconduit-worker flag-id: data folder"));
    EXPECT_THAT(worker.Log(), HasSubstr("lease 4 s, stages up to features"));
  }
}

// A file shared with reconduit-server: the top-level names and [worker] apply, [server] is
// skipped (its port and web would be unknown names here).
TEST_F(WorkerProcessTest, ConfigFileWithSectionsReadsTopLevelAndWorkerSection) {
  const fs::path config = dir_.path() / "reconduit.conf";
  std::ofstream(config) << "data = " << layout_.root().string() << "\n"
                        << "[server]\n"
                        << "port = 8080\n"
                        << "web = /nowhere\n"
                        << "threads = 64\n"
                        << "[worker]\n"
                        << "id = from-section\n"
                        << "lease = 2.5\n"
                        << "poll = 0.1\n"
                        << "until = ingest\n"
                        << "once = true\n";
  const std::string id = CreateJob(kSmall);
  WorkerProcess worker(layout_.root(), "", {}, {"RECONDUIT_CONFIG=" + config.string()});
  const std::optional<int> status = worker.Wait(30s);
  ASSERT_TRUE(status.has_value()) << "once = true must make it exit\n" << worker.Log();
  EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) == 0) << worker.Log();
  EXPECT_THAT(worker.Log(), HasSubstr("reconduit-worker from-section: data folder"));
  EXPECT_THAT(worker.Log(), HasSubstr("lease 2.5 s, stages up to ingest"));
  EXPECT_EQ(Get(id).state, JobState::kSucceeded) << Describe(id);
}

TEST_F(WorkerProcessTest, BadConfigFileExitsWithStatus2NamingFileAndKey) {
  struct Case {
    std::string text;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {"lease = 5\ncolour = blue\n", "unrecognised option 'colour'"},
      {"lease = soon\n", "invalid value 'soon' for 'lease'"},
      {"until = everything\n", "invalid value 'everything' for 'until'"},
      {"once = perhaps\n", "invalid value 'perhaps' for 'once'"},
      {"poll = 1\npoll = 2\n", "'poll' cannot be specified more than once"},
      // [worker] is read, other known sections are skipped; typos are still errors.
      {"[worker]\nlease = 5\ncolour = blue\n", "unrecognised option 'worker.colour'"},
      {"[wroker]\nlease = 5\n", "unknown section [wroker]"},
      {"lease = 5\n[worker]\nlease = 6\n", "'lease' cannot be specified more than once"},
      {"[worker]\nlease = 0.1\n", "invalid value '0.1' for 'worker.lease'"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(cases[i].text);
    const fs::path config = dir_.path() / ("bad" + std::to_string(i) + ".conf");
    std::ofstream(config) << cases[i].text;
    WorkerProcess worker(layout_.root(), "bad" + std::to_string(i),
                         {"--config", config.string(), "--once"});
    const std::optional<int> status = worker.Wait(10s);
    ASSERT_TRUE(status.has_value()) << worker.Log();
    EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) == 2) << worker.Log();
    EXPECT_THAT(worker.Log(), HasSubstr("config file '" + config.string() + "'"));
    EXPECT_THAT(worker.Log(), HasSubstr(cases[i].expected));
  }
  const fs::path missing = dir_.path() / "missing.conf";
  WorkerProcess worker(layout_.root(), "missing", {"--once"},
                       {"RECONDUIT_CONFIG=" + missing.string()});
  const std::optional<int> status = worker.Wait(10s);
  ASSERT_TRUE(status.has_value()) << worker.Log();
  EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) == 2) << worker.Log();
  EXPECT_THAT(worker.Log(), HasSubstr("cannot read the config file '" + missing.string() + "'"));
}

}  // namespace
}  // namespace reconduit
