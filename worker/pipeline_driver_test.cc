#include "worker/pipeline_driver.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// Reports some progress and succeeds.
class QuickStage : public Stage {
 public:
  explicit QuickStage(std::string name) : name_(std::move(name)) {}
  std::string_view Name() const override { return name_; }
  std::string_view Title() const override { return "Quick"; }
  StageResult Run(StageContext& context) const override {
    context.progress.Restart(2, "items");
    context.progress.Advance();
    context.progress.Advance();
    return StageResult::Success();
  }

 private:
  std::string name_;
};

StageListFactory TwoStages() {
  return [] {
    StageList stages;
    stages.push_back(std::make_unique<QuickStage>("a"));
    stages.push_back(std::make_unique<QuickStage>("b"));
    return Result<StageList>(std::move(stages));
  };
}

class PipelineDriverTest : public ::testing::Test {
 protected:
  void SetUp() override {
    workspace_.work_dir = fs::temp_directory_path() /
                          (std::string("reconduit_driver_") +
                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(workspace_.work_dir);
  }
  void TearDown() override { fs::remove_all(workspace_.work_dir); }

  PipelineResult Run(const StageListFactory& stages, const PipelineCallbacks& callbacks = {}) {
    return RunJobPipeline(workspace_, PipelineOptions(), stages, CancelToken(), callbacks);
  }

  Workspace workspace_;
};

TEST_F(PipelineDriverTest, RunsTheStages) {
  const PipelineResult result = Run(TwoStages());
  EXPECT_EQ(result.status, StageStatus::kSuccess);
  ASSERT_EQ(result.stages.size(), 2u);
}

TEST_F(PipelineDriverTest, FactoryErrorsAndEmptyListsAreFailures) {
  PipelineResult result = Run([] { return Result<StageList>(Status::InvalidArgument("no")); });
  EXPECT_EQ(result.status, StageStatus::kFailed);
  EXPECT_EQ(result.message, "cannot set up the pipeline: no");

  result = Run([]() -> Result<StageList> { throw std::runtime_error("factory on fire"); });
  EXPECT_EQ(result.status, StageStatus::kFailed);
  EXPECT_EQ(result.message, "factory on fire");

  result = Run([] { return Result<StageList>(StageList()); });
  EXPECT_EQ(result.status, StageStatus::kFailed);
  EXPECT_EQ(result.message, "the pipeline has no stages");

  EXPECT_EQ(Run(StagesUntil("nonsense")).status, StageStatus::kFailed);
}

TEST_F(PipelineDriverTest, CallbackExceptionsFailTheStageTheyCameFrom) {
  // Outside a stage (its start): the run fails, naming the stage.
  PipelineCallbacks callbacks;
  callbacks.on_stage_start = [](const Stage& stage, double) {
    if (stage.Name() == "b") throw std::runtime_error("start callback on fire");
  };
  PipelineResult result = Run(TwoStages(), callbacks);
  EXPECT_EQ(result.status, StageStatus::kFailed);
  EXPECT_EQ(result.failed_stage, "b");
  EXPECT_EQ(result.message, "start callback on fire");

  // Inside a stage (progress): that stage fails like any stage exception.
  fs::remove_all(workspace_.work_dir);  // a would resume from the run above.
  callbacks = {};
  callbacks.on_progress = [](const Stage& stage, const ProgressUpdate&, double) {
    if (stage.Name() == "a") throw std::runtime_error("progress callback on fire");
  };
  result = Run(TwoStages(), callbacks);
  EXPECT_EQ(result.status, StageStatus::kFailed);
  EXPECT_EQ(result.failed_stage, "a");
  EXPECT_EQ(result.message, "progress callback on fire");
  ASSERT_EQ(result.stages.size(), 1u);
  EXPECT_EQ(result.stages[0].status, StageStatus::kFailed);
}

TEST(CheckUntilStage, KnowsThePipelineStages) {
  EXPECT_TRUE(CheckUntilStage("").ok());
  EXPECT_TRUE(CheckUntilStage("matching").ok());
  EXPECT_EQ(CheckUntilStage("nonsense").code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reconduit
