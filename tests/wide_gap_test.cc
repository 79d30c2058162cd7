// Issue 13, wide baselines, on real photos: the first 8 photos of templeSparseRing (no EXIF)
// stand in three groups around the temple, 55, 117 and 73 deg apart (azimuths -1, 23 | 78,
// 100, 122 | 239, 262, 286 deg). SIFT verifies no pair across a gap, so the model used to
// hold 3 photos; the matching stage's affine-adapted features (core/feature/affine_features.h)
// verify the pair across the 55 deg gap and the model holds the 5 photos on that side. (The
// 117 deg gap shows the temple's other side; across the 73 deg one, templeSR0008 and 0001,
// neither SIFT nor affine-adapted SIFT finds a true match.) The second test takes every
// second photo (8 photos about 45 deg apart), where two pairs 147 and 157 deg apart used to
// verify from exactly 15 false F inliers of 33 putative matches. Skips when
// ../shared/datasets is absent.
#include "core/eval/camera_evaluation.h"
#include "core/io/reconstruction_json.h"
#include "core/pipeline/default_stages.h"
#include "core/pipeline/runner.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
#include <utility>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

const fs::path kTemple = "../shared/datasets/templeSparseRing";

// Runs the sparse pipeline on the temple photos numbered `numbers` in a fresh folder.
class WideGap : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(kTemple / "images") || !fs::exists(kTemple / "gt/templeSR_par.txt")) {
      GTEST_SKIP() << "dataset absent: " << kTemple << " (see ../shared/datasets/README.md)";
    }
    root_ = fs::temp_directory_path() / ("reconduit_wide_gap_test_" + std::to_string(getpid()));
    fs::remove_all(root_);
  }
  void TearDown() override {
    if (!root_.empty()) fs::remove_all(root_);
  }

  void Run(const std::vector<int>& numbers) {
    for (int i : numbers) {
      char name[32];
      std::snprintf(name, sizeof(name), "templeSR%04d.png", i);
      workspace_.images.push_back({kTemple / "images" / name, name});
    }
    workspace_.work_dir = root_ / "work";
    workspace_.output_dir = root_ / "output";
    auto stages = CreatePipelineStages("sparse");
    ASSERT_TRUE(stages.ok()) << stages.status();
    const PipelineResult result =
        RunPipeline(*stages, workspace_, PipelineOptions(), CancelToken());
    ASSERT_EQ(result.status, StageStatus::kSuccess)
        << result.failed_stage << ": " << result.message;
    std::ifstream summary_file(workspace_.StageDir("matching") / "summary.json");
    matching_ = nlohmann::json::parse(summary_file);
    auto model = ReadReconstructionJson(workspace_.StageDir("sparse") / "model_0.json");
    ASSERT_TRUE(model.ok()) << model.status();
    auto truth = ReadGroundTruth(kTemple / "gt/templeSR_par.txt");
    ASSERT_TRUE(truth.ok()) << truth.status();
    evaluation_ = EvaluateCameras(*model, *truth);
  }

  // The verified pair of photos a and b (indices into `numbers`), or null.
  const nlohmann::json* VerifiedPair(int a, int b) const {
    for (const nlohmann::json& pair : matching_.at("pairs")) {
      if (pair.at("image1") == a && pair.at("image2") == b &&
          (pair.at("model") == "fundamental" || pair.at("model") == "homography")) {
        return &pair;
      }
    }
    return nullptr;
  }

  fs::path root_;
  Workspace workspace_;
  nlohmann::json matching_;
  CameraEvaluation evaluation_;
};

TEST_F(WideGap, FirstEightTemplePhotosBridgeTheir55DegreeGap) {
  ASSERT_NO_FATAL_FAILURE(Run({1, 2, 3, 4, 5, 6, 7, 8}));
  // The bridge: photos 1 and 2 (templeSR0002, 0003) verified from affine-adapted features.
  bool bridged = false;
  std::string affine;  // The pairs kept from affine features, for the message.
  for (const nlohmann::json& pair : matching_.at("pairs")) {
    if (!pair.at("affine").get<bool>()) continue;
    affine += " " + pair.at("image1").dump() + "-" + pair.at("image2").dump();
    bridged |=
        pair.at("image1") == 1 && pair.at("image2") == 2 && pair.at("model") == "fundamental";
  }
  EXPECT_TRUE(bridged) << "templeSR0002-0003 (55 deg apart) verified from affine features; "
                       << "affine pairs:" << affine;
  std::printf(
      "first 8 temple photos: %d/8 in the model, relative rotation %.3f deg, focal %.3f "
      "%%\n",
      evaluation_.num_registered, evaluation_.mean_relative_rotation_error_deg,
      evaluation_.mean_focal_error_percent);
  EXPECT_GE(evaluation_.num_registered, 5);
  // Measured: 2.4-2.7 deg and 2.5-3.9 % (2.53 deg, 3.90 % with the final outlier filter; the
  // issue asks for 2 deg and 2 %; see its note).
  EXPECT_LT(evaluation_.mean_relative_rotation_error_deg, 4.0);
  EXPECT_LT(evaluation_.mean_focal_error_percent, 6.0);
}

TEST_F(WideGap, EverySecondTemplePhotoRefusesTheFalsePairsAcrossTheRing) {
  ASSERT_NO_FATAL_FAILURE(Run({1, 3, 5, 7, 9, 11, 13, 15}));
  // templeSR0009-0013 (157 deg apart) and 0001-0013 (147 deg) show opposite sides of the
  // temple: whatever verifies there is false (15 F inliers each when min_num_inliers was 15).
  for (const auto& [a, b] : {std::pair{4, 6}, std::pair{0, 6}}) {
    const nlohmann::json* pair = VerifiedPair(a, b);
    EXPECT_EQ(pair, nullptr) << "a pair across the ring verified: " << pair->dump();
  }
  std::printf(
      "every second temple photo: %d/8 in the model, centre %.3f %% of the radius, relative "
      "rotation %.3f deg, focal %.3f %%\n",
      evaluation_.num_registered, evaluation_.mean_center_error_percent_of_radius,
      evaluation_.mean_relative_rotation_error_deg, evaluation_.mean_focal_error_percent);
  EXPECT_EQ(evaluation_.num_registered, 8);
  // The issue asks for 2 deg and 2 %. Measured: 1.71 deg and 0.72 % (2.72 deg and 1.12 %
  // without the mapper's final outlier filter; 3.05 deg and 2.65 % with the false pairs).
  EXPECT_LT(evaluation_.mean_relative_rotation_error_deg, 2.0);
  EXPECT_LT(evaluation_.mean_focal_error_percent, 2.0);
}

}  // namespace
}  // namespace reconduit
