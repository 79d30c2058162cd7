#include "core/scene/render.h"
#include "core/util/timer.h"

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>

#include <string>
#include <vector>

namespace reconduit {
namespace {

// The procedural textures must give a feature detector plenty to find: SIFT on a 640x480
// gray render of the default room from each of a few ring views.
TEST(RenderScene, SiftFindsManyFeatures) {
  const TexturedScene scene = MakeBoxRoomScene();
  const Camera camera = Camera::FromFocal(640, 480, 500.0);
  RenderOptions options;
  options.grayscale = true;
  options.num_threads = 1;
  const std::vector<Rigid3d> poses = BoxRoomCameraRing(8);
  for (const int i : {0, 3, 5}) {
    const Timer timer;
    const RenderedView view = RenderScene(scene, camera, poses[i], options);
    RecordProperty("render_640x480_seconds_1_thread_view" + std::to_string(i),
                   std::to_string(timer.ElapsedSeconds()));
    std::vector<cv::KeyPoint> keypoints;
    cv::SIFT::create()->detect(view.image, keypoints);
    EXPECT_GT(keypoints.size(), 300u) << "view " << i;
  }
}

}  // namespace
}  // namespace reconduit
