#include "worker/worker_test_util.h"

#include "core/pipeline/default_stages.h"
#include "core/pipeline/stage.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/pipeline/stages/package_stage.h"
#include "core/scene/render.h"
#include "core/scene/textured_scene.h"
#include "core/util/logging.h"

#include <opencv2/imgcodecs.hpp>
#include <zip.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <stdexcept>
#include <stdlib.h>
#include <thread>
#include <vector>

namespace reconduit {
namespace testing_util {
namespace {

class ToyStage : public Stage {
 public:
  explicit ToyStage(ToyPipeline toy) : toy_(std::move(toy)) {}
  std::string_view Name() const override { return "toy"; }
  std::string_view Title() const override { return "Toy work"; }
  StageResult Run(StageContext& context) const override {
    ++toy_.runs->middle;
    toy_.runs->num_threads = context.options.num_threads;
    if (toy_.on_run) toy_.on_run();
    std::ofstream(context.stage_dir / "toy.txt") << "toy output\n";
    switch (toy_.behaviour) {
      case ToyBehaviour::kSucceed:
        context.progress.Restart(10, "toy items");
        for (int i = 0; i < 10; ++i) context.progress.Advance();
        return StageResult::Success({{"items", 10}});
      case ToyBehaviour::kThrow:
        throw std::runtime_error("toy stage exploded");
      case ToyBehaviour::kWaitForCancel: {
        context.progress.Restart(0, "waiting for a cancel request");
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
        while (std::chrono::steady_clock::now() < deadline) {
          context.cancel.ThrowIfCanceled();
          std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        return StageResult::Failed("no cancel arrived within 30 s");
      }
      case ToyBehaviour::kSleep:
        std::this_thread::sleep_for(std::chrono::milliseconds(toy_.sleep_ms));
        return StageResult::Success({{"slept_ms", toy_.sleep_ms}});
      case ToyBehaviour::kHogMemory: {
        std::vector<std::vector<char>> blocks;
        for (int mib = 0; mib < toy_.hog_mib; mib += 16) {
          context.cancel.ThrowIfCanceled();
          blocks.emplace_back(std::size_t{16} << 20, '\1');  // Touched: resident.
        }
        // Long enough for any watch to sample what is held.
        for (int i = 0; i < 100; ++i) {
          context.cancel.ThrowIfCanceled();
          std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        return StageResult::Success({{"held_mib", toy_.hog_mib}});
      }
      case ToyBehaviour::kLogFlood:
        for (int i = 0; i < toy_.flood_lines; ++i) LOG_INFO << "toy line " << i;
        return StageResult::Success({{"lines", toy_.flood_lines}});
    }
    return {};
  }

 private:
  ToyPipeline toy_;
};

// Counts the real ingest stage's runs.
class CountingIngest : public IngestStage {
 public:
  explicit CountingIngest(std::shared_ptr<ToyStageRuns> runs) : runs_(std::move(runs)) {}
  StageResult Run(StageContext& context) const override {
    ++runs_->ingest;
    return IngestStage::Run(context);
  }

 private:
  std::shared_ptr<ToyStageRuns> runs_;
};

class ThrowingStage : public Stage {
 public:
  std::string_view Name() const override { return "boom"; }
  std::string_view Title() const override { return "Exploding"; }
  StageResult Run(StageContext&) const override { throw std::runtime_error("boom stage exploded"); }
};

}  // namespace

TempDir::TempDir() {
  std::string pattern =
      (std::filesystem::temp_directory_path() / "reconduit-worker-XXXXXX").string();
  if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path_ = pattern;
}

TempDir::~TempDir() {
  std::error_code ignored;
  std::filesystem::remove_all(path_, ignored);
}

std::vector<std::string> WriteBoxRoomPhotos(const std::filesystem::path& dir,
                                            int count,
                                            int width,
                                            int height) {
  THROW_CHECK_GE(count, 2);
  std::filesystem::create_directories(dir);
  const TexturedScene scene = MakeBoxRoomScene(3);
  const Camera camera = Camera::FromFocal(width, height, 0.8 * width);
  RenderOptions options;
  options.samples_per_axis = 1;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<std::string> names;
  for (int i = 0; i < count; ++i) {
    const double angle = (-60.0 + 120.0 * i / (count - 1)) * M_PI / 180.0;
    const Eigen::Vector3d centre(3.6 * std::sin(angle), -3.6 * std::cos(angle), 1.6 + 0.3 * u(rng));
    const Eigen::Vector3d target(0.6 * u(rng), 0.6 * u(rng), 0.4 + 0.3 * u(rng));
    const Rigid3d cam_from_world = Rigid3d::LookAt(centre, target, Eigen::Vector3d::UnitZ());
    const RenderedView view = RenderScene(scene, camera, cam_from_world, options);
    char name[32];
    std::snprintf(name, sizeof(name), "%04d.jpg", i + 1);
    if (!cv::imwrite((dir / name).string(), view.image, {cv::IMWRITE_JPEG_QUALITY, 92})) {
      throw std::runtime_error("cannot write " + (dir / name).string());
    }
    names.push_back(name);
  }
  return names;
}

StageListFactory MakeToyPipeline(const ToyPipeline& toy) {
  return [toy]() -> Result<StageList> {
    StageList stages;
    stages.push_back(std::make_unique<CountingIngest>(toy.runs));
    stages.push_back(std::make_unique<ToyStage>(toy));
    stages.push_back(std::make_unique<PackageStage>());
    return stages;
  };
}

StageListFactory MakeRealStagesThenThrow(const std::string& until) {
  return [until]() -> Result<StageList> {
    Result<StageList> real = CreatePipelineStages(until);
    if (!real.ok()) return real.status();
    StageList stages = std::move(real).value();
    stages.pop_back();  // Packaging comes after the throwing stage.
    stages.push_back(std::make_unique<ThrowingStage>());
    stages.push_back(std::make_unique<PackageStage>());
    return stages;
  };
}

}  // namespace testing_util
}  // namespace reconduit
