#include "core/pipeline/stages/matching_stage.h"

#include "core/feature/affine_features.h"
#include "core/feature/matcher.h"
#include "core/image/image_reader.h"
#include "core/io/file_util.h"
#include "core/pipeline/stages/features_stage.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/pipeline/stages/pairs_stage.h"
#include "core/pipeline/stages/weak_pairs.h"
#include "core/util/logging.h"
#include "core/util/parallel.h"
#include "core/util/timer.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>

namespace reconduit {
namespace {

// pairs.bin: "RCMT", u32 version, u64 count, then per pair:
//   i32 image1, i32 image2, i32 type, i32 num_putative, i32 inliers_F, i32 inliers_H,
//   f64 gric_F, f64 gric_H, f64 F[9] (row-major), f64 H[9], u64 n, n x (i32 index1, i32 index2)
constexpr char kMagic[4] = {'R', 'C', 'M', 'T'};
constexpr std::uint32_t kVersion = 1;

template <typename T>
void Put(std::string* out, const T& value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <typename T>
bool Get(const std::string& in, std::size_t* offset, T* value) {
  if (*offset + sizeof(T) > in.size()) return false;
  std::memcpy(value, in.data() + *offset, sizeof(T));
  *offset += sizeof(T);
  return true;
}

void PutMatrix(std::string* out, const Eigen::Matrix3d& m) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) Put(out, m(r, c));
  }
}

bool GetMatrix(const std::string& in, std::size_t* offset, Eigen::Matrix3d* m) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (!Get(in, offset, &(*m)(r, c))) return false;
    }
  }
  return true;
}

std::string Serialize(const std::vector<VerifiedPair>& pairs) {
  std::string out(kMagic, 4);
  Put(&out, kVersion);
  Put(&out, static_cast<std::uint64_t>(pairs.size()));
  for (const VerifiedPair& p : pairs) {
    Put(&out, static_cast<std::int32_t>(p.matches.image1));
    Put(&out, static_cast<std::int32_t>(p.matches.image2));
    Put(&out, static_cast<std::int32_t>(p.type));
    Put(&out, static_cast<std::int32_t>(p.num_putative));
    Put(&out, static_cast<std::int32_t>(p.num_inliers_F));
    Put(&out, static_cast<std::int32_t>(p.num_inliers_H));
    Put(&out, p.gric_F);
    Put(&out, p.gric_H);
    PutMatrix(&out, p.F);
    PutMatrix(&out, p.H);
    Put(&out, static_cast<std::uint64_t>(p.matches.matches.size()));
    for (const FeatureMatch& m : p.matches.matches) {
      Put(&out, static_cast<std::int32_t>(m.index1));
      Put(&out, static_cast<std::int32_t>(m.index2));
    }
  }
  return out;
}

// The match graph: photos on a circle, an edge per verified pair, thicker for more inliers,
// green for F pairs and orange for H (planar or rotation-only) pairs.
cv::Mat RenderMatchGraph(int num_images,
                         const std::vector<int>& indices,
                         const std::vector<VerifiedPair>& pairs) {
  const int size = 640, radius = 260;
  cv::Mat picture(size, size, CV_8UC3, cv::Scalar(255, 255, 255));
  std::map<int, cv::Point> position;
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const double angle = 2 * M_PI * k / std::max<std::size_t>(1, indices.size()) - M_PI / 2;
    position[indices[k]] = cv::Point(size / 2 + static_cast<int>(radius * std::cos(angle)),
                                     size / 2 + static_cast<int>(radius * std::sin(angle)));
  }
  int most = 1;
  for (const VerifiedPair& p : pairs) most = std::max<int>(most, p.matches.matches.size());
  for (const VerifiedPair& p : pairs) {
    if (p.type != TwoViewModelType::kFundamental && p.type != TwoViewModelType::kHomography)
      continue;
    const int thickness = 1 + static_cast<int>(5.0 * p.matches.matches.size() / most);
    const cv::Scalar colour = p.type == TwoViewModelType::kFundamental ? cv::Scalar(60, 160, 60)
                                                                       : cv::Scalar(0, 140, 255);
    cv::line(picture, position[p.matches.image1], position[p.matches.image2], colour, thickness,
             cv::LINE_AA);
  }
  for (const auto& [index, point] : position) {
    cv::circle(picture, point, 12, cv::Scalar(90, 60, 30), cv::FILLED, cv::LINE_AA);
    cv::putText(picture, std::to_string(index), point + cv::Point(-8, 5), cv::FONT_HERSHEY_SIMPLEX,
                0.4, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  (void)num_images;
  return picture;
}

// Guided matching along the epipolar lines of a pair's F (core/feature/matcher.h). Adds the
// guided matches whose features are not matched yet to `matches` (the RANSAC inliers), so each
// feature keeps at most one partner; returns how many were added.
int AddGuidedMatches(const DescriptorMatrix& descriptors1,
                     const DescriptorMatrix& descriptors2,
                     const std::vector<Eigen::Vector2d>& keypoints1,
                     const std::vector<Eigen::Vector2d>& keypoints2,
                     const Eigen::Matrix3d& F,
                     PairMatches* matches) {
  // The defaults (1.5 px, ratio 0.8). Measured on fountain-P11 against the RANSAC band (3 px,
  // 0.9): 16,037 instead of 14,187 points, mean reprojection error 0.38 instead of 0.44 px,
  // relative rotation error 0.048 instead of 0.058 deg (0.089 without guided matching).
  const GuidedMatchingOptions options;
  const std::vector<FeatureMatch> guided =
      GuidedMatchDescriptors(descriptors1, descriptors2, keypoints1, keypoints2, F, options);
  std::vector<char> used1(keypoints1.size(), 0), used2(keypoints2.size(), 0);
  for (const FeatureMatch& m : matches->matches) used1[m.index1] = used2[m.index2] = 1;
  int added = 0;
  for (const FeatureMatch& m : guided) {
    if (used1[m.index1] || used2[m.index2]) continue;
    used1[m.index1] = used2[m.index2] = 1;
    matches->matches.push_back(m);
    ++added;
  }
  std::sort(matches->matches.begin(), matches->matches.end(),
            [](const FeatureMatch& a, const FeatureMatch& b) { return a.index1 < b.index1; });
  return added;
}

// Keypoints and unit-norm descriptors of every photo that takes part in a chosen pair.
struct PairFeatures {
  std::map<int, FeatureSet> features;  // Keypoints only (descriptors released).
  std::map<int, DescriptorMatrix> descriptors;
  std::map<int, std::vector<Eigen::Vector2d>> keypoints;
  std::vector<int> indices;  // The photos, ascending.
};

Status ReadPairFeatures(const Workspace& workspace,
                        const std::vector<ImagePair>& chosen,
                        PairFeatures* out) {
  for (const ImagePair& p : chosen) {
    for (int index : {p.image1, p.image2}) {
      if (out->features.count(index)) continue;
      auto f = ReadImageFeatures(workspace, index);
      if (!f.ok()) return f.status();
      out->descriptors[index] = ToDescriptorMatrix(*f);
      for (const Keypoint& kp : f->keypoints) out->keypoints[index].emplace_back(kp.x, kp.y);
      f->descriptors.release();  // Only keypoints are needed from here on.
      out->features[index] = std::move(*f);
      out->indices.push_back(index);
    }
  }
  std::sort(out->indices.begin(), out->indices.end());
  return Status::Ok();
}

// Putative matches at Lowe's ratio `max_ratio` and the two-view geometry of their inliers.
VerifiedPair VerifyPutative(const ImagePair& pair,
                            const PairFeatures& in,
                            const TwoViewGeometryOptions& geometry,
                            double max_ratio,
                            const CancelToken& cancel) {
  VerifiedPair out;
  out.matches.image1 = pair.image1;
  out.matches.image2 = pair.image2;
  MatchingOptions matching;
  matching.max_ratio = max_ratio;
  const std::vector<FeatureMatch> putative =
      MatchDescriptors(in.descriptors.at(pair.image1), in.descriptors.at(pair.image2), matching);
  out.num_putative = static_cast<int>(putative.size());
  const FeatureSet& f1 = in.features.at(pair.image1);
  const FeatureSet& f2 = in.features.at(pair.image2);
  std::vector<Eigen::Vector2d> points1, points2;
  for (const FeatureMatch& m : putative) {
    points1.emplace_back(f1.keypoints[m.index1].x, f1.keypoints[m.index1].y);
    points2.emplace_back(f2.keypoints[m.index2].x, f2.keypoints[m.index2].y);
  }
  const TwoViewGeometryReport report = EstimateTwoViewGeometry(points1, points2, geometry, &cancel);
  cancel.ThrowIfCanceled();
  out.type = report.type;
  out.F = report.F;
  out.H = report.H;
  out.num_inliers_F = static_cast<int>(report.num_inliers_F);
  out.num_inliers_H = static_cast<int>(report.num_inliers_H);
  out.gric_F = report.gric_F;
  out.gric_H = report.gric_H;
  if (report.success) {
    const std::vector<char>& mask = report.inlier_mask();
    for (std::size_t i = 0; i < putative.size(); ++i) {
      if (mask[i]) out.matches.matches.push_back(putative[i]);
    }
  }
  return out;
}

// One pair: putative matches by descriptor at Lowe's ratio `max_ratio`, the two-view geometry
// and its inliers, then guided matching along the epipolar lines when the pair has an F.
VerifiedPair VerifyPair(const ImagePair& pair,
                        const PairFeatures& in,
                        const TwoViewGeometryOptions& geometry,
                        double max_ratio,
                        const CancelToken& cancel) {
  VerifiedPair out = VerifyPutative(pair, in, geometry, max_ratio, cancel);
  if (out.type == TwoViewModelType::kFundamental && !out.matches.matches.empty()) {
    out.num_guided = AddGuidedMatches(in.descriptors.at(pair.image1),
                                      in.descriptors.at(pair.image2), in.keypoints.at(pair.image1),
                                      in.keypoints.at(pair.image2), out.F, &out.matches);
  }
  return out;
}

// Verifies the weak pairs PairsToRetry chooses again at the looser ratio (weak_pairs.h),
// keeping the retries that pass KeepRetry.
void RetryWeakPairs(const std::vector<ImagePair>& chosen,
                    const PairFeatures& features,
                    const TwoViewGeometryOptions& geometry,
                    StageContext& context,
                    std::vector<VerifiedPair>* verified) {
  const WeakPairOptions options;
  std::vector<PairStrength> strengths;
  for (const VerifiedPair& p : *verified) {
    strengths.push_back({p.matches.image1, p.matches.image2,
                         std::max(p.num_inliers_F, p.num_inliers_H), !p.matches.matches.empty()});
  }
  const std::vector<std::size_t> retry = PairsToRetry(strengths, options);
  ParallelFor(
      0, retry.size(),
      [&](std::size_t k) {
        context.cancel.ThrowIfCanceled();
        VerifiedPair again =
            VerifyPair(chosen[retry[k]], features, geometry, options.retry_ratio, context.cancel);
        if (!again.matches.matches.empty() &&
            KeepRetry(again.type == TwoViewModelType::kFundamental, again.num_inliers_F,
                      again.num_putative, options)) {
          again.retried = true;
          (*verified)[retry[k]] = std::move(again);
        }
      },
      context.options.num_threads);
  int kept = 0;
  for (std::size_t k : retry) kept += (*verified)[k].retried;
  LOG_INFO << "matching: " << retry.size() << " weak pairs of photos with fewer than "
           << options.min_strong_pairs << " strong pairs verified again at Lowe's ratio "
           << options.retry_ratio << "; " << kept << " kept";
}

// Photos whose weak pairs are matched again with affine-adapted features: those of the weak
// pairs PairsToRetry still chooses after the looser ratio test, in the pairs' order (best
// global similarity first), at most kMaxAffinePhotos of them (memory: ~10-20 MB of float
// descriptors a photo; time: 1-5 s a photo on one core).
constexpr std::size_t kMaxAffinePhotos = 32;

struct AffinePlan {
  std::vector<std::size_t> pairs;  // Indices into the chosen pairs.
  std::vector<int> photos;         // Ascending.
};

AffinePlan PlanAffineRetry(const std::vector<VerifiedPair>& verified) {
  std::vector<PairStrength> strengths;
  for (const VerifiedPair& p : verified) {
    strengths.push_back({p.matches.image1, p.matches.image2,
                         std::max(p.num_inliers_F, p.num_inliers_H), !p.matches.matches.empty()});
  }
  AffinePlan plan;
  std::set<int> photos;
  for (std::size_t k : PairsToRetry(strengths, WeakPairOptions())) {
    std::set<int> with = photos;
    with.insert(verified[k].matches.image1);
    with.insert(verified[k].matches.image2);
    if (with.size() > kMaxAffinePhotos) continue;
    photos = std::move(with);
    plan.pairs.push_back(k);
  }
  plan.photos.assign(photos.begin(), photos.end());
  return plan;
}

// Each photo's SIFT features (the features stage's, with their descriptors) followed by its
// affine-adapted features that lie more than 1 px from every SIFT keypoint: a match in either
// numbering then names the same keypoint, so tracks run through SIFT and affine matches alike.
struct AffineFeatures {
  PairFeatures features;
  std::map<int, FeatureSet> added;  // Photo -> the appended keypoints and their descriptors.
};

FeatureSet ExtractAffineOf(const IngestedImage& image,
                           const AffineFeatureOptions& options,
                           const StageContext& context) {
  ImageReaderOptions reader;
  reader.min_side = context.options.min_image_side;
  reader.max_pixels = context.options.max_image_pixels;
  reader.read_exif = false;
  reader.grey = true;
  reader.max_side = options.max_image_side;
  ImageInfo info;
  auto pixels = ReadImage(image.path, reader, &info);
  if (!pixels.ok()) {
    throw std::runtime_error("the photo " + image.name + " can no longer be read (" +
                             pixels.status().message() + ")");
  }
  return ExtractAffineFeatures(*pixels, options, cv::Size(info.width, info.height));
}

AffineFeatures ExtractAffineFeaturesOf(const std::vector<int>& photos,
                                       const std::vector<IngestedImage>& images,
                                       const AffineFeatureOptions& options,
                                       StageContext& context) {
  std::map<int, const IngestedImage*> by_index;
  for (const IngestedImage& image : images) by_index[image.index] = &image;
  std::vector<FeatureSet> unions(photos.size()), added(photos.size());
  context.progress.Restart(photos.size(), "photos (affine-adapted features)");
  // One OpenCV thread per photo in flight, as in the features stage.
  const int previous_cv_threads = cv::getNumThreads();
  cv::setNumThreads(1);
  try {
    ParallelFor(
        0, photos.size(),
        [&](std::size_t k) {
          context.cancel.ThrowIfCanceled();
          const FeatureSet affine = ExtractAffineOf(*by_index.at(photos[k]), options, context);
          auto sift = ReadImageFeatures(context.workspace, photos[k]);
          if (!sift.ok()) throw std::runtime_error(sift.status().message());
          std::vector<Keypoint> appended;
          const std::vector<int> index =
              MergeKeypoints(sift->keypoints, affine.keypoints, 1.0, &appended);
          FeatureSet& extra = added[k];
          extra.image_width = sift->image_width;
          extra.image_height = sift->image_height;
          extra.keypoints = std::move(appended);
          extra.descriptors.create(static_cast<int>(extra.keypoints.size()), 128, CV_8U);
          const int base = static_cast<int>(sift->size());
          for (std::size_t i = 0; i < index.size(); ++i) {
            if (index[i] < base) continue;
            affine.descriptors.row(static_cast<int>(i))
                .copyTo(extra.descriptors.row(index[i] - base));
          }
          FeatureSet& both = unions[k];
          both.image_width = sift->image_width;
          both.image_height = sift->image_height;
          both.keypoints = sift->keypoints;
          both.keypoints.insert(both.keypoints.end(), extra.keypoints.begin(),
                                extra.keypoints.end());
          cv::vconcat(sift->descriptors, extra.descriptors, both.descriptors);
          context.progress.Advance();
        },
        context.options.num_threads);
  } catch (...) {
    cv::setNumThreads(previous_cv_threads);
    throw;
  }
  cv::setNumThreads(previous_cv_threads);
  AffineFeatures out;
  for (std::size_t k = 0; k < photos.size(); ++k) {
    const int index = photos[k];
    out.features.descriptors[index] = ToDescriptorMatrix(unions[k]);
    for (const Keypoint& kp : unions[k].keypoints) {
      out.features.keypoints[index].emplace_back(kp.x, kp.y);
    }
    unions[k].descriptors.release();
    out.features.features[index] = std::move(unions[k]);
    out.features.indices.push_back(index);
    out.added[index] = std::move(added[k]);
  }
  return out;
}

std::filesystem::path AddedKeypointsPath(const Workspace& workspace, int index) {
  char name[32];
  std::snprintf(name, sizeof(name), "%05d.added.feat", index);
  return workspace.StageDir("matching") / name;
}

// Verifies `pairs` (indices into `chosen`) with the affine features and replaces a pair by
// its new verification when that passes KeepRetry with more inliers than the pair had.
// Returns the replaced ones.
std::vector<std::size_t> VerifyWithAffineFeatures(const std::vector<std::size_t>& pairs,
                                                  const std::vector<ImagePair>& chosen,
                                                  const PairFeatures& affine,
                                                  const TwoViewGeometryOptions& geometry,
                                                  StageContext& context,
                                                  std::vector<VerifiedPair>* verified) {
  std::vector<VerifiedPair> again(pairs.size());
  context.progress.Restart(pairs.size(), "pairs (affine-adapted features)");
  ParallelFor(
      0, pairs.size(),
      [&](std::size_t k) {
        context.cancel.ThrowIfCanceled();
        again[k] = VerifyPair(chosen[pairs[k]], affine, geometry, MatchingOptions().max_ratio,
                              context.cancel);
        context.progress.Advance();
      },
      context.options.num_threads);
  std::vector<std::size_t> replaced;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    VerifiedPair& before = (*verified)[pairs[k]];
    VerifiedPair& after = again[k];
    const int had =
        before.matches.matches.empty() ? 0 : std::max(before.num_inliers_F, before.num_inliers_H);
    const bool keep = !after.matches.matches.empty() && after.num_inliers_F > had &&
                      KeepRetry(after.type == TwoViewModelType::kFundamental, after.num_inliers_F,
                                after.num_putative, WeakPairOptions());
    LOG_DEBUG << "matching: photos " << after.matches.image1 << " and " << after.matches.image2
              << " with affine-adapted features: " << after.num_inliers_F << " inliers of F of "
              << after.num_putative << " putative (" << had << " before)" << (keep ? ", kept" : "");
    if (!keep) continue;
    after.affine = true;
    after.retried = before.retried;
    before = std::move(after);
    replaced.push_back(pairs[k]);
  }
  return replaced;
}

// Trying harder still (issue 13): the weak pairs PairsToRetry chooses after the looser ratio
// test are matched again with affine-adapted features (core/feature/affine_features.h) at the
// default ratio; a result is kept when it passes KeepRetry with more inliers than the pair
// had. Then the other verified pairs among the photos of a kept pair are matched again the
// same way, so that the bridge's new keypoints also get matches to the photos beyond it: a
// bridge whose points no third photo sees gives the mapper no scale to go on (the first 8
// templeSparseRing photos: 9 shared points instead of hundreds). Photos with enough strong
// pairs are never touched, so well-connected sets keep their matches to the bit. Returns the
// pairs replaced.
int RetryWithAffineFeatures(const std::vector<ImagePair>& chosen,
                            const std::vector<IngestedImage>& images,
                            const TwoViewGeometryOptions& geometry,
                            StageContext& context,
                            std::vector<VerifiedPair>* verified) {
  const AffinePlan plan = PlanAffineRetry(*verified);
  if (plan.pairs.empty()) return 0;
  const Timer timer;
  const AffineFeatures affine =
      ExtractAffineFeaturesOf(plan.photos, images, AffineFeatureOptions(), context);
  std::vector<std::size_t> kept =
      VerifyWithAffineFeatures(plan.pairs, chosen, affine.features, geometry, context, verified);
  const std::size_t bridges = kept.size();
  std::set<int> touched;
  for (std::size_t k : kept) {
    touched.insert((*verified)[k].matches.image1);
    touched.insert((*verified)[k].matches.image2);
  }
  const std::set<std::size_t> tried(plan.pairs.begin(), plan.pairs.end());
  std::vector<std::size_t> around;
  for (std::size_t k = 0; k < verified->size(); ++k) {
    if (tried.count(k)) continue;
    const VerifiedPair& p = (*verified)[k];
    const int a = p.matches.image1, b = p.matches.image2;
    if (!p.affine && !p.matches.matches.empty() && affine.added.count(a) && affine.added.count(b) &&
        (touched.count(a) || touched.count(b))) {
      around.push_back(k);
    }
  }
  const std::vector<std::size_t> more =
      VerifyWithAffineFeatures(around, chosen, affine.features, geometry, context, verified);
  kept.insert(kept.end(), more.begin(), more.end());
  std::set<int> used;
  for (std::size_t k : kept) {
    used.insert((*verified)[k].matches.image1);
    used.insert((*verified)[k].matches.image2);
  }
  std::size_t added = 0;
  for (int photo : used) {
    const FeatureSet& extra = affine.added.at(photo);
    if (extra.keypoints.empty()) continue;
    const Status written = WriteFeatures(AddedKeypointsPath(context.workspace, photo), extra);
    THROW_CHECK(written.ok()) << written.message();
    added += extra.size();
  }
  LOG_INFO << "matching: " << plan.pairs.size() << " weak pairs of " << plan.photos.size()
           << " photos matched again with affine-adapted features; " << bridges << " kept, then "
           << more.size() << " of " << around.size() << " pairs around them improved; " << added
           << " keypoints added to " << used.size() << " photos ("
           << static_cast<int>(timer.ElapsedSeconds()) << " s)";
  return static_cast<int>(kept.size());
}

// The verified pairs sorted out: those with matches (kept), one summary.json record per pair,
// and the counts.
struct MatchingTally {
  std::vector<VerifiedPair> usable;
  nlohmann::json summary_pairs = nlohmann::json::array();
  int num_f = 0, num_h = 0;
  std::size_t inliers = 0, guided = 0;
  int retried = 0;
  int affine = 0;
};

MatchingTally Tally(std::vector<VerifiedPair>* verified) {
  MatchingTally tally;
  for (VerifiedPair& p : *verified) {
    tally.summary_pairs.push_back(
        {{"image1", p.matches.image1},
         {"image2", p.matches.image2},
         {"model", TwoViewModelTypeName(p.type)},
         {"putative", p.num_putative},
         {"guided", p.num_guided},
         {"retried", p.retried},
         {"affine", p.affine},
         {"inliers_F", p.num_inliers_F},
         {"inliers_H", p.num_inliers_H},
         {"gric_F", std::isfinite(p.gric_F) ? nlohmann::json(p.gric_F) : nlohmann::json()},
         {"gric_H", std::isfinite(p.gric_H) ? nlohmann::json(p.gric_H) : nlohmann::json()}});
    if (p.type == TwoViewModelType::kFundamental) ++tally.num_f;
    if (p.type == TwoViewModelType::kHomography) ++tally.num_h;
    tally.guided += p.num_guided;
    tally.retried += p.retried;
    tally.affine += p.affine;
    if (!p.matches.matches.empty()) {
      tally.inliers += p.matches.matches.size();
      tally.usable.push_back(std::move(p));
    }
  }
  return tally;
}

// work/matching/pairs.bin and summary.json, and output/report/match_graph.png.
Status WriteMatchingFiles(const StageContext& context,
                          int num_images,
                          const std::vector<int>& indices,
                          const MatchingTally& tally) {
  if (Status s = WriteFileAtomically(context.stage_dir / "pairs.bin", Serialize(tally.usable));
      !s.ok()) {
    return s;
  }
  if (Status s = WriteFileAtomically(context.stage_dir / "summary.json",
                                     nlohmann::json{{"pairs", tally.summary_pairs}}.dump(1) + "\n");
      !s.ok()) {
    return s;
  }
  std::filesystem::create_directories(context.workspace.output_dir / "report");
  std::vector<std::uint8_t> png;
  cv::imencode(".png", RenderMatchGraph(num_images, indices, tally.usable), png);
  return WriteFileAtomically(
      context.workspace.output_dir / "report" / "match_graph.png",
      std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

}  // namespace

StageResult MatchingStage::Run(StageContext& context) const {
  auto images = ReadIngestedImages(context.workspace);
  if (!images.ok()) return StageResult::Failed(images.status().message());
  auto chosen = ReadImagePairs(context.workspace);
  if (!chosen.ok()) return StageResult::Failed(chosen.status().message());
  PairFeatures features;
  if (Status s = ReadPairFeatures(context.workspace, *chosen, &features); !s.ok()) {
    return StageResult::Failed(s.message());
  }

  const TwoViewGeometryOptions geometry;
  std::vector<VerifiedPair> verified(chosen->size());
  context.progress.Restart(chosen->size(), "pairs");
  ParallelFor(
      0, chosen->size(),
      [&](std::size_t k) {
        context.cancel.ThrowIfCanceled();
        verified[k] = VerifyPair((*chosen)[k], features, geometry, MatchingOptions().max_ratio,
                                 context.cancel);
        context.progress.Advance();
      },
      context.options.num_threads);
  RetryWeakPairs(*chosen, features, geometry, context, &verified);
  RetryWithAffineFeatures(*chosen, *images, geometry, context, &verified);

  const MatchingTally tally = Tally(&verified);
  if (Status s =
          WriteMatchingFiles(context, static_cast<int>(images->size()), features.indices, tally);
      !s.ok()) {
    return StageResult::Failed(s.message());
  }
  LOG_INFO << "matching: " << verified.size() << " pairs, " << tally.num_f
           << " with epipolar geometry, " << tally.num_h << " planar or rotation-only, "
           << tally.inliers << " inlier matches (" << tally.guided
           << " of them from guided matching); " << tally.retried
           << " weak pairs kept from a second verification at a looser ratio test, " << tally.affine
           << " from affine-adapted features";
  if (tally.usable.empty()) {
    return StageResult::Degenerate("no pair of photos could be matched: do the photos overlap?");
  }
  return StageResult::Success({{"pairs", verified.size()},
                               {"fundamental", tally.num_f},
                               {"homography", tally.num_h},
                               {"inlier_matches", tally.inliers},
                               {"guided_matches", tally.guided},
                               {"retried_pairs", tally.retried},
                               {"affine_pairs", tally.affine}});
}

Result<std::vector<Keypoint>> ReadMatchedKeypoints(const Workspace& workspace, int index) {
  auto features = ReadImageFeatures(workspace, index);
  if (!features.ok()) return features.status();
  std::vector<Keypoint> keypoints = std::move(features->keypoints);
  const std::filesystem::path added = AddedKeypointsPath(workspace, index);
  if (std::filesystem::exists(added)) {
    auto more = ReadFeatures(added);
    if (!more.ok()) return more.status();
    keypoints.insert(keypoints.end(), more->keypoints.begin(), more->keypoints.end());
  }
  return keypoints;
}

Result<std::vector<VerifiedPair>> ReadVerifiedPairs(const Workspace& workspace) {
  const std::filesystem::path path = workspace.StageDir("matching") / "pairs.bin";
  auto bytes = ReadFile(path);
  if (!bytes.ok()) return bytes.status();
  const std::string& in = *bytes;
  std::size_t offset = 4;
  std::uint32_t version = 0;
  std::uint64_t count = 0;
  if (in.size() < 4 || std::memcmp(in.data(), kMagic, 4) != 0 || !Get(in, &offset, &version) ||
      version != kVersion || !Get(in, &offset, &count)) {
    return Status::Internal(path.string() + ": not a Reconduit matches file (version 1)");
  }
  std::vector<VerifiedPair> pairs(count);
  for (VerifiedPair& p : pairs) {
    std::int32_t i1, i2, type, putative, inliers_f, inliers_h;
    std::uint64_t n = 0;
    bool ok = Get(in, &offset, &i1) && Get(in, &offset, &i2) && Get(in, &offset, &type) &&
              Get(in, &offset, &putative) && Get(in, &offset, &inliers_f) &&
              Get(in, &offset, &inliers_h) && Get(in, &offset, &p.gric_F) &&
              Get(in, &offset, &p.gric_H) && GetMatrix(in, &offset, &p.F) &&
              GetMatrix(in, &offset, &p.H) && Get(in, &offset, &n);
    if (!ok || offset + n * 8 > in.size()) return Status::Internal(path.string() + ": truncated");
    p.matches.image1 = i1;
    p.matches.image2 = i2;
    p.type = static_cast<TwoViewModelType>(type);
    p.num_putative = putative;
    p.num_inliers_F = inliers_f;
    p.num_inliers_H = inliers_h;
    p.matches.matches.resize(n);
    for (FeatureMatch& m : p.matches.matches) {
      std::int32_t a = 0, b = 0;
      Get(in, &offset, &a);
      Get(in, &offset, &b);
      m = {a, b};
    }
  }
  if (offset != in.size()) return Status::Internal(path.string() + ": trailing bytes");
  return pairs;
}

}  // namespace reconduit
