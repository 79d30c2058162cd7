// A synthetic aerial survey of any size (issue 13's scaling benchmark): a terrain of gentle
// hills tiled over the area the photos see, and a rows x cols grid of cameras looking down
// with a small random tilt and altitude jitter, as a drone's lawn-mower flight takes them.
//
// Each photo overlaps its neighbours like a photogrammetric flight (default: ~75 % forward
// along a row, ~65 % sideways), so it shares a view with ~20-30 others whatever the survey's
// size: a pipeline that scales well spends about the same time per photo on 50 photos as on
// 200. The terrain is made of 12 m tiles (separate height fields, each with its own texture and
// 2 x 2 hills that end inside it, so the surface is continuous across tiles): a ray tests only
// the tiles whose bounding box it crosses, so rendering time per photo does not grow with the
// area either.
#ifndef RECONDUIT_CORE_SCENE_SURVEY_H_
#define RECONDUIT_CORE_SCENE_SURVEY_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/scene/textured_scene.h"

#include <cstdint>
#include <string>
#include <vector>

namespace reconduit {

struct SurveyOptions {
  int rows = 5;                  // Camera rows (along world y), >= 1.
  int cols = 10;                 // Cameras per row (along world x), >= 1.
  double spacing = 3.0;          // Metres between neighbouring cameras, > 0.
  double altitude = 10.0;        // Metres above z = 0, > 2.
  double altitude_jitter = 0.5;  // Metres, uniform in [-jitter, jitter], [0, altitude / 4].
  double max_tilt_deg = 6.0;  // Off-nadir tilt, uniform in [0, max] in a random direction, [0, 30].
  // The photos: width x height pixels, focal in pixels (800 x 600 at 700 px: 60 x 47 deg).
  int width = 800;
  int height = 600;
  double focal = 700.0;
  std::uint64_t seed = 0;

  // False, with a message naming the field, when an option is out of range.
  bool Check(std::string* error) const;
};

struct Survey {
  TexturedScene scene;
  Camera camera;
  std::vector<Rigid3d> cams_from_world;  // Row by row, rows * cols of them.
};

// Throws CheckError when the options fail Check(). Deterministic in the options.
Survey MakeSurvey(const SurveyOptions& options);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SCENE_SURVEY_H_
