// Test helpers for the worker tests (a test-only library; not linked into reconduit-worker).
//
#ifndef RECONDUIT_WORKER_WORKER_TEST_UTIL_H_
#define RECONDUIT_WORKER_WORKER_TEST_UTIL_H_

#include "core/io/zip_test_util.h"  // ReadZipEntries, used by the worker tests.
#include "worker/pipeline_driver.h"

#include <atomic>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace reconduit {
namespace testing_util {

// A fresh directory under the system temp folder, removed with everything in it on
// destruction.
class TempDir {
 public:
  TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir();
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// Renders `count` (>= 2) views of the textured box room (MakeBoxRoomScene(3)), `width` x
// `height` pixels with focal 0.8 * width, and writes them as JPEG (quality 92, no EXIF) to
// `dir`/0001.jpg, 0002.jpg, ... Returns the file names in order. The cameras follow
// tests/sparse_pipeline_test: spread over a 120 degree arc 3.6 m from the boxes, at varied
// heights and aimed at varied points (so that focal self-calibration is well posed): the whole
// pipeline, sparse reconstruction included, succeeds on them. Deterministic. Throws on a write
// error.
std::vector<std::string> WriteBoxRoomPhotos(const std::filesystem::path& dir,
                                            int count,
                                            int width = 640,
                                            int height = 480);

// Counts how often each toy stage ran (shared with the factory's stages).
struct ToyStageRuns {
  std::atomic<int> ingest{0};
  std::atomic<int> middle{0};
  // The options' num_threads the middle stage last ran with.
  std::atomic<int> num_threads{-1};
};

// What the middle toy stage does.
enum class ToyBehaviour {
  kSucceed,        // Writes a file, reports progress, succeeds.
  kThrow,          // Throws std::runtime_error("toy stage exploded").
  kWaitForCancel,  // Calls `on_run`, then polls the cancel token for up to 30 s.
  kLogFlood,       // Logs `flood_lines` lines, then succeeds.
  kSleep,          // Calls `on_run`, sleeps `sleep_ms` without looking at the cancel token.
  kHogMemory,      // Touches `hog_mib` MiB in 16 MiB blocks, polling the cancel token between
                   // blocks and for a while after, then frees it all and succeeds.
};

struct ToyPipeline {
  ToyBehaviour behaviour = ToyBehaviour::kSucceed;
  // Called by the middle stage when it starts (kWaitForCancel: the test asks for the cancel).
  std::function<void()> on_run;
  int flood_lines = 1000;
  int sleep_ms = 2000;
  int hog_mib = 256;
  std::shared_ptr<ToyStageRuns> runs = std::make_shared<ToyStageRuns>();
};

// Stages "ingest" (the real one), "toy" (behaves as told) and "package" (the real one).
StageListFactory MakeToyPipeline(const ToyPipeline& toy);

// The real pipeline's stages up to and including `until`, then a stage named "boom" that
// throws, then packaging: for a first run that fails after some real stages finished.
StageListFactory MakeRealStagesThenThrow(const std::string& until);

}  // namespace testing_util
}  // namespace reconduit

#endif  // RECONDUIT_WORKER_WORKER_TEST_UTIL_H_
