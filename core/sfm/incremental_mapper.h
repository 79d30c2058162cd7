// Incremental structure and motion: from verified pairwise matches and tracks to one or more
// reconstructions (cameras, poses, 3-D points).
//
// The classic loop of Bundler and COLMAP (Schönberger & Frahm 2016, "Structure-from-Motion
// Revisited"), kept small:
//  1. Initial pair. Candidates are pairs with epipolar geometry (GRIC preferred F over H:
//     planar and rotation-only pairs cannot fix the structure), ranked by inliers discounted
//     by the share a homography also explains (a proxy for parallax). For each, the essential
//     matrix from undistorted normalised points gives the relative pose; the pair is accepted
//     when enough points triangulate in front of both cameras with small reprojection error
//     and the median triangulation angle is large enough.
//  2. Registration. The unregistered photo that sees most reconstructed points is posed by
//     P3P in RANSAC (OpenCV's solvePnPRansac on normalised points) and refined (RefinePose).
//     When PnP can place no photo (photos far apart see too few of the model's points), one
//     is registered from its two-view geometry with registered photos instead
//     (relative_registration.h: the scale from the few points it sees, or two neighbours'
//     rays), the photo with most verified matches to the model first.
//  3. Triangulation of the tracks it shares with registered photos (DLT over all registered
//     observations, with depth, reprojection and angle checks); observations of existing
//     points are added when they reproject well.
//  4. Local bundle adjustment around the new photo; global bundle adjustment whenever the
//     model grew by `global_ba_growth`; intrinsics (focal, k1, k2) are refined in global
//     adjustments once the model has `min_images_for_intrinsics` photos.
//  5. Outlier filtering after each adjustment: observations reprojecting worse than
//     `max_reprojection_error_px`, points seen under less than `min_triangulation_angle_deg`.
// When no photo can be registered any more, the remaining tracks are triangulated again, a
// final global adjustment refines everything, and — if photos are left — a new model starts
// from the best remaining pair. A later model may also register photos of earlier ones (a
// model that stopped at a weak link is reached from the other side). When all models are
// grown, those that share photos or tracks are merged (model_merger.h), each model tries
// again to register the photos left out with its final intrinsics, and a photo still in
// several models is kept in the largest. Models are returned largest first.
//
// Before all this, cameras whose focal length is only a guess are searched for with small
// trial reconstructions (IncrementalMapperOptions::focal_search): pairwise self-calibration
// fails when the optical axes meet, as around an object, but three or more views with the
// focal refined in bundle adjustment recover it.
#ifndef RECONDUIT_CORE_SFM_INCREMENTAL_MAPPER_H_
#define RECONDUIT_CORE_SFM_INCREMENTAL_MAPPER_H_

#include "core/feature/matcher.h"
#include "core/scene/reconstruction.h"
#include "core/sfm/bundle_adjustment.h"
#include "core/sfm/model_merger.h"
#include "core/sfm/relative_registration.h"
#include "core/sfm/tracks.h"
#include "core/util/cancel.h"
#include "core/util/progress.h"

#include <Eigen/Core>

#include <map>
#include <set>
#include <string>
#include <vector>

namespace reconduit {

struct MapperImage {
  std::string name;
  int camera_id = kInvalidId;
  std::vector<Eigen::Vector2d> keypoints;  // Original-image pixels.
  // Positional standard deviation of each keypoint in pixels (bundle adjustment weights);
  // empty: 1 px for all. See RegisteredImage::keypoint_stddevs.
  std::vector<double> keypoint_stddevs;
};

struct MapperPair {
  int image1 = kInvalidId;
  int image2 = kInvalidId;
  bool epipolar = false;  // GRIC chose F (a real baseline), not H.
  int num_inliers_F = 0;
  int num_inliers_H = 0;
  std::vector<FeatureMatch> matches;  // Verified inliers.
};

struct MapperInput {
  std::map<int, Camera> cameras;      // Initial intrinsics per camera id.
  std::map<int, MapperImage> images;  // By image id.
  std::vector<MapperPair> pairs;
  std::vector<Track> tracks;
  // Cameras whose initial focal length is a guess (e.g. no EXIF and pairwise self-calibration
  // degenerate): the mapper searches for it first (IncrementalMapperOptions::focal_search).
  std::set<int> uncertain_focal_camera_ids;
};

// How the final adjustment treats the principal point (see IncrementalMapperOptions).
enum class PrincipalPointMode { kCenter, kRefine, kAuto };

struct IncrementalMapperOptions {
  // Initial pair: at least this many verified matches. [8, ...]
  int min_initial_inliers = 50;
  // Initial pair: median triangulation angle of its points, degrees. [0, 90)
  double min_initial_angle_deg = 2.0;
  // Initial pair: candidates tried per model. [1, ...]
  int max_initial_pair_trials = 40;
  // When no pair meets the bar above and nothing has been reconstructed yet (few-feature
  // photos: a small object on a plain background may give every pair only 20-50 matches), a
  // weak initial pair is accepted: at least `weak_initial_inliers` verified matches, of which
  // `weak_initial_essential_share` agree with one essential matrix at 1.5 px and triangulate
  // in front of both cameras, with a median triangulation angle of at least
  // `weak_initial_angle_deg`, as many points surviving the pair's adjustment, and no
  // homography fitting over 80 % of the essential inliers at 3 px (pure rotation, plane). Off with
  // weak_initial_inliers = 0. Logged "weak initial pair ...".
  int weak_initial_inliers = 20;              // 0 or [8, min_initial_inliers]
  double weak_initial_essential_share = 0.8;  // [0, 1]
  double weak_initial_angle_deg = 4.0;        // [min_initial_angle_deg, 90)
  // Observations reprojecting worse than this (pixels) are outliers. (0, ...)
  double max_reprojection_error_px = 4.0;
  // Once a model is grown, its final adjustment removes the observations reprojecting worse
  // than this multiple of the model's median reprojection error (but at least
  // `final_min_outlier_px`, at most max_reprojection_error_px), then adjusts again, twice.
  // The 4 px bar suits a model still growing from rough poses; at the end, matches a pixel or
  // two off (a blob centred differently across a wide baseline, a near-epipolar mismatch)
  // are what bends the poses: templeSparseRing every second photo has a median of 0.22 px
  // and 11 % of its matches over 1.5 px from the true epipolar lines. With 6 medians (about
  // 7 sigma of Gaussian noise, so clean noise loses nothing): its relative rotations 2.72 ->
  // 1.71 deg, the whole ring's 0.35 -> 0.23 deg, fountain-P11's centres 3.08 -> 2.53 mm.
  // 0 turns it off; otherwise >= 3.
  double final_outlier_multiple = 6.0;
  double final_min_outlier_px = 0.5;  // (0, ...)
  // Points seen under a smaller angle (degrees) are not kept. [0, 90)
  double min_triangulation_angle_deg = 1.5;
  // A photo needs this many 2-D/3-D correspondences (and PnP inliers) to be registered. [4, ...]
  int min_registration_points = 20;
  // PnP RANSAC inlier threshold in pixels. (0, ...)
  double pnp_max_error_px = 8.0;
  // ... and this share of its correspondences must be inliers. [0, 1]
  double min_pnp_inlier_ratio = 0.2;
  // Local adjustment: the new photo and up to this many photos sharing most points with it.
  int local_ba_num_images = 6;
  // A global adjustment runs when the number of registered photos grew by this factor. > 1
  double global_ba_growth = 1.3;
  // Intrinsics refinement in global adjustments.
  bool refine_focal = true;
  bool refine_distortion = true;
  // The principal point (shared per camera id), decided in the final adjustment of models
  // with at least `min_images_for_principal_point` photos:
  //   kCenter  it stays where the input cameras put it (the image centre).
  //   kRefine  it is refined, whatever the evidence. It trades off against the rotations: on
  //            a synthetic 10-photo ring whose true principal point IS the centre, refining it
  //            moves it 10 px and tilts every camera by up to 0.8 deg.
  //   kAuto    model selection: the final adjustment is run again with the principal point
  //            free, and the result is kept only when the drop in the sum of squared
  //            residuals, in units of the residual variance, exceeds the Bayesian
  //            information criterion's price of the extra parameters, k ln n (k = 2 per
  //            camera, n residuals; Schwarz 1978) -- the test GRIC applies to F versus H --
  //            and the shift is plausible (at most `max_principal_point_shift` of the longer
  //            image side). On fountain-P11, whose principal point is 15 px off the centre,
  //            it is kept and cuts the camera-centre error from 6.3 to 2.7 mm; on the
  //            synthetic ring above it is rejected. A coordinate the free solve determines
  //            only poorly (`max_principal_point_stddev`) stays at the centre.
  PrincipalPointMode principal_point = PrincipalPointMode::kAuto;
  double max_principal_point_shift = 0.1;
  // ... and each coordinate is refined only when the free solve determines it to this share
  // of the longer image side (one standard deviation), else held at the centre and the other
  // decided alone (DecidePrincipalPoint in incremental_mapper.cc has the measurements). > 0
  double max_principal_point_stddev = 0.015;
  int min_images_for_principal_point = 8;
  int min_images_for_intrinsics = 4;
  // Focal search for the cameras in MapperInput::uncertain_focal_camera_ids, before the
  // reconstruction: trial models of up to `focal_search_images` photos with the focal refined
  // in bundle adjustment, first from the guess and then from the trial's result; when the two
  // agree within `focal_search_tolerance` (relative), the reconstruction starts from the
  // second. Otherwise trials start from `focal_search_hypotheses` focal lengths log-spaced
  // over [min, max] x the longer image side, and the trial that registers most photos, then
  // with the lowest reprojection error, gives the start. Costs 2 small trial models in the
  // usual case (1.8 s of templeSparseRing's sparse stage), nothing when no focal is
  // uncertain. The tolerance is loose on purpose: the search only has to start the
  // reconstruction inside bundle adjustment's basin; trials of 6 temple photos scatter by
  // about 3 % and the full model refines the focal further.
  // A trial whose seed pair grows no further (cut off from the other photos by a wide gap)
  // moves on to the next seed among the photos left, up to `focal_search_seeds` seeds.
  bool focal_search = true;
  int focal_search_seeds = 3;  // [1, ...]
  // The fixed-point iteration runs up to this many trials (each from the last one's focal)
  // before falling back to the multi-start: from a guess half the truth, a ring of photos 45
  // deg apart (templeSparseRing every second photo) moves 768 -> 1307 -> 1482 px, still 13 %
  // per step after two trials, where the multi-start's lowest error picks a poor 1215 px.
  int focal_search_rounds = 4;             // [2, ...]
  int focal_search_images = 6;             // [3, ...]
  double focal_search_tolerance = 0.1;     // (0, 1)
  int focal_search_hypotheses = 6;         // [1, ...]
  double focal_search_min_multiple = 0.5;  // (0, max)
  double focal_search_max_multiple = 5.0;
  // When PnP can register no photo (too few of its keypoints see reconstructed points, as
  // when photos are far apart), register one from its two-view geometry with registered
  // photos (relative_registration.h): the scale of the baseline from the few points it sees,
  // or the rays from two neighbours.
  bool relative_registration = true;
  RelativeRegistrationOptions relative;
  // When every model is grown, models that share photos (a later model may re-register photos
  // of an earlier one) or tracks are merged (model_merger.h: a robust similarity, the union,
  // a joint adjustment; `merge.max_reprojection_error_px` is replaced by the mapper's), so
  // every photo either registered stays. Logged "merged model B (n photos) into A ...".
  bool merge_models = true;
  ModelMergerOptions merge;
  // Then each model (after its global adjustment) tries again to register the photos left
  // out, with its final intrinsics; when any joins, the final adjustment runs again.
  bool reregister = true;
  // Every finished model (after its final adjustment, also after a merge or re-registration)
  // is checked against the two-view geometry of its photos' verified pairs: a pair whose own
  // relative pose (EstimateRelativePose at the model's focal) explains at least
  // `contradiction_min_pair_share` of its matches with a median parallax of at least
  // `contradiction_min_parallax_deg`, while the model's two poses explain fewer than 90 %
  // and put their relative rotation more than `contradiction_min_rotation_deg` away from the
  // pair's, contradicts the model: one of its photos was placed wrongly (PnP on a few points of
  // one plane, or on points of a poor two-view start, can land 50-130 deg off with a low
  // reprojection error). The photo in most contradictions (on a tie the later registered; never
  // one of the initial pair) leaves the model, which is adjusted again and checked again; the
  // photo may start or join another model. Only pairs classified epipolar (F) with at least
  // `contradiction_min_matches` matches take part: a homography's matches do not fix a
  // relative pose. Logged "removed X from the model: its pose contradicts ...". Off with
  // contradiction_min_rotation_deg = 0. On real photos of small objects (templeSparseRing,
  // kermit) true pairs differ from their model by up to 7 deg; fountain-P11 by 0.2 deg.
  double contradiction_min_rotation_deg = 15.0;  // 0 or (0, 180)
  // When the pair's own pose explains at least `contradiction_clear_margin` of its matches more
  // than the model does, a smaller difference contradicts: `contradiction_clear_rotation_deg`.
  // (Rendered ring of 10 photos 36 deg apart: a photo PnP placed 11 deg off on points two of
  // its neighbours had triangulated; its pair with a neighbour: own pose 681 of 690 matches,
  // the model 430. On the real sets every pair checked is explained better by the model than
  // by its own pose.)
  double contradiction_clear_rotation_deg = 5.0;  // (0, contradiction_min_rotation_deg]
  double contradiction_clear_margin = 0.2;        // (0, 1]
  int contradiction_min_matches = 50;             // [8, ...]
  double contradiction_min_pair_share = 0.8;      // (0, 1]
  double contradiction_min_parallax_deg = 5.0;    // [0, 90)
  // Models with fewer photos are dropped. [2, ...]
  int min_model_images = 2;
  // Threads Ceres uses in bundle adjustment; <= 0 means all hardware threads. One by default,
  // measured on the 2-core target machine: with two, Ceres 2.1 took 1.7x as long on 11
  // synthetic photos (35k observations), 2.8x on 80 (512k observations), and the fountain-P11
  // sparse stage 27.9 s instead of 20.9 s. The profile shows the Schur elimination's cell
  // locks: every point's update of the reduced camera matrix touches the cells of the shared
  // intrinsics block. The pipeline's num_threads does not reach it: on a many-core machine,
  // measure (reconduit benchmark) before raising it here.
  int bundle_adjustment_threads = 1;

  bool Check(std::string* error) const;
};

struct MapperSummary {
  int num_models = 0;
  int num_registered = 0;
  int num_images = 0;
  int num_points = 0;
  double mean_reprojection_error_px = 0.0;
  // Photos registered by relative pose (IncrementalMapperOptions::relative_registration), in
  // every model built, including ones later dropped or merged.
  int num_relative_registrations = 0;
  // Models merged into another (IncrementalMapperOptions::merge_models), and photos registered
  // by the re-registration after the global adjustment.
  int num_merges = 0;
  int num_reregistered = 0;
  // Photos removed from a model whose verified pairs their pose contradicted
  // (IncrementalMapperOptions::contradiction_min_rotation_deg).
  int num_contradicted = 0;
  std::vector<std::string> log;  // One line per notable event (initial pairs, failures).
  // Where the mapping time went (seconds; the focal search's trial models are not counted):
  // PnP registration tries, triangulation, local and global bundle adjustments (the global
  // ones with the final adjustment and its intrinsics' precision, and the principal-point
  // decision), and the whole run (with what the others leave out: merges, filtering).
  struct Times {
    double registration = 0.0;
    double triangulation = 0.0;
    double local_adjustment = 0.0;
    double global_adjustment = 0.0;
    double total = 0.0;
    int registration_tries = 0;
    int local_adjustments = 0;
    int global_adjustments = 0;
  } times;
  // Per camera id: the focal length the reconstruction started from after the focal search
  // (only cameras that were searched).
  std::map<int, double> searched_focal;
  // Per camera id of the largest model: the standard deviations of its refined intrinsics
  // from the final bundle adjustment (BundleAdjustmentSummary::intrinsics_stddev).
  std::map<int, IntrinsicsStddev> intrinsics_stddev;
};

std::vector<Reconstruction> ReconstructIncrementally(const MapperInput& input,
                                                     const IncrementalMapperOptions& options,
                                                     Progress& progress,
                                                     const CancelToken& cancel,
                                                     MapperSummary* summary = nullptr);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SFM_INCREMENTAL_MAPPER_H_
