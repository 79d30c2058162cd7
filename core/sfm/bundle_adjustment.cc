// The Ceres-free part of bundle adjustment: names, option validation and reports. The solver
// itself is in bundle_adjustment_ceres.cc.
#include "core/sfm/bundle_adjustment.h"

#include <cmath>
#include <iomanip>
#include <sstream>

namespace reconduit {
namespace {

// Writes "BundleAdjustmentOptions.<field> <what>, got <value>" and returns false.
template <typename T>
bool Fail(std::string* error,
          std::string_view prefix,
          std::string_view field,
          std::string_view what,
          const T& value) {
  if (error != nullptr) {
    std::ostringstream s;
    s << prefix << "." << field << " " << what << ", got " << value;
    *error = s.str();
  }
  return false;
}

bool IsPositiveFinite(double x) { return std::isfinite(x) && x > 0.0; }
bool IsNonNegativeFinite(double x) { return std::isfinite(x) && x >= 0.0; }

}  // namespace

std::string_view BundleAdjustmentLossName(BundleAdjustmentLoss loss) {
  switch (loss) {
    case BundleAdjustmentLoss::kTrivial:
      return "trivial";
    case BundleAdjustmentLoss::kHuber:
      return "huber";
    case BundleAdjustmentLoss::kCauchy:
      return "cauchy";
  }
  return "unknown";
}

std::string_view BundleAdjustmentLinearSolverName(BundleAdjustmentLinearSolver solver) {
  switch (solver) {
    case BundleAdjustmentLinearSolver::kAuto:
      return "auto";
    case BundleAdjustmentLinearSolver::kDenseSchur:
      return "dense_schur";
    case BundleAdjustmentLinearSolver::kSparseSchur:
      return "sparse_schur";
    case BundleAdjustmentLinearSolver::kIterativeSchur:
      return "iterative_schur";
  }
  return "unknown";
}

bool BundleAdjustmentOptions::Check(std::string* error) const {
  constexpr std::string_view kName = "BundleAdjustmentOptions";
  if (!IsPositiveFinite(loss_scale)) {
    return Fail(error, kName, "loss_scale", "must be positive and finite (pixels)", loss_scale);
  }
  if (max_num_iterations <= 0) {
    return Fail(error, kName, "max_num_iterations", "must be > 0", max_num_iterations);
  }
  if (!IsPositiveFinite(function_tolerance)) {
    return Fail(error, kName, "function_tolerance", "must be > 0", function_tolerance);
  }
  if (!IsNonNegativeFinite(gradient_tolerance)) {
    return Fail(error, kName, "gradient_tolerance", "must be >= 0", gradient_tolerance);
  }
  if (!IsNonNegativeFinite(parameter_tolerance)) {
    return Fail(error, kName, "parameter_tolerance", "must be >= 0", parameter_tolerance);
  }
  if (!(max_solver_time_seconds > 0.0)) {
    return Fail(error, kName, "max_solver_time_seconds", "must be > 0", max_solver_time_seconds);
  }
  if (max_images_dense_schur < 1) {
    return Fail(error, kName, "max_images_dense_schur", "must be >= 1", max_images_dense_schur);
  }
  if (max_images_sparse_schur < max_images_dense_schur) {
    return Fail(error, kName, "max_images_sparse_schur", "must be >= max_images_dense_schur",
                max_images_sparse_schur);
  }
  if (estimate_intrinsics_stddev && loss != BundleAdjustmentLoss::kTrivial) {
    return Fail(error, kName, "estimate_intrinsics_stddev",
                "needs the trivial loss (a robust loss reweighs cost and Jacobian)",
                BundleAdjustmentLossName(loss));
  }
  if (max_observations_for_stddev < 0) {
    return Fail(error, kName, "max_observations_for_stddev", "must be >= 0",
                max_observations_for_stddev);
  }
  if (max_poses_for_stddev < 0) {
    return Fail(error, kName, "max_poses_for_stddev", "must be >= 0", max_poses_for_stddev);
  }
  if (scale_fixing_translation_index < -1 || scale_fixing_translation_index > 2) {
    return Fail(error, kName, "scale_fixing_translation_index", "must be -1 (auto), 0, 1 or 2",
                scale_fixing_translation_index);
  }
  if (scale_fixing_image_id != kInvalidId) {
    if (scale_fixing_image_id < 0) {
      return Fail(error, kName, "scale_fixing_image_id", "must be an image id or kInvalidId (-1)",
                  scale_fixing_image_id);
    }
    for (int id : constant_pose_image_ids) {
      if (id == scale_fixing_image_id) {
        return Fail(error, kName, "scale_fixing_image_id",
                    "must not be in constant_pose_image_ids (its pose is constant already)",
                    scale_fixing_image_id);
      }
    }
  }
  return true;
}

bool PoseRefinementOptions::Check(std::string* error) const {
  constexpr std::string_view kName = "PoseRefinementOptions";
  if (!IsPositiveFinite(loss_scale)) {
    return Fail(error, kName, "loss_scale", "must be positive and finite (pixels)", loss_scale);
  }
  if (max_num_iterations <= 0) {
    return Fail(error, kName, "max_num_iterations", "must be > 0", max_num_iterations);
  }
  if (!IsPositiveFinite(function_tolerance)) {
    return Fail(error, kName, "function_tolerance", "must be > 0", function_tolerance);
  }
  if (!IsNonNegativeFinite(gradient_tolerance)) {
    return Fail(error, kName, "gradient_tolerance", "must be >= 0", gradient_tolerance);
  }
  if (!IsNonNegativeFinite(parameter_tolerance)) {
    return Fail(error, kName, "parameter_tolerance", "must be >= 0", parameter_tolerance);
  }
  return true;
}

std::string BundleAdjustmentSummary::BriefReport() const {
  std::ostringstream s;
  s << "BA " << termination << ": " << num_images << " images (" << num_variable_images
    << " variable), " << num_cameras << " cameras, " << num_points << " points, "
    << num_observations << " obs";
  if (num_skipped_points > 0 || num_skipped_observations > 0) {
    s << " (skipped " << num_skipped_points << " points, " << num_skipped_observations << " obs)";
  }
  s << std::setprecision(4) << ", rms " << initial_rms_px << " -> " << final_rms_px << " px, "
    << num_iterations << " iterations, " << time_seconds << " s";
  if (!linear_solver.empty()) s << " (" << linear_solver << ")";
  if (!success) s << " -- " << message;
  return s.str();
}

}  // namespace reconduit
