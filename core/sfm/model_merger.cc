#include "core/sfm/model_merger.h"

#include "core/util/logging.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <random>
#include <set>
#include <sstream>

namespace reconduit {
namespace {

// One correspondence's positions in both models and its distance scale; photos also carry
// their orientations (world-from-camera rotations).
struct Item {
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double tolerance = 0.0;  // Distance within which it agrees, A's units.
  bool image = false;
  // cam_from_world rotations (photos only).
  Eigen::Matrix3d rotation_a = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d rotation_b = Eigen::Matrix3d::Identity();
};

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// The items of the correspondences, each with its tolerance: `max_alignment_error` x the larger
// of the model's extent (median distance of A's photos and points from A's camera centroid)
// and the item's own distance from that centroid.
std::vector<Item> MakeItems(const Reconstruction& a,
                            const Reconstruction& b,
                            const ModelCorrespondences& c,
                            double max_alignment_error) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& [id, image] : a.images) centroid += image.cam_from_world.CenterInWorld();
  centroid /= std::max<std::size_t>(1, a.images.size());
  std::vector<double> distances;
  for (const auto& [id, image] : a.images) {
    distances.push_back((image.cam_from_world.CenterInWorld() - centroid).norm());
  }
  for (const auto& [id, point] : a.points) {
    distances.push_back((point.xyz_in_world - centroid).norm());
  }
  const double extent = Median(distances);
  std::vector<Item> items;
  for (int id : c.images) {
    Item item;
    item.image = true;
    item.a = a.images.at(id).cam_from_world.CenterInWorld();
    item.b = b.images.at(id).cam_from_world.CenterInWorld();
    item.rotation_a = a.images.at(id).cam_from_world.rotation.toRotationMatrix();
    item.rotation_b = b.images.at(id).cam_from_world.rotation.toRotationMatrix();
    items.push_back(item);
  }
  for (const auto& [pa, pb] : c.points) {
    Item item;
    item.a = a.points.at(pa).xyz_in_world;
    item.b = b.points.at(pb).xyz_in_world;
    items.push_back(item);
  }
  for (Item& item : items) {
    item.tolerance = max_alignment_error * std::max(extent, (item.a - centroid).norm());
  }
  return items;
}

double RotationErrorDeg(const Similarity3& s, const Item& item) {
  // cam_from_world in A = R_b * R^T for the same photo.
  const Eigen::Matrix3d mapped = item.rotation_b * s.rotation.transpose();
  return Eigen::AngleAxisd(mapped * item.rotation_a.transpose()).angle() * 180.0 / M_PI;
}

bool Agrees(const Similarity3& s, const Item& item, const ModelMergerOptions& options) {
  if ((s * item.b - item.a).norm() > item.tolerance) return false;
  return !item.image || RotationErrorDeg(s, item) <= options.max_rotation_error_deg;
}

// Whether positions span at least a plane: the second singular value of their centred
// coordinates against the first.
bool SpanPlane(const Eigen::Matrix3Xd& x) {
  if (x.cols() < 3) return false;
  const Eigen::Matrix3Xd centred = x.colwise() - x.rowwise().mean();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred);
  const Eigen::VectorXd s = svd.singularValues();
  return s(0) > 0 && s(1) > 1e-3 * s(0);
}

std::optional<Similarity3> FitUmeyama(const std::vector<Item>& items,
                                      const std::vector<int>& which) {
  Eigen::Matrix3Xd from(3, which.size()), to(3, which.size());
  for (std::size_t k = 0; k < which.size(); ++k) {
    from.col(k) = items[which[k]].b;
    to.col(k) = items[which[k]].a;
  }
  if (!SpanPlane(from) || !SpanPlane(to)) return std::nullopt;
  const Eigen::Matrix4d m = Eigen::umeyama(from, to, true);
  Similarity3 s;
  s.scale = m.topLeftCorner<3, 3>().col(0).norm();
  if (!(s.scale > 0) || !std::isfinite(s.scale)) return std::nullopt;
  s.rotation = m.topLeftCorner<3, 3>() / s.scale;
  s.translation = m.topRightCorner<3, 1>();
  return s;
}

// From two shared photos: the rotation from the first one's orientations, the scale from the
// distance between the centres, the translation from the first centre.
std::optional<Similarity3> FitTwoPhotos(const Item& p, const Item& q) {
  const double db = (p.b - q.b).norm();
  if (!(db > 0)) return std::nullopt;
  Similarity3 s;
  s.rotation = p.rotation_a.transpose() * p.rotation_b;
  s.scale = (p.a - q.a).norm() / db;
  if (!(s.scale > 0)) return std::nullopt;
  s.translation = p.a - s.scale * (s.rotation * p.b);
  return s;
}

std::vector<int> Inliers(const Similarity3& s,
                         const std::vector<Item>& items,
                         const ModelMergerOptions& options) {
  std::vector<int> inliers;
  for (int k = 0; k < static_cast<int>(items.size()); ++k) {
    if (Agrees(s, items[k], options)) inliers.push_back(k);
  }
  return inliers;
}

// RANSAC over both kinds of hypotheses; the best by inlier count, refitted on its inliers.
std::optional<std::pair<Similarity3, std::vector<int>>> RobustSimilarity(
    const std::vector<Item>& items, const ModelMergerOptions& options) {
  std::vector<Similarity3> hypotheses;
  std::vector<int> photos;
  for (int k = 0; k < static_cast<int>(items.size()); ++k) {
    if (items[k].image) photos.push_back(k);
  }
  std::mt19937_64 random(options.seed);
  const std::size_t n = photos.size();
  const std::size_t max_pairs = static_cast<std::size_t>(options.ransac_iterations);
  if (n >= 2 && n * (n - 1) <= max_pairs) {
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = 0; j < n; ++j) {
        if (i == j) continue;
        if (auto s = FitTwoPhotos(items[photos[i]], items[photos[j]])) hypotheses.push_back(*s);
      }
    }
  } else if (n >= 2) {
    std::uniform_int_distribution<std::size_t> pick(0, n - 1);
    for (std::size_t k = 0; k < max_pairs; ++k) {
      const std::size_t i = pick(random), j = pick(random);
      if (i == j) continue;
      if (auto s = FitTwoPhotos(items[photos[i]], items[photos[j]])) hypotheses.push_back(*s);
    }
  }
  if (items.size() >= 3) {
    std::uniform_int_distribution<int> pick(0, static_cast<int>(items.size()) - 1);
    for (int it = 0; it < options.ransac_iterations; ++it) {
      const std::vector<int> sample = {pick(random), pick(random), pick(random)};
      if (sample[0] == sample[1] || sample[1] == sample[2] || sample[0] == sample[2]) continue;
      if (auto s = FitUmeyama(items, sample)) hypotheses.push_back(*s);
    }
  }
  std::optional<std::pair<Similarity3, std::vector<int>>> best;
  for (const Similarity3& s : hypotheses) {
    std::vector<int> inliers = Inliers(s, items, options);
    if (!best || inliers.size() > best->second.size()) best.emplace(s, std::move(inliers));
  }
  if (!best) return std::nullopt;
  // Refit on the inliers (twice: the refit may gather a few more).
  for (int round = 0; round < 2; ++round) {
    const auto refit = FitUmeyama(items, best->second);
    if (!refit) break;
    std::vector<int> inliers = Inliers(*refit, items, options);
    if (inliers.size() < best->second.size()) break;
    best.emplace(*refit, std::move(inliers));
  }
  return best;
}

}  // namespace

Rigid3d Similarity3::MapPose(const Rigid3d& b_pose) const {
  const Eigen::Matrix3d r = b_pose.rotation.toRotationMatrix() * rotation.transpose();
  return Rigid3d(r, scale * b_pose.translation - r * translation);
}

bool ModelMergerOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (!(max_alignment_error > 0 && max_alignment_error < 1)) {
    m << "max_alignment_error must be in (0, 1), got " << max_alignment_error;
  } else if (!(max_rotation_error_deg > 0 && max_rotation_error_deg < 180)) {
    m << "max_rotation_error_deg must be in (0, 180), got " << max_rotation_error_deg;
  } else if (min_inliers < 3) {
    m << "min_inliers must be at least 3, got " << min_inliers;
  } else if (!(min_inlier_ratio > 0 && min_inlier_ratio <= 1)) {
    m << "min_inlier_ratio must be in (0, 1], got " << min_inlier_ratio;
  } else if (ransac_iterations < 1) {
    m << "ransac_iterations must be at least 1, got " << ransac_iterations;
  } else if (!(max_reprojection_error_px > 0)) {
    m << "max_reprojection_error_px must be positive, got " << max_reprojection_error_px;
  } else if (!(max_error_growth >= 1)) {
    m << "max_error_growth must be at least 1, got " << max_error_growth;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

ModelCorrespondences FindModelCorrespondences(const Reconstruction& a,
                                              const Reconstruction& b,
                                              const KeypointTracks* tracks) {
  ModelCorrespondences c;
  for (const auto& [id, image] : b.images) {
    if (a.images.count(id)) c.images.push_back(id);
  }
  // The key of an observation: its track, or the photo and keypoint.
  auto key = [&](const Observation& o) -> std::int64_t {
    if (tracks != nullptr) {
      auto it = tracks->find(o.image_id);
      if (it == tracks->end() || o.keypoint < 0 ||
          o.keypoint >= static_cast<int>(it->second.size()) || it->second[o.keypoint] < 0) {
        return -1;
      }
      return it->second[o.keypoint];
    }
    return (static_cast<std::int64_t>(o.image_id) << 32) | static_cast<std::uint32_t>(o.keypoint);
  };
  std::map<std::int64_t, int> point_of_key;  // -> point id in A
  for (const auto& [id, point] : a.points) {
    for (const Observation& o : point.observations) {
      if (const std::int64_t k = key(o); k >= 0) point_of_key.emplace(k, id);
    }
  }
  std::set<int> used;
  for (const auto& [id, point] : b.points) {
    for (const Observation& o : point.observations) {
      const std::int64_t k = key(o);
      auto it = k >= 0 ? point_of_key.find(k) : point_of_key.end();
      if (it == point_of_key.end() || used.count(it->second)) continue;
      used.insert(it->second);
      c.points.emplace_back(it->second, id);
      break;
    }
  }
  return c;
}

std::optional<ModelAlignment> AlignModels(const Reconstruction& a,
                                          const Reconstruction& b,
                                          const ModelCorrespondences& correspondences,
                                          const ModelMergerOptions& options,
                                          std::string* why) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  const std::vector<Item> items = MakeItems(a, b, correspondences, options.max_alignment_error);
  ModelAlignment alignment;
  alignment.num_images = static_cast<int>(correspondences.images.size());
  alignment.num_points = static_cast<int>(correspondences.points.size());
  std::ostringstream reason;
  reason << alignment.num_images << " shared photos / " << alignment.num_points
         << " shared points: ";
  if (static_cast<int>(items.size()) < options.min_inliers) {
    if (why != nullptr) *why = reason.str() + "too few";
    return std::nullopt;
  }
  const auto best = RobustSimilarity(items, options);
  if (!best) {
    if (why != nullptr) *why = reason.str() + "no similarity (degenerate configuration)";
    return std::nullopt;
  }
  const int inliers = static_cast<int>(best->second.size());
  if (inliers < options.min_inliers ||
      inliers < options.min_inlier_ratio * static_cast<double>(items.size())) {
    if (why != nullptr) {
      *why = reason.str() + "only " + std::to_string(inliers) + " of " +
             std::to_string(items.size()) + " agree";
    }
    return std::nullopt;
  }
  alignment.a_from_b = best->first;
  alignment.point_inliers.assign(correspondences.points.size(), false);
  for (int k : best->second) {
    if (items[k].image) {
      ++alignment.num_inlier_images;
    } else {
      alignment.point_inliers[k - alignment.num_images] = true;
      ++alignment.num_inlier_points;
    }
  }
  if (why != nullptr) {
    *why =
        reason.str() + std::to_string(inliers) + " of " + std::to_string(items.size()) + " agree";
  }
  return alignment;
}

void JoinModels(const Reconstruction& b,
                const ModelCorrespondences& correspondences,
                const ModelAlignment& alignment,
                Reconstruction* a) {
  THROW_CHECK(a != nullptr);
  const Similarity3& s = alignment.a_from_b;
  for (const auto& [id, camera] : b.cameras) a->cameras.emplace(id, camera);
  for (const auto& [id, image] : b.images) {
    if (a->images.count(id)) continue;
    RegisteredImage added = image;
    added.cam_from_world = s.MapPose(image.cam_from_world);
    std::fill(added.point_for_keypoint.begin(), added.point_for_keypoint.end(), kInvalidId);
    a->images.emplace(id, std::move(added));
  }
  std::map<int, int> fused;  // B point -> A point (agreeing correspondences only).
  for (std::size_t k = 0; k < correspondences.points.size(); ++k) {
    if (alignment.point_inliers.at(k)) {
      fused[correspondences.points[k].second] = correspondences.points[k].first;
    }
  }
  auto free = [&](const Observation& o) {
    return a->images.at(o.image_id).point_for_keypoint.at(o.keypoint) == kInvalidId;
  };
  for (const auto& [id, point] : b.points) {
    auto into = fused.find(id);
    if (into != fused.end() && a->points.count(into->second)) {
      for (const Observation& o : point.observations) {
        if (free(o)) a->AddObservation(into->second, o);
      }
      continue;
    }
    std::vector<Observation> observations;
    for (const Observation& o : point.observations) {
      if (free(o)) observations.push_back(o);
    }
    if (observations.size() >= 2) {
      const int added = a->AddPoint(s * point.xyz_in_world, observations);
      a->points.at(added).rgb = point.rgb;
    }
  }
}

MergeSummary MergeModels(const Reconstruction& b,
                         const KeypointTracks* tracks,
                         const ModelMergerOptions& options,
                         const BundleAdjustmentOptions& bundle,
                         const CancelToken& cancel,
                         Reconstruction* a) {
  THROW_CHECK(a != nullptr);
  MergeSummary summary;
  summary.num_images_a = static_cast<int>(a->images.size());
  summary.num_images_b = static_cast<int>(b.images.size());
  const ModelCorrespondences c = FindModelCorrespondences(*a, b, tracks);
  std::string why;
  const auto alignment = AlignModels(*a, b, c, options, &why);
  std::ostringstream line;
  line << "model B (" << b.images.size() << " photos) into A (" << a->images.size()
       << " photos) via ";
  if (!alignment) {
    summary.message = "not merged: " + line.str() + why;
    return summary;
  }
  summary.alignment = *alignment;
  Reconstruction merged = *a;
  JoinModels(b, c, *alignment, &merged);
  BundleAdjustmentOptions ba = bundle;
  if (ba.constant_pose_image_ids.empty() && ba.variable_pose_image_ids.empty()) {
    ba.constant_pose_image_ids = {a->images.begin()->first};
    if (ba.scale_fixing_image_id == kInvalidId && a->images.size() >= 2) {
      ba.scale_fixing_image_id = std::next(a->images.begin())->first;
      ba.scale_fixing_translation_index = -1;
    }
  }
  BundleAdjust(ba, cancel, &merged);
  std::vector<std::pair<int, Observation>> bad;
  for (const auto& [id, point] : merged.points) {
    for (const Observation& o : point.observations) {
      if (merged.ReprojectionError(point, o) > options.max_reprojection_error_px) {
        bad.emplace_back(id, o);
      }
    }
  }
  for (const auto& [id, o] : bad) {
    if (merged.points.count(id)) merged.DeleteObservation(id, o);
  }
  const double before = std::max(a->MeanReprojectionError(), b.MeanReprojectionError());
  const double after = merged.MeanReprojectionError();
  line << std::fixed << std::setprecision(2) << alignment->num_images << " shared photos / "
       << alignment->num_points << " shared points (" << alignment->num_inlier_images << " / "
       << alignment->num_inlier_points << " agree), scale " << alignment->a_from_b.scale
       << ", mean reprojection error " << after << " px (inputs " << before << " px), "
       << bad.size() << " observations removed";
  if (after > options.max_error_growth * before &&
      after > 0.5 * options.max_reprojection_error_px) {
    summary.message = "not merged (inconsistent after adjustment): " + line.str();
    return summary;
  }
  summary.num_images = static_cast<int>(merged.images.size());
  summary.merged = true;
  summary.message = "merged " + line.str() + "; " + std::to_string(summary.num_images) + " photos";
  *a = std::move(merged);
  return summary;
}

}  // namespace reconduit
