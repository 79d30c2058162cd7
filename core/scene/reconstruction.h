// A sparse reconstruction: cameras (intrinsics), registered images (poses), 3-D points with
// the image observations that see them.
//
// Ids: cameras, images and points are addressed by plain integers. An image id is the photo's
// index in the pipeline's input list; a camera id groups photos that share intrinsics; a point
// id is assigned by AddPoint. Keypoint indices refer to the photo's FeatureSet.
// Frames: poses are cam_from_world (core/geometry/rigid3.h); pixel conventions are those of
// core/geometry/camera.h, in ORIGINAL image pixels.
//
// Thread-safety: none; one thread builds and refines a Reconstruction.
#ifndef RECONDUIT_CORE_SCENE_RECONSTRUCTION_H_
#define RECONDUIT_CORE_SCENE_RECONSTRUCTION_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/util/logging.h"

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace reconduit {

constexpr int kInvalidId = -1;

struct Observation {
  int image_id = kInvalidId;
  int keypoint = kInvalidId;
};

struct Point3D {
  Eigen::Vector3d xyz_in_world = Eigen::Vector3d::Zero();
  std::vector<Observation> observations;
  Eigen::Matrix<std::uint8_t, 3, 1> rgb{128, 128, 128};
  // Mean reprojection error over the observations, pixels (set by the caller).
  double error = 0.0;
};

struct RegisteredImage {
  int image_id = kInvalidId;
  int camera_id = kInvalidId;
  std::string name;
  Rigid3d cam_from_world;
  // Keypoint positions in original-image pixels (a copy, so the reconstruction is
  // self-contained for bundle adjustment and export).
  std::vector<Eigen::Vector2d> keypoints;
  // Standard deviation of each keypoint's position in pixels, the weight of its residuals in
  // bundle adjustment (residual / stddev); empty means 1 px for every keypoint.
  std::vector<double> keypoint_stddevs;
  // Point id observed by each keypoint, or kInvalidId.
  std::vector<int> point_for_keypoint;

  double KeypointStddev(int keypoint) const {
    if (keypoint_stddevs.empty()) return 1.0;
    THROW_CHECK_EQ(keypoint_stddevs.size(), keypoints.size()) << "image " << image_id;
    const double stddev = keypoint_stddevs[keypoint];
    // A weight of 1 / stddev: zero, negative or NaN would blow up or flip the residual.
    THROW_CHECK(stddev > 0.0 && std::isfinite(stddev))
        << "image " << image_id << " keypoint " << keypoint << " stddev " << stddev;
    return stddev;
  }

  int NumPoints() const {
    int n = 0;
    for (int id : point_for_keypoint) n += id != kInvalidId;
    return n;
  }
};

class Reconstruction {
 public:
  std::map<int, Camera> cameras;
  std::map<int, RegisteredImage> images;
  std::map<int, Point3D> points;

  // Adds a point observed by `observations` (each image must be registered and its keypoint
  // free); returns its id.
  int AddPoint(const Eigen::Vector3d& xyz, const std::vector<Observation>& observations) {
    const int id = next_point_id_++;
    Point3D& point = points[id];
    point.xyz_in_world = xyz;
    for (const Observation& o : observations) AddObservation(id, o);
    return id;
  }

  void AddObservation(int point_id, const Observation& o) {
    RegisteredImage& image = images.at(o.image_id);
    THROW_CHECK(o.keypoint >= 0 && o.keypoint < static_cast<int>(image.point_for_keypoint.size()));
    THROW_CHECK_EQ(image.point_for_keypoint[o.keypoint], kInvalidId)
        << "keypoint " << o.keypoint << " of image " << o.image_id << " already observes a point";
    image.point_for_keypoint[o.keypoint] = point_id;
    points.at(point_id).observations.push_back(o);
  }

  // Removes one observation; removes the point too when fewer than two remain.
  void DeleteObservation(int point_id, const Observation& o) {
    Point3D& point = points.at(point_id);
    std::erase_if(point.observations, [&](const Observation& x) {
      return x.image_id == o.image_id && x.keypoint == o.keypoint;
    });
    images.at(o.image_id).point_for_keypoint[o.keypoint] = kInvalidId;
    if (point.observations.size() < 2) DeletePoint(point_id);
  }

  void DeletePoint(int point_id) {
    auto it = points.find(point_id);
    if (it == points.end()) return;
    for (const Observation& o : it->second.observations) {
      images.at(o.image_id).point_for_keypoint[o.keypoint] = kInvalidId;
    }
    points.erase(it);
  }

  // Removes a registered image and its observations; points left with fewer than two
  // observations go too. Its camera stays (other images may share it).
  void DeleteImage(int image_id) {
    const RegisteredImage& image = images.at(image_id);
    for (std::size_t k = 0; k < image.point_for_keypoint.size(); ++k) {
      const int point_id = image.point_for_keypoint[k];
      if (point_id != kInvalidId) DeleteObservation(point_id, {image_id, static_cast<int>(k)});
    }
    images.erase(image_id);
  }

  // Reprojection error of one observation in pixels; infinity behind the camera.
  double ReprojectionError(const Point3D& point, const Observation& o) const {
    const RegisteredImage& image = images.at(o.image_id);
    const auto pixel =
        cameras.at(image.camera_id).ImgFromCam(image.cam_from_world * point.xyz_in_world);
    if (!pixel) return std::numeric_limits<double>::infinity();
    return (*pixel - image.keypoints[o.keypoint]).norm();
  }

  // Mean reprojection error over all observations, pixels (0 when empty).
  double MeanReprojectionError() const {
    double sum = 0.0;
    std::size_t n = 0;
    for (const auto& [id, point] : points) {
      for (const Observation& o : point.observations) {
        sum += ReprojectionError(point, o);
        ++n;
      }
    }
    return n == 0 ? 0.0 : sum / n;
  }

  std::size_t NumObservations() const {
    std::size_t n = 0;
    for (const auto& [id, point] : points) n += point.observations.size();
    return n;
  }

 private:
  int next_point_id_ = 0;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SCENE_RECONSTRUCTION_H_
