#include "core/pipeline/stages/sparse_stage.h"

#include "core/image/image_reader.h"
#include "core/io/file_util.h"
#include "core/io/reconstruction_json.h"
#include "core/pipeline/stages/features_stage.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/pipeline/stages/left_out.h"
#include "core/pipeline/stages/matching_stage.h"
#include "core/sfm/incremental_mapper.h"
#include "core/sfm/initial_calibration.h"
#include "core/sfm/tracks.h"
#include "core/util/logging.h"
#include "core/util/parallel.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <map>
#include <mutex>

namespace reconduit {
namespace {

// Radial distortion (k1, k2) is refined only when the matched keypoints reach out into the
// photos: this share of the half-diagonal (see ObservationReach). Near the centre the radial
// terms look like a change of focal length, so with no observations further out bundle
// adjustment trades one for the other: templeSparseRing (an object on a black background,
// reach 0.56) refined k1 and k2 to -0.57 and 2.4, its focal 4 % off the truth instead of 1 %,
// and tilted every camera by 1.6 deg (0.3 deg with distortion held at zero). kermit (0.76)
// and fountain-P11 (0.79) are above and keep it.
constexpr double kMinDistortionReach = 0.65;

// A SIFT keypoint is the centre of a blob of Gaussian scale sigma = size / 2 (OpenCV's size
// is the diameter 2 sigma); its position is known to about sigma, and never better than
// ~1 px at the finest scales. Bundle adjustment weighs each observation by 1 / stddev^2 with
// stddev = max(1, size / 2) px. Measured on templeSparseRing over four feature sets (SIFT
// contrast threshold 0.005, 0.01, 0.02 (ours), 0.03): focal error 0.25, 1.01, 0.06, 0.34 %
// against 0.57, 1.06, 0.72, 0.66 % with equal weights, centre error 0.19, 0.43, 0.24, 0.38 %
// of the radius against 0.24, 0.49, 0.31, 0.41 %; fountain-P11 about the same (3.17 against
// 3.23 mm, focal 0.039 against 0.048 % from fx).
double KeypointStddev(const Keypoint& kp) { return std::max(1.0, 0.5 * kp.scale); }

// The 95th percentile, over every track observation, of the keypoint's distance from its
// photo's centre as a share of the half-diagonal.
double ObservationReach(const MapperInput& input) {
  std::vector<double> reach;
  for (const Track& track : input.tracks) {
    for (const Observation& o : track.observations) {
      const MapperImage& image = input.images.at(o.image_id);
      const Camera& camera = input.cameras.at(image.camera_id);
      const Eigen::Vector2d centre((camera.width - 1) / 2.0, (camera.height - 1) / 2.0);
      reach.push_back((image.keypoints[o.keypoint] - centre).norm() /
                      (0.5 * std::hypot(camera.width, camera.height)));
    }
  }
  if (reach.empty()) return 0.0;
  const auto q = reach.begin() + static_cast<std::ptrdiff_t>(0.95 * (reach.size() - 1));
  std::nth_element(reach.begin(), q, reach.end());
  return *q;
}

// Mean colour of every point's observations, read from the photos (in parallel).
void ColourPoints(const std::vector<IngestedImage>& images,
                  const PipelineOptions& options,
                  const CancelToken& cancel,
                  Reconstruction* model) {
  std::map<int, const IngestedImage*> by_id;
  for (const IngestedImage& image : images) by_id[image.index] = &image;
  std::vector<int> ids;
  for (const auto& [id, image] : model->images) ids.push_back(id);
  std::map<int, Eigen::Vector3d> sums;
  std::map<int, int> counts;
  std::mutex mutex;
  ImageReaderOptions reader;
  reader.min_side = options.min_image_side;
  reader.max_pixels = options.max_image_pixels;
  reader.read_exif = false;
  ParallelFor(
      0, ids.size(),
      [&](std::size_t k) {
        cancel.ThrowIfCanceled();
        const RegisteredImage& image = model->images.at(ids[k]);
        auto pixels = ReadImage(by_id.at(ids[k])->path, reader);
        if (!pixels.ok()) return;
        std::vector<std::pair<int, Eigen::Vector3d>> local;
        for (std::size_t kp = 0; kp < image.point_for_keypoint.size(); ++kp) {
          const int point = image.point_for_keypoint[kp];
          if (point == kInvalidId) continue;
          const int x = std::clamp(static_cast<int>(std::lround(image.keypoints[kp].x())), 0,
                                   pixels->cols - 1);
          const int y = std::clamp(static_cast<int>(std::lround(image.keypoints[kp].y())), 0,
                                   pixels->rows - 1);
          const cv::Vec3b bgr = pixels->at<cv::Vec3b>(y, x);
          local.emplace_back(point, Eigen::Vector3d(bgr[2], bgr[1], bgr[0]));
        }
        std::lock_guard lock(mutex);
        for (const auto& [point, rgb] : local) {
          sums[point] += rgb;
          ++counts[point];
        }
      },
      options.num_threads);
  for (auto& [id, point] : model->points) {
    if (counts[id] == 0) continue;
    const Eigen::Vector3d mean = sums[id] / counts[id];
    for (int c = 0; c < 3; ++c)
      point.rgb[c] = static_cast<std::uint8_t>(std::clamp(std::lround(mean[c]), 0L, 255L));
  }
}

// The accepted photos as the mapper's images with their keypoints. Photos that share a camera
// key share a camera, numbered 0, 1, ... in order of first appearance; `members` lists each
// camera's photos.
Status AddImagesByCamera(const Workspace& workspace,
                         const std::vector<IngestedImage>& images,
                         MapperInput* input,
                         std::map<int, std::vector<const IngestedImage*>>* members) {
  std::map<std::string, int> camera_of_key;
  for (const IngestedImage& image : images) {
    if (!image.photo.accepted) continue;
    auto [it, inserted] =
        camera_of_key.try_emplace(image.camera_key, static_cast<int>(camera_of_key.size()));
    (*members)[it->second].push_back(&image);
    auto keypoints = ReadMatchedKeypoints(workspace, image.index);
    if (!keypoints.ok()) return keypoints.status();
    MapperImage mapper_image;
    mapper_image.name = image.name;
    mapper_image.camera_id = it->second;
    for (const Keypoint& kp : *keypoints) {
      mapper_image.keypoints.emplace_back(kp.x, kp.y);
      mapper_image.keypoint_stddevs.push_back(KeypointStddev(kp));
    }
    input->images[image.index] = std::move(mapper_image);
  }
  return Status::Ok();
}

// What core/sfm/initial_calibration.h needs to know about camera `camera_id`: its size, its
// photos' EXIF focal lengths, and the fundamental matrices of pairs of its photos.
InitialCalibrationInput CalibrationInputOf(int camera_id,
                                           const std::vector<const IngestedImage*>& photos,
                                           const std::vector<VerifiedPair>& pairs,
                                           const MapperInput& input) {
  InitialCalibrationInput calibration;
  calibration.width = photos.front()->photo.width;
  calibration.height = photos.front()->photo.height;
  for (const IngestedImage* p : photos) {
    if (p->photo.exif_focal_px) calibration.exif_focals.push_back(*p->photo.exif_focal_px);
  }
  auto of_camera = [&](int image_id) {
    auto it = input.images.find(image_id);
    return it != input.images.end() && it->second.camera_id == camera_id;
  };
  for (const VerifiedPair& pair : pairs) {
    if (pair.type == TwoViewModelType::kFundamental && of_camera(pair.matches.image1) &&
        of_camera(pair.matches.image2)) {
      calibration.fundamentals.push_back({pair.F, pair.num_inliers_F});
    }
  }
  return calibration;
}

// The camera's record in work/sparse/calibration.json (and the stage summary), and the log
// lines a person reads about it.
nlohmann::json CalibrationRecord(int camera_id,
                                 std::size_t num_photos,
                                 const InitialCalibration& c) {
  const Camera& camera = c.camera;
  nlohmann::json record = {{"camera_id", camera_id},
                           {"photos", num_photos},
                           {"width", camera.width},
                           {"height", camera.height},
                           {"pairs", c.num_pairs}};
  if (c.self_calibration) {
    record["self_calibrated_focal"] = c.self_calibration->focal;
    record["self_calibration_pairs_agreeing"] = c.self_calibration->num_agreeing;
    record["self_calibration_spread"] = c.self_calibration->spread;
  } else {
    record["self_calibration"] = c.self_calibration_error;
  }
  if (c.exif_focal) record["exif_focal"] = *c.exif_focal;
  record["initial_focal_source"] = std::string(InitialFocalSourceName(c.source));
  if (!c.warning.empty()) record["warning"] = c.warning;
  record["initial_focal"] = camera.focal;

  if (c.source == InitialFocalSource::kExif && !c.warning.empty()) {
    LOG_WARNING << "sparse: camera " << camera_id << ": EXIF focal " << camera.focal
                << " px disagrees with self-calibration " << c.self_calibration->focal << " px";
  } else if (c.source == InitialFocalSource::kDefault) {
    LOG_WARNING << "sparse: camera " << camera_id << ": " << c.self_calibration_error
                << "; searching for the focal from " << camera.focal << " px";
  }
  LOG_INFO << "sparse: camera " << camera_id << " (" << num_photos << " photos, " << camera.width
           << "x" << camera.height << "): initial focal " << camera.focal << " px from "
           << InitialFocalSourceName(c.source);
  return record;
}

// Every camera's initial calibration into `input` (cameras, and those whose focal is a guess
// for the mapper to search for); returns the cameras' calibration records.
nlohmann::json CalibrateCameras(const std::map<int, std::vector<const IngestedImage*>>& members,
                                const std::vector<VerifiedPair>& pairs,
                                const PipelineOptions& options,
                                MapperInput* input) {
  InitialCalibrationOptions calibration_options;
  calibration_options.use_exif = options.use_exif;
  nlohmann::json records = nlohmann::json::array();
  for (const auto& [camera_id, photos] : members) {
    const InitialCalibration c = EstimateInitialCalibration(
        CalibrationInputOf(camera_id, photos, pairs, *input), calibration_options);
    records.push_back(CalibrationRecord(camera_id, photos.size(), c));
    input->cameras[camera_id] = c.camera;
    if (c.UncertainFocal()) input->uncertain_focal_camera_ids.insert(camera_id);
  }
  return records;
}

// The verified pairs for the mapper, and the tracks they make.
void AddPairsAndTracks(const std::vector<VerifiedPair>& pairs, MapperInput* input) {
  std::vector<PairMatches> pair_matches;
  for (const VerifiedPair& pair : pairs) {
    pair_matches.push_back(pair.matches);
    MapperPair mp;
    mp.image1 = pair.matches.image1;
    mp.image2 = pair.matches.image2;
    mp.epipolar = pair.type == TwoViewModelType::kFundamental;
    mp.num_inliers_F = pair.num_inliers_F;
    mp.num_inliers_H = pair.num_inliers_H;
    mp.matches = pair.matches.matches;
    input->pairs.push_back(std::move(mp));
  }
  TrackStatistics track_stats;
  input->tracks = BuildTracks(pair_matches, 2, &track_stats);
  LOG_INFO << "sparse: " << track_stats.num_tracks << " tracks, " << track_stats.num_observations
           << " observations (" << track_stats.num_conflicting_matches
           << " matches refused: they would join two keypoints of one photo)";
}

// The mapper's options from the pipeline's: the principal-point mode, and radial distortion
// refined only when the observations reach far enough out (kMinDistortionReach).
IncrementalMapperOptions MapperOptionsFor(const PipelineOptions& options, double reach) {
  IncrementalMapperOptions mapper_options;
  mapper_options.principal_point = options.principal_point == "center" ? PrincipalPointMode::kCenter
                                   : options.principal_point == "refine"
                                       ? PrincipalPointMode::kRefine
                                       : PrincipalPointMode::kAuto;
  mapper_options.refine_distortion = reach >= kMinDistortionReach;
  if (!mapper_options.refine_distortion) {
    LOG_INFO << "sparse: matched keypoints reach " << reach
             << " of the half-diagonal; radial distortion held at zero";
  }
  return mapper_options;
}

// Adds to each camera's record the focal the mapper's focal search started from.
void RecordSearchedFocals(const MapperSummary& summary, nlohmann::json* calibration) {
  for (nlohmann::json& record : *calibration) {
    auto searched = summary.searched_focal.find(record["camera_id"].get<int>());
    if (searched != summary.searched_focal.end()) record["searched_focal"] = searched->second;
  }
}

// Adds to each camera's record the largest model's calibration and its precision (one
// standard deviation, from the final bundle adjustment; absent when it could not be estimated).
void RecordFinalCalibration(const Reconstruction& best,
                            const MapperSummary& summary,
                            nlohmann::json* calibration) {
  for (nlohmann::json& record : *calibration) {
    const int id = record["camera_id"].get<int>();
    auto camera = best.cameras.find(id);
    if (camera == best.cameras.end()) continue;
    record["final_focal"] = camera->second.focal;
    // Without EXIF a focal length needs three photos to be estimated (self-calibration from
    // the pairs, or the focal search's trial models): a smaller model keeps the guess, and its
    // angles are only approximate (rendered rings: 2-photo models 7-21 deg off).
    const auto photos =
        std::count_if(best.images.begin(), best.images.end(),
                      [&](const auto& image) { return image.second.camera_id == id; });
    if (record["initial_focal_source"] == "default" && photos < 3) {
      record["final_focal_warning"] =
          "a guess: the model has " + std::to_string(photos) +
          " photo(s) of this camera and, without EXIF, estimating it needs at least 3; the "
          "model's angles and shape are only approximate";
      LOG_WARNING << "sparse: camera " << id << ": focal " << camera->second.focal << " px is "
                  << record["final_focal_warning"].get<std::string>();
    }
    auto stddev = summary.intrinsics_stddev.find(id);
    if (stddev == summary.intrinsics_stddev.end()) continue;
    const IntrinsicsStddev& s = stddev->second;
    record["stddev"] = {{"focal", s.focal}, {"cx", s.cx}, {"cy", s.cy}, {"k1", s.k1}, {"k2", s.k2}};
    LOG_INFO << "sparse: camera " << id << ": focal " << camera->second.focal << " +- " << s.focal
             << " px (1 sigma), principal point (" << camera->second.cx << " +- " << s.cx << ", "
             << camera->second.cy << " +- " << s.cy << ")";
  }
}

// Each model's size, error and cameras, for calibration.json.
nlohmann::json ModelSummaries(const std::vector<Reconstruction>& models) {
  nlohmann::json model_summaries = nlohmann::json::array();
  for (const Reconstruction& model : models) {
    nlohmann::json cameras = nlohmann::json::array();
    for (const auto& [id, camera] : model.cameras) {
      cameras.push_back({{"camera_id", id},
                         {"focal", camera.focal},
                         {"cx", camera.cx},
                         {"cy", camera.cy},
                         {"k1", camera.k1},
                         {"k2", camera.k2}});
    }
    model_summaries.push_back({{"images", model.images.size()},
                               {"points", model.points.size()},
                               {"observations", model.NumObservations()},
                               {"mean_reprojection_error_px", model.MeanReprojectionError()},
                               {"cameras", cameras}});
  }
  return model_summaries;
}

// work/sparse/calibration.json and model_<k>.json (largest first).
Status WriteStageFiles(const std::filesystem::path& stage_dir,
                       const nlohmann::json& calibration_json,
                       const std::vector<Reconstruction>& models) {
  if (Status s =
          WriteFileAtomically(stage_dir / "calibration.json", calibration_json.dump(2) + "\n");
      !s.ok()) {
    return s;
  }
  for (std::size_t k = 0; k < models.size(); ++k) {
    const Status s =
        WriteReconstructionJson(stage_dir / ("model_" + std::to_string(k) + ".json"), models[k]);
    if (!s.ok()) return s;
  }
  return Status::Ok();
}

}  // namespace

StageResult SparseStage::Run(StageContext& context) const {
  const Workspace& workspace = context.workspace;
  auto images = ReadIngestedImages(workspace);
  if (!images.ok()) return StageResult::Failed(images.status().message());
  auto pairs = ReadVerifiedPairs(workspace);
  if (!pairs.ok()) return StageResult::Failed(pairs.status().message());

  MapperInput input;
  std::map<int, std::vector<const IngestedImage*>> members;
  if (Status s = AddImagesByCamera(workspace, *images, &input, &members); !s.ok())
    return StageResult::Failed(s.message());
  nlohmann::json calibration = CalibrateCameras(members, *pairs, context.options, &input);
  AddPairsAndTracks(*pairs, &input);

  const double reach = ObservationReach(input);
  const IncrementalMapperOptions mapper_options = MapperOptionsFor(context.options, reach);
  MapperSummary summary;
  std::vector<Reconstruction> models =
      ReconstructIncrementally(input, mapper_options, context.progress, context.cancel, &summary);
  RecordSearchedFocals(summary, &calibration);
  if (models.empty()) {
    return StageResult::Degenerate(
        "no reconstruction: no pair of photos had enough parallax and matches to start from");
  }

  for (Reconstruction& model : models)
    ColourPoints(*images, context.options, context.cancel, &model);
  const Reconstruction& best = models.front();
  RecordFinalCalibration(best, summary, &calibration);
  if (Status s = WriteStageFiles(context.stage_dir,
                                 {{"cameras", calibration},
                                  {"observation_reach", reach},
                                  {"distortion_refined", mapper_options.refine_distortion},
                                  {"models", ModelSummaries(models)},
                                  {"log", summary.log}},
                                 models);
      !s.ok()) {
    return StageResult::Failed(s.message());
  }
  // Photos the delivered model left out, said plainly (left_out.h): in the job's log, and in
  // the summary the page and report.html show.
  const LeftOutPhotos left_out = FindLeftOutPhotos(input, models);
  if (!left_out.empty()) {
    LOG_WARNING << "sparse: " << left_out.Note();
  }
  // "registered" counts the photos of the delivered (largest) model only; photos in smaller
  // disconnected models are counted apart.
  nlohmann::json summary_json = {
      {"models", models.size()},
      {"registered", best.images.size()},
      {"registered_in_other_models", summary.num_registered - static_cast<int>(best.images.size())},
      {"photos", input.images.size()},
      {"registered_by_relative_pose", summary.num_relative_registrations},
      {"models_merged", summary.num_merges},
      {"registered_again", summary.num_reregistered},
      {"removed_as_contradicted", summary.num_contradicted},
      {"points", best.points.size()},
      {"mean_reprojection_error_px", best.MeanReprojectionError()},
      {"seconds",
       {{"registration", summary.times.registration},
        {"registration_tries", summary.times.registration_tries},
        {"triangulation", summary.times.triangulation},
        {"local_adjustment", summary.times.local_adjustment},
        {"local_adjustments", summary.times.local_adjustments},
        {"global_adjustment", summary.times.global_adjustment},
        {"global_adjustments", summary.times.global_adjustments},
        {"mapping", summary.times.total}}},
      {"cameras", calibration}};
  if (!left_out.empty()) summary_json["left_out"] = left_out.ToJson();
  return StageResult::Success(std::move(summary_json));
}

}  // namespace reconduit
