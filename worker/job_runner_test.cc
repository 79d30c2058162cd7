#include "worker/job_runner.h"

#include "core/io/file_util.h"
#include "core/util/timer.h"
#include "worker/worker_test_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "store/data_layout.h"
#include "store/job_store.h"
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

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
using ::testing::AllOf;
using ::testing::Contains;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;
using testing_util::MakeRealStagesThenThrow;
using testing_util::MakeToyPipeline;
using testing_util::TempDir;
using testing_util::ToyBehaviour;
using testing_util::ToyPipeline;

constexpr int kPhotos = 6;

// Rendered once per test binary, copied into each job (rendering is the slow part).
const fs::path& RenderedPhotos() {
  static TempDir dir;
  static const bool rendered = [] {
    testing_util::WriteBoxRoomPhotos(dir.path(), kPhotos, 640, 480);
    return true;
  }();
  THROW_CHECK(rendered);
  return dir.path();
}

class JobRunnerTest : public ::testing::Test {
 protected:
  JobRunnerTest() : layout_(dir_.path()), store_(OpenOrDie(layout_.DatabasePath().string())) {}

  // A queued job whose photos are the rendered room, uploaded as IMG_000N.JPG.
  std::string CreateJob(nlohmann::json options = nlohmann::json::object()) {
    NewJob job;
    job.id = NewJobId();
    job.options = std::move(options);
    fs::create_directories(layout_.InputDir(job.id));
    for (int i = 0; i < kPhotos; ++i) {
      char stored[16];
      std::snprintf(stored, sizeof(stored), "%04d.jpg", i + 1);
      fs::copy_file(RenderedPhotos() / stored, layout_.InputDir(job.id) / stored);
      JobImageRecord image;
      image.index = i;
      image.original_name = "IMG_000" + std::to_string(i + 1) + ".JPG";
      image.stored_name = stored;
      image.photo.bytes =
          static_cast<std::int64_t>(fs::file_size(layout_.InputDir(job.id) / stored));
      job.images.push_back(image);
    }
    // A rejected photo must not reach the pipeline.
    JobImageRecord rejected;
    rejected.index = kPhotos;
    rejected.original_name = "broken.jpg";
    rejected.stored_name = "9999.jpg";
    rejected.photo.accepted = false;
    rejected.photo.reason = "truncated JPEG";
    job.images.push_back(rejected);
    Result<Job> created = store_->CreateJob(job);
    THROW_CHECK(created.ok()) << created.status();
    return job.id;
  }

  Job Claim(const std::string& expected_id, const std::string& worker = "test-worker") {
    Result<std::optional<Job>> job = store_->ClaimNextJob(worker, 30s);
    THROW_CHECK(job.ok()) << job.status();
    THROW_CHECK(job->has_value()) << "queue unexpectedly empty";
    THROW_CHECK_EQ((*job)->id, expected_id);
    return **job;
  }

  Job Get(const std::string& id) {
    Result<Job> job = store_->GetJob(id);
    THROW_CHECK(job.ok()) << job.status();
    return std::move(job).value();
  }

  std::vector<std::string> EventMessages(const std::string& id) {
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

  // Runs the job `id` (claimed here) with `options`; expects it failed in `stage`.
  Job RunToFailure(const std::string& id,
                   const JobRunnerOptions& options,
                   const std::string& stage) {
    JobRunner runner(*store_, options);
    const JobRunReport report = runner.Run(Claim(id));
    EXPECT_EQ(report.outcome, JobRunOutcome::kFailed) << report.message;
    Job job = Get(id);
    EXPECT_EQ(job.state, JobState::kFailed);
    EXPECT_EQ(job.error_stage, stage);
    return job;
  }

  JobRunnerOptions Options(StageListFactory stages = {}) {
    JobRunnerOptions options;
    options.data_dir = layout_.root();
    options.worker_id = "test-worker";
    options.lease = 30s;
    options.cancel_check_interval = 50ms;
    options.sink.progress_interval = 100ms;
    options.default_num_threads = 2;
    options.make_stages = std::move(stages);
    return options;
  }

  TempDir dir_;
  DataLayout layout_;
  std::unique_ptr<JobStore> store_;
};

TEST_F(JobRunnerTest, RealStagesSucceedWithResultArchive) {
  const std::string id = CreateJob({{"keep_work_files", true}});  // Read below.
  // The real stages up to matching, then packaging. (The stages after matching are still being
  // written and do not yet reconstruct these renders; the worker runs whatever it is given.)
  JobRunner runner(*store_, Options(StagesUntil("matching")));
  const JobRunReport report = runner.Run(Claim(id));
  ASSERT_EQ(report.outcome, JobRunOutcome::kSucceeded) << report.stage << ": " << report.message;
  EXPECT_THAT(report.resumed_stages, IsEmpty());
  EXPECT_THAT(report.run_stages,
              ElementsAre("ingest", "features", "pairs", "matching", "export", "package"));

  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kSucceeded);
  EXPECT_DOUBLE_EQ(job.progress, 1.0);
  // Export and packaging are not resumable and are not listed: a rerun writes and packs again.
  EXPECT_EQ(job.finished_stages,
            std::vector<std::string>(report.run_stages.begin(), report.run_stages.end() - 2));
  EXPECT_EQ(job.counts.images.value_or(-1), kPhotos) << job.counts.ToJson().dump();
  EXPECT_GT(job.counts.features.value_or(0), 100) << job.counts.ToJson().dump();
  EXPECT_GT(job.counts.matched_pairs.value_or(0), 0) << job.counts.ToJson().dump();
  for (const std::string& stage : report.run_stages) {
    ASSERT_TRUE(job.stage_progress.contains(stage)) << job.stage_progress.dump();
    EXPECT_DOUBLE_EQ(job.stage_progress[stage].value("progress", 0.0), 1.0) << stage;
    EXPECT_TRUE(job.stage_progress[stage].contains("seconds")) << stage;
  }
  EXPECT_GT(job.stage_progress["features"].value("peak_memory_bytes", 0), 0);
  // The stage's own peak, never above the process's.
  const std::int64_t stage_peak =
      job.stage_progress["features"].value("stage_peak_memory_bytes", std::int64_t{0});
  EXPECT_GT(stage_peak, 0);
  EXPECT_LE(stage_peak, job.stage_progress["features"].value("peak_memory_bytes", std::int64_t{0}));
  EXPECT_TRUE(job.stage_progress["features"].contains("stage_peak_memory_own"));

  // result.zip: the size and hash in the job are the file's; the manifest lists report.json.
  const fs::path zip = layout_.ResultZip(id);
  ASSERT_TRUE(fs::exists(zip));
  ASSERT_TRUE(job.result_bytes.has_value());
  EXPECT_EQ(*job.result_bytes, static_cast<std::int64_t>(fs::file_size(zip)));
  EXPECT_EQ(job.result_sha256, *Sha256OfFile(zip));
  const auto entries = testing_util::ReadZipEntries(zip);
  ASSERT_TRUE(entries.count("manifest.json"));
  ASSERT_TRUE(entries.count("report.json"));
  const nlohmann::json manifest = nlohmann::json::parse(entries.at("manifest.json"));
  std::vector<std::string> listed;
  for (const auto& file : manifest["files"]) listed.push_back(file["name"]);
  EXPECT_THAT(listed, Contains("report.json")) << manifest.dump();
  const nlohmann::json report_json = nlohmann::json::parse(entries.at("report.json"));
  EXPECT_EQ(report_json["image_count"], kPhotos) << "the rejected photo is not given to the run";

  // The pipeline saw the uploaded names, never the stored ones or the rejected photo.
  const nlohmann::json ingested =
      nlohmann::json::parse(*ReadFile(layout_.WorkDir(id) / "ingest" / "images.json"));
  ASSERT_EQ(ingested["images"].size(), static_cast<std::size_t>(kPhotos));
  EXPECT_EQ(ingested["images"][0]["name"], "IMG_0001.JPG");

  const std::vector<std::string> events = EventMessages(id);
  EXPECT_THAT(events, Contains("features|stage 'features' started: Finding features"))
      << ::testing::PrintToString(events);
  EXPECT_THAT(events, Contains(AllOf(HasSubstr("features|stage 'features' success after"),
                                     HasSubstr("\"features\":"))));
  EXPECT_THAT(events, Contains("|succeeded"));
}

// Issue 12's fault injection: a photo deleted under a running job (after ingest checked it).
// The job fails in the stage that needed it, naming the photo as uploaded; other jobs go on.
TEST_F(JobRunnerTest, PhotoVanishedUnderARunningJobFailsItNamingThePhoto) {
  const std::string id = CreateJob();
  JobRunnerOptions options = Options(StagesUntil("features"));
  options.on_moment = [&](const std::string& moment) {
    if (moment == "stage-done:ingest") fs::remove(layout_.InputDir(id) / "0002.jpg");
  };
  const Job job = RunToFailure(id, options, "features");
  EXPECT_THAT(job.error, HasSubstr("IMG_0002.JPG"));
  EXPECT_THAT(job.error, Not(HasSubstr("Check failed"))) << "a message for users";
  std::printf("the vanished photo's message: %s\n", job.error.c_str());

  const std::string next = CreateJob();
  JobRunner next_runner(*store_, Options(StagesUntil("features")));
  EXPECT_EQ(next_runner.Run(Claim(next)).outcome, JobRunOutcome::kSucceeded);
}

TEST_F(JobRunnerTest, InvalidOptionsFailNamingTheField) {
  const std::string id = CreateJob({{"max_features", 3}});
  JobRunner runner(*store_, Options());
  const JobRunReport report = runner.Run(Claim(id));
  EXPECT_EQ(report.outcome, JobRunOutcome::kFailed);
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kFailed);
  EXPECT_THAT(job.error, HasSubstr("max_features"));
  EXPECT_FALSE(fs::exists(layout_.WorkDir(id) / "ingest")) << "no stage may run";

  const std::string unknown = CreateJob({{"quality", "fast"}});
  EXPECT_EQ(runner.Run(Claim(unknown)).outcome, JobRunOutcome::kFailed);
  EXPECT_THAT(Get(unknown).error, HasSubstr("quality"));
}

// A job may ask for fewer threads than the worker's --threads, never more (issue 12: a client
// asked for 256).
TEST_F(JobRunnerTest, JobThreadsAreCappedByTheWorker) {
  const std::map<int, int> expected = {{256, 2}, {3, 2}, {1, 1}, {0, 2}};
  for (const auto& [requested, granted] : expected) {
    const std::string id = CreateJob({{"num_threads", requested}});
    ToyPipeline toy;
    JobRunner runner(*store_, Options(MakeToyPipeline(toy)));  // default_num_threads = 2
    ASSERT_EQ(runner.Run(Claim(id)).outcome, JobRunOutcome::kSucceeded);
    EXPECT_EQ(toy.runs->num_threads, granted) << "asked for " << requested;
  }
  const std::string unset = CreateJob();
  ToyPipeline toy;
  JobRunner runner(*store_, Options(MakeToyPipeline(toy)));
  ASSERT_EQ(runner.Run(Claim(unset)).outcome, JobRunOutcome::kSucceeded);
  EXPECT_EQ(toy.runs->num_threads, 2);
}

TEST(JobThreads, AllCoresWhenTheWorkerSetsNoLimit) {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  EXPECT_EQ(JobThreads(256, 0), cores);
  EXPECT_EQ(JobThreads(0, 0), cores);
  EXPECT_EQ(JobThreads(1, 0), 1);
  EXPECT_EQ(JobThreads(8, 4), 4);
}

TEST_F(JobRunnerTest, CancelRequestedMidRunEndsCanceled) {
  const std::string id = CreateJob();
  ToyPipeline toy;
  toy.behaviour = ToyBehaviour::kWaitForCancel;
  toy.on_run = [&] { ASSERT_EQ(*store_->RequestCancel(id), JobState::kRunning); };
  JobRunner runner(*store_, Options(MakeToyPipeline(toy)));
  const auto start = std::chrono::steady_clock::now();
  const JobRunReport report = runner.Run(Claim(id));
  EXPECT_EQ(report.outcome, JobRunOutcome::kCanceled) << report.message;
  EXPECT_LT(std::chrono::steady_clock::now() - start, 10s) << "the probe must see the cancel";
  EXPECT_EQ(toy.runs->middle, 1);
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kCanceled);
  EXPECT_THAT(job.finished_stages, ElementsAre("ingest"));
  EXPECT_FALSE(fs::exists(layout_.ResultZip(id)));
}

TEST_F(JobRunnerTest, ThrowingStageFailsTheJobNotTheWorker) {
  const std::string id = CreateJob();
  ToyPipeline toy;
  toy.behaviour = ToyBehaviour::kThrow;
  JobRunner runner(*store_, Options(MakeToyPipeline(toy)));
  const JobRunReport report = runner.Run(Claim(id));
  EXPECT_EQ(report.outcome, JobRunOutcome::kFailed);
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kFailed);
  EXPECT_EQ(job.error_stage, "toy");
  EXPECT_THAT(job.error, HasSubstr("toy stage exploded"));

  // The same runner goes on to the next job.
  const std::string next = CreateJob();
  ToyPipeline good;
  JobRunner next_runner(*store_, Options(MakeToyPipeline(good)));
  EXPECT_EQ(next_runner.Run(Claim(next)).outcome, JobRunOutcome::kSucceeded);
  EXPECT_EQ(Get(next).state, JobState::kSucceeded);
}

// A job over the worker's memory budget fails naming the stage and the figures; the worker
// goes on to the next job, which fits.
TEST_F(JobRunnerTest, JobOverTheMemoryBudgetFailsAndTheNextJobRuns) {
  const std::int64_t baseline = CurrentMemoryBytes();
  ASSERT_GT(baseline, 0) << "no /proc/self/statm";
  const std::string id = CreateJob();
  ToyPipeline hog;
  hog.behaviour = ToyBehaviour::kHogMemory;
  hog.hog_mib = 2048;
  // Room for ASan's quarantine of freed blocks (256 MiB) when the next job runs.
  const std::int64_t allowance = std::int64_t{512} << 20;
  JobRunnerOptions options = Options(MakeToyPipeline(hog));
  options.memory_budget_bytes = baseline + allowance;
  options.memory_check_interval = 20ms;
  const Job job = RunToFailure(id, options, "toy");
  EXPECT_THAT(job.error, HasSubstr("stage toy needed more memory than this worker allows"));
  EXPECT_THAT(job.error, HasSubstr("--memory-budget"));
  EXPECT_LT(CurrentMemoryBytes(), baseline + allowance) << "the stage's memory must be freed";

  // The next job holds less than the budget and succeeds with the same budget.
  const std::string next = CreateJob();
  ToyPipeline small;
  small.behaviour = ToyBehaviour::kHogMemory;
  small.hog_mib = 64;
  JobRunnerOptions next_options = Options(MakeToyPipeline(small));
  next_options.memory_budget_bytes = options.memory_budget_bytes;
  next_options.memory_check_interval = 20ms;
  JobRunner next_runner(*store_, next_options);
  EXPECT_EQ(next_runner.Run(Claim(next)).outcome, JobRunOutcome::kSucceeded);
  EXPECT_EQ(Get(next).state, JobState::kSucceeded);
}

TEST_F(JobRunnerTest, WorkFilesAreRemovedAfterSuccessOnly) {
  const std::string id = CreateJob();
  {
    JobRunner runner(*store_, Options(MakeRealStagesThenThrow("ingest")));
    ASSERT_EQ(runner.Run(Claim(id)).outcome, JobRunOutcome::kFailed);
  }
  EXPECT_TRUE(fs::exists(layout_.WorkDir(id) / "ingest" / "stage.json")) << "kept to resume";
  ASSERT_TRUE(store_->RestartJob(id).ok());
  JobRunner runner(*store_, Options(StagesUntil("features")));
  const JobRunReport report = runner.Run(Claim(id));
  ASSERT_EQ(report.outcome, JobRunOutcome::kSucceeded) << report.stage << ": " << report.message;
  EXPECT_THAT(report.resumed_stages, ElementsAre("ingest"));
  EXPECT_FALSE(fs::exists(layout_.WorkDir(id)));
  EXPECT_TRUE(fs::exists(layout_.ResultZip(id)));
  EXPECT_TRUE(fs::exists(layout_.OutputDir(id) / "report.json"));
}

TEST_F(JobRunnerTest, ResumeSkipsStagesFinishedEarlier) {
  const std::string id = CreateJob({{"keep_work_files", true}});  // Its markers are read below.
  {
    // First run: the real ingest and features, then a stage that throws.
    JobRunner runner(*store_, Options(MakeRealStagesThenThrow("features")));
    const JobRunReport report = runner.Run(Claim(id));
    ASSERT_EQ(report.outcome, JobRunOutcome::kFailed);
    EXPECT_EQ(report.stage, "boom");
  }
  EXPECT_THAT(Get(id).finished_stages, ElementsAre("ingest", "features"));
  const std::string features_marker = *ReadFile(layout_.WorkDir(id) / "features" / "stage.json");
  const auto features_time = fs::last_write_time(layout_.WorkDir(id) / "features" / "stage.json");

  ASSERT_TRUE(store_->RestartJob(id).ok());
  JobRunner runner(*store_, Options(StagesUntil("matching")));
  const JobRunReport report = runner.Run(Claim(id));
  ASSERT_EQ(report.outcome, JobRunOutcome::kSucceeded) << report.stage << ": " << report.message;
  EXPECT_THAT(report.resumed_stages, ElementsAre("ingest", "features"));
  EXPECT_THAT(report.run_stages, ElementsAre("pairs", "matching", "export", "package"));
  EXPECT_EQ(*ReadFile(layout_.WorkDir(id) / "features" / "stage.json"), features_marker);
  EXPECT_EQ(fs::last_write_time(layout_.WorkDir(id) / "features" / "stage.json"), features_time);
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kSucceeded);
  EXPECT_THAT(job.finished_stages, ElementsAre("ingest", "features", "pairs", "matching"));
  EXPECT_EQ(job.counts.images.value_or(-1), kPhotos) << "counts of resumed stages are kept";

  const std::vector<std::string> events = EventMessages(id);
  EXPECT_THAT(events, Contains(HasSubstr("ingest|stage 'ingest' finished in an earlier run")));
  EXPECT_THAT(events, Contains(HasSubstr("features|stage 'features' finished in an earlier run")));
  // The stage start of features appears once: in the first run only.
  EXPECT_EQ(std::count(events.begin(), events.end(),
                       "features|stage 'features' started: Finding features"),
            1);
}

TEST_F(JobRunnerTest, StoreCatchesUpWithStagesFinishedOnDisk) {
  // A worker that died between writing ingest's stage.json and MarkStageFinished: the marker is
  // on disk, the store does not list the stage. Simulated by copying another job's work folder.
  const std::string donor = CreateJob();
  ToyPipeline failing;
  failing.behaviour = ToyBehaviour::kThrow;
  ASSERT_EQ(JobRunner(*store_, Options(MakeToyPipeline(failing))).Run(Claim(donor)).outcome,
            JobRunOutcome::kFailed);

  const std::string id = CreateJob();
  fs::create_directories(layout_.WorkDir(id));
  fs::copy(layout_.WorkDir(donor) / "ingest", layout_.WorkDir(id) / "ingest");
  ASSERT_THAT(Get(id).finished_stages, IsEmpty());
  ToyPipeline toy;
  const JobRunReport report = JobRunner(*store_, Options(MakeToyPipeline(toy))).Run(Claim(id));
  ASSERT_EQ(report.outcome, JobRunOutcome::kSucceeded) << report.message;
  EXPECT_THAT(report.resumed_stages, ElementsAre("ingest"));
  EXPECT_EQ(toy.runs->ingest, 0);
  EXPECT_THAT(Get(id).finished_stages, ElementsAre("ingest", "toy"));
}

TEST_F(JobRunnerTest, HalfWrittenFilesOfAKilledRunAreNotDelivered) {
  // A worker killed inside an atomic write of a deliverable leaves "<file>.tmp-<pid>-<random>"
  // in output/; packaging packs every file there, so the next run must remove it first.
  const std::string id = CreateJob();
  const fs::path output = layout_.OutputDir(id);
  fs::create_directories(output / "sparse");
  std::ofstream(output / "sparse.ply.tmp-4242-17") << "ply";
  std::ofstream(output / "sparse" / "images.txt.tmp-1-2") << "# half";
  std::ofstream(output / "notes.tmp-draft.txt") << "not a temporary file";
  ToyPipeline toy;
  const JobRunReport report = JobRunner(*store_, Options(MakeToyPipeline(toy))).Run(Claim(id));
  ASSERT_EQ(report.outcome, JobRunOutcome::kSucceeded) << report.message;
  EXPECT_FALSE(fs::exists(output / "sparse.ply.tmp-4242-17"));
  EXPECT_FALSE(fs::exists(output / "sparse" / "images.txt.tmp-1-2"));
  const std::map<std::string, std::string> entries =
      testing_util::ReadZipEntries(layout_.ResultZip(id));
  EXPECT_EQ(entries.count("sparse.ply.tmp-4242-17"), 0u);
  EXPECT_EQ(entries.count("sparse/images.txt.tmp-1-2"), 0u);
  EXPECT_EQ(entries.count("notes.tmp-draft.txt"), 1u);
  EXPECT_THAT(EventMessages(id),
              Contains(HasSubstr("removed 2 half-written file(s) of an interrupted run")));
}

TEST_F(JobRunnerTest, StageListedInStoreButMissingOnDiskRunsAgain) {
  const std::string id = CreateJob();
  ToyPipeline failing;
  failing.behaviour = ToyBehaviour::kThrow;
  ASSERT_EQ(JobRunner(*store_, Options(MakeToyPipeline(failing))).Run(Claim(id)).outcome,
            JobRunOutcome::kFailed);
  ASSERT_THAT(Get(id).finished_stages, ElementsAre("ingest"));
  fs::remove(layout_.WorkDir(id) / "ingest" / "stage.json");

  ASSERT_TRUE(store_->RestartJob(id).ok());
  ToyPipeline toy;
  const JobRunReport report = JobRunner(*store_, Options(MakeToyPipeline(toy))).Run(Claim(id));
  ASSERT_EQ(report.outcome, JobRunOutcome::kSucceeded) << report.message;
  EXPECT_EQ(toy.runs->ingest, 1);
  EXPECT_THAT(report.run_stages, ElementsAre("ingest", "toy", "package"));
  EXPECT_THAT(EventMessages(id), Contains(HasSubstr("was recorded as finished but its output")));
  EXPECT_THAT(Get(id).finished_stages, ElementsAre("ingest", "toy"));
}

TEST_F(JobRunnerTest, ChattyStageCannotFloodTheEvents) {
  const std::string id = CreateJob();
  ToyPipeline toy;
  toy.behaviour = ToyBehaviour::kLogFlood;
  toy.flood_lines = 5000;
  JobRunnerOptions options = Options(MakeToyPipeline(toy));
  options.sink.event_burst = 20;
  options.sink.events_per_second = 5;
  const JobRunReport report = JobRunner(*store_, options).Run(Claim(id));
  ASSERT_EQ(report.outcome, JobRunOutcome::kSucceeded) << report.message;
  const std::vector<std::string> events = EventMessages(id);
  const auto toy_lines = std::count_if(events.begin(), events.end(), [](const std::string& e) {
    return e.find("toy|toy line ") == 0;
  });
  EXPECT_GE(toy_lines, 1);
  EXPECT_LE(toy_lines, 40) << "burst 20 plus 5 per second";
  EXPECT_THAT(events, Contains(HasSubstr("log lines not recorded")));
}

TEST_F(JobRunnerTest, HeartbeatThreadKeepsTheLeaseThroughASilentStage) {
  const std::string id = CreateJob();
  ToyPipeline toy;
  toy.behaviour = ToyBehaviour::kSleep;
  toy.sleep_ms = 2500;
  std::optional<SweepResult> swept;
  std::thread sweeper;
  toy.on_run = [&] {
    sweeper = std::thread([&] {
      // Well past the 600 ms lease: without heartbeats the sweep would requeue the job.
      std::this_thread::sleep_for(1500ms);
      Result<SweepResult> result = store_->SweepExpiredLeases();
      if (result.ok()) swept = *result;
    });
  };
  JobRunnerOptions options = Options(MakeToyPipeline(toy));
  options.lease = 600ms;
  Result<std::optional<Job>> claimed = store_->ClaimNextJob("test-worker", options.lease);
  ASSERT_TRUE(claimed.ok() && claimed->has_value());
  const JobRunReport report = JobRunner(*store_, options).Run(**claimed);
  sweeper.join();
  ASSERT_TRUE(swept.has_value());
  EXPECT_EQ(swept->requeued, 0);
  EXPECT_EQ(report.outcome, JobRunOutcome::kSucceeded) << report.message;
  EXPECT_EQ(Get(id).state, JobState::kSucceeded);
}

TEST_F(JobRunnerTest, RequestStopReleasesTheJobToTheQueue) {
  const std::string id = CreateJob();
  ToyPipeline toy;
  toy.behaviour = ToyBehaviour::kWaitForCancel;
  JobRunner* runner_ptr = nullptr;
  toy.on_run = [&] { runner_ptr->RequestStop(); };
  JobRunner runner(*store_, Options(MakeToyPipeline(toy)));
  runner_ptr = &runner;
  const JobRunReport report = runner.Run(Claim(id));
  EXPECT_EQ(report.outcome, JobRunOutcome::kReleased) << report.message;
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kQueued);
  EXPECT_EQ(job.attempts, 0) << "a clean release does not spend an attempt";
  EXPECT_THAT(job.finished_stages, ElementsAre("ingest"));
  EXPECT_TRUE(runner.running_job_id().empty());
}

TEST_F(JobRunnerTest, LostLeaseLeavesTheJobAlone) {
  const std::string id = CreateJob();
  ToyPipeline toy;
  toy.behaviour = ToyBehaviour::kWaitForCancel;
  // Someone else takes the job: released and claimed by another worker.
  toy.on_run = [&] {
    ASSERT_TRUE(store_->ReleaseJob(id, "test-worker").ok());
    ASSERT_TRUE(store_->ClaimNextJob("other-worker", 30s).ok());
  };
  const JobRunReport report = JobRunner(*store_, Options(MakeToyPipeline(toy))).Run(Claim(id));
  EXPECT_EQ(report.outcome, JobRunOutcome::kLeaseLost) << report.message;
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kRunning);
  EXPECT_EQ(job.lease_owner, "other-worker");
  EXPECT_THAT(EventMessages(id), Not(Contains("|canceled")));
}

TEST(PhotosFromRecords, AcceptedPhotosWithSafeUniqueNames) {
  std::vector<JobImageRecord> records(4);
  records[0] = {.index = 2, .original_name = "../x/a.jpg", .stored_name = "0003.jpg"};
  records[1] = {.index = 0, .original_name = "a.jpg", .stored_name = "0001.jpg"};
  records[2] = {.index = 1, .original_name = "", .stored_name = "0002.jpg"};
  records[3] = {.index = 3, .original_name = "b.jpg", .stored_name = "0004.jpg"};
  records[3].photo.accepted = false;
  const Result<std::vector<InputImage>> photos = PhotosFromRecords(records, "/in");
  ASSERT_TRUE(photos.ok()) << photos.status();
  ASSERT_EQ(photos->size(), 3u);
  EXPECT_EQ((*photos)[0].path, fs::path("/in/0001.jpg"));
  EXPECT_EQ((*photos)[0].name, "a.jpg");
  EXPECT_EQ((*photos)[1].name, "0002.jpg");
  EXPECT_EQ((*photos)[2].name, "a (2).jpg");

  records[1].stored_name = "../0001.jpg";
  EXPECT_FALSE(PhotosFromRecords(records, "/in").ok());
  records[1].stored_name = "0001.jpg";
  for (JobImageRecord& record : records) record.photo.accepted = false;
  EXPECT_FALSE(PhotosFromRecords(records, "/in").ok());
}

// A successful stage's record with `summary`.
StageRecord Finished(std::string name, nlohmann::json summary) {
  StageRecord record;
  record.name = std::move(name);
  record.status = StageStatus::kSuccess;
  record.summary = std::move(summary);
  return record;
}

TEST(CountsOfStage, MapsKnownFields) {
  EXPECT_EQ(
      CountsOfStage(Finished("ingest", {{"accepted", 5}, {"rejected", 1}, {"images", 6}})).ToJson(),
      (nlohmann::json{{"images", 5}, {"rejected_images", 1}}));
  EXPECT_EQ(CountsOfStage(Finished("sfm", {{"registered", 12}, {"points", 3400}})).ToJson(),
            (nlohmann::json{{"registered", 12}, {"points", 3400}}));
  EXPECT_TRUE(CountsOfStage(Finished("pairs", {{"method", "all"}})).empty());
}

TEST(CountsOfStage, FailedStagesCountNothingAndPackagingCountsItsFiles) {
  StageRecord failed = Finished("ingest", {{"accepted", 5}});
  failed.status = StageStatus::kFailed;
  EXPECT_TRUE(CountsOfStage(failed).empty());

  StageRecord package = Finished("package", {{"files", 99}});
  package.package = PackageResult{"/r.zip", {}};
  package.package->archive.files.resize(3);
  EXPECT_EQ(CountsOfStage(package).ToJson(), (nlohmann::json{{"result_files", 3}}));
}

}  // namespace
}  // namespace reconduit
