#include "core/pipeline/runner.h"

#include "core/io/file_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <sys/mman.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// A toy stage: counts its runs, writes a file, and behaves as told.
class ToyStage : public Stage {
 public:
  enum class Behaviour { kSucceed, kThrow, kCancelInside, kDegenerate };
  ToyStage(std::string name, Behaviour behaviour, int* runs, bool resumable = true)
      : name_(std::move(name)), behaviour_(behaviour), runs_(runs), resumable_(resumable) {}
  bool Resumable() const override { return resumable_; }
  std::string_view Name() const override { return name_; }
  std::string_view Title() const override { return "Toy"; }
  StageResult Run(StageContext& context) const override {
    ++*runs_;
    EXPECT_TRUE(fs::is_directory(context.stage_dir));
    EXPECT_TRUE(fs::is_empty(context.stage_dir)) << "the runner empties the stage folder";
    std::ofstream(context.stage_dir / "out.txt") << name_;
    context.progress.Restart(4, "items");
    for (int i = 0; i < 4; ++i) context.progress.Advance();
    switch (behaviour_) {
      case Behaviour::kSucceed:
        return StageResult::Success({{"items", 4}, {"previous", context.previous.size()}});
      case Behaviour::kThrow:
        throw std::runtime_error("disk on fire");
      case Behaviour::kCancelInside:
        context.cancel.RequestCancel();
        context.cancel.ThrowIfCanceled();
        return StageResult::Success();
      case Behaviour::kDegenerate:
        return StageResult::Degenerate("all photos show a flat wall");
    }
    return {};
  }

 private:
  std::string name_;
  Behaviour behaviour_;
  int* runs_;
  bool resumable_;
};

class RunnerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    workspace_.work_dir = fs::temp_directory_path() /
                          (std::string("reconduit_runner_") +
                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(workspace_.work_dir);
    fs::create_directories(workspace_.work_dir);
  }
  void TearDown() override { fs::remove_all(workspace_.work_dir); }

  std::vector<std::unique_ptr<Stage>> Stages(ToyStage::Behaviour second) {
    std::vector<std::unique_ptr<Stage>> stages;
    stages.push_back(std::make_unique<ToyStage>("a", ToyStage::Behaviour::kSucceed, &runs_[0]));
    stages.push_back(std::make_unique<ToyStage>("b", second, &runs_[1]));
    stages.push_back(std::make_unique<ToyStage>("c", ToyStage::Behaviour::kSucceed, &runs_[2]));
    return stages;
  }

  Workspace workspace_;
  PipelineOptions options_;
  int runs_[3] = {0, 0, 0};
};

TEST_F(RunnerTest, RunsAllStagesInOrderAndReportsProgress) {
  std::vector<double> overall;
  std::vector<std::string> ended;
  PipelineCallbacks callbacks;
  callbacks.on_progress = [&](const Stage&, const ProgressUpdate&, double o) {
    overall.push_back(o);
  };
  callbacks.on_stage_end = [&](const Stage& s, const StageRecord&, double) {
    ended.emplace_back(s.Name());
  };
  const PipelineResult result = RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_,
                                            options_, CancelToken(), callbacks);
  EXPECT_EQ(result.status, StageStatus::kSuccess);
  ASSERT_EQ(result.stages.size(), 3u);
  EXPECT_EQ(result.stages[2].summary["previous"], 2);
  EXPECT_THAT(ended, ::testing::ElementsAre("a", "b", "c"));
  ASSERT_FALSE(overall.empty());
  EXPECT_TRUE(std::is_sorted(overall.begin(), overall.end()));
  EXPECT_DOUBLE_EQ(overall.back(), 1.0);
  EXPECT_TRUE(fs::exists(workspace_.StageDir("c") / "stage.json"));
}

TEST_F(RunnerTest, ExceptionFailsTheStageAndStops) {
  const PipelineResult result =
      RunPipeline(Stages(ToyStage::Behaviour::kThrow), workspace_, options_, CancelToken());
  EXPECT_EQ(result.status, StageStatus::kFailed);
  EXPECT_EQ(result.failed_stage, "b");
  EXPECT_EQ(result.message, "disk on fire");
  EXPECT_EQ(runs_[2], 0);
  EXPECT_FALSE(fs::exists(workspace_.StageDir("b") / "stage.json"));
}

TEST_F(RunnerTest, DegenerateStopsWithItsMessage) {
  const PipelineResult result =
      RunPipeline(Stages(ToyStage::Behaviour::kDegenerate), workspace_, options_, CancelToken());
  EXPECT_EQ(result.status, StageStatus::kDegenerate);
  EXPECT_EQ(result.message, "all photos show a flat wall");
}

TEST_F(RunnerTest, CancellationInsideAStage) {
  const PipelineResult result =
      RunPipeline(Stages(ToyStage::Behaviour::kCancelInside), workspace_, options_, CancelToken());
  EXPECT_EQ(result.status, StageStatus::kCanceled);
  EXPECT_EQ(result.failed_stage, "b");
  EXPECT_EQ(runs_[2], 0);
}

TEST_F(RunnerTest, CanceledBeforeStartRunsNothing) {
  CancelToken cancel;
  cancel.RequestCancel();
  const PipelineResult result =
      RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_, options_, cancel);
  EXPECT_EQ(result.status, StageStatus::kCanceled);
  EXPECT_EQ(runs_[0], 0);
}

TEST_F(RunnerTest, ResumesAfterTheLastFinishedStage) {
  RunPipeline(Stages(ToyStage::Behaviour::kThrow), workspace_, options_, CancelToken());
  ASSERT_EQ(runs_[0], 1);
  // A leftover from the failed attempt must be cleared before the stage runs again.
  std::ofstream(workspace_.StageDir("b") / "partial.tmp") << "x";
  const PipelineResult result =
      RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_, options_, CancelToken());
  EXPECT_EQ(result.status, StageStatus::kSuccess);
  EXPECT_EQ(runs_[0], 1) << "stage a finished before: not run again";
  EXPECT_EQ(runs_[1], 2);
  EXPECT_TRUE(result.stages[0].resumed);
  EXPECT_FALSE(result.stages[1].resumed);
  EXPECT_FALSE(fs::exists(workspace_.StageDir("b") / "partial.tmp"));
  EXPECT_EQ(ReadFinishedStages(workspace_, Stages(ToyStage::Behaviour::kSucceed), options_).size(),
            3u);
}

TEST_F(RunnerTest, StageAfterARerunStageRunsAgain) {
  RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_, options_, CancelToken());
  fs::remove(workspace_.StageDir("b") / "stage.json");  // b's outputs are suspect now.
  RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_, options_, CancelToken());
  EXPECT_EQ(runs_[0], 1);
  EXPECT_EQ(runs_[1], 2);
  EXPECT_EQ(runs_[2], 2) << "c consumed b's old outputs, so it runs again";
}

// A stage that depends on one option only.
class OptionStage : public ToyStage {
 public:
  OptionStage(std::string name, int* runs) : ToyStage(std::move(name), Behaviour::kSucceed, runs) {}
  std::vector<std::string> OptionsUsed() const override { return {"max_features"}; }
};

TEST_F(RunnerTest, ChangedOptionsRerunTheStagesThatUseThemAndWhatFollows) {
  auto stages = [&] {
    std::vector<std::unique_ptr<Stage>> s;
    s.push_back(std::make_unique<OptionStage>("a", &runs_[0]));  // max_features only.
    s.push_back(std::make_unique<ToyStage>("b", ToyStage::Behaviour::kSucceed, &runs_[1]));
    s.push_back(std::make_unique<ToyStage>("c", ToyStage::Behaviour::kSucceed, &runs_[2]));
    return s;
  };
  RunPipeline(stages(), workspace_, options_, CancelToken());
  const nlohmann::json marker =
      nlohmann::json::parse(*ReadFile(workspace_.StageDir("a") / "stage.json"));
  EXPECT_EQ(marker.at("options"), nlohmann::json({{"max_features", options_.max_features}}));

  // Threads change how fast, not what: everything resumes.
  options_.num_threads = 1;
  RunPipeline(stages(), workspace_, options_, CancelToken());
  EXPECT_EQ(runs_[0], 1);
  EXPECT_EQ(runs_[2], 1);

  // An option only b and c use (by default a stage uses every option): a resumes, b and c run.
  options_.use_exif = !options_.use_exif;
  RunPipeline(stages(), workspace_, options_, CancelToken());
  EXPECT_EQ(runs_[0], 1);
  EXPECT_EQ(runs_[1], 2);
  EXPECT_EQ(runs_[2], 2);
  EXPECT_EQ(ReadFinishedStages(workspace_, stages(), options_).size(), 3u);

  // a's option: all three run again.
  options_.max_features = 1000;
  EXPECT_EQ(ReadFinishedStages(workspace_, stages(), options_).size(), 0u);
  RunPipeline(stages(), workspace_, options_, CancelToken());
  EXPECT_EQ(runs_[0], 2);
  EXPECT_EQ(runs_[1], 3);
  EXPECT_EQ(runs_[2], 3);
}

TEST_F(RunnerTest, MarkerWithoutOptionsIsNotResumed) {
  RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_, options_, CancelToken());
  nlohmann::json marker = nlohmann::json::parse(*ReadFile(workspace_.StageDir("a") / "stage.json"));
  marker.erase("options");  // As written before options were recorded.
  ASSERT_TRUE(WriteFileAtomically(workspace_.StageDir("a") / "stage.json", marker.dump()).ok());
  RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_, options_, CancelToken());
  EXPECT_EQ(runs_[0], 2);
}

// A stage that maps, touches and unmaps `mib` MiB (unmapped pages leave the resident set
// whatever the allocator or a sanitizer does with freed blocks).
class MemoryStage : public ToyStage {
 public:
  MemoryStage(std::string name, std::int64_t mib, int* runs)
      : ToyStage(std::move(name), Behaviour::kSucceed, runs), bytes_(mib << 20) {}
  StageResult Run(StageContext& context) const override {
    const auto size = static_cast<std::size_t>(bytes_);
    void* block = mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (block == MAP_FAILED) return StageResult::Failed("cannot map memory");
    std::memset(block, 7, size);
    const int value = static_cast<volatile char*>(block)[size / 2];
    munmap(block, size);
    ToyStage::Run(context);
    return StageResult::Success({{"value", value}});
  }

 private:
  std::int64_t bytes_;
};

TEST_F(RunnerTest, RecordsEachStagesOwnPeakMemoryBesideTheProcesss) {
  constexpr std::int64_t kMiB = 1 << 20;
  std::vector<std::unique_ptr<Stage>> stages;
  stages.push_back(std::make_unique<MemoryStage>("big", 150, &runs_[0]));
  stages.push_back(std::make_unique<MemoryStage>("small", 10, &runs_[1]));
  const PipelineResult result = RunPipeline(stages, workspace_, options_, CancelToken());
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.message;
  const StageRecord& big = result.stages[0];
  const StageRecord& small = result.stages[1];
  EXPECT_EQ(big.summary["value"], 7);
  // The process's peak never drops, whatever the kernel's mark does.
  EXPECT_GE(big.peak_memory_bytes, 150 * kMiB);
  EXPECT_GE(small.peak_memory_bytes, big.peak_memory_bytes);
  EXPECT_LE(big.stage_peak_memory_bytes, big.peak_memory_bytes);
  EXPECT_LE(small.stage_peak_memory_bytes, small.peak_memory_bytes);
  // stage.json keeps both figures.
  const StageRecord marker = StageRecord::FromJson(
      nlohmann::json::parse(*ReadFile(workspace_.StageDir("small") / "stage.json")));
  EXPECT_EQ(marker.peak_memory_bytes, small.peak_memory_bytes);
  EXPECT_EQ(marker.stage_peak_memory_bytes, small.stage_peak_memory_bytes);
  EXPECT_EQ(marker.stage_peak_memory_own, small.stage_peak_memory_own);
  if (!big.stage_peak_memory_own) {
    // Without a resettable mark the figure is the process's, and says so.
    EXPECT_EQ(small.stage_peak_memory_bytes, small.peak_memory_bytes);
    GTEST_SKIP() << "/proc/self/clear_refs cannot be written here";
  }
  ASSERT_TRUE(small.stage_peak_memory_own);
  EXPECT_GE(big.stage_peak_memory_bytes, 150 * kMiB);
  // The small stage's own mark is far below the big one's, and below the process's peak.
  EXPECT_GE(small.stage_peak_memory_bytes, 10 * kMiB);
  EXPECT_LT(small.stage_peak_memory_bytes, big.stage_peak_memory_bytes - 100 * kMiB);
  EXPECT_LT(small.stage_peak_memory_bytes, small.peak_memory_bytes - 100 * kMiB);
}

TEST_F(RunnerTest, MarkerWithoutTheStagesOwnPeakMemoryStillResumes) {
  RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_, options_, CancelToken());
  nlohmann::json marker = nlohmann::json::parse(*ReadFile(workspace_.StageDir("a") / "stage.json"));
  ASSERT_TRUE(marker.contains("stage_peak_memory_bytes"));
  ASSERT_TRUE(marker.contains("stage_peak_memory_own"));
  // As written before stages kept their own peak.
  marker.erase("stage_peak_memory_bytes");
  marker.erase("stage_peak_memory_own");
  ASSERT_TRUE(WriteFileAtomically(workspace_.StageDir("a") / "stage.json", marker.dump()).ok());
  const PipelineResult result =
      RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_, options_, CancelToken());
  EXPECT_EQ(result.status, StageStatus::kSuccess);
  EXPECT_EQ(runs_[0], 1);
  ASSERT_TRUE(result.stages[0].resumed);
  EXPECT_GT(result.stages[0].peak_memory_bytes, 0);
  EXPECT_EQ(result.stages[0].stage_peak_memory_bytes, 0) << "unknown";
  EXPECT_FALSE(result.stages[0].stage_peak_memory_own);
}

TEST(StageRecord, JsonRoundTripKeepsBothPeaks) {
  StageRecord record;
  record.name = "dense";
  record.status = StageStatus::kSuccess;
  record.seconds = 4.5;
  record.peak_memory_bytes = 3'000'000'000;
  record.stage_peak_memory_bytes = 1'200'000'000;
  record.stage_peak_memory_own = true;
  record.summary = {{"maps", {{{"image", "a.jpg"}, {"seconds", 4.2}}}}};
  const StageRecord back = StageRecord::FromJson(nlohmann::json::parse(record.ToJson().dump()));
  EXPECT_EQ(back.name, "dense");
  EXPECT_EQ(back.status, StageStatus::kSuccess);
  EXPECT_EQ(back.peak_memory_bytes, 3'000'000'000);
  EXPECT_EQ(back.stage_peak_memory_bytes, 1'200'000'000);
  EXPECT_TRUE(back.stage_peak_memory_own);
  EXPECT_EQ(back.summary, record.summary);
}

TEST_F(RunnerTest, NonResumableStageRunsEveryTimeAndSoDoesWhatFollows) {
  auto stages = [&] {
    std::vector<std::unique_ptr<Stage>> s;
    s.push_back(std::make_unique<ToyStage>("a", ToyStage::Behaviour::kSucceed, &runs_[0]));
    s.push_back(std::make_unique<ToyStage>("b", ToyStage::Behaviour::kSucceed, &runs_[1], false));
    s.push_back(std::make_unique<ToyStage>("c", ToyStage::Behaviour::kSucceed, &runs_[2]));
    return s;
  };
  RunPipeline(stages(), workspace_, options_, CancelToken());
  RunPipeline(stages(), workspace_, options_, CancelToken());
  EXPECT_EQ(runs_[0], 1);
  EXPECT_EQ(runs_[1], 2);
  EXPECT_EQ(runs_[2], 2);
}

TEST_F(RunnerTest, AnnouncesThePlanAndTheOverallFigureAtStageBoundaries) {
  auto stages = [&] {
    std::vector<std::unique_ptr<Stage>> s;
    s.push_back(std::make_unique<ToyStage>("a", ToyStage::Behaviour::kSucceed, &runs_[0]));
    s.push_back(std::make_unique<ToyStage>("b", ToyStage::Behaviour::kSucceed, &runs_[1], false));
    return s;
  };
  RunPipeline(stages(), workspace_, options_, CancelToken());

  std::vector<StagePlan> plan;
  std::vector<std::pair<std::string, double>> starts, ends;
  std::vector<StageRecord> records;
  PipelineCallbacks callbacks;
  callbacks.on_plan = [&](const std::vector<StagePlan>& p) { plan = p; };
  callbacks.on_stage_start = [&](const Stage& s, double overall) {
    EXPECT_FALSE(plan.empty()) << "the plan comes before the first stage";
    starts.emplace_back(s.Name(), overall);
  };
  callbacks.on_stage_end = [&](const Stage& s, const StageRecord& record, double overall) {
    ends.emplace_back(s.Name(), overall);
    records.push_back(record);
  };
  const PipelineResult result =
      RunPipeline(stages(), workspace_, options_, CancelToken(), callbacks);
  EXPECT_EQ(result.status, StageStatus::kSuccess);

  // a resumes; b (not resumable) runs again.
  ASSERT_EQ(plan.size(), 2u);
  EXPECT_EQ(plan[0].name, "a");
  EXPECT_EQ(plan[0].title, "Toy");
  EXPECT_TRUE(plan[0].finished_on_disk);
  EXPECT_TRUE(plan[0].resumable);
  EXPECT_FALSE(plan[1].finished_on_disk);
  EXPECT_FALSE(plan[1].resumable);
  // Equal weights: a is the first half of the run, b the second.
  EXPECT_THAT(starts, ::testing::ElementsAre(std::pair<std::string, double>("a", 0.0),
                                             std::pair<std::string, double>("b", 0.5)));
  EXPECT_THAT(ends, ::testing::ElementsAre(std::pair<std::string, double>("a", 0.5),
                                           std::pair<std::string, double>("b", 1.0)));
  ASSERT_EQ(records.size(), 2u);
  EXPECT_TRUE(records[0].resumed);
  EXPECT_TRUE(records[0].resumable);
  EXPECT_FALSE(records[1].resumed);
  EXPECT_FALSE(records[1].resumable);
  EXPECT_FALSE(records[1].package.has_value()) << "only packaging hands over an archive";

  // PlanPipeline says the same without running anything.
  const std::vector<StagePlan> planned = PlanPipeline(stages(), workspace_, options_);
  ASSERT_EQ(planned.size(), 2u);
  EXPECT_TRUE(planned[0].finished_on_disk);
  EXPECT_FALSE(planned[1].finished_on_disk);
  EXPECT_EQ(runs_[0], 1);
  EXPECT_EQ(runs_[1], 2);
}

TEST_F(RunnerTest, AFailedStageEndsAtTheFigureItStartedFrom) {
  std::vector<double> ends;
  PipelineCallbacks callbacks;
  callbacks.on_stage_end = [&](const Stage&, const StageRecord&, double overall) {
    ends.push_back(overall);
  };
  RunPipeline(Stages(ToyStage::Behaviour::kThrow), workspace_, options_, CancelToken(), callbacks);
  ASSERT_EQ(ends.size(), 2u);
  EXPECT_NEAR(ends[0], 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(ends[1], 1.0 / 3.0, 1e-12) << "b failed: the figure stays at its start";
}

// A stage that makes three parts, one file each, skipping those an earlier attempt finished, and
// throws after `fail_after` new parts (-1: never).
class PartsStage : public Stage {
 public:
  PartsStage(int fail_after, int* made) : fail_after_(fail_after), made_(made) {}
  std::string_view Name() const override { return "parts"; }
  std::string_view Title() const override { return "Parts"; }
  bool KeepsFinishedParts() const override { return true; }
  std::vector<std::string> OptionsUsed() const override { return {"use_exif"}; }
  StageResult Run(StageContext& context) const override {
    int made_now = 0;
    for (int part = 0; part < 3; ++part) {
      const fs::path file = context.stage_dir / ("part" + std::to_string(part));
      if (fs::exists(file)) continue;
      if (made_now == fail_after_) throw std::runtime_error("killed");
      std::ofstream(file) << part;
      ++made_now;
      ++*made_;
    }
    return StageResult::Success();
  }

 private:
  int fail_after_;
  int* made_;
};

TEST_F(RunnerTest, AStageThatKeepsFinishedPartsRedoesOnlyTheRest) {
  int made = 0;
  auto stages = [&](int fail_after) {
    std::vector<std::unique_ptr<Stage>> s;
    s.push_back(std::make_unique<OptionStage>("a", &runs_[0]));  // max_features only.
    s.push_back(std::make_unique<PartsStage>(fail_after, &made));
    return s;
  };
  EXPECT_EQ(RunPipeline(stages(2), workspace_, options_, CancelToken()).status,
            StageStatus::kFailed);
  EXPECT_EQ(made, 2);
  EXPECT_EQ(RunPipeline(stages(-1), workspace_, options_, CancelToken()).status,
            StageStatus::kSuccess);
  EXPECT_EQ(made, 3) << "the two finished parts are kept";
  EXPECT_EQ(runs_[0], 1);

  // Interrupted again with other options: the parts are made with the new ones.
  fs::remove(workspace_.StageDir("parts") / "stage.json");
  options_.use_exif = !options_.use_exif;
  RunPipeline(stages(-1), workspace_, options_, CancelToken());
  EXPECT_EQ(made, 6) << "options changed: every part again";
  EXPECT_EQ(runs_[0], 1);

  // When a stage before it runs again, its parts are stale.
  fs::remove(workspace_.StageDir("parts") / "stage.json");
  fs::remove(workspace_.StageDir("a") / "stage.json");
  RunPipeline(stages(-1), workspace_, options_, CancelToken());
  EXPECT_EQ(made, 9) << "stage a ran again: every part again";
  EXPECT_EQ(runs_[0], 2);
}

TEST_F(RunnerTest, InvalidOptionsThrow) {
  options_.min_image_side = 1;
  EXPECT_THROW(
      RunPipeline(Stages(ToyStage::Behaviour::kSucceed), workspace_, options_, CancelToken()),
      CheckError);
}

}  // namespace
}  // namespace reconduit
