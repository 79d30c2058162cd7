#include "store/job_store.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "store/sqlite_util.h"
#include "store/store_test_util.h"
#include <set>

namespace reconduit {
namespace {

using namespace std::chrono_literals;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing_util::FakeClock;
using testing_util::MakeNewJob;
using testing_util::OpenOrDie;
using testing_util::TempDir;

constexpr auto kLease = 1000ms;
const std::string kSha(64, 'a');

class JobStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SqliteJobStoreOptions options;
    options.now_ms = clock_.AsFunction();
    store_ = OpenOrDie(path(), options);
  }

  std::string path() const { return dir_.File("jobs.db"); }

  // Creates a job and advances the clock by 1 ms so creation times are distinct.
  Job Create(NewJob job = MakeNewJob()) {
    Result<Job> created = store_->CreateJob(job);
    THROW_CHECK(created.ok()) << created.status();
    clock_.Advance(1);
    return std::move(created).value();
  }

  Job Get(const std::string& id) {
    Result<Job> job = store_->GetJob(id);
    THROW_CHECK(job.ok()) << job.status();
    return std::move(job).value();
  }

  // Claims a job that must exist.
  Job Claim(std::string_view worker) {
    Result<std::optional<Job>> job = store_->ClaimNextJob(worker, kLease);
    THROW_CHECK(job.ok()) << job.status();
    THROW_CHECK(job->has_value()) << "queue unexpectedly empty";
    return **job;
  }

  std::vector<JobEvent> Events(const std::string& id) {
    Result<std::vector<JobEvent>> events = store_->ListEvents(id, 0, 1000);
    THROW_CHECK(events.ok()) << events.status();
    return std::move(events).value();
  }

  TempDir dir_;
  FakeClock clock_;
  std::unique_ptr<JobStore> store_;
};

// ---- Names and ids ------------------------------------------------------------------------------

TEST(JobState, NamesRoundTrip) {
  for (int i = 0; i < kNumJobStates; ++i) {
    const auto state = static_cast<JobState>(i);
    EXPECT_EQ(ParseJobState(JobStateName(state)), state);
  }
  EXPECT_EQ(ParseJobState("done"), std::nullopt);
  EXPECT_TRUE(IsFinalState(JobState::kCanceled));
  EXPECT_FALSE(IsFinalState(JobState::kRunning));
}

TEST(JobCounts, JsonWithTheApiNamesAndMerge) {
  JobCounts counts;
  EXPECT_TRUE(counts.empty());
  EXPECT_EQ(counts.ToJson(), nlohmann::json::object());
  counts.images = 12;
  counts.registered = 10;
  EXPECT_FALSE(counts.empty());
  EXPECT_EQ(counts.ToJson(), (nlohmann::json{{"images", 12}, {"registered", 10}}));
  EXPECT_EQ(JobCounts::FromJson(counts.ToJson()), counts);

  JobCounts patch;
  patch.registered = 11;
  patch.result_files = 4;
  counts.Merge(patch);
  EXPECT_EQ(counts.ToJson(),
            (nlohmann::json{{"images", 12}, {"registered", 11}, {"result_files", 4}}));

  // Unknown names and values that are not integers are ignored.
  EXPECT_EQ(JobCounts::FromJson({{"points", 5}, {"colour", 3}, {"faces", "many"}}).ToJson(),
            (nlohmann::json{{"points", 5}}));
  EXPECT_TRUE(JobCounts::FromJson(nullptr).empty());
}

TEST(NewJobId, Is128RandomBitsInHex) {
  std::set<std::string> ids;
  for (int i = 0; i < 1000; ++i) {
    const std::string id = NewJobId();
    EXPECT_TRUE(IsValidJobId(id)) << id;
    ids.insert(id);
  }
  EXPECT_EQ(ids.size(), 1000u);
  EXPECT_FALSE(IsValidJobId("0123456789ABCDEF0123456789abcdef"));  // Upper case.
  EXPECT_FALSE(IsValidJobId("0123456789abcdef0123456789abcde"));   // 31 digits.
  EXPECT_FALSE(IsValidJobId("../../etc/passwd"));
}

// ---- Create, get, list --------------------------------------------------------------------------

TEST_F(JobStoreTest, CreateStoresTheJobAndItsPhotos) {
  NewJob new_job = MakeNewJob(3);
  new_job.images[1].photo.accepted = false;
  new_job.images[1].photo.reason = "truncated JPEG";
  new_job.images[1].photo.width = 0;
  new_job.images[1].photo.height = 0;
  new_job.images[2].photo.exif_focal_px = 1234.5;
  new_job.images[2].photo.make = "Canon";
  new_job.images[2].photo.model = "EOS 5D";
  const Job created = Create(new_job);

  EXPECT_TRUE(IsValidJobId(created.id));
  const Job job = Get(created.id);
  EXPECT_EQ(job.state, JobState::kQueued);
  EXPECT_EQ(job.options, new_job.options);
  EXPECT_EQ(job.image_count, 2);  // Accepted photos only.
  EXPECT_EQ(job.created_at_ms, clock_.Now() - 1);
  EXPECT_EQ(job.queued_at_ms, job.created_at_ms);
  EXPECT_EQ(job.started_at_ms, std::nullopt);
  EXPECT_EQ(job.attempts, 0);
  EXPECT_EQ(job.max_attempts, 3);
  EXPECT_TRUE(job.lease_owner.empty());
  EXPECT_TRUE(job.finished_stages.empty());
  EXPECT_TRUE(job.counts.empty());

  Result<std::vector<JobImageRecord>> images = store_->ListImages(job.id);
  ASSERT_TRUE(images.ok()) << images.status();
  EXPECT_EQ(*images, new_job.images);

  const std::vector<JobEvent> events = Events(job.id);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].message, "queued with 2 photos (1 rejected)");
}

TEST_F(JobStoreTest, CreateUsesTheCallersIdAndRefusesDuplicates) {
  NewJob new_job = MakeNewJob();
  new_job.id = NewJobId();
  EXPECT_EQ(Create(new_job).id, new_job.id);
  EXPECT_EQ(store_->CreateJob(new_job).status().code(), StatusCode::kAlreadyExists);
}

TEST_F(JobStoreTest, CreateIsAllOrNothing) {
  NewJob new_job = MakeNewJob(3);
  new_job.images[2].index = 0;  // Duplicate photo index: the third image insert fails.
  new_job.images[2].stored_name = "0002.jpg";
  const Result<Job> result = store_->CreateJob(new_job);
  EXPECT_EQ(result.status().code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr("UNIQUE constraint failed"));
  Result<JobPage> page = store_->ListJobs({});
  ASSERT_TRUE(page.ok());
  EXPECT_EQ(page->total, 0);  // Neither the job nor its first two photos are visible.
  Result<QueueStats> stats = store_->GetQueueStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->QueueLength(), 0);
}

TEST_F(JobStoreTest, CreateValidatesItsInput) {
  NewJob bad_id = MakeNewJob();
  bad_id.id = "../../x";
  EXPECT_EQ(store_->CreateJob(bad_id).status().code(), StatusCode::kInvalidArgument);

  NewJob no_accepted = MakeNewJob(1);
  no_accepted.images[0].photo.accepted = false;
  EXPECT_THAT(store_->CreateJob(no_accepted).status().message(),
              HasSubstr("at least one accepted photo"));
  EXPECT_EQ(store_->CreateJob(NewJob{}).status().code(), StatusCode::kInvalidArgument);

  for (const char* unsafe : {"../0001.jpg", "/etc/passwd", "a\\b.jpg", "..", ""}) {
    NewJob job = MakeNewJob(1);
    job.images[0].stored_name = unsafe;
    EXPECT_EQ(store_->CreateJob(job).status().code(), StatusCode::kInvalidArgument) << unsafe;
  }

  NewJob array_options = MakeNewJob();
  array_options.options = nlohmann::json::array({1, 2});
  EXPECT_EQ(store_->CreateJob(array_options).status().code(), StatusCode::kInvalidArgument);

  NewJob zero_attempts = MakeNewJob();
  zero_attempts.max_attempts = 0;
  EXPECT_EQ(store_->CreateJob(zero_attempts).status().code(), StatusCode::kInvalidArgument);

  Result<JobPage> page = store_->ListJobs({});
  ASSERT_TRUE(page.ok());
  EXPECT_EQ(page->total, 0);
}

TEST_F(JobStoreTest, CreateRefusesWhenTheQueueIsFull) {
  NewJob job = MakeNewJob();
  job.max_queued_jobs = 2;
  Create(job);
  Create(job);
  const Result<Job> third = store_->CreateJob(job);
  EXPECT_EQ(third.status().code(), StatusCode::kResourceExhausted);
  EXPECT_THAT(third.status().message(), HasSubstr("queue is full"));
  Claim("w");  // One leaves the queue: there is room again.
  EXPECT_TRUE(store_->CreateJob(job).ok());
}

TEST_F(JobStoreTest, GetUnknownOrMalformedIdIsNotFound) {
  EXPECT_EQ(store_->GetJob(NewJobId()).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store_->GetJob("nonsense").status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store_->GetJob("").status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store_->ListImages(NewJobId()).status().code(), StatusCode::kNotFound);
}

TEST_F(JobStoreTest, ListIsNewestFirstWithPagesAndTotal) {
  std::vector<std::string> ids;  // Oldest first.
  for (int i = 0; i < 7; ++i) ids.push_back(Create().id);

  Result<JobPage> first = store_->ListJobs({.limit = 3, .offset = 0});
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_EQ(first->total, 7);
  ASSERT_EQ(first->jobs.size(), 3u);
  EXPECT_EQ(first->jobs[0].id, ids[6]);
  EXPECT_EQ(first->jobs[1].id, ids[5]);
  EXPECT_EQ(first->jobs[2].id, ids[4]);

  Result<JobPage> last = store_->ListJobs({.limit = 3, .offset = 6});
  ASSERT_TRUE(last.ok());
  ASSERT_EQ(last->jobs.size(), 1u);
  EXPECT_EQ(last->jobs[0].id, ids[0]);

  Result<JobPage> beyond = store_->ListJobs({.limit = 3, .offset = 100});
  ASSERT_TRUE(beyond.ok());
  EXPECT_TRUE(beyond->jobs.empty());
  EXPECT_EQ(beyond->total, 7);

  ASSERT_TRUE(store_->RequestCancel(ids[2]).ok());
  Result<JobPage> canceled = store_->ListJobs({.limit = 10, .state = JobState::kCanceled});
  ASSERT_TRUE(canceled.ok());
  EXPECT_EQ(canceled->total, 1);
  ASSERT_EQ(canceled->jobs.size(), 1u);
  EXPECT_EQ(canceled->jobs[0].id, ids[2]);

  EXPECT_EQ(store_->ListJobs({.limit = 0}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->ListJobs({.limit = 5000}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->ListJobs({.offset = -1}).status().code(), StatusCode::kInvalidArgument);
}

TEST_F(JobStoreTest, ListOrdersJobsCreatedInTheSameMillisecondByInsertion) {
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) ids.push_back(store_->CreateJob(MakeNewJob()).value().id);
  Result<JobPage> page = store_->ListJobs({});
  ASSERT_TRUE(page.ok());
  ASSERT_EQ(page->jobs.size(), 3u);
  EXPECT_EQ(page->jobs[0].id, ids[2]);
  EXPECT_EQ(page->jobs[2].id, ids[0]);
}

// ---- Claim, heartbeat, leases -------------------------------------------------------------------

TEST_F(JobStoreTest, ClaimTakesTheOldestQueuedJobThenNothing) {
  const std::string a = Create().id;
  const std::string b = Create().id;
  const Job claimed = Claim("worker-1");
  EXPECT_EQ(claimed.id, a);
  EXPECT_EQ(claimed.state, JobState::kRunning);
  EXPECT_EQ(claimed.lease_owner, "worker-1");
  EXPECT_EQ(claimed.lease_until_ms, clock_.Now() + 1000);
  EXPECT_EQ(claimed.started_at_ms, clock_.Now());
  EXPECT_EQ(Get(a).state, JobState::kRunning);
  EXPECT_EQ(Claim("worker-2").id, b);

  Result<std::optional<Job>> none = store_->ClaimNextJob("worker-3", kLease);
  ASSERT_TRUE(none.ok()) << none.status();
  EXPECT_FALSE(none->has_value());
  EXPECT_THAT(Events(a).back().message, HasSubstr("started by worker 'worker-1' (run 1 of"));
}

TEST_F(JobStoreTest, ClaimOnAnEmptyStoreReturnsNothing) {
  Result<std::optional<Job>> none = store_->ClaimNextJob("w", kLease);
  ASSERT_TRUE(none.ok()) << none.status();
  EXPECT_FALSE(none->has_value());
  EXPECT_EQ(store_->ClaimNextJob("", kLease).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->ClaimNextJob("w", 0ms).status().code(), StatusCode::kInvalidArgument);
}

TEST_F(JobStoreTest, HeartbeatExtendsTheLease) {
  const std::string id = Create().id;
  Claim("w");
  clock_.Advance(800);
  Result<HeartbeatReply> beat = store_->Heartbeat(id, "w", kLease);
  ASSERT_TRUE(beat.ok()) << beat.status();
  EXPECT_TRUE(beat->owned);
  EXPECT_FALSE(beat->cancel_requested);
  EXPECT_EQ(beat->lease_until_ms, clock_.Now() + 1000);
  clock_.Advance(800);  // Past the first lease, within the extended one.
  Result<SweepResult> sweep = store_->SweepExpiredLeases();
  ASSERT_TRUE(sweep.ok());
  EXPECT_EQ(sweep->requeued, 0);
  EXPECT_EQ(Get(id).state, JobState::kRunning);
  // Someone else's heartbeat does not extend it.
  Result<HeartbeatReply> other = store_->Heartbeat(id, "intruder", kLease);
  ASSERT_TRUE(other.ok());
  EXPECT_FALSE(other->owned);
}

TEST_F(JobStoreTest, ExpiredLeaseRequeuesWithOneMoreAttempt) {
  const std::string id = Create().id;
  Claim("w1");
  clock_.Advance(1001);
  Result<SweepResult> sweep = store_->SweepExpiredLeases();
  ASSERT_TRUE(sweep.ok()) << sweep.status();
  EXPECT_EQ(sweep->requeued, 1);
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kQueued);
  EXPECT_EQ(job.attempts, 1);
  EXPECT_TRUE(job.lease_owner.empty());
  EXPECT_EQ(job.lease_until_ms, std::nullopt);
  EXPECT_THAT(Events(id).back().message, HasSubstr("worker 'w1' stopped heart-beating"));
  EXPECT_EQ(Events(id).back().level, LogLevel::kWarning);
}

TEST_F(JobStoreTest, LeaseExactlyAtItsEndIsStillValid) {
  const std::string id = Create().id;
  Claim("w1");
  clock_.Advance(1000);
  ASSERT_TRUE(store_->SweepExpiredLeases().ok());
  EXPECT_EQ(Get(id).state, JobState::kRunning);
}

TEST_F(JobStoreTest, ClaimRequeuesAnExpiredJobAndTakesItInTheSameCall) {
  const std::string old_job = Create().id;
  const std::string newer_job = Create().id;
  EXPECT_EQ(Claim("dead-worker").id, old_job);
  clock_.Advance(5000);
  const Job reclaimed = Claim("live-worker");
  EXPECT_EQ(reclaimed.id, old_job);  // Keeps its place ahead of the newer job.
  EXPECT_EQ(reclaimed.attempts, 1);
  EXPECT_EQ(reclaimed.lease_owner, "live-worker");
  EXPECT_EQ(Claim("live-worker").id, newer_job);
}

TEST_F(JobStoreTest, AfterMaxAttemptsTheJobFailsWithAClearError) {
  const std::string id = Create(MakeNewJob(2, /*max_attempts=*/2)).id;
  Claim("w1");
  ASSERT_TRUE(store_->RecordProgress(id, "w1", {.stage = "features", .progress = 0.2}).ok());
  clock_.Advance(1001);
  EXPECT_EQ(Claim("w2").id, id);  // Run 2 of 2.
  ASSERT_TRUE(store_->RecordProgress(id, "w2", {.stage = "matching", .progress = 0.3}).ok());
  clock_.Advance(1001);
  Result<SweepResult> sweep = store_->SweepExpiredLeases();
  ASSERT_TRUE(sweep.ok());
  EXPECT_EQ(sweep->failed, 1);
  EXPECT_EQ(sweep->requeued, 0);

  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kFailed);
  EXPECT_EQ(job.attempts, 2);
  EXPECT_EQ(job.error_stage, "matching");
  EXPECT_THAT(job.error, HasSubstr("gave up after 2 runs"));
  EXPECT_THAT(job.error, HasSubstr("worker 'w2' in stage 'matching'"));
  EXPECT_EQ(job.finished_at_ms, clock_.Now());
  Result<std::optional<Job>> none = store_->ClaimNextJob("w3", kLease);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
}

TEST_F(JobStoreTest, AWorkerThatLostItsLeaseCannotTouchTheJob) {
  const std::string id = Create().id;
  Claim("slow");
  clock_.Advance(1001);
  EXPECT_EQ(Claim("fast").id, id);

  Result<HeartbeatReply> beat = store_->Heartbeat(id, "slow", kLease);
  ASSERT_TRUE(beat.ok());
  EXPECT_FALSE(beat->owned);
  const Status finish =
      store_->FinishSucceeded(id, "slow", {.result_bytes = 1, .result_sha256 = kSha});
  EXPECT_EQ(finish.code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(finish.message(), HasSubstr("leased to worker 'fast', not 'slow'"));
  EXPECT_EQ(store_->FinishFailed(id, "slow", "boom", "x").code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->FinishCanceled(id, "slow").code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->RecordProgress(id, "slow", {.progress = 0.9}).code(),
            StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->MarkStageFinished(id, "slow", "features", 1.0).code(),
            StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->ReleaseJob(id, "slow").status().code(), StatusCode::kFailedPrecondition);
  EXPECT_TRUE(Get(id).finished_stages.empty());

  ASSERT_TRUE(store_->FinishSucceeded(id, "fast", {.result_bytes = 1, .result_sha256 = kSha}).ok());
  EXPECT_EQ(Get(id).state, JobState::kSucceeded);
  // Once finished, even the last owner cannot finish it again.
  EXPECT_EQ(store_->FinishFailed(id, "fast", "late", "").code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->FinishFailed(NewJobId(), "fast", "x", "").code(), StatusCode::kNotFound);
}

TEST_F(JobStoreTest, ReleaseRequeuesWithoutSpendingAnAttempt) {
  const std::string a = Create().id;
  const std::string b = Create().id;
  Claim("w");
  Result<JobState> state = store_->ReleaseJob(a, "w");
  ASSERT_TRUE(state.ok()) << state.status();
  EXPECT_EQ(*state, JobState::kQueued);
  EXPECT_EQ(Get(a).attempts, 0);
  EXPECT_EQ(Claim("w2").id, a);  // Still first in line.
  EXPECT_EQ(Claim("w2").id, b);
}

// ---- Progress, stages, finishing ----------------------------------------------------------------

TEST_F(JobStoreTest, ProgressMergesPerStageFiguresAndCounts) {
  const std::string id = Create().id;
  Claim("w");
  ASSERT_TRUE(store_
                  ->RecordProgress(id, "w",
                                   {.stage = "features",
                                    .progress = 0.1,
                                    .stage_progress = {{"features", {{"progress", 0.5}}}}})
                  .ok());
  ASSERT_TRUE(store_
                  ->RecordProgress(id, "w",
                                   {.stage = "matching",
                                    .progress = 7.0,  // Clamped.
                                    .stage_progress = {{"matching", {{"progress", 0.25}}}},
                                    .counts = {.registered = 12}})
                  .ok());
  const Job job = Get(id);
  EXPECT_EQ(job.stage, "matching");
  EXPECT_DOUBLE_EQ(job.progress, 1.0);
  EXPECT_EQ(job.stage_progress["features"]["progress"], 0.5);
  EXPECT_EQ(job.stage_progress["matching"]["progress"], 0.25);
  EXPECT_EQ(job.counts.registered, 12);

  EXPECT_EQ(store_->RecordProgress(id, "w", {.stage_progress = 3}).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->RecordProgress(id, "w", {.progress = std::nan("")}).code(),
            StatusCode::kInvalidArgument);
  // An empty stage keeps the current one.
  ASSERT_TRUE(store_->RecordProgress(id, "w", {.progress = 0.5}).ok());
  EXPECT_EQ(Get(id).stage, "matching");
}

TEST_F(JobStoreTest, SucceededJobKeepsItsResult) {
  const std::string id = Create().id;
  Claim("w");
  const std::string sha = "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef";
  EXPECT_EQ(store_->FinishSucceeded(id, "w", {.result_bytes = 5, .result_sha256 = "xyz"}).code(),
            StatusCode::kInvalidArgument);
  ASSERT_TRUE(store_
                  ->FinishSucceeded(id, "w",
                                    {.result_bytes = 123456,
                                     .result_sha256 = sha,
                                     .counts = {.points = 2000, .faces = 4000}})
                  .ok());
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kSucceeded);
  EXPECT_EQ(job.result_bytes, 123456);
  EXPECT_EQ(job.result_sha256, sha);
  EXPECT_EQ(job.counts.points, 2000);
  EXPECT_DOUBLE_EQ(job.progress, 1.0);
  EXPECT_TRUE(job.lease_owner.empty());
  EXPECT_EQ(job.finished_at_ms, clock_.Now());
}

TEST_F(JobStoreTest, FailedJobRecordsErrorAndStage) {
  const std::string id = Create().id;
  Claim("w");
  EXPECT_EQ(store_->FinishFailed(id, "w", "", "sfm").code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE(store_->FinishFailed(id, "w", "no initial pair", "sfm").ok());
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kFailed);
  EXPECT_EQ(job.error, "no initial pair");
  EXPECT_EQ(job.error_stage, "sfm");
  EXPECT_EQ(Events(id).back().level, LogLevel::kError);
}

TEST_F(JobStoreTest, MarkStageFinishedRecordsEachStageOnce) {
  const std::string id = Create().id;
  Claim("w");
  ASSERT_TRUE(store_->MarkStageFinished(id, "w", "ingest", 1.5).ok());
  ASSERT_TRUE(store_->MarkStageFinished(id, "w", "features", 12.0).ok());
  ASSERT_TRUE(store_->MarkStageFinished(id, "w", "ingest", 1.5).ok());  // Idempotent.
  Result<std::vector<std::string>> stages = store_->ListFinishedStages(id);
  ASSERT_TRUE(stages.ok()) << stages.status();
  EXPECT_THAT(*stages, ElementsAre("ingest", "features"));
  const Job job = Get(id);
  EXPECT_EQ(job.stage_progress["features"]["seconds"], 12.0);
  EXPECT_EQ(job.stage_progress["features"]["progress"], 1.0);
  EXPECT_EQ(store_->MarkStageFinished(id, "w", "", 1.0).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->ListFinishedStages(NewJobId()).status().code(), StatusCode::kNotFound);
}

// ---- Cancel -------------------------------------------------------------------------------------

TEST_F(JobStoreTest, CancelQueuedJobIsImmediate) {
  const std::string id = Create().id;
  Result<JobState> state = store_->RequestCancel(id);
  ASSERT_TRUE(state.ok()) << state.status();
  EXPECT_EQ(*state, JobState::kCanceled);
  EXPECT_EQ(Get(id).state, JobState::kCanceled);
  Result<std::optional<Job>> none = store_->ClaimNextJob("w", kLease);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
}

TEST_F(JobStoreTest, CancelRunningJobSetsTheFlagForTheWorker) {
  const std::string id = Create().id;
  Claim("w");
  Result<JobState> state = store_->RequestCancel(id);
  ASSERT_TRUE(state.ok());
  EXPECT_EQ(*state, JobState::kRunning);
  EXPECT_TRUE(Get(id).cancel_requested);
  EXPECT_TRUE(store_->RequestCancel(id).ok());  // Asking twice is harmless.

  Result<HeartbeatReply> beat = store_->Heartbeat(id, "w", kLease);
  ASSERT_TRUE(beat.ok());
  EXPECT_TRUE(beat->owned);
  EXPECT_TRUE(beat->cancel_requested);
  ASSERT_TRUE(store_->FinishCanceled(id, "w").ok());
  EXPECT_EQ(Get(id).state, JobState::kCanceled);
}

TEST_F(JobStoreTest, CancelFinishedJobIsAFailedPrecondition) {
  const std::string done = Create().id;
  const std::string failed = Create().id;
  const std::string canceled = Create().id;
  Claim("w");
  ASSERT_TRUE(store_->FinishSucceeded(done, "w", {.result_bytes = 1, .result_sha256 = kSha}).ok());
  Claim("w");
  ASSERT_TRUE(store_->FinishFailed(failed, "w", "boom", "").ok());
  ASSERT_TRUE(store_->RequestCancel(canceled).ok());
  for (const std::string& id : {done, failed, canceled}) {
    const Result<JobState> state = store_->RequestCancel(id);
    EXPECT_EQ(state.status().code(), StatusCode::kFailedPrecondition);
    EXPECT_THAT(state.status().message(), HasSubstr("is already"));
  }
  EXPECT_EQ(store_->RequestCancel(NewJobId()).status().code(), StatusCode::kNotFound);
}

TEST_F(JobStoreTest, ExpiredLeaseOfACancelRequestedJobCancelsIt) {
  const std::string id = Create().id;
  Claim("w");
  ASSERT_TRUE(store_->RequestCancel(id).ok());
  clock_.Advance(2000);
  Result<SweepResult> sweep = store_->SweepExpiredLeases();
  ASSERT_TRUE(sweep.ok());
  EXPECT_EQ(sweep->canceled, 1);
  EXPECT_EQ(Get(id).state, JobState::kCanceled);
}

TEST_F(JobStoreTest, ReleaseOfACancelRequestedJobCancelsIt) {
  const std::string id = Create().id;
  Claim("w");
  ASSERT_TRUE(store_->RequestCancel(id).ok());
  Result<JobState> state = store_->ReleaseJob(id, "w");
  ASSERT_TRUE(state.ok());
  EXPECT_EQ(*state, JobState::kCanceled);
}

// ---- Restart ------------------------------------------------------------------------------------

TEST_F(JobStoreTest, RestartKeepsFinishedStagesSoTheJobResumes) {
  const std::string id = Create().id;
  Claim("w");
  ASSERT_TRUE(store_->MarkStageFinished(id, "w", "ingest", 1.0).ok());
  ASSERT_TRUE(store_->MarkStageFinished(id, "w", "features", 2.0).ok());
  ASSERT_TRUE(store_->FinishFailed(id, "w", "out of memory", "matching").ok());

  Result<Job> restarted = store_->RestartJob(id);
  ASSERT_TRUE(restarted.ok()) << restarted.status();
  EXPECT_EQ(restarted->state, JobState::kQueued);
  EXPECT_TRUE(restarted->error.empty());
  EXPECT_TRUE(restarted->error_stage.empty());
  EXPECT_EQ(restarted->attempts, 0);
  EXPECT_EQ(restarted->finished_at_ms, std::nullopt);
  EXPECT_THAT(restarted->finished_stages, ElementsAre("ingest", "features"));

  const Job reclaimed = Claim("w2");
  EXPECT_EQ(reclaimed.id, id);
  EXPECT_THAT(reclaimed.finished_stages, ElementsAre("ingest", "features"));
  EXPECT_THAT(Events(id).back().message, HasSubstr("resuming after stage 'features'"));
}

TEST_F(JobStoreTest, RestartOfACanceledJobClearsTheCancelFlag) {
  const std::string id = Create().id;
  Claim("w");
  ASSERT_TRUE(store_->RequestCancel(id).ok());
  ASSERT_TRUE(store_->FinishCanceled(id, "w").ok());
  Result<Job> restarted = store_->RestartJob(id);
  ASSERT_TRUE(restarted.ok());
  EXPECT_FALSE(restarted->cancel_requested);
  Claim("w");
  Result<HeartbeatReply> beat = store_->Heartbeat(id, "w", kLease);
  ASSERT_TRUE(beat.ok());
  EXPECT_FALSE(beat->cancel_requested);
}

TEST_F(JobStoreTest, RestartJoinsTheEndOfTheQueue) {
  const std::string first = Create().id;
  Claim("w");
  ASSERT_TRUE(store_->FinishFailed(first, "w", "boom", "").ok());
  const std::string second = Create().id;
  ASSERT_TRUE(store_->RestartJob(first).ok());
  EXPECT_EQ(Claim("w").id, second);
  EXPECT_EQ(Claim("w").id, first);
}

TEST_F(JobStoreTest, RestartRefusesJobsThatAreNotFailedOrCanceled) {
  const std::string queued = Create().id;
  EXPECT_EQ(store_->RestartJob(queued).status().code(), StatusCode::kFailedPrecondition);
  Claim("w");
  EXPECT_EQ(store_->RestartJob(queued).status().code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(
      store_->FinishSucceeded(queued, "w", {.result_bytes = 1, .result_sha256 = kSha}).ok());
  EXPECT_EQ(store_->RestartJob(queued).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->RestartJob(NewJobId()).status().code(), StatusCode::kNotFound);
}

// ---- Events -------------------------------------------------------------------------------------

TEST_F(JobStoreTest, EventsPageAfterAnId) {
  const std::string id = Create().id;
  const std::string other = Create().id;
  std::vector<std::int64_t> ids = {Events(id).front().id};  // The "queued" event.
  for (int i = 0; i < 9; ++i) {
    Result<std::int64_t> event_id =
        store_->AppendEvent(id, {.stage = "features",
                                 .level = i == 4 ? LogLevel::kWarning : LogLevel::kInfo,
                                 .message = "line " + std::to_string(i),
                                 .progress = i / 10.0});
    ASSERT_TRUE(event_id.ok()) << event_id.status();
    ids.push_back(*event_id);
    ASSERT_TRUE(store_->AppendEvent(other, {.message = "noise"}).ok());
  }
  std::vector<JobEvent> seen;
  std::int64_t after = 0;
  for (;;) {
    Result<std::vector<JobEvent>> page = store_->ListEvents(id, after, 4);
    ASSERT_TRUE(page.ok()) << page.status();
    if (page->empty()) break;
    EXPECT_LE(page->size(), 4u);
    seen.insert(seen.end(), page->begin(), page->end());
    after = page->back().id;
  }
  ASSERT_EQ(seen.size(), 10u);
  for (std::size_t i = 0; i < seen.size(); ++i) {
    EXPECT_EQ(seen[i].id, ids[i]);
    EXPECT_EQ(seen[i].job_id, id);
  }
  EXPECT_EQ(seen[5].message, "line 4");
  EXPECT_EQ(seen[5].level, LogLevel::kWarning);
  EXPECT_EQ(seen[5].stage, "features");
  EXPECT_DOUBLE_EQ(seen[5].progress.value(), 0.4);
  EXPECT_EQ(seen[0].time_ms, clock_.Now() - 2);

  Result<std::vector<JobEvent>> tail = store_->ListEvents(id, ids[7], 100);
  ASSERT_TRUE(tail.ok());
  ASSERT_EQ(tail->size(), 2u);
  EXPECT_EQ((*tail)[0].id, ids[8]);

  EXPECT_EQ(store_->ListEvents(id, 0, 0).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->ListEvents(NewJobId(), 0, 10).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store_->AppendEvent(NewJobId(), {.message = "x"}).status().code(),
            StatusCode::kNotFound);
  EXPECT_EQ(store_->AppendEvent(id, {.message = "x", .progress = 1.5}).status().code(),
            StatusCode::kInvalidArgument);
}

// ---- Delete -------------------------------------------------------------------------------------

TEST_F(JobStoreTest, DeleteCascadesToEventsAndPhotos) {
  const std::string doomed = Create(MakeNewJob(5)).id;
  const std::string kept = Create(MakeNewJob(3)).id;
  ASSERT_TRUE(store_->AppendEvent(doomed, {.message = "hello"}).ok());
  const std::int64_t last_event = Events(doomed).back().id;

  Result<JobState> state = store_->DeleteJob(doomed);
  ASSERT_TRUE(state.ok()) << state.status();
  EXPECT_EQ(*state, JobState::kQueued);
  EXPECT_EQ(store_->GetJob(doomed).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store_->DeleteJob(doomed).status().code(), StatusCode::kNotFound);

  SqliteConnection raw = SqliteConnection::Open(path());
  Statement images(raw.get(), "SELECT count(*) FROM images WHERE job_id = ?1");
  images.Bind(1, doomed);
  ASSERT_TRUE(images.Step());
  EXPECT_EQ(images.Int64(0), 0);
  Statement events(raw.get(), "SELECT count(*) FROM job_events WHERE job_id = ?1");
  events.Bind(1, doomed);
  ASSERT_TRUE(events.Step());
  EXPECT_EQ(events.Int64(0), 0);
  EXPECT_EQ(store_->ListImages(kept).value().size(), 3u);

  // Event ids are never reused, so a client following ?after=N never misses a line.
  Result<std::int64_t> next = store_->AppendEvent(kept, {.message = "after delete"});
  ASSERT_TRUE(next.ok());
  EXPECT_GT(*next, last_event);
}

TEST_F(JobStoreTest, DeleteRefusesARunningJobUntilItIsCanceled) {
  const std::string id = Create().id;
  Claim("w");
  const Result<JobState> refused = store_->DeleteJob(id);
  EXPECT_EQ(refused.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(refused.status().message(), HasSubstr("is running"));
  ASSERT_TRUE(store_->RequestCancel(id).ok());
  EXPECT_EQ(store_->DeleteJob(id).status().code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(store_->FinishCanceled(id, "w").ok());
  Result<JobState> state = store_->DeleteJob(id);
  ASSERT_TRUE(state.ok());
  EXPECT_EQ(*state, JobState::kCanceled);
}

// ---- Metrics and persistence --------------------------------------------------------------------

TEST_F(JobStoreTest, QueueStatsCountJobsByState) {
  const std::string a = Create().id;
  Create();
  Create();
  const std::string d = Create().id;
  Claim("w");
  ASSERT_TRUE(store_->FinishFailed(a, "w", "x", "").ok());
  Claim("w");
  ASSERT_TRUE(store_->RequestCancel(d).ok());
  Result<QueueStats> stats = store_->GetQueueStats();
  ASSERT_TRUE(stats.ok()) << stats.status();
  EXPECT_EQ(stats->QueueLength(), 1);
  EXPECT_EQ(stats->Count(JobState::kRunning), 1);
  EXPECT_EQ(stats->Count(JobState::kFailed), 1);
  EXPECT_EQ(stats->Count(JobState::kCanceled), 1);
  EXPECT_EQ(stats->Count(JobState::kSucceeded), 0);
  ASSERT_TRUE(stats->oldest_queued_at_ms.has_value());
  EXPECT_EQ(*stats->oldest_queued_at_ms, Get(d).created_at_ms - 1);
}

TEST_F(JobStoreTest, EverythingSurvivesReopening) {
  const std::string id = Create().id;
  Claim("w");
  ASSERT_TRUE(store_->MarkStageFinished(id, "w", "ingest", 1.0).ok());
  store_.reset();
  SqliteJobStoreOptions options;
  options.now_ms = clock_.AsFunction();
  store_ = OpenOrDie(path(), options);
  const Job job = Get(id);
  EXPECT_EQ(job.state, JobState::kRunning);
  EXPECT_EQ(job.lease_owner, "w");
  EXPECT_THAT(job.finished_stages, ElementsAre("ingest"));
}

}  // namespace
}  // namespace reconduit
