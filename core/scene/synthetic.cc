#include "core/scene/synthetic.h"

#include "core/scene/camera_layouts.h"
#include "core/util/logging.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <sstream>

namespace reconduit {
namespace {

// Independent random streams per generation stage, so that e.g. more noise does not move the
// cameras, and per image so that outliers in one image do not change another's noise.
enum class Stage : std::uint64_t { kIntrinsics = 1, kPoses, kStructure, kObservations };

std::mt19937_64 StageRng(std::uint64_t seed, Stage stage, std::uint64_t index = 0) {
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                    static_cast<std::uint32_t>(stage), static_cast<std::uint32_t>(index),
                    static_cast<std::uint32_t>(index >> 32)};
  return std::mt19937_64(seq);
}

double Uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

Eigen::Quaterniond RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  // A normalised 4-D Gaussian is uniform on the rotation group.
  return Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
}

std::vector<Camera> MakeCameras(const SyntheticSceneOptions& options) {
  Camera nominal = Camera::FromFocal(options.width, options.height, options.focal);
  nominal.k1 = options.k1;
  nominal.k2 = options.k2;
  nominal.cx += options.principal_point_offset.x();
  nominal.cy += options.principal_point_offset.y();
  std::vector<Camera> cameras(options.num_cameras, nominal);
  if (options.shared_intrinsics) return cameras;
  std::mt19937_64 rng = StageRng(options.seed, Stage::kIntrinsics);
  for (Camera& camera : cameras) {
    const double f = options.focal_variation;
    const double c = options.principal_point_variation;
    const double k = options.distortion_variation;
    camera.focal *= 1.0 + Uniform(rng, -f, f);
    camera.cx += Uniform(rng, -c, c);
    camera.cy += Uniform(rng, -c, c);
    camera.k1 += Uniform(rng, -k, k);
    camera.k2 += Uniform(rng, -k, k);
  }
  return cameras;
}

std::vector<Rigid3d> MakePoses(const SyntheticSceneOptions& options) {
  std::mt19937_64 rng = StageRng(options.seed, Stage::kPoses);
  const int n = options.num_cameras;
  const double jitter = options.target_jitter;
  const auto random_target = [&](double half_size) -> Eigen::Vector3d {
    return {Uniform(rng, -half_size, half_size), Uniform(rng, -half_size, half_size),
            Uniform(rng, -half_size, half_size)};
  };

  std::vector<Eigen::Vector3d> centers;
  switch (options.layout) {
    case SyntheticCameraLayout::kRing:
    case SyntheticCameraLayout::kArc: {
      const double arc = options.layout == SyntheticCameraLayout::kRing ? 360.0 : options.arc_deg;
      const double start = options.layout == SyntheticCameraLayout::kRing ? 0.0 : -90.0 - arc / 2;
      for (const Rigid3d& pose : CamerasOnArc(n, Eigen::Vector3d::Zero(), options.camera_distance,
                                              options.camera_height, arc, start)) {
        centers.push_back(pose.CenterInWorld());
      }
      break;
    }
    case SyntheticCameraLayout::kLine: {
      const Eigen::Vector3d middle(0.0, -options.camera_distance, options.camera_height);
      const Eigen::Vector3d half(0.5 * options.line_length, 0.0, 0.0);
      for (const Rigid3d& pose :
           CamerasOnLine(n, Eigen::Vector3d::Zero(), middle - half, middle + half)) {
        centers.push_back(pose.CenterInWorld());
      }
      break;
    }
    case SyntheticCameraLayout::kRandom:
      for (int i = 0; i < n; ++i) {
        const double azimuth = Uniform(rng, 0.0, 2.0 * M_PI);
        const double elevation = Uniform(rng, 10.0, 60.0) * M_PI / 180.0;
        const double distance = options.camera_distance * Uniform(rng, 1.0, 1.5);
        centers.push_back(distance * Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                                     std::cos(elevation) * std::sin(azimuth),
                                                     std::sin(elevation)));
      }
      break;
    case SyntheticCameraLayout::kPureRotation:
      centers.assign(n, Eigen::Vector3d(0.0, -options.camera_distance, options.camera_height));
      break;
  }

  std::vector<Rigid3d> cams_from_world;
  cams_from_world.reserve(n);
  for (const Eigen::Vector3d& center : centers) {
    const Eigen::Vector3d target = options.layout == SyntheticCameraLayout::kPureRotation
                                       ? random_target(options.scene_radius)
                                       : random_target(jitter);
    cams_from_world.push_back(Rigid3d::LookAt(center, target, kSyntheticWorldUp));
  }
  return cams_from_world;
}

// Points uniform over the faces of random boxes inside [-r, r]³.
std::vector<Eigen::Vector3d> PointsOnBoxes(const SyntheticSceneOptions& options,
                                           std::mt19937_64& rng) {
  const double r = options.scene_radius;
  struct Box {
    Eigen::Matrix3d world_from_box;
    Eigen::Vector3d center;
    Eigen::Vector3d half_size;
    double area;
  };
  std::vector<Box> boxes;
  for (int i = 0; i < options.num_boxes; ++i) {
    Box box;
    box.world_from_box = RandomRotation(rng).toRotationMatrix();
    box.half_size = {Uniform(rng, 0.15, 0.45) * r, Uniform(rng, 0.15, 0.45) * r,
                     Uniform(rng, 0.15, 0.45) * r};
    // The box's circumradius is at most 0.45 sqrt(3) r < 0.8 r; keep it inside the cube.
    box.center = {Uniform(rng, -0.2, 0.2) * r, Uniform(rng, -0.2, 0.2) * r,
                  Uniform(rng, -0.2, 0.2) * r};
    const Eigen::Vector3d& h = box.half_size;
    box.area = 8.0 * (h.x() * h.y() + h.y() * h.z() + h.z() * h.x());
    boxes.push_back(box);
  }
  std::vector<double> areas;
  for (const Box& box : boxes) areas.push_back(box.area);
  std::discrete_distribution<int> pick_box(areas.begin(), areas.end());

  std::vector<Eigen::Vector3d> points;
  points.reserve(options.num_points);
  for (int i = 0; i < options.num_points; ++i) {
    const Box& box = boxes[pick_box(rng)];
    const Eigen::Vector3d& h = box.half_size;
    // Pick a face pair by area (faces normal to axis a have area 4 h_b h_c), then a side.
    const double face_areas[3] = {h.y() * h.z(), h.x() * h.z(), h.x() * h.y()};
    std::discrete_distribution<int> pick_axis(face_areas, face_areas + 3);
    const int axis = pick_axis(rng);
    Eigen::Vector3d local(Uniform(rng, -h.x(), h.x()), Uniform(rng, -h.y(), h.y()),
                          Uniform(rng, -h.z(), h.z()));
    local[axis] = Uniform(rng, 0.0, 1.0) < 0.5 ? -h[axis] : h[axis];
    points.push_back(box.center + box.world_from_box * local);
  }
  return points;
}

// Points uniform over a square of side 2r in a plane through the origin, tilted up to 20
// degrees from horizontal so that it faces cameras placed above it.
std::vector<Eigen::Vector3d> PointsOnPlane(const SyntheticSceneOptions& options,
                                           std::mt19937_64& rng) {
  const double r = options.scene_radius;
  const double tilt_azimuth = Uniform(rng, 0.0, M_PI);
  const Eigen::Vector3d tilt_axis(std::cos(tilt_azimuth), std::sin(tilt_azimuth), 0.0);
  const Eigen::Matrix3d world_from_plane =
      Eigen::AngleAxisd(Uniform(rng, -20.0, 20.0) * M_PI / 180.0, tilt_axis).toRotationMatrix();
  std::vector<Eigen::Vector3d> points;
  points.reserve(options.num_points);
  for (int i = 0; i < options.num_points; ++i) {
    points.push_back(world_from_plane *
                     Eigen::Vector3d(Uniform(rng, -r, r), Uniform(rng, -r, r), 0.0));
  }
  return points;
}

// Observations of all visible points in one image, with noise and outliers.
std::vector<SyntheticObservation> Observe(const SyntheticSceneOptions& options,
                                          const SyntheticImage& image,
                                          const std::vector<Eigen::Vector3d>& points3D,
                                          int image_index) {
  const Camera& camera = image.camera;
  std::vector<SyntheticObservation> observations;
  for (int p = 0; p < static_cast<int>(points3D.size()); ++p) {
    const Eigen::Vector3d point_in_cam = image.cam_from_world * points3D[p];
    const auto pixel = camera.ImgFromCam(point_in_cam);
    if (!pixel || !camera.InImage(*pixel)) continue;
    // With negative distortion, points far outside the field of view can fold back into the
    // image; a real lens never shows them there, so keep only invertible projections.
    const auto ray = camera.CamFromImg(*pixel);
    const Eigen::Vector2d normalized = point_in_cam.head<2>() / point_in_cam.z();
    if (!ray || (ray->head<2>() - normalized).norm() > 1e-6 * (1.0 + normalized.norm())) continue;
    SyntheticObservation observation;
    observation.true_pixel = *pixel;
    observation.pixel = *pixel;
    observation.point_index = p;
    observation.source_point = p;
    observations.push_back(observation);
  }

  std::mt19937_64 rng = StageRng(options.seed, Stage::kObservations, image_index);
  if (options.pixel_noise_stddev > 0.0) {
    std::normal_distribution<double> noise(0.0, options.pixel_noise_stddev);
    for (SyntheticObservation& observation : observations) {
      observation.pixel += Eigen::Vector2d(noise(rng), noise(rng));
    }
  }
  const int num_outliers =
      static_cast<int>(std::lround(options.outlier_fraction * observations.size()));
  std::vector<int> order(observations.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  for (int i = 0; i < num_outliers; ++i) {
    SyntheticObservation& observation = observations[order[i]];
    observation.pixel = {Uniform(rng, -0.5, camera.width - 0.5),
                         Uniform(rng, -0.5, camera.height - 0.5)};
    observation.point_index = -1;
    observation.is_outlier = true;
  }
  return observations;
}

void CheckImageIndex(const SyntheticScene& scene, int image) {
  THROW_CHECK(image >= 0 && image < static_cast<int>(scene.images.size()))
      << "image " << image << " of " << scene.images.size();
}

}  // namespace

std::string_view SyntheticCameraLayoutName(SyntheticCameraLayout layout) {
  switch (layout) {
    case SyntheticCameraLayout::kRing:
      return "ring";
    case SyntheticCameraLayout::kArc:
      return "arc";
    case SyntheticCameraLayout::kLine:
      return "line";
    case SyntheticCameraLayout::kRandom:
      return "random";
    case SyntheticCameraLayout::kPureRotation:
      return "pure_rotation";
  }
  return "unknown";
}

std::string_view SyntheticStructureName(SyntheticStructure structure) {
  switch (structure) {
    case SyntheticStructure::kBoxes:
      return "boxes";
    case SyntheticStructure::kPlane:
      return "plane";
  }
  return "unknown";
}

bool SyntheticSceneOptions::Check(std::string* error) const {
  std::ostringstream message;
  const auto finite = [](double v) { return std::isfinite(v); };
  if (num_cameras < 1) {
    message << "num_cameras must be >= 1, got " << num_cameras;
  } else if (!finite(scene_radius) || scene_radius <= 0.0) {
    message << "scene_radius must be positive, got " << scene_radius;
  } else if (!finite(camera_distance) || camera_distance <= std::sqrt(3.0) * scene_radius) {
    message << "camera_distance must exceed sqrt(3) * scene_radius = "
            << std::sqrt(3.0) * scene_radius << " (cameras outside the structure), got "
            << camera_distance;
  } else if (!finite(camera_height)) {
    message << "camera_height must be finite";
  } else if (!finite(arc_deg) || arc_deg <= 0.0 || arc_deg > 360.0) {
    message << "arc_deg must be in (0, 360], got " << arc_deg;
  } else if (!finite(line_length) || line_length <= 0.0) {
    message << "line_length must be positive, got " << line_length;
  } else if (!finite(target_jitter) || target_jitter < 0.0) {
    message << "target_jitter must be >= 0, got " << target_jitter;
  } else if (width <= 0 || height <= 0) {
    message << "width and height must be positive, got " << width << "x" << height;
  } else if (!finite(focal) || focal <= 0.0) {
    message << "focal must be positive, got " << focal;
  } else if (!finite(k1) || !finite(k2)) {
    message << "k1 and k2 must be finite";
  } else if (!principal_point_offset.allFinite()) {
    message << "principal_point_offset must be finite";
  } else if (!finite(focal_variation) || focal_variation < 0.0 || focal_variation >= 0.5) {
    message << "focal_variation must be in [0, 0.5), got " << focal_variation;
  } else if (!finite(principal_point_variation) || principal_point_variation < 0.0) {
    message << "principal_point_variation must be >= 0, got " << principal_point_variation;
  } else if (!finite(distortion_variation) || distortion_variation < 0.0) {
    message << "distortion_variation must be >= 0, got " << distortion_variation;
  } else if (shared_intrinsics && (focal_variation > 0.0 || principal_point_variation > 0.0 ||
                                   distortion_variation > 0.0)) {
    message << "focal_variation, principal_point_variation and distortion_variation need "
               "shared_intrinsics = false";
  } else if (num_points < 1) {
    message << "num_points must be >= 1, got " << num_points;
  } else if (num_boxes < 1) {
    message << "num_boxes must be >= 1, got " << num_boxes;
  } else if (!finite(pixel_noise_stddev) || pixel_noise_stddev < 0.0) {
    message << "pixel_noise_stddev must be >= 0, got " << pixel_noise_stddev;
  } else if (!(outlier_fraction >= 0.0 && outlier_fraction <= 1.0)) {
    message << "outlier_fraction must be in [0, 1], got " << outlier_fraction;
  } else {
    return true;
  }
  if (error != nullptr) *error = message.str();
  return false;
}

SyntheticScene SynthesizeScene(const SyntheticSceneOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;

  SyntheticScene scene;
  std::mt19937_64 structure_rng = StageRng(options.seed, Stage::kStructure);
  scene.points3D = options.structure == SyntheticStructure::kPlane
                       ? PointsOnPlane(options, structure_rng)
                       : PointsOnBoxes(options, structure_rng);

  const std::vector<Camera> cameras = MakeCameras(options);
  const std::vector<Rigid3d> poses = MakePoses(options);
  scene.images.resize(options.num_cameras);
  for (int i = 0; i < options.num_cameras; ++i) {
    SyntheticImage& image = scene.images[i];
    image.camera_id = options.shared_intrinsics ? 0 : i;
    image.camera = cameras[i];
    image.cam_from_world = poses[i];
    image.observations = Observe(options, image, scene.points3D, i);
  }
  return scene;
}

std::vector<SyntheticCorrespondence> FindCorrespondences(const SyntheticScene& scene,
                                                         int image1,
                                                         int image2) {
  CheckImageIndex(scene, image1);
  CheckImageIndex(scene, image2);
  const auto& observations1 = scene.images[image1].observations;
  const auto& observations2 = scene.images[image2].observations;
  // Both lists are sorted by source point: merge them.
  std::vector<SyntheticCorrespondence> correspondences;
  std::size_t i = 0, j = 0;
  while (i < observations1.size() && j < observations2.size()) {
    const SyntheticObservation& a = observations1[i];
    const SyntheticObservation& b = observations2[j];
    if (a.source_point < b.source_point) {
      ++i;
    } else if (b.source_point < a.source_point) {
      ++j;
    } else {
      SyntheticCorrespondence c;
      c.observation1 = static_cast<int>(i);
      c.observation2 = static_cast<int>(j);
      c.pixel1 = a.pixel;
      c.pixel2 = b.pixel;
      c.is_outlier = a.is_outlier || b.is_outlier;
      c.point_index = c.is_outlier ? -1 : a.source_point;
      correspondences.push_back(c);
      ++i;
      ++j;
    }
  }
  return correspondences;
}

Rigid3d RelativePose(const SyntheticScene& scene, int image1, int image2) {
  CheckImageIndex(scene, image1);
  CheckImageIndex(scene, image2);
  return scene.images[image2].cam_from_world * scene.images[image1].cam_from_world.Inverse();
}

std::optional<Eigen::Vector2d> ProjectPoint(const SyntheticImage& image,
                                            const Eigen::Vector3d& point_in_world) {
  return image.camera.ImgFromCam(image.cam_from_world * point_in_world);
}

}  // namespace reconduit
