// Synthetic sparse scenes with exact ground truth: cameras, poses, 3-D points and their
// (optionally noisy, optionally corrupted) observations, for testing estimators and the
// structure-from-motion pipeline. Modelled on COLMAP's SynthesizeDataset and
// SyntheticNoiseOptions.
//
// World frame: right-handed, metres, +z up, the structure centred at the origin (see
// camera_layouts.h). Poses are cam_from_world; pixels follow the camera model's convention
// (pixel centres at integers, core/geometry/camera.h).
//
// Visibility: a point is observed in an image when it is in front of the camera and its
// projection falls inside the image (and inside the radius where the distortion is
// invertible). There is no occlusion test: sparse points on the far side of a box are seen
// through it, as in COLMAP's generator.
//
// Reproducibility: everything is drawn from std::mt19937_64 seeded from `seed` and the stage
// (intrinsics, poses, structure, per-image noise), so the same options give the same scene on
// a given standard library, and changing e.g. the noise does not move the points or cameras.
#ifndef RECONDUIT_CORE_SCENE_SYNTHETIC_H_
#define RECONDUIT_CORE_SCENE_SYNTHETIC_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit {

// Where the camera centres go. All cameras look at the structure.
enum class SyntheticCameraLayout {
  kRing,          // Evenly on a horizontal circle around the structure.
  kArc,           // Evenly on a horizontal arc of `arc_deg` degrees centred on the -y side, first
                  // and last camera at its ends.
  kLine,          // Evenly on a horizontal segment of `line_length` parallel to x on the -y side
                  // (degenerate: collinear centres).
  kRandom,        // Random azimuth, elevation 10-60 degrees, distance 1-1.5 camera_distance.
  kPureRotation,  // Degenerate: all centres at one point on the -y side; only the viewing
                  // directions differ.
};

// What the 3-D points lie on.
enum class SyntheticStructure {
  kBoxes,  // The faces of `num_boxes` randomly placed and rotated boxes: a generic 3-D scene.
  kPlane,  // One plane through the origin, tilted up to 20 degrees from horizontal
           // (degenerate: a homography relates every pair of views).
};

std::string_view SyntheticCameraLayoutName(SyntheticCameraLayout layout);
std::string_view SyntheticStructureName(SyntheticStructure structure);

struct SyntheticSceneOptions {
  // --- Cameras -------------------------------------------------------------------------------
  // Number of images, >= 1.
  int num_cameras = 10;
  SyntheticCameraLayout layout = SyntheticCameraLayout::kRing;
  // Horizontal distance in metres from the structure's centre to the ring or arc, to the line
  // (its nearest point) or to the pure-rotation centre; the minimum 3-D distance for kRandom.
  // Must exceed sqrt(3) scene_radius so every camera is outside the structure.
  double camera_distance = 6.0;
  // Height in metres of the centres above the structure's centre (not used by kRandom).
  double camera_height = 3.0;
  // Angle spanned by kArc, degrees, (0, 360].
  double arc_deg = 90.0;
  // Length of the kLine segment, metres, > 0.
  double line_length = 4.0;
  // Each camera looks at the origin plus a uniform random offset in [-j, j]³, metres, >= 0.
  // kPureRotation instead spreads its targets over the whole structure (+-scene_radius) so
  // that the rotations differ.
  double target_jitter = 0.2;

  // --- Intrinsics ----------------------------------------------------------------------------
  // Image size in pixels, > 0.
  int width = 640;
  int height = 480;
  // Focal length in pixels, > 0 (500 px at 640 wide: a 65 degree horizontal field of view).
  double focal = 500.0;
  // Radial distortion of the nominal camera (see core/geometry/camera.h).
  double k1 = 0.0;
  double k2 = 0.0;
  // Offset in pixels of the nominal principal point from the image centre (a real lens is
  // rarely centred on its sensor; fountain-P11's is 15 px off), finite.
  Eigen::Vector2d principal_point_offset = Eigen::Vector2d::Zero();
  // True: every image has exactly the nominal intrinsics and camera_id 0. False: each image
  // is its own camera (camera_id = image index), drawn around the nominal one with the
  // variations below (which must be 0 when shared).
  bool shared_intrinsics = true;
  // Per image: focal * (1 + U(-v, v)); [0, 0.5).
  double focal_variation = 0.0;
  // Per image: principal point + U(-v, v) pixels in x and y, >= 0.
  double principal_point_variation = 0.0;
  // Per image: k1 + U(-v, v) and k2 + U(-v, v), >= 0.
  double distortion_variation = 0.0;

  // --- Structure -----------------------------------------------------------------------------
  // Number of 3-D points, >= 1 (not all need be observed).
  int num_points = 500;
  SyntheticStructure structure = SyntheticStructure::kBoxes;
  // Number of boxes for kBoxes, >= 1.
  int num_boxes = 4;
  // Half the side in metres of the cube [-r, r]³ holding the structure, > 0.
  double scene_radius = 2.0;

  // --- Observations --------------------------------------------------------------------------
  // Standard deviation of the Gaussian noise added to each pixel coordinate, pixels, >= 0.
  double pixel_noise_stddev = 0.0;
  // Fraction of each image's observations replaced by uniform random pixels in the image,
  // [0, 1]; round(fraction * observations) per image.
  double outlier_fraction = 0.0;
  // Seed of all random draws.
  std::uint64_t seed = 0;

  // False, with a message naming the field, when an option is out of range.
  bool Check(std::string* error) const;
};

// One observation of a point in an image.
struct SyntheticObservation {
  // The observed pixel: the projection plus noise, or a uniform random pixel for an outlier.
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  // The exact (noise-free) projection of points3D[source_point].
  Eigen::Vector2d true_pixel = Eigen::Vector2d::Zero();
  // Index into SyntheticScene::points3D of the point seen here; -1 for an outlier.
  int point_index = -1;
  // The point this observation was generated from, also for outliers (whose pixel was
  // replaced): lets correspondences between images include wrong matches.
  int source_point = -1;
  bool is_outlier = false;
};

struct SyntheticImage {
  // Images with the same camera_id have identical intrinsics.
  int camera_id = 0;
  Camera camera;
  Rigid3d cam_from_world;
  // Ordered by increasing source_point.
  std::vector<SyntheticObservation> observations;
};

struct SyntheticScene {
  std::vector<SyntheticImage> images;
  // World frame, metres.
  std::vector<Eigen::Vector3d> points3D;
};

// Builds a scene from the options. Throws CheckError when options.Check() fails.
SyntheticScene SynthesizeScene(const SyntheticSceneOptions& options);

// A pair of observations of the same source point in two images.
struct SyntheticCorrespondence {
  int observation1 = -1;                             // Index into images[image1].observations.
  int observation2 = -1;                             // Index into images[image2].observations.
  Eigen::Vector2d pixel1 = Eigen::Vector2d::Zero();  // Observed pixels (noisy or outlier).
  Eigen::Vector2d pixel2 = Eigen::Vector2d::Zero();
  int point_index = -1;     // The 3-D point both see, or -1 when either side is an outlier.
  bool is_outlier = false;  // Either observation is an outlier: a wrong match.
};

// The 2-view correspondences between two images: one per source point observed in both, in
// increasing point order, outliers included and flagged. Throws CheckError for bad indices.
std::vector<SyntheticCorrespondence> FindCorrespondences(const SyntheticScene& scene,
                                                         int image1,
                                                         int image2);

// The relative pose cam2_from_cam1 = cam2_from_world * world_from_cam1 of two images.
Rigid3d RelativePose(const SyntheticScene& scene, int image1, int image2);

// Exact projection of a world point into an image: nullopt when behind the camera.
std::optional<Eigen::Vector2d> ProjectPoint(const SyntheticImage& image,
                                            const Eigen::Vector3d& point_in_world);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SCENE_SYNTHETIC_H_
