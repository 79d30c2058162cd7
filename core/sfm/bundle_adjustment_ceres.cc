// Bundle adjustment with Ceres: the only implementation of bundle_adjustment.h and, with
// reprojection_error.h, the only code in core/ that sees Ceres types.
//
// The solver works on copies of the parameters (poses, intrinsics, points) held here, and
// writes them back into the Reconstruction only after a usable solve. That keeps the
// reconstruction untouched when the solve fails or is canceled, and keeps constant
// parameters bit-identical.
#include "core/sfm/bundle_adjustment.h"
#include "core/sfm/reprojection_error.h"
#include "core/util/logging.h"
#include "core/util/parallel.h"
#include "core/util/timer.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <ceres/covariance.h>
#include <ceres/iteration_callback.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/ordered_groups.h>
#include <ceres/problem.h>
#include <ceres/solver.h>
#include <ceres/types.h>

#include <array>
#include <cmath>
#include <glog/logging.h>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <sstream>
#include <unordered_map>
#include <utility>
#include <vector>

namespace reconduit {
namespace {

using IntrinsicsBlock = std::array<double, kNumIntrinsics>;

// Ceres's loss for our enum; nullptr is Ceres's trivial loss. Caller owns the result.
std::unique_ptr<ceres::LossFunction> CreateLoss(BundleAdjustmentLoss loss, double scale) {
  switch (loss) {
    case BundleAdjustmentLoss::kTrivial:
      return nullptr;
    case BundleAdjustmentLoss::kHuber:
      return std::make_unique<ceres::HuberLoss>(scale);
    case BundleAdjustmentLoss::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(scale);
  }
  return nullptr;
}

IntrinsicsBlock IntrinsicsFromCamera(const Camera& camera) {
  return {camera.focal, camera.cx, camera.cy, camera.k1, camera.k2};
}

void IntrinsicsToCamera(const IntrinsicsBlock& block, Camera* camera) {
  camera->focal = block[kIntrinsicsFocal];
  camera->cx = block[kIntrinsicsCx];
  camera->cy = block[kIntrinsicsCy];
  camera->k1 = block[kIntrinsicsK1];
  camera->k2 = block[kIntrinsicsK2];
}

// Polls the cancel token once per solver iteration (and after the initial evaluation) and
// logs progress at debug level. Returning SOLVER_ABORT makes Ceres stop with USER_FAILURE
// without updating the parameter blocks.
class CancelAndLogCallback : public ceres::IterationCallback {
 public:
  CancelAndLogCallback(const CancelToken& cancel, std::string_view what)
      : cancel_(cancel), what_(what) {}

  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    LOG_DEBUG << what_ << " iteration " << summary.iteration << ": cost " << summary.cost
              << ", change " << summary.cost_change << ", |gradient| " << summary.gradient_max_norm
              << ", |step| " << summary.step_norm << ", radius " << summary.trust_region_radius
              << (summary.step_is_successful ? "" : " (rejected)");
    if (cancel_.IsCanceled()) {
      canceled_ = true;
      return ceres::SOLVER_ABORT;
    }
    return ceres::SOLVER_CONTINUE;
  }

  bool canceled() const { return canceled_; }

 private:
  const CancelToken& cancel_;
  std::string_view what_;
  bool canceled_ = false;
};

// One pose in the problem: a copy of cam_from_world in Ceres's parameter layout.
struct PoseBlock {
  std::array<double, 4> rotation{};  // Eigen order x, y, z, w.
  std::array<double, 3> translation{};
  bool constant = true;
};

PoseBlock PoseBlockFromRigid(const Rigid3d& cam_from_world) {
  PoseBlock block;
  Eigen::Map<Eigen::Vector4d>(block.rotation.data()) = cam_from_world.rotation.coeffs();
  Eigen::Map<Eigen::Vector3d>(block.translation.data()) = cam_from_world.translation;
  return block;
}

void PoseBlockToRigid(const PoseBlock& block, Rigid3d* cam_from_world) {
  cam_from_world->rotation.coeffs() = Eigen::Map<const Eigen::Vector4d>(block.rotation.data());
  cam_from_world->rotation.normalize();
  cam_from_world->translation = Eigen::Map<const Eigen::Vector3d>(block.translation.data());
}

// An observation that entered the problem.
struct UsedObservation {
  int point_id;
  int image_id;
  int keypoint;
};

// RMS reprojection error in pixels of the used observations, as Camera::ImgFromCam computes
// it; an observation behind its camera counts as infinite.
double RmsReprojectionError(const Reconstruction& reconstruction,
                            const std::vector<UsedObservation>& observations) {
  if (observations.empty()) return 0.0;
  double sum = 0.0;
  for (const UsedObservation& o : observations) {
    const double e = reconstruction.ReprojectionError(reconstruction.points.at(o.point_id),
                                                      Observation{o.image_id, o.keypoint});
    sum += e * e;
  }
  return std::sqrt(sum / static_cast<double>(observations.size()));
}

// Ceres logs through glog: its warnings (e.g. "Linear solver failure ... dense Cholesky
// factorization", from which Levenberg-Marquardt recovers by shrinking its trust region) would
// reach terminals and job logs unformatted and alarming. They pass only when our own log level
// is debug; glog errors always pass. Decided once per process, at the first adjustment.
void QuietCeresUnlessDebugging() {
  static std::once_flag once;
  std::call_once(once, [] {
    FLAGS_minloglevel = MinLogLevel() <= LogLevel::kDebug ? google::GLOG_INFO : google::GLOG_ERROR;
  });
}

// The linear solver for `num_variable_images` under the options.
void ChooseLinearSolver(const BundleAdjustmentOptions& options,
                        int num_variable_images,
                        ceres::Solver::Options* solver_options) {
  BundleAdjustmentLinearSolver choice = options.linear_solver;
  if (choice == BundleAdjustmentLinearSolver::kAuto) {
    if (num_variable_images <= options.max_images_dense_schur) {
      choice = BundleAdjustmentLinearSolver::kDenseSchur;
    } else if (num_variable_images <= options.max_images_sparse_schur) {
      choice = BundleAdjustmentLinearSolver::kSparseSchur;
    } else {
      choice = BundleAdjustmentLinearSolver::kIterativeSchur;
    }
  }
  if (choice == BundleAdjustmentLinearSolver::kSparseSchur) {
    if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
      solver_options->sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
    } else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE)) {
      solver_options->sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
    } else {
      choice = BundleAdjustmentLinearSolver::kIterativeSchur;
    }
  }
  switch (choice) {
    case BundleAdjustmentLinearSolver::kAuto:
    case BundleAdjustmentLinearSolver::kDenseSchur:
      solver_options->linear_solver_type = ceres::DENSE_SCHUR;
      break;
    case BundleAdjustmentLinearSolver::kSparseSchur:
      solver_options->linear_solver_type = ceres::SPARSE_SCHUR;
      break;
    case BundleAdjustmentLinearSolver::kIterativeSchur:
      solver_options->linear_solver_type = ceres::ITERATIVE_SCHUR;
      solver_options->preconditioner_type = ceres::SCHUR_JACOBI;
      break;
  }
}

// The translation coordinate of `image` to hold constant to fix the scale: the largest
// coordinate of the vector from its centre to the reference centre, in its camera frame
// (holding a coordinate that is near zero would leave the scale free).
int AutoScaleFixingIndex(const Rigid3d& cam_from_world, const Rigid3d* reference) {
  const Eigen::Vector3d direction =
      reference != nullptr ? Eigen::Vector3d(cam_from_world * reference->CenterInWorld())
                           : cam_from_world.translation;
  int index = 0;
  direction.cwiseAbs().maxCoeff(&index);
  return index;
}

std::string TerminationName(ceres::TerminationType type) {
  return ceres::TerminationTypeToString(type);
}

// A camera's intrinsics covariance, (JᵀJ)⁻¹ of the whitened residuals, in ambient coordinates
// (entries a subset manifold holds have zero rows and columns).
using IntrinsicsCovariance = Eigen::Matrix<double, kNumIntrinsics, kNumIntrinsics, Eigen::RowMajor>;

// By ceres::Covariance (sparse QR of the whole Jacobian; detects rank deficiency).
bool CovarianceBySparseQr(int num_threads,
                          const std::map<int, double*>& wanted,
                          ceres::Problem* problem,
                          std::map<int, IntrinsicsCovariance>* out) {
  std::vector<std::pair<const double*, const double*>> blocks;
  for (const auto& [camera_id, block] : wanted) blocks.emplace_back(block, block);
  ceres::Covariance::Options covariance_options;
  covariance_options.algorithm_type = ceres::SPARSE_QR;
  covariance_options.num_threads = num_threads;
  ceres::Covariance covariance(covariance_options);
  if (!covariance.Compute(blocks, problem)) return false;
  for (const auto& [camera_id, block] : wanted) {
    IntrinsicsCovariance c;
    if (covariance.GetCovarianceBlock(block, block, c.data())) (*out)[camera_id] = c;
  }
  return true;
}

// By the Schur complement, for problems too large for a QR of the whole Jacobian. With the
// columns ordered [intrinsics, poses | points], JᵀJ = [U W; Wᵀ V] with V block-diagonal
// (3 x 3 a point), and the covariance of the camera side is the inverse of
// S = U - W V⁻¹ Wᵀ (Triggs et al., "Bundle Adjustment — A Modern Synthesis", §6.1). S is
// dense, (6 n + 5 c)², and factored by Cholesky after a Jacobi scaling (focal, quaternion and
// distortion columns differ by orders of magnitude); a reciprocal condition number below
// 1e-14 (a free gauge) means no estimate. A point whose V is singular (rays nearly parallel)
// enters through the pseudo-inverse of its V, as the QR's rank detection would treat it.
bool CovarianceBySchur(int num_threads,
                       const std::map<int, double*>& wanted,
                       const std::vector<double*>& points,
                       int max_poses,
                       ceres::Problem* problem,
                       std::map<int, IntrinsicsCovariance>* out) {
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.num_threads = num_threads;
  evaluate.apply_loss_function = false;
  std::set<const double*> camera_side;
  std::vector<int> offsets;  // Column of each wanted block, in `wanted`'s order.
  int num_camera_columns = 0;
  for (const auto& [camera_id, block] : wanted) {
    evaluate.parameter_blocks.push_back(block);
    camera_side.insert(block);
    offsets.push_back(num_camera_columns);
    num_camera_columns += problem->ParameterBlockTangentSize(block);
  }
  const std::set<const double*> is_point(points.begin(), points.end());
  std::vector<double*> all;
  problem->GetParameterBlocks(&all);
  int pose_blocks = 0;
  for (double* block : all) {
    if (problem->IsParameterBlockConstant(block) || is_point.contains(block) ||
        camera_side.contains(block)) {
      continue;
    }
    evaluate.parameter_blocks.push_back(block);
    num_camera_columns += problem->ParameterBlockTangentSize(block);
    ++pose_blocks;
  }
  if (pose_blocks / 2 > max_poses) {  // A rotation and a translation block a pose.
    LOG_INFO << "BA: " << pose_blocks / 2 << " variable poses, more than " << max_poses
             << ": intrinsics precision not estimated";
    return false;
  }
  int num_point_columns = 0;
  for (double* block : points) {
    if (problem->IsParameterBlockConstant(block)) continue;
    THROW_CHECK(problem->ParameterBlockTangentSize(block) == 3) << "a point block of size 3";
    evaluate.parameter_blocks.push_back(block);
    num_point_columns += 3;
  }
  using SparseMatrix = Eigen::SparseMatrix<double>;  // Column-major: column blocks are cheap.
  SparseMatrix camera_jacobian, point_jacobian;
  {
    // Scoped: Ceres' CRS form and the whole column-major Jacobian go before the products
    // below (each as large as the two parts together: 1.5 M observations of 200 photos).
    ceres::CRSMatrix crs;
    if (!problem->Evaluate(evaluate, nullptr, nullptr, nullptr, &crs)) return false;
    const SparseMatrix jacobian = Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor>>(
        crs.num_rows, crs.num_cols, static_cast<Eigen::Index>(crs.values.size()), crs.rows.data(),
        crs.cols.data(), crs.values.data());
    crs = ceres::CRSMatrix();
    camera_jacobian = jacobian.leftCols(num_camera_columns);
    point_jacobian = jacobian.rightCols(num_point_columns);
  }

  std::vector<Eigen::Triplet<double>> inverse_v;
  inverse_v.reserve(static_cast<std::size_t>(num_point_columns) * 3);
  for (int j = 0; j < num_point_columns; j += 3) {
    // Dot products of the point's three sparse columns. (Not columns.transpose() * columns:
    // that transpose allocates and clears one entry per residual row, for every point, and
    // took 100 of the 110 s of the final adjustment of 100 rendered photos, 631k observations.)
    Eigen::Matrix3d v;
    for (int r = 0; r < 3; ++r) {
      for (int c = r; c < 3; ++c) {
        v(r, c) = v(c, r) = point_jacobian.col(j + r).dot(point_jacobian.col(j + c));
      }
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(v);
    const Eigen::Vector3d values = eigen.eigenvalues();
    Eigen::Vector3d inverse_values = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      if (values(k) > 1e-12 * values(2)) inverse_values(k) = 1.0 / values(k);
    }
    const Eigen::Matrix3d inverse =
        eigen.eigenvectors() * inverse_values.asDiagonal() * eigen.eigenvectors().transpose();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) inverse_v.emplace_back(j + r, j + c, inverse(r, c));
    }
  }
  SparseMatrix v_inverse(num_point_columns, num_point_columns);
  v_inverse.setFromTriplets(inverse_v.begin(), inverse_v.end());
  const SparseMatrix w = camera_jacobian.transpose() * point_jacobian;
  const SparseMatrix w_v_inverse = w * v_inverse;
  Eigen::MatrixXd schur = Eigen::MatrixXd(camera_jacobian.transpose() * camera_jacobian);
  schur -= Eigen::MatrixXd(w_v_inverse * w.transpose());

  Eigen::VectorXd scale = schur.diagonal();
  for (Eigen::Index i = 0; i < scale.size(); ++i) {
    if (!(scale(i) > 0.0)) return false;  // A column without information.
    scale(i) = 1.0 / std::sqrt(scale(i));
  }
  const Eigen::MatrixXd scaled = scale.asDiagonal() * schur * scale.asDiagonal();
  const Eigen::LLT<Eigen::MatrixXd> cholesky(scaled);
  if (cholesky.info() != Eigen::Success || !(cholesky.rcond() >= 1e-14)) return false;
  std::size_t k = 0;
  for (const auto& [camera_id, block] : wanted) {
    const int offset = offsets[k++];
    const int size = problem->ParameterBlockTangentSize(block);
    Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(num_camera_columns, size);
    for (int i = 0; i < size; ++i) unit(offset + i, i) = 1.0;
    const Eigen::MatrixXd tangent = scale.segment(offset, size).asDiagonal() *
                                    Eigen::MatrixXd(cholesky.solve(unit)).middleRows(offset, size) *
                                    scale.segment(offset, size).asDiagonal();
    // Tangent to ambient: the manifold's plus Jacobian (a selection for a subset manifold).
    Eigen::MatrixXd plus = Eigen::MatrixXd::Identity(kNumIntrinsics, size);
    if (const ceres::Manifold* manifold = problem->GetManifold(block)) {
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> j(kNumIntrinsics,
                                                                               size);
      if (!manifold->PlusJacobian(block, j.data())) return false;
      plus = j;
    }
    (*out)[camera_id] = plus * tangent * plus.transpose();
  }
  return true;
}

// Fills summary->intrinsics_stddev and variance_factor from the solved `problem` (see
// BundleAdjustmentOptions::estimate_intrinsics_stddev). The covariance is that of the
// whitened residuals, (J^T J)^-1, times the a posteriori variance factor.
void EstimateIntrinsicsStddev(const BundleAdjustmentOptions& options,
                              int num_threads,
                              const std::map<int, IntrinsicsBlock>& intrinsics,
                              const std::vector<double*>& points,
                              ceres::Problem* problem,
                              BundleAdjustmentSummary* summary) {
  std::map<int, double*> wanted;
  for (const auto& [camera_id, block] : intrinsics) {
    if (!problem->IsParameterBlockConstant(block.data())) {
      wanted[camera_id] = const_cast<double*>(block.data());
    }
  }
  if (wanted.empty()) return;
  std::vector<double*> blocks;
  problem->GetParameterBlocks(&blocks);
  int parameters = 0;
  for (double* block : blocks) {
    if (!problem->IsParameterBlockConstant(block)) {
      parameters += problem->ParameterBlockTangentSize(block);
    }
  }
  const int redundancy = problem->NumResiduals() - parameters;
  if (redundancy <= 0) return;
  const double variance_factor = 2.0 * summary->final_cost / redundancy;

  Timer timer;
  std::map<int, IntrinsicsCovariance> covariance;
  const bool by_qr = summary->num_observations <= options.max_observations_for_stddev;
  const bool estimated =
      by_qr ? CovarianceBySparseQr(num_threads, wanted, problem, &covariance)
            : CovarianceBySchur(num_threads, wanted, points, options.max_poses_for_stddev, problem,
                                &covariance);
  if (!estimated) {
    LOG_DEBUG << "BA: intrinsics covariance not estimable (is the gauge fixed?)";
    return;
  }
  LOG_DEBUG << "BA: intrinsics covariance in " << timer.ElapsedSeconds() << " s"
            << (by_qr ? " (sparse QR)" : " (Schur complement)");
  summary->variance_factor = variance_factor;
  for (const auto& [camera_id, c] : covariance) {
    const auto stddev = [&](int i) { return std::sqrt(std::max(0.0, variance_factor * c(i, i))); };
    summary->intrinsics_stddev[camera_id] = {stddev(kIntrinsicsFocal), stddev(kIntrinsicsCx),
                                             stddev(kIntrinsicsCy), stddev(kIntrinsicsK1),
                                             stddev(kIntrinsicsK2)};
  }
}

// Which poses and cameras an adjustment may change, from the options' id lists. Ids named in
// the options must exist: a wrong id is a caller bug, not a data condition.
struct VariableSelection {
  std::set<int> constant_poses;
  std::set<int> variable_poses;  // Non-empty: a local adjustment of these poses only.
  std::set<int> constant_cameras;

  bool local() const { return !variable_poses.empty(); }
  bool PoseIsVariable(int image_id) const {
    return !constant_poses.contains(image_id) && (!local() || variable_poses.contains(image_id));
  }
};

VariableSelection SelectVariables(const BundleAdjustmentOptions& options,
                                  const Reconstruction& rec) {
  VariableSelection selection;
  selection.constant_poses =
      std::set<int>(options.constant_pose_image_ids.begin(), options.constant_pose_image_ids.end());
  selection.variable_poses =
      std::set<int>(options.variable_pose_image_ids.begin(), options.variable_pose_image_ids.end());
  selection.constant_cameras =
      std::set<int>(options.constant_camera_ids.begin(), options.constant_camera_ids.end());
  for (const std::set<int>* ids : {&selection.constant_poses, &selection.variable_poses}) {
    for (int id : *ids) THROW_CHECK(rec.images.contains(id)) << "no image " << id;
  }
  for (int id : selection.constant_cameras) {
    THROW_CHECK(rec.cameras.contains(id)) << "no camera " << id;
  }
  if (options.scale_fixing_image_id != kInvalidId) {
    THROW_CHECK(rec.images.contains(options.scale_fixing_image_id))
        << "no image " << options.scale_fixing_image_id;
  }
  return selection;
}

// The points to adjust: all of them (global), or those seen by the variable images (local).
std::vector<int> CandidatePoints(const Reconstruction& rec, const VariableSelection& selection) {
  std::vector<int> candidate_points;
  if (selection.local()) {
    std::set<int> seen;
    for (int image_id : selection.variable_poses) {
      for (int point_id : rec.images.at(image_id).point_for_keypoint) {
        if (point_id != kInvalidId && rec.points.contains(point_id)) seen.insert(point_id);
      }
    }
    candidate_points.assign(seen.begin(), seen.end());
  } else {
    candidate_points.reserve(rec.points.size());
    for (const auto& [point_id, point] : rec.points) candidate_points.push_back(point_id);
  }
  return candidate_points;
}

// The copies of the parameters an adjustment works on, and the observations that use them.
// std::map nodes do not move, so pointers into them stay valid while Ceres holds them.
//
// The results depend on the heap layout, to the last bit: Ceres orders the parameter blocks of
// an elimination group by address (ParameterBlockOrdering), and the elimination order changes
// the rounding. So the buffers used to set up the problem live as long as the problem
// (`usable` here; the candidate points, held intrinsics and ordering in BundleAdjust), as they
// did when BundleAdjust was one function; changing what is allocated, or when, before the
// solve changes results in the last digits (not their accuracy).
struct ProblemParameters {
  std::map<int, PoseBlock> poses;
  std::map<int, IntrinsicsBlock> intrinsics;
  std::unordered_map<int, std::array<double, 3>> points;
  std::vector<UsedObservation> used;
  std::vector<UsedObservation> usable;  // One point's usable observations, reused.
};

// The observations of `point_id` in front of their cameras (counted in `summary` when not).
void UsableObservations(const Reconstruction& rec,
                        int point_id,
                        BundleAdjustmentSummary* summary,
                        std::vector<UsedObservation>* usable) {
  const Point3D& point = rec.points.at(point_id);
  usable->clear();
  for (const Observation& o : point.observations) {
    const auto image_it = rec.images.find(o.image_id);
    THROW_CHECK(image_it != rec.images.end())
        << "point " << point_id << " is observed by unknown image " << o.image_id;
    const RegisteredImage& image = image_it->second;
    THROW_CHECK(o.keypoint >= 0 && o.keypoint < static_cast<int>(image.keypoints.size()))
        << "point " << point_id << ": keypoint " << o.keypoint << " of image " << o.image_id;
    THROW_CHECK(rec.cameras.contains(image.camera_id))
        << "image " << o.image_id << " has unknown camera " << image.camera_id;
    // A point behind the camera has no projection (ImgFromCam); it could not be evaluated.
    if (!((image.cam_from_world * point.xyz_in_world).z() > 0.0)) {
      ++summary->num_skipped_observations;
      continue;
    }
    usable->push_back({point_id, o.image_id, o.keypoint});
  }
}

// Copies the parameters of every candidate point with 2 or more usable observations, and of
// the poses and cameras of those observations, into `parameters`; counts them in `summary`.
void CollectParameters(const Reconstruction& rec,
                       const std::vector<int>& candidate_points,
                       const VariableSelection& selection,
                       ProblemParameters* parameters,
                       BundleAdjustmentSummary* summary) {
  parameters->points.reserve(candidate_points.size());
  std::vector<UsedObservation>& usable = parameters->usable;
  for (int point_id : candidate_points) {
    UsableObservations(rec, point_id, summary, &usable);
    if (usable.size() < 2) {
      ++summary->num_skipped_points;
      continue;
    }
    Eigen::Map<Eigen::Vector3d>(parameters->points[point_id].data()) =
        rec.points.at(point_id).xyz_in_world;
    for (const UsedObservation& o : usable) {
      const RegisteredImage& image = rec.images.at(o.image_id);
      if (!parameters->poses.contains(o.image_id)) {
        PoseBlock& block = parameters->poses[o.image_id] = PoseBlockFromRigid(image.cam_from_world);
        block.constant = !selection.PoseIsVariable(o.image_id);
      }
      if (!parameters->intrinsics.contains(image.camera_id)) {
        parameters->intrinsics[image.camera_id] =
            IntrinsicsFromCamera(rec.cameras.at(image.camera_id));
      }
      parameters->used.push_back(o);
    }
  }
  summary->num_images = static_cast<int>(parameters->poses.size());
  for (const auto& [image_id, block] : parameters->poses) {
    summary->num_variable_images += !block.constant;
  }
  summary->num_cameras = static_cast<int>(parameters->intrinsics.size());
  summary->num_points = static_cast<int>(parameters->points.size());
  summary->num_observations = static_cast<int>(parameters->used.size());
}

// One reprojection residual per used observation, weighted by its keypoint's stddev.
void AddResiduals(const Reconstruction& rec,
                  ceres::LossFunction* loss,
                  ProblemParameters* parameters,
                  ceres::Problem* problem) {
  for (const UsedObservation& o : parameters->used) {
    const RegisteredImage& image = rec.images.at(o.image_id);
    PoseBlock& pose = parameters->poses.at(o.image_id);
    problem->AddResidualBlock(
        ReprojectionError::Create(image.keypoints[o.keypoint], image.KeypointStddev(o.keypoint)),
        loss, pose.rotation.data(), pose.translation.data(),
        parameters->points.at(o.point_id).data(),
        parameters->intrinsics.at(image.camera_id).data());
  }
}

// Poses: rotation on the unit-quaternion manifold; constant blocks stay untouched; the
// scale-fixing image holds one translation coordinate.
void ParameterisePoses(const BundleAdjustmentOptions& options,
                       const Reconstruction& rec,
                       std::map<int, PoseBlock>* poses,
                       ceres::Problem* problem) {
  const Rigid3d* scale_reference = nullptr;
  for (int id : options.constant_pose_image_ids) {
    if (poses->contains(id)) {
      scale_reference = &rec.images.at(id).cam_from_world;
      break;
    }
  }
  for (auto& [image_id, pose] : *poses) {
    if (pose.constant) {
      problem->SetParameterBlockConstant(pose.rotation.data());
      problem->SetParameterBlockConstant(pose.translation.data());
      continue;
    }
    problem->SetManifold(pose.rotation.data(), new ceres::EigenQuaternionManifold);
    if (image_id == options.scale_fixing_image_id) {
      const int index =
          options.scale_fixing_translation_index >= 0
              ? options.scale_fixing_translation_index
              : AutoScaleFixingIndex(rec.images.at(image_id).cam_from_world, scale_reference);
      problem->SetManifold(pose.translation.data(), new ceres::SubsetManifold(3, {index}));
      LOG_DEBUG << "BA: scale fixed by translation[" << index << "] of image " << image_id;
    }
  }
  if (options.scale_fixing_image_id != kInvalidId &&
      (!poses->contains(options.scale_fixing_image_id) ||
       poses->at(options.scale_fixing_image_id).constant)) {
    LOG_WARNING << "BA: scale-fixing image " << options.scale_fixing_image_id
                << " is not a variable pose of this problem; the scale is not fixed by it";
  }
}

// The entries of an intrinsics block that the options hold constant.
std::vector<int> HeldIntrinsics(const BundleAdjustmentOptions& options) {
  std::vector<int> constant_intrinsics;
  if (!options.refine_focal) constant_intrinsics.push_back(kIntrinsicsFocal);
  if (!options.refine_principal_point || options.hold_principal_point_x) {
    constant_intrinsics.push_back(kIntrinsicsCx);
  }
  if (!options.refine_principal_point || options.hold_principal_point_y) {
    constant_intrinsics.push_back(kIntrinsicsCy);
  }
  if (!options.refine_k1) constant_intrinsics.push_back(kIntrinsicsK1);
  if (!options.refine_k2) constant_intrinsics.push_back(kIntrinsicsK2);
  return constant_intrinsics;
}

// Intrinsics: one block per camera; the held entries through a subset manifold, a block with
// every entry held (or of a constant camera) constant.
void ParameteriseIntrinsics(const std::vector<int>& constant_intrinsics,
                            const std::set<int>& constant_cameras,
                            std::map<int, IntrinsicsBlock>* intrinsics,
                            ceres::Problem* problem) {
  for (auto& [camera_id, block] : *intrinsics) {
    if (constant_cameras.contains(camera_id) ||
        constant_intrinsics.size() == static_cast<std::size_t>(kNumIntrinsics)) {
      problem->SetParameterBlockConstant(block.data());
    } else if (!constant_intrinsics.empty()) {
      problem->SetManifold(block.data(),
                           new ceres::SubsetManifold(kNumIntrinsics, constant_intrinsics));
    }
  }
}

// Schur ordering: eliminate the points first (group 0), then solve for cameras.
std::shared_ptr<ceres::ParameterBlockOrdering> SchurOrdering(ProblemParameters* parameters) {
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (auto& [point_id, xyz] : parameters->points) ordering->AddElementToGroup(xyz.data(), 0);
  for (auto& [image_id, pose] : parameters->poses) {
    ordering->AddElementToGroup(pose.rotation.data(), 1);
    ordering->AddElementToGroup(pose.translation.data(), 1);
  }
  for (auto& [camera_id, block] : parameters->intrinsics) {
    ordering->AddElementToGroup(block.data(), 1);
  }
  return ordering;
}

// The solver's options: the ordering, linear solver, tolerances, threads (no callbacks yet).
ceres::Solver::Options SolverOptionsFor(const BundleAdjustmentOptions& options,
                                        std::shared_ptr<ceres::ParameterBlockOrdering> ordering,
                                        int num_variable_images) {
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_ordering = std::move(ordering);
  ChooseLinearSolver(options, num_variable_images, &solver_options);
  solver_options.max_num_iterations = options.max_num_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.max_solver_time_in_seconds = options.max_solver_time_seconds;
  solver_options.num_threads = EffectiveNumThreads(options.num_threads);
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  return solver_options;
}

// Copies what varied back into the reconstruction.
void WriteBack(const ProblemParameters& parameters,
               const ceres::Problem& problem,
               Reconstruction* rec) {
  for (const auto& [image_id, pose] : parameters.poses) {
    if (!pose.constant) PoseBlockToRigid(pose, &rec->images.at(image_id).cam_from_world);
  }
  for (const auto& [camera_id, block] : parameters.intrinsics) {
    if (!problem.IsParameterBlockConstant(block.data())) {
      IntrinsicsToCamera(block, &rec->cameras.at(camera_id));
    }
  }
  for (const auto& [point_id, xyz] : parameters.points) {
    rec->points.at(point_id).xyz_in_world = Eigen::Map<const Eigen::Vector3d>(xyz.data());
  }
}

// Fills the summary's solver figures from Ceres's.
void RecordSolve(const ceres::Solver::Summary& ceres_summary, BundleAdjustmentSummary* summary) {
  summary->termination = TerminationName(ceres_summary.termination_type);
  summary->linear_solver = ceres::LinearSolverTypeToString(ceres_summary.linear_solver_type_used);
  summary->initial_cost = ceres_summary.initial_cost;
  summary->final_cost = ceres_summary.final_cost;
  summary->num_iterations =
      std::max(0, ceres_summary.num_successful_steps + ceres_summary.num_unsuccessful_steps);
}

}  // namespace

BundleAdjustmentSummary BundleAdjust(const BundleAdjustmentOptions& options,
                                     const CancelToken& cancel,
                                     Reconstruction* reconstruction) {
  THROW_CHECK_NOTNULL(reconstruction);
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  cancel.ThrowIfCanceled();
  const Timer timer;
  Reconstruction& rec = *reconstruction;
  BundleAdjustmentSummary summary;

  const VariableSelection selection = SelectVariables(options, rec);
  const std::vector<int> candidate_points = CandidatePoints(rec, selection);
  ProblemParameters parameters;
  CollectParameters(rec, candidate_points, selection, &parameters, &summary);
  if (parameters.used.empty()) {
    summary.message = "nothing to adjust: no point has 2 or more usable observations";
    summary.time_seconds = timer.ElapsedSeconds();
    return summary;
  }
  summary.initial_rms_px = RmsReprojectionError(rec, parameters.used);

  // The loss is shared by all residuals and owned here; it must outlive the problem.
  const std::unique_ptr<ceres::LossFunction> loss = CreateLoss(options.loss, options.loss_scale);
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  AddResiduals(rec, loss.get(), &parameters, &problem);
  ParameterisePoses(options, rec, &parameters.poses, &problem);
  const std::vector<int> constant_intrinsics = HeldIntrinsics(options);
  ParameteriseIntrinsics(constant_intrinsics, selection.constant_cameras, &parameters.intrinsics,
                         &problem);

  const std::shared_ptr<ceres::ParameterBlockOrdering> ordering = SchurOrdering(&parameters);
  ceres::Solver::Options solver_options =
      SolverOptionsFor(options, ordering, summary.num_variable_images);
  CancelAndLogCallback callback(cancel, "BA");
  solver_options.callbacks.push_back(&callback);  // Not owned by Ceres.
  ceres::Solver::Summary ceres_summary;
  QuietCeresUnlessDebugging();
  ceres::Solve(solver_options, &problem, &ceres_summary);
  // Canceled: Ceres did not update the copies and nothing is written back.
  if (callback.canceled()) {
    LOG_DEBUG << "BA canceled after " << ceres_summary.iterations.size() << " iterations";
    throw CanceledError();
  }

  LOG_DEBUG << ceres_summary.FullReport();
  RecordSolve(ceres_summary, &summary);
  if (!ceres_summary.IsSolutionUsable()) {
    summary.success = false;
    summary.message = "solver failed: " + ceres_summary.message;
    summary.final_rms_px = summary.initial_rms_px;
    summary.time_seconds = timer.ElapsedSeconds();
    LOG_WARNING << summary.BriefReport();
    return summary;
  }

  WriteBack(parameters, problem, &rec);
  summary.final_rms_px = RmsReprojectionError(rec, parameters.used);
  summary.success = true;
  summary.message = ceres_summary.message;
  if (options.estimate_intrinsics_stddev && !cancel.IsCanceled()) {
    std::vector<double*> points;
    points.reserve(parameters.points.size());
    for (auto& [point_id, xyz] : parameters.points) points.push_back(xyz.data());
    EstimateIntrinsicsStddev(options, solver_options.num_threads, parameters.intrinsics, points,
                             &problem, &summary);
  }
  summary.time_seconds = timer.ElapsedSeconds();
  LOG_DEBUG << summary.BriefReport();
  return summary;
}

BundleAdjustmentSummary RefinePose(const PoseRefinementOptions& options,
                                   const Camera& camera,
                                   const std::vector<Eigen::Vector2d>& points2D,
                                   const std::vector<Eigen::Vector3d>& points3D,
                                   Rigid3d* cam_from_world) {
  THROW_CHECK_NOTNULL(cam_from_world);
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  THROW_CHECK_EQ(points2D.size(), points3D.size());
  const Timer timer;
  BundleAdjustmentSummary summary;
  summary.num_images = 1;
  summary.num_variable_images = 1;
  summary.num_cameras = 1;

  std::vector<std::size_t> used;
  for (std::size_t i = 0; i < points3D.size(); ++i) {
    if ((*cam_from_world * points3D[i]).z() > 0.0) {
      used.push_back(i);
    } else {
      ++summary.num_skipped_observations;
    }
  }
  summary.num_points = summary.num_observations = static_cast<int>(used.size());
  const auto rms = [&](const Rigid3d& pose) {
    double sum = 0.0;
    for (std::size_t i : used) {
      const auto pixel = camera.ImgFromCam(pose * points3D[i]);
      const double e =
          pixel ? (*pixel - points2D[i]).norm() : std::numeric_limits<double>::infinity();
      sum += e * e;
    }
    return used.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(used.size()));
  };
  if (used.size() < 3) {
    summary.message = "pose refinement needs at least 3 points in front of the camera, got " +
                      std::to_string(used.size());
    summary.time_seconds = timer.ElapsedSeconds();
    return summary;
  }
  summary.initial_rms_px = rms(*cam_from_world);

  PoseBlock pose = PoseBlockFromRigid(*cam_from_world);
  const Eigen::Matrix<double, kNumIntrinsics, 1> intrinsics(
      Eigen::Map<const Eigen::Matrix<double, kNumIntrinsics, 1>>(
          IntrinsicsFromCamera(camera).data()));
  const std::unique_ptr<ceres::LossFunction> loss = CreateLoss(options.loss, options.loss_scale);
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  for (std::size_t i : used) {
    problem.AddResidualBlock(
        PoseOnlyReprojectionError::Create(points2D[i], points3D[i], intrinsics), loss.get(),
        pose.rotation.data(), pose.translation.data());
  }
  problem.SetManifold(pose.rotation.data(), new ceres::EigenQuaternionManifold);

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.max_num_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.num_threads = 1;  // 7 unknowns: threads would cost more than they save.
  solver_options.logging_type = ceres::SILENT;
  ceres::Solver::Summary ceres_summary;
  QuietCeresUnlessDebugging();
  ceres::Solve(solver_options, &problem, &ceres_summary);

  summary.termination = TerminationName(ceres_summary.termination_type);
  summary.linear_solver = ceres::LinearSolverTypeToString(ceres_summary.linear_solver_type_used);
  summary.initial_cost = ceres_summary.initial_cost;
  summary.final_cost = ceres_summary.final_cost;
  summary.num_iterations =
      std::max(0, ceres_summary.num_successful_steps + ceres_summary.num_unsuccessful_steps);
  summary.message = ceres_summary.message;
  if (ceres_summary.IsSolutionUsable()) {
    PoseBlockToRigid(pose, cam_from_world);
    summary.success = true;
  } else {
    summary.message = "solver failed: " + ceres_summary.message;
  }
  summary.final_rms_px = rms(*cam_from_world);
  summary.time_seconds = timer.ElapsedSeconds();
  return summary;
}

}  // namespace reconduit
