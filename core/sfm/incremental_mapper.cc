#include "core/sfm/incremental_mapper.h"

#include "core/estimators/triangulation.h"
#include "core/sfm/bundle_adjustment.h"
#include "core/sfm/model_merger.h"
#include "core/sfm/relative_registration.h"
#include "core/util/logging.h"
#include "core/util/timer.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>

namespace reconduit {
namespace {

constexpr std::uint64_t kSeed = 0x5f3759df;

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// Adds the seconds from its construction to its destruction to *seconds.
class ScopedSeconds {
 public:
  explicit ScopedSeconds(double* seconds) : seconds_(seconds) {}
  ~ScopedSeconds() { *seconds_ += timer_.ElapsedSeconds(); }
  ScopedSeconds(const ScopedSeconds&) = delete;
  ScopedSeconds& operator=(const ScopedSeconds&) = delete;

 private:
  double* seconds_;
  Timer timer_;
};

class Mapper {
 public:
  Mapper(const MapperInput& input,
         const IncrementalMapperOptions& options,
         Progress& progress,
         const CancelToken& cancel,
         MapperSummary* summary)
      : input_(input),
        options_(options),
        progress_(progress),
        cancel_(cancel),
        summary_(summary),
        cameras_(input.cameras) {
    for (const auto& [id, image] : input.images) {
      track_of_[id].assign(image.keypoints.size(), -1);
    }
    for (int t = 0; t < static_cast<int>(input.tracks.size()); ++t) {
      for (const Observation& o : input.tracks[t].observations) {
        auto it = track_of_.find(o.image_id);
        THROW_CHECK(it != track_of_.end()) << "track observes unknown image " << o.image_id;
        THROW_CHECK(o.keypoint >= 0 && o.keypoint < static_cast<int>(it->second.size()));
        it->second[o.keypoint] = t;
      }
    }
  }

  std::vector<Reconstruction> Run() {
    const Timer run_timer;
    std::vector<GrownModel> grown;
    progress_.Restart(input_.images.size(), "registering photos");
    while (true) {
      cancel_.ThrowIfCanceled();
      // The track <-> point maps describe the model being built; a new model starts empty
      // (points of earlier models must neither be looked up nor block re-triangulation).
      track_point_.clear();
      point_track_.clear();
      Reconstruction model;
      final_stddev_.clear();
      contradicted_.clear();
      if (!Initialize(&model)) break;
      Grow(&model);
      Finish(&model);
      for (const auto& [id, image] : model.images) used_.insert(id);
      if (static_cast<int>(model.images.size()) >= options_.min_model_images) {
        Note("model " + std::to_string(grown.size() + 1) + ": " +
             std::to_string(model.images.size()) + " photos, " +
             std::to_string(model.points.size()) + " points, mean reprojection error " +
             std::to_string(model.MeanReprojectionError()) + " px");
        grown.push_back(
            {std::move(model), final_stddev_, init_image1_, init_image2_, contradicted_});
      }
    }
    if (options_.merge_models) MergeAll(&grown);
    if (options_.reregister) {
      for (GrownModel& g : grown) Reregister(&g);
    }
    std::vector<Reconstruction> models;
    std::vector<std::map<int, IntrinsicsStddev>> stddevs;  // Of each model's cameras.
    for (GrownModel& g : grown) {
      models.push_back(std::move(g.model));
      stddevs.push_back(std::move(g.stddev));
    }
    const auto larger = [](const Reconstruction& a, const Reconstruction& b) {
      return a.images.size() > b.images.size();
    };
    // The first of the largest models is the one the stable sort puts in front.
    if (summary_ != nullptr && !models.empty()) {
      const auto largest = std::min_element(models.begin(), models.end(), larger);
      summary_->intrinsics_stddev = stddevs[largest - models.begin()];
    }
    std::stable_sort(models.begin(), models.end(), larger);
    ResolveSharedPhotos(&models);
    if (summary_ != nullptr) {
      summary_->num_models = static_cast<int>(models.size());
      summary_->num_images = static_cast<int>(input_.images.size());
      summary_->num_registered = 0;
      summary_->num_points = 0;
      double error_sum = 0.0;
      std::size_t observations = 0;
      for (const Reconstruction& m : models) {
        summary_->num_registered += static_cast<int>(m.images.size());
        summary_->num_points += static_cast<int>(m.points.size());
        error_sum += m.MeanReprojectionError() * m.NumObservations();
        observations += m.NumObservations();
      }
      summary_->mean_reprojection_error_px = observations ? error_sum / observations : 0.0;
    }
    times_.total = run_timer.ElapsedSeconds();
    LOG_INFO << "sfm: mapping took " << times_.total << " s: registration " << times_.registration
             << " s (" << times_.registration_tries << " tries), triangulation "
             << times_.triangulation << " s, local adjustments " << times_.local_adjustment
             << " s (" << times_.local_adjustments << "), global adjustments "
             << times_.global_adjustment << " s (" << times_.global_adjustments << ")";
    if (summary_ != nullptr) summary_->times = times_;
    return models;
  }

  // A model as grown, with what later steps need to adjust it again.
  struct GrownModel {
    Reconstruction model;
    std::map<int, IntrinsicsStddev> stddev;  // From its last final adjustment.
    int init_image1 = kInvalidId;            // The gauge of its adjustments.
    int init_image2 = kInvalidId;
    std::set<int> contradicted;  // Photos it removed (RemoveContradictedPhoto).
    bool merged = false;         // Another model was merged into it since its final adjustment.
    int id = 0;  // For MergeAll: which model, and how often it has grown by merging.
    int version = 0;
  };

  // Replaces the initial intrinsics of the input (a focal hypothesis).
  void SetInitialCameras(const std::map<int, Camera>& cameras) { cameras_ = cameras; }

  // A small model for the focal search: the initial pair, photos up to `max_images`, then one
  // global adjustment (which refines the focal when the model has at least
  // `min_images_for_intrinsics` photos). The model is empty when no initial pair is found.
  // When a seed's model stays at two photos (its pair is cut off from the others), the next
  // seed among the photos left is tried, up to `max_seeds` seeds.
  Reconstruction RunTrial(int max_images, int max_seeds) {
    max_images_ = static_cast<std::size_t>(max_images);
    contradicted_.clear();
    Reconstruction model;
    for (int seed = 0; seed < max_seeds; ++seed) {
      track_point_.clear();
      point_track_.clear();
      Reconstruction next;
      if (!Initialize(&next)) break;
      model = std::move(next);
      Grow(&model);
      if (model.images.size() > 2) {
        GlobalAdjust(&model, /*final=*/false);
        break;
      }
      for (const auto& [id, image] : model.images) used_.insert(id);
    }
    return model;
  }

 private:
  void Note(const std::string& line) {
    LOG_INFO << "sfm: " << line;
    if (summary_ != nullptr) summary_->log.push_back(line);
  }

  // Undistorted normalised coordinates of a keypoint; nullopt outside the invertible range.
  std::optional<Eigen::Vector2d> Normalized(const Camera& camera,
                                            const Eigen::Vector2d& pixel) const {
    const auto ray = camera.CamFromImg(pixel);
    if (!ray) return std::nullopt;
    return ray->head<2>();
  }

  // Models are sorted largest first. A photo registered in several models (a later model
  // may re-register photos of earlier ones, see Grow) stays in the largest; smaller models
  // lose it and are dropped when fewer than `min_model_images` photos remain.
  void ResolveSharedPhotos(std::vector<Reconstruction>* models) {
    std::set<int> claimed;
    std::vector<Reconstruction> kept;
    for (Reconstruction& model : *models) {
      std::vector<int> shared;
      for (const auto& [id, image] : model.images) {
        if (claimed.count(id)) shared.push_back(id);
      }
      for (int id : shared) RemoveImage(&model, id);
      if (!shared.empty()) {
        Note("a model of " + std::to_string(model.images.size() + shared.size()) +
             " photos shares " + std::to_string(shared.size()) + " with a larger model; it keeps " +
             std::to_string(model.images.size()));
      }
      if (static_cast<int>(model.images.size()) < options_.min_model_images) continue;
      for (const auto& [id, image] : model.images) claimed.insert(id);
      kept.push_back(std::move(model));
    }
    *models = std::move(kept);
  }

  // Merges the models that share photos or tracks (model_merger.h), each into the largest that
  // takes it, until no merge succeeds.
  void MergeAll(std::vector<GrownModel>* grown) {
    ModelMergerOptions merge = options_.merge;
    merge.max_reprojection_error_px = options_.max_reprojection_error_px;
    for (std::size_t k = 0; k < grown->size(); ++k) (*grown)[k].id = static_cast<int>(k);
    // Pairs refused as they were (ids and versions): tried again only when either changed.
    std::set<std::tuple<int, int, int, int>> refused;
    int merges = 0, refusals = 0;
    for (bool changed = true; changed;) {
      changed = false;
      std::stable_sort(grown->begin(), grown->end(), [](const GrownModel& a, const GrownModel& b) {
        return a.model.images.size() > b.model.images.size();
      });
      for (std::size_t i = 0; i < grown->size() && !changed; ++i) {
        for (std::size_t j = i + 1; j < grown->size() && !changed; ++j) {
          cancel_.ThrowIfCanceled();
          GrownModel& into = (*grown)[i];
          const GrownModel& from = (*grown)[j];
          const auto key = std::make_tuple(into.id, into.version, from.id, from.version);
          if (refused.count(key)) continue;
          init_image1_ = into.init_image1;
          init_image2_ = into.init_image2;
          const BundleAdjustmentOptions ba = GlobalBundleOptions(into.model, /*final=*/false);
          const MergeSummary merged =
              MergeModels(from.model, &track_of_, merge, ba, cancel_, &into.model);
          Note(merged.message);
          if (!merged.merged) {
            ++refusals;
            refused.insert(key);
            continue;
          }
          ++merges;
          into.contradicted.insert(from.contradicted.begin(), from.contradicted.end());
          into.merged = true;
          ++into.version;
          grown->erase(grown->begin() + static_cast<std::ptrdiff_t>(j));
          changed = true;  // Sizes changed: every pair with the merged model is tried again.
        }
      }
    }
    if (merges + refusals > 0) {
      Note("model merging: " + std::to_string(merges) + " merged, " + std::to_string(refusals) +
           " refused; " + std::to_string(grown->size()) + " model(s) left");
    }
    if (summary_ != nullptr) summary_->num_merges = merges;
  }

  // After the global adjustment of a merged model, the photos left out are tried again with the
  // model's final intrinsics; the final adjustment follows when any joins.
  void Reregister(GrownModel* g) {
    Reconstruction& model = g->model;
    init_image1_ = g->init_image1;
    init_image2_ = g->init_image2;
    contradicted_ = g->contradicted;
    AdoptTrackPoints(model);
    if (g->merged) {
      Finish(&model);
      g->stddev = final_stddev_;
    }
    const std::size_t before = model.images.size();
    last_global_size_ = before;
    Grow(&model);
    g->contradicted = contradicted_;
    if (model.images.size() == before) return;
    Note("re-registration with the final intrinsics: " +
         std::to_string(model.images.size() - before) + " photo(s) joined a model of " +
         std::to_string(before));
    if (summary_ != nullptr) {
      summary_->num_reregistered += static_cast<int>(model.images.size() - before);
    }
    for (const auto& [id, image] : model.images) used_.insert(id);
    Finish(&model);
    g->stddev = final_stddev_;
    g->contradicted = contradicted_;
  }

  // The track <-> point maps of `model` (built by another pass or merged): each point stands
  // for the track of its observations; a track with two points keeps the first.
  void AdoptTrackPoints(const Reconstruction& model) {
    track_point_.clear();
    point_track_.clear();
    for (const auto& [id, point] : model.points) {
      for (const Observation& o : point.observations) {
        const int track = track_of_.at(o.image_id)[o.keypoint];
        if (track < 0 || track_point_.count(track)) continue;
        track_point_[track] = id;
        point_track_[id] = track;
        break;
      }
    }
  }

  static void RemoveImage(Reconstruction* model, int image_id) {
    const std::vector<int> points = model->images.at(image_id).point_for_keypoint;
    for (int kp = 0; kp < static_cast<int>(points.size()); ++kp) {
      if (points[kp] != kInvalidId && model->points.count(points[kp])) {
        model->DeleteObservation(points[kp], {image_id, kp});
      }
    }
    model->images.erase(image_id);
  }

  // ---------------------------------------------------------------------------------------
  // Initial pair.

  // What an initial pair must show (IncrementalMapperOptions: the usual bar, or the weak one
  // used when nothing better exists).
  struct InitialPairBar {
    int min_inliers = 0;             // Verified matches of the pair.
    int min_in_front = 0;            // Essential-matrix inliers in front of both cameras.
    int min_points = 0;              // Triangulated, and after the pair's adjustment.
    double min_angle_deg = 0;        // Median triangulation angle.
    double min_essential_share = 0;  // In-front essential inliers / matches used.
    bool weak = false;
  };

  // A weak initial pair whose essential-matrix inliers a homography fits beyond this share
  // (at 3 px, see TryInitialPair) is refused (COLMAP's initial pair uses a similar H/E ratio).
  static constexpr double kMaxWeakHomographyShare = 0.8;

  bool Initialize(Reconstruction* model) {
    InitialPairBar bar;
    bar.min_inliers = options_.min_initial_inliers;
    bar.min_in_front = options_.min_initial_inliers / 2;
    bar.min_points = std::max(30, options_.min_initial_inliers / 2);
    bar.min_angle_deg = options_.min_initial_angle_deg;
    if (InitializeWith(bar, model)) return true;
    // Nothing better exists: no pair met the usual bar and no photo is reconstructed yet.
    if (options_.weak_initial_inliers <= 0 || !used_.empty()) return false;
    InitialPairBar weak;
    weak.min_inliers = options_.weak_initial_inliers;
    weak.min_essential_share = options_.weak_initial_essential_share;
    weak.min_in_front = static_cast<int>(std::ceil(weak.min_inliers * weak.min_essential_share));
    weak.min_points = weak.min_in_front;
    weak.min_angle_deg = options_.weak_initial_angle_deg;
    weak.weak = true;
    return InitializeWith(weak, model);
  }

  bool InitializeWith(const InitialPairBar& bar, Reconstruction* model) {
    std::vector<const MapperPair*> candidates;
    for (const MapperPair& pair : input_.pairs) {
      if (!pair.epipolar || static_cast<int>(pair.matches.size()) < bar.min_inliers) continue;
      if (used_.count(pair.image1) || used_.count(pair.image2)) continue;
      if (tried_initial_.count({pair.image1, pair.image2, bar.weak})) continue;
      candidates.push_back(&pair);
    }
    auto score = [](const MapperPair* p) {
      const double h_share = p->num_inliers_F > 0
                                 ? std::clamp(double(p->num_inliers_H) / p->num_inliers_F, 0.0, 1.0)
                                 : 1.0;
      return p->matches.size() * (1.0 - 0.8 * h_share);
    };
    std::stable_sort(candidates.begin(), candidates.end(),
                     [&](const MapperPair* a, const MapperPair* b) { return score(a) > score(b); });
    const int trials = std::min<int>(candidates.size(), options_.max_initial_pair_trials);
    for (int k = 0; k < trials; ++k) {
      cancel_.ThrowIfCanceled();
      const MapperPair& pair = *candidates[k];
      tried_initial_.insert({pair.image1, pair.image2, bar.weak});
      std::string why;
      if (TryInitialPair(pair, bar, model, &why)) {
        Note(std::string(bar.weak ? "weak initial pair " : "initial pair ") +
             input_.images.at(pair.image1).name + " + " + input_.images.at(pair.image2).name +
             ": " + why +
             (bar.weak ? " (no pair has " + std::to_string(options_.min_initial_inliers) +
                             " matches and a good geometry)"
                       : ""));
        return true;
      }
      LOG_DEBUG << "sfm: " << (bar.weak ? "weak " : "") << "initial pair " << pair.image1 << "-"
                << pair.image2 << " rejected: " << why;
    }
    return false;
  }

  bool TryInitialPair(const MapperPair& pair,
                      const InitialPairBar& bar,
                      Reconstruction* model,
                      std::string* why) {
    const MapperImage& image1 = input_.images.at(pair.image1);
    const MapperImage& image2 = input_.images.at(pair.image2);
    const Camera& camera1 = cameras_.at(image1.camera_id);
    const Camera& camera2 = cameras_.at(image2.camera_id);

    std::vector<Eigen::Vector2d> p1, p2;
    std::vector<const FeatureMatch*> used;
    for (const FeatureMatch& m : pair.matches) {
      const auto a = Normalized(camera1, image1.keypoints[m.index1]);
      const auto b = Normalized(camera2, image2.keypoints[m.index2]);
      if (!a || !b) continue;
      p1.push_back(*a);
      p2.push_back(*b);
      used.push_back(&m);
    }
    if (p1.size() < 8) {
      *why = "too few matches";
      return false;
    }
    // The essential matrix by RANSAC, then refined over every match (RefineRelativePose): a
    // small object's RANSAC pose can be many degrees off. The dim ring of
    // tests/few_features_test detected at the usual SIFT threshold started from a pair whose
    // median triangulation angle came out 45 deg for photos 22 deg apart; refined, 24 deg.
    RelativeRegistrationOptions relative;  // Its 1.5 px threshold.
    relative.min_pair_inliers = 8;
    const double focal = 0.5 * (camera1.focal + camera2.focal);
    const std::optional<PairPose> pose = EstimateRelativePose(p1, p2, focal, relative);
    const int in_front = pose ? pose->num_inliers : 0;
    if (!pose || in_front < bar.min_in_front || in_front < bar.min_essential_share * p1.size()) {
      *why = "only " + std::to_string(in_front) + " of " + std::to_string(p1.size()) +
             " matches agree with an essential matrix in front of both cameras";
      return false;
    }
    if (bar.weak) {
      // Few matches leave the essential matrix poorly constrained when a homography (a pure
      // rotation or a plane) explains them as well; the usual bar leaves that to GRIC's
      // F-versus-H choice over many matches, the weak one refuses it outright.
      std::vector<cv::Point2d> q1, q2;
      for (std::size_t i = 0; i < p1.size(); ++i) {
        if (!pose->inliers[i]) continue;
        q1.emplace_back(p1[i].x() * focal, p1[i].y() * focal);
        q2.emplace_back(p2[i].x() * focal, p2[i].y() * focal);
      }
      cv::Mat h_mask;
      // The transfer error puts both photos' noise into one: twice the essential matrix's
      // 1.5 px (at 0.5 px noise a pure rotation's matches fit at 1.5 px 25 of 40, at 3 px 38).
      const cv::Mat h = cv::findHomography(q1, q2, cv::RANSAC, 2.0 * relative.max_epipolar_error_px,
                                           h_mask, 2000, 0.999);
      const int h_inliers = h.empty() ? 0 : cv::countNonZero(h_mask);
      if (h_inliers > kMaxWeakHomographyShare * q1.size()) {
        *why = "a homography explains " + std::to_string(h_inliers) + " of its " +
               std::to_string(q1.size()) + " essential-matrix inliers";
        return false;
      }
    }
    const Eigen::Matrix3d r = pose->new_from_registered.rotation.toRotationMatrix();
    const Eigen::Vector3d t = pose->new_from_registered.translation;

    Reconstruction candidate;
    candidate.cameras[image1.camera_id] = camera1;
    candidate.cameras[image2.camera_id] = camera2;
    AddImage(&candidate, pair.image1, Rigid3d());
    AddImage(&candidate, pair.image2, Rigid3d(r, t));

    std::vector<double> angles;
    for (std::size_t i = 0; i < used.size(); ++i) {
      if (!pose->inliers[i]) continue;
      const FeatureMatch& m = *used[i];
      const int track = track_of_.at(pair.image1)[m.index1];
      if (track < 0 || track_of_.at(pair.image2)[m.index2] != track) continue;  // Inconsistent.
      if (track_point_.count(track)) continue;

      const std::vector<Observation> obs = {{pair.image1, m.index1}, {pair.image2, m.index2}};
      if (auto id = TriangulateObservations(&candidate, obs, track)) {
        angles.push_back(MaxAngle(candidate, candidate.points.at(*id)));
      }
    }

    const double median_angle = Median(angles);
    std::ostringstream s;
    s << angles.size() << " points, median triangulation angle " << median_angle << " deg";
    *why = s.str();
    if (static_cast<int>(angles.size()) < bar.min_points || median_angle < bar.min_angle_deg) {
      ForgetTrackPoints(candidate);
      return false;
    }

    BundleAdjustmentOptions ba = BaseBundleOptions();
    ba.constant_pose_image_ids = {pair.image1};
    ba.scale_fixing_image_id = pair.image2;
    ba.scale_fixing_translation_index = LargestComponent(t);
    ba.refine_focal = ba.refine_k1 = ba.refine_k2 = false;
    ba.loss = BundleAdjustmentLoss::kCauchy;
    BundleAdjust(ba, cancel_, &candidate);
    FilterPoints(&candidate, {pair.image1, pair.image2});
    if (static_cast<int>(candidate.points.size()) < bar.min_points) {
      *why += "; too few points survive bundle adjustment";
      ForgetTrackPoints(candidate);
      return false;
    }
    init_image1_ = pair.image1;
    init_image2_ = pair.image2;
    *model = std::move(candidate);
    last_global_size_ = 2;
    progress_.Advance(2);
    return true;
  }

  static int LargestComponent(const Eigen::Vector3d& v) {
    int index = 0;
    v.cwiseAbs().maxCoeff(&index);
    return index;
  }

  // ---------------------------------------------------------------------------------------
  // Growing the model.

  void Grow(Reconstruction* model) {
    std::set<int> failed;           // Photos that failed since the model last changed.
    std::set<int> failed_relative;  // ... by relative pose.
    while (model->images.size() < max_images_) {
      cancel_.ThrowIfCanceled();
      std::vector<std::pair<int, int>> candidates;  // (visible points, image)
      for (const auto& [id, image] : input_.images) {
        // Photos of earlier models may join this one too: a model that stopped growing at a
        // weak link (on templeSparseRing, a 4-photo arc seeded with a poor focal guess) is
        // then absorbed by a later model that reaches its photos from the other side of the
        // ring, and ResolveSharedPhotos drops it. Seeds (Initialize) stay unused photos.
        if (model->images.count(id) || failed.count(id) || contradicted_.count(id)) continue;
        int visible = 0;
        for (int track : track_of_.at(id)) visible += track >= 0 && track_point_.count(track);
        if (visible >= options_.min_registration_points) candidates.emplace_back(visible, id);
      }
      std::stable_sort(candidates.begin(), candidates.end(),
                       [](const auto& a, const auto& b) { return a.first > b.first; });
      bool registered = false;
      for (const auto& [visible, id] : candidates) {
        std::string why;
        if (TryRegister(model, id, &why)) {
          registered = true;
          failed.clear();
          LOG_INFO << "sfm: registered " << input_.images.at(id).name << " (" << why << "), "
                   << model->images.size() << " photos, " << model->points.size() << " points";
          if (!used_.count(id)) progress_.Advance();
          AfterRegistration(model, id);
          break;
        }
        LOG_DEBUG << "sfm: cannot register " << input_.images.at(id).name << ": " << why;
        failed.insert(id);
      }
      if (!registered && options_.relative_registration) {
        registered = RegisterByRelativePose(model, &failed_relative);
        if (registered) failed.clear();
      }
      if (!registered) return;
      failed_relative.clear();
    }
  }

  bool TryRegister(Reconstruction* model, int image_id, std::string* why) {
    const ScopedSeconds timed(&times_.registration);
    ++times_.registration_tries;
    const MapperImage& image = input_.images.at(image_id);
    if (!model->cameras.count(image.camera_id)) {
      model->cameras[image.camera_id] = cameras_.at(image.camera_id);
    }
    const Camera& camera = model->cameras.at(image.camera_id);
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> normalized;
    std::vector<int> keypoints;
    const std::vector<int>& tracks = track_of_.at(image_id);
    for (int kp = 0; kp < static_cast<int>(tracks.size()); ++kp) {
      if (tracks[kp] < 0) continue;
      auto it = track_point_.find(tracks[kp]);
      if (it == track_point_.end()) continue;
      const auto n = Normalized(camera, image.keypoints[kp]);
      if (!n) continue;
      const Eigen::Vector3d& x = model->points.at(it->second).xyz_in_world;
      object.emplace_back(x.x(), x.y(), x.z());
      normalized.emplace_back(n->x(), n->y());
      keypoints.push_back(kp);
    }
    if (static_cast<int>(object.size()) < options_.min_registration_points) {
      *why = std::to_string(object.size()) + " correspondences";
      return false;
    }
    cv::theRNG().state = kSeed + image_id;
    cv::Mat rvec, tvec;
    std::vector<int> inliers;
    const bool found = cv::solvePnPRansac(
        object, normalized, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec, tvec, false, 2000,
        static_cast<float>(options_.pnp_max_error_px / camera.focal), 0.9999, inliers,
        cv::SOLVEPNP_AP3P);
    if (!found || static_cast<int>(inliers.size()) < options_.min_registration_points ||
        inliers.size() < options_.min_pnp_inlier_ratio * object.size()) {
      *why = std::to_string(inliers.size()) + " PnP inliers of " + std::to_string(object.size());
      return false;
    }
    cv::Mat r_cv;
    cv::Rodrigues(rvec, r_cv);
    Eigen::Matrix3d r;
    Eigen::Vector3d t;
    cv::cv2eigen(r_cv, r);
    cv::cv2eigen(tvec, t);
    Rigid3d pose(r, t);

    std::vector<Eigen::Vector2d> points2d;
    std::vector<Eigen::Vector3d> points3d;
    for (int i : inliers) {
      points2d.push_back(image.keypoints[keypoints[i]]);
      points3d.emplace_back(object[i].x, object[i].y, object[i].z);
    }
    PoseRefinementOptions refine;
    RefinePose(refine, camera, points2d, points3d, &pose);

    AddImage(model, image_id, pose);
    const int added = AddVisibleObservations(model, image_id);
    *why = std::to_string(inliers.size()) + " PnP inliers of " + std::to_string(object.size());
    return added >= options_.min_registration_points / 2;
  }

  // Adds the observations of the reconstructed points that a registered photo sees within
  // `max_error_px` (default: the reprojection threshold) and does not observe yet; returns
  // how many.
  int AddVisibleObservations(Reconstruction* model, int image_id, double max_error_px = 0) {
    if (max_error_px <= 0) max_error_px = options_.max_reprojection_error_px;
    const MapperImage& image = input_.images.at(image_id);
    const Camera& camera = model->cameras.at(image.camera_id);
    const Rigid3d pose = model->images.at(image_id).cam_from_world;
    const std::vector<int>& tracks = track_of_.at(image_id);
    int added = 0;
    for (int kp = 0; kp < static_cast<int>(tracks.size()); ++kp) {
      if (tracks[kp] < 0 || model->images.at(image_id).point_for_keypoint[kp] != kInvalidId)
        continue;
      auto it = track_point_.find(tracks[kp]);
      if (it == track_point_.end()) continue;
      const Point3D& point = model->points.at(it->second);
      if (!HasPositiveDepth(pose, point.xyz_in_world)) continue;
      const auto pixel = camera.ImgFromCam(pose * point.xyz_in_world);
      if (!pixel || (*pixel - image.keypoints[kp]).norm() > max_error_px) continue;
      model->AddObservation(it->second, {image_id, kp});
      ++added;
    }
    return added;
  }

  // Registration by relative pose (relative_registration.h) when PnP can place no photo: the
  // unregistered photo with most verified matches to registered photos first. Photos that
  // fail go into `failed`.
  bool RegisterByRelativePose(Reconstruction* model, std::set<int>* failed) {
    std::map<int, std::vector<const MapperPair*>> links;  // Photo -> pairs with the model.
    for (const MapperPair& pair : input_.pairs) {
      if (!pair.epipolar ||
          static_cast<int>(pair.matches.size()) < options_.relative.min_pair_inliers) {
        continue;
      }
      const bool in1 = model->images.count(pair.image1) > 0;
      const bool in2 = model->images.count(pair.image2) > 0;
      if (in1 == in2) continue;
      const int fresh = in1 ? pair.image2 : pair.image1;
      if (!failed->count(fresh) && !contradicted_.count(fresh)) links[fresh].push_back(&pair);
    }
    std::vector<std::pair<std::size_t, int>> ranked;  // (matches, photo)
    for (const auto& [id, pairs] : links) {
      std::size_t matches = 0;
      for (const MapperPair* pair : pairs) matches += pair->matches.size();
      ranked.emplace_back(matches, id);
    }
    std::stable_sort(ranked.begin(), ranked.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    for (const auto& [matches, id] : ranked) {
      cancel_.ThrowIfCanceled();
      const MapperImage& image = input_.images.at(id);
      if (!model->cameras.count(image.camera_id)) {
        model->cameras[image.camera_id] = cameras_.at(image.camera_id);
      }
      std::string how;
      const std::optional<Rigid3d> pose = RelativePoseOf(*model, id, links.at(id), &how);
      if (!pose) {
        LOG_DEBUG << "sfm: cannot register " << image.name << " by relative pose: " << how;
        failed->insert(id);
        continue;
      }
      AddImage(model, id, *pose);
      // The pose from two views is only as good as they make it (relative_registration.h):
      // the points that agreed on the scale may reproject well beyond the usual threshold.
      // Their observations tie the photo to the model in the local adjustment (the pair's own
      // points only to its neighbour, up to two-view ambiguities), which also filters them.
      const double loose_px = model->cameras.at(image.camera_id).focal *
                              std::tan(options_.relative.max_scale_angle_deg * M_PI / 180.0);
      const int added =
          AddVisibleObservations(model, id, std::max(loose_px, options_.max_reprojection_error_px));
      if (!used_.count(id)) progress_.Advance();
      if (summary_ != nullptr) ++summary_->num_relative_registrations;
      AfterRegistration(model, id);
      const int more = AddVisibleObservations(model, id);
      Note("registered " + image.name + " by relative pose " + how + "; it sees " +
           std::to_string(added) + " points, " + std::to_string(more) +
           " more after the local adjustment");
      return true;
    }
    return false;
  }

  // The pose of unregistered photo `id` from its `pairs` with registered photos: the scale from
  // the points it sees, else the rays of two or more neighbours.
  std::optional<Rigid3d> RelativePoseOf(const Reconstruction& model,
                                        int id,
                                        const std::vector<const MapperPair*>& pairs,
                                        std::string* how) {
    const MapperImage& image = input_.images.at(id);
    const Camera& camera = model.cameras.at(image.camera_id);
    std::vector<std::pair<NeighbourPose, int>> neighbours;  // With the neighbour's id.
    int low_parallax = 0;  // Pairs whose pose leaves the baseline's direction undetermined.
    for (const MapperPair* pair : pairs) {
      const bool registered_first = pair->image1 != id;
      const int other = registered_first ? pair->image1 : pair->image2;
      const RegisteredImage& neighbour = model.images.at(other);
      const Camera& other_camera = model.cameras.at(neighbour.camera_id);
      std::vector<Eigen::Vector2d> a, b;
      for (const FeatureMatch& m : pair->matches) {
        const auto x =
            Normalized(other_camera, neighbour.keypoints[registered_first ? m.index1 : m.index2]);
        const auto y = Normalized(camera, image.keypoints[registered_first ? m.index2 : m.index1]);
        if (!x || !y) continue;
        a.push_back(*x);
        b.push_back(*y);
      }
      const double focal = 0.5 * (camera.focal + other_camera.focal);
      if (auto relative = EstimateRelativePose(a, b, focal, options_.relative)) {
        if (relative->median_parallax_deg < options_.relative.min_median_parallax_deg) {
          ++low_parallax;
          LOG_DEBUG << "sfm: " << image.name << " - " << input_.images.at(other).name
                    << ": relative pose with " << relative->num_inliers
                    << " inliers refused, median parallax " << relative->median_parallax_deg
                    << " deg";
          continue;
        }
        neighbours.push_back({{neighbour.cam_from_world, *relative}, other});
      }
    }
    std::stable_sort(neighbours.begin(), neighbours.end(), [](const auto& a, const auto& b) {
      return a.first.relative.num_inliers > b.first.relative.num_inliers;
    });
    std::vector<Eigen::Vector3d> points;
    std::vector<Eigen::Vector2d> observations;
    const std::vector<int>& tracks = track_of_.at(id);
    for (int kp = 0; kp < static_cast<int>(tracks.size()); ++kp) {
      auto it = tracks[kp] < 0 ? track_point_.end() : track_point_.find(tracks[kp]);
      if (it == track_point_.end()) continue;
      const auto n = Normalized(camera, image.keypoints[kp]);
      if (!n) continue;
      points.push_back(model.points.at(it->second).xyz_in_world);
      observations.push_back(*n);
    }
    for (const auto& [neighbour, other] : neighbours) {
      const auto r = RegisterFromPoints(neighbour, points, observations, options_.relative);
      if (!r) continue;
      *how = "from " + input_.images.at(other).name + " (" +
             std::to_string(neighbour.relative.num_inliers) + " inliers), scale from " +
             std::to_string(r->num_points) + " of " + std::to_string(points.size()) + " points";
      return r->cam_from_world;
    }
    std::vector<NeighbourPose> rays;
    for (const auto& [neighbour, other] : neighbours) rays.push_back(neighbour);
    if (const auto r = RegisterFromRays(rays, options_.relative)) {
      *how = "from the rays of " + std::to_string(r->num_rays) + " neighbours";
      return r->cam_from_world;
    }
    *how =
        std::to_string(neighbours.size()) + " of " + std::to_string(pairs.size()) +
        " pairs with a relative pose" +
        (low_parallax > 0 ? " (" + std::to_string(low_parallax) + " more with too little parallax)"
                          : "") +
        ", " + std::to_string(points.size()) + " points seen: no scale";
    return std::nullopt;
  }

  void AfterRegistration(Reconstruction* model, int image_id) {
    TriangulateImage(model, image_id);
    // Local adjustment: the new photo and the photos that share most points with it.
    std::map<int, int> shared;
    const RegisteredImage& image = model->images.at(image_id);
    for (int point_id : image.point_for_keypoint) {
      if (point_id == kInvalidId) continue;
      for (const Observation& o : model->points.at(point_id).observations) {
        if (o.image_id != image_id) ++shared[o.image_id];
      }
    }
    std::vector<std::pair<int, int>> ranked;
    for (const auto& [id, count] : shared) ranked.emplace_back(count, id);
    std::sort(ranked.rbegin(), ranked.rend());
    std::vector<int> variable = {image_id};
    for (const auto& [count, id] : ranked) {
      if (static_cast<int>(variable.size()) >= options_.local_ba_num_images) break;
      if (id != init_image1_) variable.push_back(id);
    }
    BundleAdjustmentOptions ba = BaseBundleOptions();
    ba.variable_pose_image_ids = variable;
    ba.constant_pose_image_ids = {init_image1_};
    ba.refine_focal = ba.refine_k1 = ba.refine_k2 = false;
    ba.loss = BundleAdjustmentLoss::kCauchy;
    ba.max_num_iterations = 25;
    {
      const ScopedSeconds timed(&times_.local_adjustment);
      ++times_.local_adjustments;
      BundleAdjust(ba, cancel_, model);
    }
    FilterPoints(model, std::set<int>(variable.begin(), variable.end()));

    if (model->images.size() >= global_ba_growth_threshold()) {
      GlobalAdjust(model, /*final=*/false);
    }
  }

  std::size_t global_ba_growth_threshold() const {
    return static_cast<std::size_t>(std::ceil(last_global_size_ * options_.global_ba_growth));
  }

  // The options of a global adjustment (the gauge fixed by the initial pair).
  BundleAdjustmentOptions GlobalBundleOptions(const Reconstruction& model, bool final) const {
    BundleAdjustmentOptions ba = BaseBundleOptions();
    ba.constant_pose_image_ids = {init_image1_};
    ba.scale_fixing_image_id = init_image2_;
    ba.scale_fixing_translation_index =
        LargestComponent(model.images.at(init_image2_).cam_from_world.translation);
    const bool intrinsics =
        static_cast<int>(model.images.size()) >= options_.min_images_for_intrinsics;
    ba.refine_focal = options_.refine_focal && intrinsics;
    ba.refine_k1 = ba.refine_k2 = options_.refine_distortion && intrinsics;
    ba.loss = final ? BundleAdjustmentLoss::kTrivial : BundleAdjustmentLoss::kCauchy;
    if (!final) {
      // Intermediate adjustments only need to keep the growing model sound for the next
      // registrations; the final ones converge tightly. Ceres' default tolerance and
      // COLMAP's iteration cap here cut the mapping time on fountain-P11 from 38 to 27 s with
      // the same final accuracy.
      ba.function_tolerance = kIntermediateFunctionTolerance;
      ba.max_num_iterations = kIntermediateMaxIterations;
    }
    return ba;
  }
  static constexpr double kIntermediateFunctionTolerance = 1e-6;
  static constexpr int kIntermediateMaxIterations = 50;

  static std::set<int> AllImageIds(const Reconstruction& model) {
    std::set<int> ids;
    for (const auto& [id, image] : model.images) ids.insert(id);
    return ids;
  }

  void GlobalAdjust(Reconstruction* model, bool final) {
    const ScopedSeconds timed(&times_.global_adjustment);
    ++times_.global_adjustments;
    BundleAdjustmentOptions ba = GlobalBundleOptions(*model, final);
    const bool principal_point =
        final && options_.principal_point != PrincipalPointMode::kCenter &&
        static_cast<int>(model->images.size()) >= options_.min_images_for_principal_point;
    ba.refine_principal_point =
        principal_point && options_.principal_point == PrincipalPointMode::kRefine;
    const BundleAdjustmentSummary summary = BundleAdjust(ba, cancel_, model);
    LOG_INFO << "sfm: global adjustment of " << model->images.size()
             << " photos: " << summary.BriefReport();
    principal_point_ = {ba.refine_principal_point, false, false};
    if (principal_point && options_.principal_point == PrincipalPointMode::kAuto &&
        summary.success) {
      DecidePrincipalPoint(ba, model);
    }
    FilterPoints(model, AllImageIds(*model));
    last_global_size_ = model->images.size();
  }

  // Model selection for the principal point (PrincipalPointMode::kAuto). `model` has just
  // converged with the principal point held under `ba` (least squares, no robust loss, so the
  // cost is half the sum of squared residuals); the same problem is solved again with it
  // free, from there. With n residuals, the drop D in the sum of squares, measured in units of
  // the residual variance s² = SSR_free / n, is chi-square distributed with k = 2 x cameras
  // degrees of freedom when the centre is right; BIC accepts the free principal point when
  // D > k ln n (20 for 2 parameters and 24,000 residuals: far beyond chance, yet a real offset
  // of a few pixels seen in thousands of points clears it by orders of magnitude).
  //
  // A principal point the BIC accepts may still be known well on one axis only: on a ring of
  // photos at one height looking inwards, a common shift of cy tilts every camera up or down
  // together, which the structure nearly absorbs, while cx is fixed by the ring's closure. The
  // free solve also estimates the principal point's standard deviations, and a coordinate
  // known to no better than `max_principal_point_stddev` of the longer image side (1.5 %, in
  // the range of real cameras' offsets: 0.7 % on fountain-P11, 0.9 % on kermit, 2.7 % on
  // templeSparseRing) stays at the centre, where its error is then likely no larger than the
  // estimate's; the other coordinate alone is decided again by the same test (where the
  // deviations cannot be estimated, beyond BundleAdjustmentOptions::max_poses_for_stddev
  // photos, both are decided together as before). Measured: a
  // rendered inward arc of 10 photos over 270 deg (tests/sparse_pipeline_test) had cy 15 px
  // off at a standard deviation of 16 px, taken along with a significant 0.3 px move of cx
  // (0.06 px): relative rotations 1.44 deg; with cy held, 0.08 deg. The dim ring of
  // tests/few_features_test without feature adaptation, (5, 15) px: 3.3 -> 0.72 deg.
  // templeSparseRing's every second photo (2.6, 6.8) px, 7 px off the centre in cy, keeps
  // both (held there: 1.72 -> 2.20 deg, focal 0.73 -> 2.12 %, with a bar of 1 %).
  void DecidePrincipalPoint(const BundleAdjustmentOptions& held, Reconstruction* model) {
    struct Trial {
      Reconstruction model;
      BundleAdjustmentSummary summary;
      double drop = 0.0, price = 0.0, max_shift = 0.0;
      bool plausible = true;
    };
    const auto solve = [&](bool hold_x, bool hold_y) -> std::optional<Trial> {
      Trial t{*model, {}};
      BundleAdjustmentOptions ba = held;
      ba.refine_principal_point = true;
      ba.hold_principal_point_x = hold_x;
      ba.hold_principal_point_y = hold_y;
      ba.estimate_intrinsics_stddev = !hold_x && !hold_y;
      t.summary = BundleAdjust(ba, cancel_, &t.model);
      const BundleAdjustmentSummary& free = t.summary;
      if (!free.success || free.final_cost <= 0.0 || free.num_observations == 0) {
        return std::nullopt;
      }
      const double n = 2.0 * free.num_observations;
      const double k = (hold_x || hold_y ? 1.0 : 2.0) * static_cast<double>(t.model.cameras.size());
      t.drop = n * (free.initial_cost - free.final_cost) / free.final_cost;
      t.price = k * std::log(n);
      for (const auto& [id, camera] : t.model.cameras) {
        const Camera& before = model->cameras.at(id);
        const double shift = std::hypot(camera.cx - before.cx, camera.cy - before.cy);
        t.max_shift = std::max(t.max_shift, shift);
        t.plausible = t.plausible && shift <= options_.max_principal_point_shift *
                                                  std::max(camera.width, camera.height);
      }
      return t;
    };
    std::optional<Trial> trial = solve(false, false);
    if (!trial) return;
    std::ostringstream line;
    line << std::fixed << std::setprecision(1) << "principal point: residual drop " << trial->drop
         << " (BIC price " << trial->price << "), shift " << trial->max_shift << " px";
    bool hold_x = false, hold_y = false;
    if (trial->drop > trial->price && trial->plausible) {
      for (const auto& [id, stddev] : trial->summary.intrinsics_stddev) {
        const Camera& camera = model->cameras.at(id);
        const double bar =
            options_.max_principal_point_stddev * std::max(camera.width, camera.height);
        line << ", stddev (" << stddev.cx << ", " << stddev.cy << ") px";
        hold_x = hold_x || stddev.cx > bar;
        hold_y = hold_y || stddev.cy > bar;
      }
      if (hold_x && hold_y) {
        line << ": kept at the centre (the photos determine it too poorly)";
        trial.reset();
      } else if (hold_x || hold_y) {
        line << ": " << (hold_x ? "cx" : "cy") << " held at the centre (determined too poorly)";
        trial = solve(hold_x, hold_y);
        if (trial) {
          line << "; the other alone: residual drop " << trial->drop << " (BIC price "
               << trial->price << ")";
          if (!(trial->drop > trial->price && trial->plausible)) trial.reset();
        }
      }
    } else {
      line << (trial->plausible ? ": kept at the centre (not supported by the data)"
                                : ": kept at the centre (implausible shift)");
      trial.reset();
    }
    if (trial) {
      *model = std::move(trial->model);
      principal_point_ = {true, hold_x, hold_y};
      line << ": refined";
      for (const auto& [id, camera] : model->cameras) {
        line << " [camera " << id << ": " << camera.cx << ", " << camera.cy << "]";
      }
    } else if (hold_x != hold_y) {
      line << ": kept at the centre";
    }
    Note(line.str());
  }

  // IncrementalMapperOptions::final_outlier_multiple: the bar from the model's median
  // reprojection error (a 2-D Gaussian's error norm exceeds 6 medians once in 10^11 times, so
  // only the heavy tail goes: matches a pixel or two off that the 4 px bar of the growing
  // model lets bend the poses). nullopt when the filter is off or the bar would not tighten.
  struct OutlierBar {
    double median_px = 0.0;
    double bar_px = 0.0;
  };
  std::optional<OutlierBar> FinalOutlierBar(const Reconstruction& model) const {
    if (options_.final_outlier_multiple <= 0) return std::nullopt;
    std::vector<double> errors;
    for (const auto& [id, point] : model.points) {
      for (const Observation& o : point.observations)
        errors.push_back(model.ReprojectionError(point, o));
    }
    if (errors.empty()) return std::nullopt;
    std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
    OutlierBar bar;
    bar.median_px = errors[errors.size() / 2];
    bar.bar_px = std::clamp(options_.final_outlier_multiple * bar.median_px,
                            options_.final_min_outlier_px, options_.max_reprojection_error_px);
    if (bar.bar_px >= options_.max_reprojection_error_px) return std::nullopt;
    return bar;
  }

  // The final adjustments (FinishOnce), then the check against the verified pairs: while a
  // photo's pose contradicts them, it leaves the model and the model is finished again.
  void Finish(Reconstruction* model) {
    FinishOnce(model);
    while (model->images.size() > 2 && RemoveContradictedPhoto(model)) {
      AdoptTrackPoints(*model);
      FinishOnce(model);
    }
  }

  // A verified pair of two registered photos whose own relative pose contradicts the one the
  // model gives them (IncrementalMapperOptions::contradiction_min_rotation_deg).
  struct Contradiction {
    int image1 = kInvalidId;
    int image2 = kInvalidId;
    int matches = 0;
    int model_explains = 0;  // Matches within the reprojection threshold of the model's poses.
    int pair_explains = 0;   // Inliers of the pair's own relative pose.
    double rotation_deg = 0.0;
  };

  // The rotation a pair's own pose must differ from the model's by to contradict it: the
  // lower contradiction_clear_rotation_deg when that pose explains clearly more of the
  // pair's matches than the model does (by contradiction_clear_margin of them), else
  // contradiction_min_rotation_deg.
  double RotationBar(int own_inliers, int explained, std::size_t matches) const {
    const bool clear = own_inliers - explained >=
                       options_.contradiction_clear_margin * static_cast<double>(matches);
    return clear ? options_.contradiction_clear_rotation_deg
                 : options_.contradiction_min_rotation_deg;
  }

  // Also adds to `support` (image id -> matches) the matches of each photo's other checked
  // pairs that the model explains.
  std::vector<Contradiction> FindContradictions(const Reconstruction& model,
                                                std::map<int, int>* support) {
    std::vector<Contradiction> found;
    if (!(options_.contradiction_min_rotation_deg > 0)) return found;
    for (const MapperPair& pair : input_.pairs) {
      if (!pair.epipolar ||
          static_cast<int>(pair.matches.size()) < options_.contradiction_min_matches) {
        continue;
      }
      auto it1 = model.images.find(pair.image1);
      auto it2 = model.images.find(pair.image2);
      if (it1 == model.images.end() || it2 == model.images.end()) continue;
      const Camera& camera1 = model.cameras.at(it1->second.camera_id);
      const Camera& camera2 = model.cameras.at(it2->second.camera_id);
      std::vector<Eigen::Vector2d> x1, x2;
      for (const FeatureMatch& m : pair.matches) {
        const auto a = Normalized(camera1, it1->second.keypoints[m.index1]);
        const auto b = Normalized(camera2, it2->second.keypoints[m.index2]);
        if (!a || !b) continue;
        x1.push_back(*a);
        x2.push_back(*b);
      }
      // A match the model's relative pose (image 2 from image 1) explains lies within the
      // reprojection threshold of its epipolar geometry (Sampson distance).
      const Rigid3d relative = it2->second.cam_from_world * it1->second.cam_from_world.Inverse();
      const double focal = 0.5 * (camera1.focal + camera2.focal);
      const double threshold = options_.max_reprojection_error_px / focal;
      int explained = 0;
      for (const double d : EpipolarDistances(relative, x1, x2)) explained += d < threshold;
      // Most pairs agree with their model (over 90 % of the matches): only the others cost a
      // relative pose estimate.
      const auto supports = [&] {
        (*support)[pair.image1] += explained;
        (*support)[pair.image2] += explained;
      };
      if (explained >= 0.9 * static_cast<double>(x1.size())) {
        supports();
        continue;
      }
      const std::optional<PairPose> own = EstimateRelativePose(x1, x2, focal, options_.relative);
      const double rotation_deg =
          own ? Eigen::AngleAxisd(own->new_from_registered.rotation * relative.rotation.inverse())
                        .angle() *
                    180.0 / M_PI
              : 0.0;
      LOG_DEBUG << "sfm: check " << input_.images.at(pair.image1).name << " - "
                << input_.images.at(pair.image2).name << ": the model explains " << explained
                << " of " << x1.size() << " matches; the pair's own pose: "
                << (own ? std::to_string(own->num_inliers) + " inliers, parallax " +
                              std::to_string(own->median_parallax_deg) + " deg, rotation " +
                              std::to_string(rotation_deg) + " deg off"
                        : std::string("none"));
      if (!own ||
          own->num_inliers <
              options_.contradiction_min_pair_share * static_cast<double>(x1.size()) ||
          own->median_parallax_deg < options_.contradiction_min_parallax_deg ||
          rotation_deg <= RotationBar(own->num_inliers, explained, x1.size())) {
        supports();
        continue;
      }
      found.push_back({pair.image1, pair.image2, static_cast<int>(x1.size()), explained,
                       own->num_inliers, rotation_deg});
    }
    return found;
  }

  // Removes the photo of `model` in most contradictions; on a tie the one whose other checked
  // pairs the model explains least (a photo placed wrongly by PnP often has only homography
  // pairs besides), then the later registered; never one of the initial pair, which fixes the
  // gauge. False when there is none to remove.
  bool RemoveContradictedPhoto(Reconstruction* model) {
    std::map<int, int> support;
    const std::vector<Contradiction> contradictions = FindContradictions(*model, &support);
    std::map<int, int> count;
    for (const Contradiction& c : contradictions) {
      ++count[c.image1];
      ++count[c.image2];
    }
    const auto rank = [&](int id) {
      return std::make_tuple(count.at(id), -support[id], registration_order_[id]);
    };
    int worst = kInvalidId;
    for (const auto& [id, n] : count) {
      if (id == init_image1_ || id == init_image2_) continue;
      if (worst == kInvalidId || rank(id) > rank(worst)) worst = id;
    }
    if (worst == kInvalidId) {
      if (!contradictions.empty()) {
        LOG_WARNING << "sfm: the initial pair's photos contradict " << contradictions.size()
                    << " verified pair(s); the model keeps them";
      }
      return false;
    }
    std::ostringstream line;
    line << std::fixed << std::setprecision(1) << "removed " << input_.images.at(worst).name
         << " from the model of " << model->images.size()
         << " photos: its pose contradicts the verified pair(s)";
    for (const Contradiction& c : contradictions) {
      if (c.image1 != worst && c.image2 != worst) continue;
      line << " " << input_.images.at(c.image1 == worst ? c.image2 : c.image1).name << " ("
           << c.matches << " matches: the model's poses explain " << c.model_explains
           << ", the pair's own relative pose " << c.pair_explains << ", rotations "
           << c.rotation_deg << " deg apart)";
    }
    Note(line.str());
    RemoveImage(model, worst);
    contradicted_.insert(worst);
    if (summary_ != nullptr) ++summary_->num_contradicted;
    return true;
  }

  void FinishOnce(Reconstruction* model) {
    // Tracks that could not be triangulated earlier may be now, with all photos in place.
    for (const auto& [id, image] : model->images) TriangulateImage(model, id);
    GlobalAdjust(model, /*final=*/false);
    GlobalAdjust(model, /*final=*/true);
    if (const std::optional<OutlierBar> bar = FinalOutlierBar(*model)) {
      // Twice: the first removal moves the poses, which shows more of the tail. The
      // adjustments keep the principal-point decision the final adjustment made.
      const std::size_t observations = model->NumObservations();
      const std::size_t points = model->points.size();
      const std::set<int> all = AllImageIds(*model);
      for (int round = 0; round < 2; ++round) {
        FilterPoints(model, all, bar->bar_px);
        const ScopedSeconds timed(&times_.global_adjustment);
        ++times_.global_adjustments;
        BundleAdjustmentOptions ba = GlobalBundleOptions(*model, /*final=*/true);
        ApplyPrincipalPoint(&ba);
        // From the optimum less about 1 % of the observations, at the tolerance of the
        // intermediate adjustments; the polish below ends at the final tolerance. On 100
        // rendered photos this took these two from 31 to 14 s, temple and fountain unchanged.
        ba.function_tolerance = kIntermediateFunctionTolerance;
        ba.max_num_iterations = kIntermediateMaxIterations;
        const BundleAdjustmentSummary summary = BundleAdjust(ba, cancel_, model);
        LOG_INFO << "sfm: adjustment of " << model->images.size()
                 << " photos after the outlier filter: " << summary.BriefReport();
      }
      FilterPoints(model, all, bar->bar_px);
      std::ostringstream line;
      line << std::fixed << std::setprecision(2)
           << "final outlier filter: median reprojection error " << bar->median_px << " px, bar "
           << bar->bar_px << " px: " << observations - model->NumObservations() << " of "
           << observations << " observations and " << points - model->points.size()
           << " points removed";
      Note(line.str());
    }
    // Back to the optimum without the points the last filter removed, and the precision of
    // the intrinsics there.
    BundleAdjustmentOptions ba = GlobalBundleOptions(*model, /*final=*/true);
    ApplyPrincipalPoint(&ba);
    ba.estimate_intrinsics_stddev = true;
    ba.max_num_iterations = 3;  // From an optimum less a few points: a polish.
    const ScopedSeconds timed(&times_.global_adjustment);
    const BundleAdjustmentSummary summary = BundleAdjust(ba, cancel_, model);
    LOG_INFO << "sfm: final adjustment of " << model->images.size()
             << " photos: " << summary.BriefReport();
    final_stddev_ = summary.intrinsics_stddev;
  }

  // ---------------------------------------------------------------------------------------
  // Triangulation and filtering.

  void AddImage(Reconstruction* model, int image_id, const Rigid3d& pose) {
    const MapperImage& source = input_.images.at(image_id);
    RegisteredImage& image = model->images[image_id];
    registration_order_[image_id] = ++registrations_;
    image.image_id = image_id;
    image.camera_id = source.camera_id;
    image.name = source.name;
    image.cam_from_world = pose;
    image.keypoints = source.keypoints;
    image.keypoint_stddevs = source.keypoint_stddevs;
    image.point_for_keypoint.assign(source.keypoints.size(), kInvalidId);
  }

  // Triangulates every track this photo observes that has no point yet.
  void TriangulateImage(Reconstruction* model, int image_id) {
    const ScopedSeconds timed(&times_.triangulation);
    const std::vector<int>& tracks = track_of_.at(image_id);
    for (int kp = 0; kp < static_cast<int>(tracks.size()); ++kp) {
      const int track = tracks[kp];
      if (track < 0 || track_point_.count(track)) continue;
      std::vector<Observation> obs;
      for (const Observation& o : input_.tracks[track].observations) {
        if (model->images.count(o.image_id)) obs.push_back(o);
      }
      if (obs.size() >= 2) TriangulateObservations(model, obs, track);
    }
  }

  // Triangulates `observations` (registered photos) into a new point for `track`, keeping the
  // observations that pass the depth and reprojection checks; returns the point id.
  std::optional<int> TriangulateObservations(Reconstruction* model,
                                             const std::vector<Observation>& observations,
                                             int track) {
    std::vector<Rigid3d> poses;
    std::vector<Eigen::Vector2d> points;
    std::vector<Observation> usable;
    for (const Observation& o : observations) {
      const RegisteredImage& image = model->images.at(o.image_id);
      if (image.point_for_keypoint[o.keypoint] != kInvalidId) continue;
      const auto n = Normalized(model->cameras.at(image.camera_id), image.keypoints[o.keypoint]);
      if (!n) continue;
      poses.push_back(image.cam_from_world);
      points.push_back(*n);
      usable.push_back(o);
    }
    if (usable.size() < 2) return std::nullopt;
    const auto x = TriangulatePoint(poses, points);
    if (!x) return std::nullopt;
    std::vector<Observation> kept;
    for (const Observation& o : usable) {
      const RegisteredImage& image = model->images.at(o.image_id);
      if (!HasPositiveDepth(image.cam_from_world, *x)) continue;
      const auto pixel = model->cameras.at(image.camera_id).ImgFromCam(image.cam_from_world * *x);
      if (!pixel ||
          (*pixel - image.keypoints[o.keypoint]).norm() > options_.max_reprojection_error_px) {
        continue;
      }
      kept.push_back(o);
    }
    if (kept.size() < 2) return std::nullopt;
    Point3D probe;
    probe.xyz_in_world = *x;
    probe.observations = kept;
    if (MaxAngle(*model, probe) < options_.min_triangulation_angle_deg) return std::nullopt;
    const int id = model->AddPoint(*x, kept);
    track_point_[track] = id;
    point_track_[id] = track;
    return id;
  }

  // Largest triangulation angle over the point's observations, in degrees.
  double MaxAngle(const Reconstruction& model, const Point3D& point) const {
    double best = 0.0;
    for (std::size_t i = 0; i < point.observations.size(); ++i) {
      const Eigen::Vector3d ci =
          model.images.at(point.observations[i].image_id).cam_from_world.CenterInWorld();
      for (std::size_t j = i + 1; j < point.observations.size(); ++j) {
        const Eigen::Vector3d cj =
            model.images.at(point.observations[j].image_id).cam_from_world.CenterInWorld();
        best = std::max(best, CalculateTriangulationAngle(ci, cj, point.xyz_in_world));  // Radians.
      }
    }
    return best * 180.0 / M_PI;
  }

  // Removes bad observations and points among those seen by `images`.
  void FilterPoints(Reconstruction* model, const std::set<int>& images) {
    FilterPoints(model, images, options_.max_reprojection_error_px);
  }
  void FilterPoints(Reconstruction* model, const std::set<int>& images, double max_error_px) {
    std::set<int> candidates;
    for (int id : images) {
      auto it = model->images.find(id);
      if (it == model->images.end()) continue;
      for (int point_id : it->second.point_for_keypoint) {
        if (point_id != kInvalidId) candidates.insert(point_id);
      }
    }
    for (int point_id : candidates) {
      auto it = model->points.find(point_id);
      if (it == model->points.end()) continue;
      const std::vector<Observation> observations = it->second.observations;
      for (const Observation& o : observations) {
        const RegisteredImage& image = model->images.at(o.image_id);
        const bool bad = !HasPositiveDepth(image.cam_from_world, it->second.xyz_in_world) ||
                         model->ReprojectionError(it->second, o) > max_error_px;
        if (bad) {
          model->DeleteObservation(point_id, o);
          if (!model->points.count(point_id)) break;
        }
      }
      auto still = model->points.find(point_id);
      if (still != model->points.end() &&
          MaxAngle(*model, still->second) < options_.min_triangulation_angle_deg) {
        model->DeletePoint(point_id);
      }
      if (!model->points.count(point_id)) {
        // The track may be triangulated again later, from better-posed photos.
        auto track = point_track_.find(point_id);
        if (track != point_track_.end()) {
          track_point_.erase(track->second);
          point_track_.erase(track);
        }
      }
    }
  }

  void ForgetTrackPoints(const Reconstruction& model) {
    for (const auto& [id, point] : model.points) {
      auto track = point_track_.find(id);
      if (track != point_track_.end()) {
        track_point_.erase(track->second);
        point_track_.erase(track);
      }
    }
  }

  BundleAdjustmentOptions BaseBundleOptions() const {
    BundleAdjustmentOptions ba;
    ba.num_threads =
        options_.bundle_adjustment_threads > 0 ? options_.bundle_adjustment_threads : -1;
    ba.loss_scale = 1.0;
    return ba;
  }

  const MapperInput& input_;
  const IncrementalMapperOptions& options_;
  Progress& progress_;
  const CancelToken& cancel_;
  MapperSummary* summary_;

  std::map<int, std::vector<int>> track_of_;  // image id -> track per keypoint (-1: none)
  std::map<int, int> track_point_;            // track -> point id in the current model
  std::map<int, int> point_track_;            // point id -> track
  std::set<int> used_;                        // Photos registered in an earlier model.
  // Photos the current model removed because their pose contradicted its verified pairs
  // (RemoveContradictedPhoto): Grow does not register them in it again.
  std::set<int> contradicted_;
  std::map<int, int> registration_order_;  // Image id -> when AddImage last placed it.
  int registrations_ = 0;
  std::set<std::tuple<int, int, bool>> tried_initial_;  // (image1, image2, weak bar)
  std::map<int, Camera> cameras_;  // Initial intrinsics (input_.cameras unless replaced).
  // The intrinsics' standard deviations from the current model's final adjustment.
  std::map<int, IntrinsicsStddev> final_stddev_;
  MapperSummary::Times times_;
  // The current model's principal-point decision (GlobalAdjust, DecidePrincipalPoint), which
  // the adjustments after the final one keep.
  struct PrincipalPointChoice {
    bool refine = false;
    bool hold_x = false;
    bool hold_y = false;
  };
  PrincipalPointChoice principal_point_;
  void ApplyPrincipalPoint(BundleAdjustmentOptions* ba) const {
    ba->refine_principal_point = principal_point_.refine;
    ba->hold_principal_point_x = principal_point_.hold_x;
    ba->hold_principal_point_y = principal_point_.hold_y;
  }
  std::size_t max_images_ = std::numeric_limits<std::size_t>::max();  // Per model (trials).
  int init_image1_ = kInvalidId;
  int init_image2_ = kInvalidId;
  std::size_t last_global_size_ = 0;
};

// Focal search (IncrementalMapperOptions::focal_search): the initial cameras to start the
// reconstruction from, for input cameras whose focal length is a guess.
//
// Pairwise self-calibration (self_calibration.h) is degenerate when the optical axes of the
// two photos meet, which is how people photograph an object: on templeSparseRing no pair
// constrains f and the fallback guess is half the truth. Three or more views of a ring do
// constrain it, and bundle adjustment with the focal free recovers it from far away: trial
// models of 6 temple photos started anywhere from 0.2 to 2.1 x the truth all converged to
// within 4 % of it. So rather than scoring a grid of fixed focal values (each a full trial
// reconstruction, and the cost minimum in f is shallow: the reprojection error of the
// 16-photo temple model changes by under 1 % between 0.97 and 1.03 x the best f), the search
// is a fixed-point iteration: a small trial model (initial pair, up to
// `focal_search_images` photos, global adjustment with the focal free) from the guess, then
// another from its result; when the two agree within `focal_search_tolerance`, the second
// is the start. Only when they do not (or a trial cannot build a model) is a multi-start run:
// trials from `focal_search_hypotheses` log-spaced multiples of the longer image side, the
// one that registers most photos, then with the lowest reprojection error, wins.
struct FocalTrial {
  std::map<int, Camera> result;  // The start with the trial model's refined focal lengths.
  int images = 0;
  double rms_px = 0.0;  // Root mean square reprojection error (pixels) after adjustment.
};

std::map<int, Camera> SearchFocal(const MapperInput& input,
                                  const IncrementalMapperOptions& options,
                                  const CancelToken& cancel,
                                  MapperSummary* summary) {
  const Timer timer;
  auto note = [&](const std::string& line) {
    LOG_INFO << "sfm: " << line;
    if (summary != nullptr) summary->log.push_back(line);
  };
  // Trials refine the focal only: distortion and principal point would add freedom that a
  // few photos cannot pin down. From 3 photos on (a pair does not constrain f here).
  IncrementalMapperOptions trial_options = options;
  trial_options.refine_focal = true;
  trial_options.refine_distortion = false;
  trial_options.principal_point = PrincipalPointMode::kCenter;
  trial_options.min_images_for_intrinsics = 3;

  auto focal_text = [&](const std::map<int, Camera>& cameras) {
    std::ostringstream text;
    text << std::fixed << std::setprecision(1);
    bool first = true;
    for (int id : input.uncertain_focal_camera_ids) {
      auto it = cameras.find(id);
      if (it == cameras.end()) continue;
      text << (first ? "" : ", ") << it->second.focal;
      first = false;
    }
    return text.str() + " px";
  };
  auto run = [&](const std::map<int, Camera>& start) {
    cancel.ThrowIfCanceled();
    Progress quiet;
    Mapper mapper(input, trial_options, quiet, cancel, nullptr);
    mapper.SetInitialCameras(start);
    const Reconstruction model =
        mapper.RunTrial(options.focal_search_images, options.focal_search_seeds);
    FocalTrial trial;
    trial.result = start;
    trial.images = static_cast<int>(model.images.size());
    if (trial.images >= 3) {
      for (int id : input.uncertain_focal_camera_ids) {
        if (model.cameras.count(id)) trial.result[id].focal = model.cameras.at(id).focal;
      }
      double sum = 0.0;
      std::size_t count = 0;
      for (const auto& [id, point] : model.points) {
        for (const Observation& o : point.observations) {
          sum += std::pow(model.ReprojectionError(point, o), 2);
          ++count;
        }
      }
      trial.rms_px = count > 0 ? std::sqrt(sum / count) : 0.0;
    }
    std::ostringstream line;
    line << std::fixed << std::setprecision(2) << "focal search: trial from " << focal_text(start)
         << ": " << trial.images << " photos";
    if (trial.images >= 3) {
      line << ", rms " << trial.rms_px << " px, focal " << focal_text(trial.result);
    }
    note(line.str());
    return trial;
  };
  auto usable = [](const FocalTrial& t) { return t.images >= 3; };
  auto agree = [&](const FocalTrial& a, const FocalTrial& b) {
    for (int id : input.uncertain_focal_camera_ids) {
      auto x = a.result.find(id), y = b.result.find(id);
      if (x == a.result.end() || y == b.result.end()) continue;
      if (std::abs(std::log(x->second.focal / y->second.focal)) >
          std::log1p(options.focal_search_tolerance)) {
        return false;
      }
    }
    return true;
  };
  auto done = [&](const FocalTrial& chosen, const std::string& how) {
    note("focal search: " + how + "; starting from " + focal_text(chosen.result) + " (" +
         std::to_string(timer.ElapsedSeconds()) + " s)");
    if (summary != nullptr) {
      for (int id : input.uncertain_focal_camera_ids) {
        if (chosen.result.count(id)) summary->searched_focal[id] = chosen.result.at(id).focal;
      }
    }
    return chosen.result;
  };

  FocalTrial previous = run(input.cameras);
  for (int round = 1; round < options.focal_search_rounds && usable(previous); ++round) {
    FocalTrial next = run(previous.result);
    if (usable(next) && agree(previous, next)) return done(next, "converged");
    previous = std::move(next);
  }
  std::vector<FocalTrial> trials;
  const int n = options.focal_search_hypotheses;
  for (int k = 0; k < n; ++k) {
    const double multiple =
        options.focal_search_min_multiple *
        std::pow(options.focal_search_max_multiple / options.focal_search_min_multiple,
                 n > 1 ? static_cast<double>(k) / (n - 1) : 0.5);
    std::map<int, Camera> start = input.cameras;
    for (int id : input.uncertain_focal_camera_ids) {
      auto it = start.find(id);
      if (it != start.end())
        it->second.focal = multiple * std::max(it->second.width, it->second.height);
    }
    trials.push_back(run(start));
  }
  const auto best =
      std::min_element(trials.begin(), trials.end(), [](const FocalTrial& a, const FocalTrial& b) {
        if (a.images != b.images) return a.images > b.images;
        return a.rms_px < b.rms_px;
      });
  if (best == trials.end() || !usable(*best)) {
    note("focal search: no trial model of 3 photos; keeping the initial focal");
    return input.cameras;
  }
  return done(*best, "multi-start");
}

}  // namespace

bool IncrementalMapperOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (min_initial_inliers < 8) {
    m << "min_initial_inliers must be at least 8, got " << min_initial_inliers;
  } else if (!(min_initial_angle_deg >= 0 && min_initial_angle_deg < 90)) {
    m << "min_initial_angle_deg must be in [0, 90), got " << min_initial_angle_deg;
  } else if (weak_initial_inliers != 0 &&
             (weak_initial_inliers < 8 || weak_initial_inliers > min_initial_inliers)) {
    m << "weak_initial_inliers must be 0 (off) or in [8, min_initial_inliers = "
      << min_initial_inliers << "], got " << weak_initial_inliers;
  } else if (!(weak_initial_essential_share >= 0 && weak_initial_essential_share <= 1)) {
    m << "weak_initial_essential_share must be in [0, 1], got " << weak_initial_essential_share;
  } else if (!(weak_initial_angle_deg >= min_initial_angle_deg && weak_initial_angle_deg < 90)) {
    m << "weak_initial_angle_deg must be in [min_initial_angle_deg, 90), got "
      << weak_initial_angle_deg;
  } else if (max_initial_pair_trials < 1) {
    m << "max_initial_pair_trials must be at least 1, got " << max_initial_pair_trials;
  } else if (!(max_reprojection_error_px > 0)) {
    m << "max_reprojection_error_px must be positive, got " << max_reprojection_error_px;
  } else if (!(final_outlier_multiple == 0 || final_outlier_multiple >= 3)) {
    m << "final_outlier_multiple must be 0 (off) or at least 3, got " << final_outlier_multiple;
  } else if (!(final_min_outlier_px > 0)) {
    m << "final_min_outlier_px must be positive, got " << final_min_outlier_px;
  } else if (!(min_triangulation_angle_deg >= 0 && min_triangulation_angle_deg < 90)) {
    m << "min_triangulation_angle_deg must be in [0, 90), got " << min_triangulation_angle_deg;
  } else if (min_registration_points < 4) {
    m << "min_registration_points must be at least 4, got " << min_registration_points;
  } else if (!(pnp_max_error_px > 0)) {
    m << "pnp_max_error_px must be positive, got " << pnp_max_error_px;
  } else if (!(min_pnp_inlier_ratio >= 0 && min_pnp_inlier_ratio <= 1)) {
    m << "min_pnp_inlier_ratio must be in [0, 1], got " << min_pnp_inlier_ratio;
  } else if (local_ba_num_images < 1) {
    m << "local_ba_num_images must be at least 1, got " << local_ba_num_images;
  } else if (!(global_ba_growth > 1.0)) {
    m << "global_ba_growth must be greater than 1, got " << global_ba_growth;
  } else if (min_model_images < 2) {
    m << "min_model_images must be at least 2, got " << min_model_images;
  } else if (focal_search_images < 3) {
    m << "focal_search_images must be at least 3, got " << focal_search_images;
  } else if (!(focal_search_tolerance > 0 && focal_search_tolerance < 1)) {
    m << "focal_search_tolerance must be in (0, 1), got " << focal_search_tolerance;
  } else if (focal_search_rounds < 2) {
    m << "focal_search_rounds must be at least 2, got " << focal_search_rounds;
  } else if (focal_search_seeds < 1) {
    m << "focal_search_seeds must be at least 1, got " << focal_search_seeds;
  } else if (focal_search_hypotheses < 1) {
    m << "focal_search_hypotheses must be at least 1, got " << focal_search_hypotheses;
  } else if (!(focal_search_min_multiple > 0 &&
               focal_search_max_multiple > focal_search_min_multiple)) {
    m << "focal_search_min_multiple and focal_search_max_multiple must satisfy 0 < min < max, "
         "got "
      << focal_search_min_multiple << " and " << focal_search_max_multiple;
  } else if (!(max_principal_point_shift > 0 && max_principal_point_shift <= 0.5)) {
    m << "max_principal_point_shift must be in (0, 0.5], got " << max_principal_point_shift;
  } else if (!(max_principal_point_stddev > 0)) {
    m << "max_principal_point_stddev must be positive, got " << max_principal_point_stddev;
  } else if (!(contradiction_min_rotation_deg >= 0 && contradiction_min_rotation_deg < 180)) {
    m << "contradiction_min_rotation_deg must be 0 (off) or in (0, 180), got "
      << contradiction_min_rotation_deg;
  } else if (!(contradiction_clear_rotation_deg > 0 &&
               contradiction_clear_rotation_deg <= contradiction_min_rotation_deg) &&
             contradiction_min_rotation_deg > 0) {
    m << "contradiction_clear_rotation_deg must be in (0, contradiction_min_rotation_deg], got "
      << contradiction_clear_rotation_deg;
  } else if (!(contradiction_clear_margin > 0 && contradiction_clear_margin <= 1)) {
    m << "contradiction_clear_margin must be in (0, 1], got " << contradiction_clear_margin;
  } else if (contradiction_min_matches < 8) {
    m << "contradiction_min_matches must be at least 8, got " << contradiction_min_matches;
  } else if (!(contradiction_min_pair_share > 0 && contradiction_min_pair_share <= 1)) {
    m << "contradiction_min_pair_share must be in (0, 1], got " << contradiction_min_pair_share;
  } else if (!(contradiction_min_parallax_deg >= 0 && contradiction_min_parallax_deg < 90)) {
    m << "contradiction_min_parallax_deg must be in [0, 90), got "
      << contradiction_min_parallax_deg;
  } else if (std::string relative_error; !relative.Check(&relative_error)) {
    m << "relative: " << relative_error;
  } else if (std::string merge_error; !merge.Check(&merge_error)) {
    m << "merge: " << merge_error;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

std::vector<Reconstruction> ReconstructIncrementally(const MapperInput& input,
                                                     const IncrementalMapperOptions& options,
                                                     Progress& progress,
                                                     const CancelToken& cancel,
                                                     MapperSummary* summary) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  const Timer timer;
  Mapper mapper(input, options, progress, cancel, summary);
  if (options.focal_search && !input.uncertain_focal_camera_ids.empty()) {
    mapper.SetInitialCameras(SearchFocal(input, options, cancel, summary));
  }
  std::vector<Reconstruction> models = mapper.Run();
  LOG_INFO << "sfm: " << models.size() << " model(s) in " << timer.ElapsedSeconds() << " s";
  return models;
}

}  // namespace reconduit
