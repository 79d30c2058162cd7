#include "core/scene/survey.h"

#include "core/util/logging.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>

namespace reconduit {
namespace {

constexpr double kTileSize = 12.0;  // Metres.

// One tile of the terrain over [min_xy, min_xy + kTileSize]^2: 2 x 2 hills (one in four a
// hollow), each ending at least 0.5 m inside its quarter of the tile, so the tile's height
// is base 0 along its edges and neighbouring tiles meet without a step.
TexturedHeightField MakeTile(const Eigen::Vector2d& min_xy, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  TexturedHeightField tile;
  tile.min_xy = min_xy;
  tile.max_xy = min_xy + Eigen::Vector2d::Constant(kTileSize);
  const double quarter = kTileSize / 2.0;
  for (int i = 0; i < 4; ++i) {
    Hill hill;
    hill.radius = 1.8 + 0.7 * unit(rng);  // <= 2.5: leaves >= 0.5 m to the quarter's edge.
    const double room = quarter / 2.0 - hill.radius - 0.5;
    const Eigen::Vector2d quarter_centre =
        min_xy + Eigen::Vector2d((i % 2 + 0.5) * quarter, (i / 2 + 0.5) * quarter);
    hill.center =
        quarter_centre + room * Eigen::Vector2d(2.0 * unit(rng) - 1.0, 2.0 * unit(rng) - 1.0);
    // Steepest slope 1.717 |height| / radius: at most 0.62 (32 deg).
    hill.height = (unit(rng) < 0.25 ? -1.0 : 1.0) * (0.25 + 0.4 * unit(rng));
    tile.hills.push_back(hill);
  }
  tile.texture.seed = rng();
  tile.texture.cell_size = 0.5;
  tile.texture.base_color = {80.0 + 70.0 * unit(rng), 100.0 + 60.0 * unit(rng),
                             70.0 + 60.0 * unit(rng)};
  return tile;
}

}  // namespace

bool SurveyOptions::Check(std::string* error) const {
  std::ostringstream message;
  if (rows < 1)
    message << "rows must be >= 1";
  else if (cols < 1)
    message << "cols must be >= 1";
  else if (!(spacing > 0.0 && spacing < 1e3))
    message << "spacing must be in (0, 1000) m";
  else if (!(altitude > 2.0 && altitude < 1e3))
    message << "altitude must be in (2, 1000) m";
  else if (!(altitude_jitter >= 0.0 && altitude_jitter <= altitude / 4.0))
    message << "altitude_jitter must be in [0, altitude / 4]";
  else if (!(max_tilt_deg >= 0.0 && max_tilt_deg <= 30.0))
    message << "max_tilt_deg must be in [0, 30]";
  else if (width < 16 || height < 16 || width > 20000 || height > 20000)
    message << "width and height must be in [16, 20000] pixels";
  else if (!(focal > 0.0 && focal < 1e5))
    message << "focal must be in (0, 1e5) pixels";
  if (message.tellp() == 0) return true;
  if (error != nullptr) *error = message.str();
  return false;
}

Survey MakeSurvey(const SurveyOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Survey survey;
  survey.camera = Camera::FromFocal(options.width, options.height, options.focal);
  survey.scene.background_color = {40.0, 30.0, 20.0};

  const double half_x = 0.5 * (options.cols - 1) * options.spacing;
  const double half_y = 0.5 * (options.rows - 1) * options.spacing;
  for (int r = 0; r < options.rows; ++r) {
    for (int c = 0; c < options.cols; ++c) {
      const Eigen::Vector3d centre(
          c * options.spacing - half_x, r * options.spacing - half_y,
          options.altitude + options.altitude_jitter * (2.0 * unit(rng) - 1.0));
      const double tilt = options.max_tilt_deg * M_PI / 180.0 * unit(rng);
      const double azimuth = 2.0 * M_PI * unit(rng);
      const Eigen::Vector3d target =
          centre + Eigen::Vector3d(std::sin(tilt) * std::cos(azimuth),
                                   std::sin(tilt) * std::sin(azimuth), -std::cos(tilt));
      survey.cams_from_world.push_back(Rigid3d::LookAt(centre, target, Eigen::Vector3d::UnitY()));
    }
  }

  // Tiles over everything a photo can see: the view's half-diagonal angle plus the tilt, from
  // the highest camera down to the deepest hollow (0.9 m), plus a metre.
  const double half_diagonal =
      std::atan(std::hypot(options.width, options.height) / (2.0 * options.focal));
  const double reach =
      (options.altitude + options.altitude_jitter + 1.0) *
          std::tan(std::min(half_diagonal + options.max_tilt_deg * M_PI / 180.0, 1.45)) +
      1.0;
  const int tiles_x = static_cast<int>(std::ceil(2.0 * (half_x + reach) / kTileSize));
  const int tiles_y = static_cast<int>(std::ceil(2.0 * (half_y + reach) / kTileSize));
  const Eigen::Vector2d origin(-0.5 * tiles_x * kTileSize, -0.5 * tiles_y * kTileSize);
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      survey.scene.height_fields.push_back(
          MakeTile(origin + kTileSize * Eigen::Vector2d(tx, ty), rng));
    }
  }
  return survey;
}

}  // namespace reconduit
