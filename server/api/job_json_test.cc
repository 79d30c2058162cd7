#include "server/api/job_json.h"

#include <gtest/gtest.h>

namespace reconduit::server {
namespace {

TEST(EstimateEtaSeconds, ExtrapolatesTheRateSoFar) {
  EXPECT_DOUBLE_EQ(*EstimateEtaSeconds(0.25, 60.0), 180.0);
  EXPECT_DOUBLE_EQ(*EstimateEtaSeconds(0.5, 10.0), 10.0);
  EXPECT_DOUBLE_EQ(*EstimateEtaSeconds(1.0, 10.0), 0.0);
}

TEST(EstimateEtaSeconds, UnknownUntilItMeansSomething) {
  EXPECT_FALSE(EstimateEtaSeconds(0.0, 100.0));
  EXPECT_FALSE(EstimateEtaSeconds(0.005, 100.0));
  EXPECT_FALSE(EstimateEtaSeconds(0.5, 0.2));
  EXPECT_FALSE(EstimateEtaSeconds(-0.1, 10.0));
  EXPECT_FALSE(EstimateEtaSeconds(1.5, 10.0));
  EXPECT_FALSE(EstimateEtaSeconds(0.5, -1.0));
}

TEST(FormatTimestamp, IsoUtcWithMilliseconds) {
  EXPECT_EQ(FormatTimestamp(0), "1970-01-01T00:00:00.000Z");
  EXPECT_EQ(FormatTimestamp(1700000000123), "2023-11-14T22:13:20.123Z");
  EXPECT_EQ(FormatTimestamp(-1), "1969-12-31T23:59:59.999Z");
}

Job RunningJob() {
  Job job;
  job.id = "0123456789abcdef0123456789abcdef";
  job.state = JobState::kRunning;
  job.created_at_ms = 1000;
  job.queued_at_ms = 1000;
  job.started_at_ms = 2000;
  job.updated_at_ms = 3000;
  job.stage = "features";
  job.progress = 0.25;
  job.stage_progress = {{"ingest", {{"progress", 1}, {"seconds", 2.5}}}};
  job.image_count = 3;
  job.counts.features = 1000;
  return job;
}

TEST(JobToJson, RunningJobHasProgressElapsedAndEta) {
  const nlohmann::json json = JobToJson(RunningJob(), /*now_ms=*/62000);
  EXPECT_EQ(json["state"], "running");
  EXPECT_EQ(json["stage"], "features");
  EXPECT_DOUBLE_EQ(json["progress"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(json["elapsed_seconds"].get<double>(), 60.0);
  EXPECT_DOUBLE_EQ(json["eta_seconds"].get<double>(), 180.0);
  EXPECT_EQ(json["stages"]["ingest"]["seconds"], 2.5);
  EXPECT_EQ(json["counts"]["images"], 3);
  EXPECT_EQ(json["counts"]["features"], 1000);
  EXPECT_TRUE(json["error"].is_null());
  EXPECT_TRUE(json["result"].is_null());
  EXPECT_TRUE(json["finished_at"].is_null());
  EXPECT_EQ(json["links"]["self"], "/api/v1/jobs/0123456789abcdef0123456789abcdef");
  EXPECT_EQ(json["links"]["result"], "/api/v1/jobs/0123456789abcdef0123456789abcdef/result.zip");
}

TEST(JobToJson, FailedAndSucceededJobs) {
  Job failed = RunningJob();
  failed.state = JobState::kFailed;
  failed.finished_at_ms = 12000;
  failed.error = "too few registered cameras";
  failed.error_stage = "sparse";
  nlohmann::json json = JobToJson(failed, 99999);
  EXPECT_EQ(json["error"]["message"], "too few registered cameras");
  EXPECT_EQ(json["error"]["stage"], "sparse");
  EXPECT_DOUBLE_EQ(json["elapsed_seconds"].get<double>(), 10.0);
  EXPECT_TRUE(json["eta_seconds"].is_null());

  Job succeeded = RunningJob();
  succeeded.state = JobState::kSucceeded;
  succeeded.finished_at_ms = 5000;
  succeeded.result_bytes = 1234;
  succeeded.result_sha256 = std::string(64, 'a');
  json = JobToJson(succeeded, 99999);
  EXPECT_EQ(json["result"]["bytes"], 1234);
  EXPECT_EQ(json["result"]["sha256"], std::string(64, 'a'));
  EXPECT_TRUE(json["error"].is_null());

  Job queued = RunningJob();
  queued.state = JobState::kQueued;
  queued.started_at_ms.reset();
  queued.stage.clear();
  json = JobToJson(queued, 99999);
  EXPECT_TRUE(json["stage"].is_null());
  EXPECT_TRUE(json["elapsed_seconds"].is_null());
  EXPECT_TRUE(json["eta_seconds"].is_null());
}

TEST(ImagesToJson, CountsAndReasons) {
  JobImageRecord accepted;
  accepted.index = 0;
  accepted.original_name = "a.jpg";
  accepted.stored_name = "0001.jpg";
  accepted.photo.bytes = 10;
  accepted.photo.width = 640;
  accepted.photo.height = 480;
  JobImageRecord rejected;
  rejected.index = 1;
  rejected.original_name = "b.jpg";
  rejected.stored_name = "0002.jpg";
  rejected.photo.accepted = false;
  rejected.photo.reason = "truncated";
  const nlohmann::json json = ImagesToJson({accepted, rejected});
  EXPECT_EQ(json["accepted"], 1);
  EXPECT_EQ(json["rejected"], 1);
  ASSERT_EQ(json["items"].size(), 2u);
  EXPECT_EQ(json["items"][0]["width"], 640);
  EXPECT_FALSE(json["items"][0].contains("reason"));
  EXPECT_EQ(json["items"][1]["status"], "rejected");
  EXPECT_EQ(json["items"][1]["reason"], "truncated");
  EXPECT_FALSE(json["items"][1].contains("width"));
}

TEST(EventToJson, AllFields) {
  JobEvent event;
  event.id = 7;
  event.time_ms = 0;
  event.stage = "ingest";
  event.level = LogLevel::kWarning;
  event.message = "photo 3 rejected";
  event.progress = 0.1;
  const nlohmann::json json = EventToJson(event);
  EXPECT_EQ(json["id"], 7);
  EXPECT_EQ(json["time"], "1970-01-01T00:00:00.000Z");
  EXPECT_EQ(json["stage"], "ingest");
  EXPECT_EQ(json["level"], "warning");
  EXPECT_EQ(json["message"], "photo 3 rejected");
  EXPECT_DOUBLE_EQ(json["progress"].get<double>(), 0.1);
}

}  // namespace
}  // namespace reconduit::server
