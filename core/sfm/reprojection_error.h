// Ceres cost functors for the reprojection error (Ceres-facing: include only from *_ceres.cc).
//
// Parameter blocks, all double arrays:
//   rotation     4  cam_from_world quaternion in Eigen's storage order (x, y, z, w), as
//                   Eigen::Quaterniond::coeffs() holds it; kept unit by
//                   ceres::EigenQuaternionManifold.
//   translation  3  cam_from_world translation.
//   point        3  point in world coordinates.
//   intrinsics   5  [f, cx, cy, k1, k2] in pixels (k1, k2 unitless).
// The residual is the 2-vector  projection - observed  in pixels (ReprojectionError divides
// it by the keypoint's standard deviation), where the projection is
// exactly Camera::ImgFromCam(cam_from_world * point) (core/geometry/camera.h): the same
// quaternion rotation, division by depth, radial distortion 1 + k1 r² + k2 r⁴ on normalised
// coordinates, then f and the principal point. Evaluation fails (returns false) for a point
// at or behind the camera (z <= 0), where ImgFromCam has no value; Ceres then rejects the step.
#ifndef RECONDUIT_CORE_SFM_REPROJECTION_ERROR_H_
#define RECONDUIT_CORE_SFM_REPROJECTION_ERROR_H_

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <ceres/autodiff_cost_function.h>
#include <ceres/cost_function.h>

namespace reconduit {

// Indices into the intrinsics block.
enum IntrinsicsIndex {
  kIntrinsicsFocal = 0,
  kIntrinsicsCx,
  kIntrinsicsCy,
  kIntrinsicsK1,
  kIntrinsicsK2,
  kNumIntrinsics
};

// residual = ImgFromCam(R(q) X + t) - observed; false when the point is not in front.
template <typename T>
bool ProjectionResidual(const T* rotation,
                        const T* translation,
                        const T* point,
                        const T* intrinsics,
                        const Eigen::Vector2d& observed,
                        T* residual) {
  const Eigen::Map<const Eigen::Quaternion<T>> cam_from_world_rotation(rotation);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> cam_from_world_translation(translation);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> point_in_world(point);
  const Eigen::Matrix<T, 3, 1> point_in_cam =
      cam_from_world_rotation * point_in_world + cam_from_world_translation;
  if (!(point_in_cam[2] > T(0))) return false;
  const T x = point_in_cam[0] / point_in_cam[2];
  const T y = point_in_cam[1] / point_in_cam[2];
  const T r2 = x * x + y * y;
  const T radial = T(1) + intrinsics[kIntrinsicsK1] * r2 + intrinsics[kIntrinsicsK2] * r2 * r2;
  const T& f = intrinsics[kIntrinsicsFocal];
  residual[0] = f * (x * radial) + intrinsics[kIntrinsicsCx] - T(observed.x());
  residual[1] = f * (y * radial) + intrinsics[kIntrinsicsCy] - T(observed.y());
  return true;
}

// Full bundle adjustment: pose, point and intrinsics are parameters. The residual is divided
// by the keypoint's positional standard deviation (whitening), so that a keypoint known to
// within 1 px weighs nine times as much as one known to within 3 px.
class ReprojectionError {
 public:
  explicit ReprojectionError(const Eigen::Vector2d& observed, double stddev = 1.0)
      : observed_(observed), inverse_stddev_(1.0 / stddev) {}

  template <typename T>
  bool operator()(const T* rotation,
                  const T* translation,
                  const T* point,
                  const T* intrinsics,
                  T* residual) const {
    if (!ProjectionResidual(rotation, translation, point, intrinsics, observed_, residual)) {
      return false;
    }
    residual[0] *= inverse_stddev_;
    residual[1] *= inverse_stddev_;
    return true;
  }

  // A new cost function; the caller (normally ceres::Problem) takes ownership.
  // @param stddev  the keypoint's positional standard deviation in pixels, > 0.
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed, double stddev = 1.0) {
    return new ceres::AutoDiffCostFunction<ReprojectionError, 2, 4, 3, 3, kNumIntrinsics>(
        new ReprojectionError(observed, stddev));
  }

 private:
  Eigen::Vector2d observed_;
  double inverse_stddev_;
};

// Motion only: the point and the intrinsics are constants stored in the functor, so the
// automatic differentiation carries 7 derivatives instead of 15.
class PoseOnlyReprojectionError {
 public:
  PoseOnlyReprojectionError(const Eigen::Vector2d& observed,
                            const Eigen::Vector3d& point_in_world,
                            const Eigen::Matrix<double, kNumIntrinsics, 1>& intrinsics)
      : observed_(observed), point_in_world_(point_in_world), intrinsics_(intrinsics) {}

  template <typename T>
  bool operator()(const T* rotation, const T* translation, T* residual) const {
    const Eigen::Matrix<T, 3, 1> point = point_in_world_.cast<T>();
    const Eigen::Matrix<T, kNumIntrinsics, 1> intrinsics = intrinsics_.cast<T>();
    return ProjectionResidual(rotation, translation, point.data(), intrinsics.data(), observed_,
                              residual);
  }

  // A new cost function; the caller (normally ceres::Problem) takes ownership.
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed,
                                     const Eigen::Vector3d& point_in_world,
                                     const Eigen::Matrix<double, kNumIntrinsics, 1>& intrinsics) {
    return new ceres::AutoDiffCostFunction<PoseOnlyReprojectionError, 2, 4, 3>(
        new PoseOnlyReprojectionError(observed, point_in_world, intrinsics));
  }

 private:
  Eigen::Vector2d observed_;
  Eigen::Vector3d point_in_world_;
  Eigen::Matrix<double, kNumIntrinsics, 1> intrinsics_;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SFM_REPROJECTION_ERROR_H_
