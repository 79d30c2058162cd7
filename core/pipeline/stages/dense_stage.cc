#include "core/pipeline/stages/dense_stage.h"

#include "core/image/image_reader.h"
#include "core/io/file_util.h"
#include "core/io/reconstruction_json.h"
#include "core/mvs/cloud_distance.h"
#include "core/mvs/dense_cloud_io.h"
#include "core/mvs/dense_previews.h"
#include "core/mvs/depth_map_io.h"
#include "core/mvs/fusion.h"
#include "core/mvs/mvs_view.h"
#include "core/mvs/patch_match.h"
#include "core/mvs/view_selection.h"
#include "core/pipeline/held_out.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/util/logging.h"
#include "core/util/timer.h"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <list>
#include <map>
#include <memory>
#include <set>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// PatchMatch sources per photo: the first neighbours of view selection, chosen for coverage of
// the photo (ViewSelectionOptions::coverage_sources). Time grows linearly
// with them; beyond six the top-2 cost rarely changes (COLMAP's default is 20 on a GPU, OpenMVS
// uses up to 8 at half resolution on the CPU).
constexpr int kMaxSources = 6;
// A photo is matched only with at least this many sparse points in it (its depth range comes
// from them).
constexpr int kMinSeeds = 10;
// The prepared photos kept between maps: each photo is a source of several neighbours, which
// are mostly computed close together in the order of the upload.
constexpr std::size_t kViewCacheSize = 2 * (kMaxSources + 1);
// Longer side of the previews in output/report/dense/.
constexpr int kPreviewSide = 480;

// What the stage decided for one registered photo before matching it.
struct ViewPlan {
  int image_id = -1;
  std::string name;
  Camera working;  // Pinhole at the working size.
  Rigid3d cam_from_world;
  std::vector<ViewNeighbor> neighbors;  // The first kMaxSources are the sources.
  double min_depth = 0.0, max_depth = 0.0;
  std::vector<DepthSeed> seeds;

  int NumSources() const { return std::min<int>(kMaxSources, neighbors.size()); }
  bool Matchable() const { return NumSources() > 0 && seeds.size() >= kMinSeeds; }
};

nlohmann::json CameraJson(const Camera& c) {
  return {{"width", c.width}, {"height", c.height}, {"focal", c.focal}, {"cx", c.cx}, {"cy", c.cy}};
}

Camera CameraFromJson(const nlohmann::json& j) {
  Camera c;
  c.width = j.at("width").get<int>();
  c.height = j.at("height").get<int>();
  c.focal = j.at("focal").get<double>();
  c.cx = j.at("cx").get<double>();
  c.cy = j.at("cy").get<double>();
  return c;
}

nlohmann::json ViewPlanJson(const ViewPlan& v) {
  nlohmann::json neighbors = nlohmann::json::array();
  for (const ViewNeighbor& n : v.neighbors) {
    neighbors.push_back({{"image_id", n.image_id},
                         {"score", n.score},
                         {"shared_points", n.shared_points},
                         {"median_angle_deg", n.median_angle_deg},
                         {"median_scale_ratio", n.median_scale_ratio}});
  }
  return {{"image_id", v.image_id},    {"name", v.name},         {"camera", CameraJson(v.working)},
          {"sources", v.NumSources()}, {"neighbors", neighbors}, {"min_depth", v.min_depth},
          {"max_depth", v.max_depth},  {"seeds", v.seeds.size()}};
}

// Depth range and seeds of `image` from the sparse points it observes, in its working camera.
void AddSeeds(const Reconstruction& model, const RegisteredImage& image, ViewPlan* plan) {
  std::vector<double> depths;
  for (int point_id : image.point_for_keypoint) {
    if (point_id == kInvalidId) continue;
    const Eigen::Vector3d in_cam = image.cam_from_world * model.points.at(point_id).xyz_in_world;
    const auto pixel = plan->working.ImgFromCam(in_cam);
    if (in_cam.z() <= 0 || !pixel) continue;
    depths.push_back(in_cam.z());
    if (pixel->x() >= 0 && pixel->y() >= 0 && pixel->x() < plan->working.width &&
        pixel->y() < plan->working.height) {
      plan->seeds.push_back({*pixel, in_cam.z()});
    }
  }
  if (depths.empty()) return;
  std::sort(depths.begin(), depths.end());
  // The 1st and 99th percentiles, widened: surfaces between sparse points may reach a little
  // nearer or farther than any of them (PatchMatch samples the range in inverse depth, so a
  // generous range costs little).
  plan->min_depth = 0.6 * depths[depths.size() / 100];
  plan->max_depth = 1.6 * depths[depths.size() - 1 - depths.size() / 100];
}

std::vector<ViewPlan> PlanViews(const Reconstruction& model, int max_side) {
  ViewSelectionOptions selection;
  selection.coverage_sources = kMaxSources;
  const std::map<int, std::vector<ViewNeighbor>> neighbors = SelectViews(model, selection);
  std::vector<ViewPlan> plans;
  for (const auto& [id, image] : model.images) {
    ViewPlan plan;
    plan.image_id = id;
    plan.name = image.name;
    plan.working = WorkingCamera(model.cameras.at(image.camera_id), max_side);
    plan.cam_from_world = image.cam_from_world;
    plan.neighbors = neighbors.at(id);
    AddSeeds(model, image, &plan);
    plans.push_back(std::move(plan));
  }
  return plans;
}

// The prepared photos most recently used (core/mvs/mvs_view.h), read from the workspace on a
// miss.
class ViewCache {
 public:
  ViewCache(const Reconstruction& model,
            std::map<int, fs::path> paths,
            const PipelineOptions& options)
      : model_(model), paths_(std::move(paths)), max_side_(options.dense_max_image_side) {
    reader_.min_side = options.min_image_side;
    reader_.max_pixels = options.max_image_pixels;
    reader_.read_exif = false;
  }

  std::shared_ptr<const PreparedView> Get(int image_id) {
    for (auto it = entries_.begin(); it != entries_.end(); ++it) {
      if (it->first != image_id) continue;
      entries_.splice(entries_.begin(), entries_, it);
      return it->second;
    }
    const RegisteredImage& image = model_.images.at(image_id);
    auto pixels = ReadImage(paths_.at(image_id), reader_);
    if (!pixels.ok()) throw std::runtime_error("dense: " + pixels.status().message());
    auto view = std::make_shared<const PreparedView>(
        PrepareView(*pixels, model_.cameras.at(image.camera_id), image.cam_from_world, max_side_));
    entries_.emplace_front(image_id, view);
    if (entries_.size() > kViewCacheSize) entries_.pop_back();
    return view;
  }

 private:
  const Reconstruction& model_;
  std::map<int, fs::path> paths_;
  int max_side_;
  ImageReaderOptions reader_;
  std::list<std::pair<int, std::shared_ptr<const PreparedView>>> entries_;
};

fs::path MapPath(const fs::path& stage_dir, int image_id) {
  return stage_dir / "maps" / (std::to_string(image_id) + ".rcdm");
}

double DepthFraction(const cv::Mat& depth) {
  return depth.empty() ? 0.0 : static_cast<double>(cv::countNonZero(depth)) / depth.total();
}

// Computes (or takes over from an interrupted attempt) the depth map of `plan`; returns its
// figures for the summary.
nlohmann::json ComputeOrResumeMap(const ViewPlan& plan, ViewCache* cache, StageContext& context) {
  const fs::path path = MapPath(context.stage_dir, plan.image_id);
  nlohmann::json figures = {{"image", plan.name}, {"image_id", plan.image_id}};
  if (fs::exists(path)) {
    auto kept = ReadDepthMapBinary(path);
    if (kept.ok() && kept->depth.cols == plan.working.width &&
        kept->depth.rows == plan.working.height) {
      figures["resumed"] = true;
      figures["seconds"] = 0.0;
      figures["depth_fraction"] = DepthFraction(kept->depth);
      return figures;
    }
    LOG_WARNING << "dense: recomputing " << plan.name << ": the kept map is unusable";
  }
  const Timer timer;
  const std::shared_ptr<const PreparedView> reference = cache->Get(plan.image_id);
  std::vector<std::shared_ptr<const PreparedView>> sources;
  PatchMatchInput input;
  input.reference = &reference->view;
  for (int k = 0; k < plan.NumSources(); ++k) {
    sources.push_back(cache->Get(plan.neighbors[k].image_id));
    input.sources.push_back(&sources.back()->view);
  }
  input.min_depth = plan.min_depth;
  input.max_depth = plan.max_depth;
  input.seeds = plan.seeds;
  PatchMatchOptions options;
  options.num_threads = context.options.num_threads;
  options.seed = static_cast<std::uint64_t>(plan.image_id);
  DepthMap map = ComputeDepthMap(input, options, context.cancel);
  // Pixels that came from outside the photo (corners of a strongly distorted lens) have no
  // depth.
  map.depth.setTo(0.0f, reference->valid == 0);
  const Status written = WriteDepthMapBinary(path, map);
  if (!written.ok()) throw std::runtime_error(written.message());
  figures["seconds"] = timer.ElapsedSeconds();
  figures["sources"] = plan.NumSources();
  figures["depth_fraction"] = DepthFraction(map.depth);
  figures["noise_stddev"] = map.noise_stddev;
  return figures;
}

// The depth maps of every matchable view, one at a time; the figures of each.
nlohmann::json ComputeMaps(const std::vector<ViewPlan>& plans,
                           ViewCache* cache,
                           StageContext& context) {
  nlohmann::json maps = nlohmann::json::array();
  std::size_t done = 0, total = 0;
  for (const ViewPlan& plan : plans) total += plan.Matchable();
  for (const ViewPlan& plan : plans) {
    if (!plan.Matchable()) {
      LOG_INFO << "dense: no depth map for " << plan.name << " (" << plan.NumSources()
               << " neighbours, " << plan.seeds.size() << " sparse points)";
      continue;
    }
    context.cancel.ThrowIfCanceled();
    context.progress.SetMessage("depth map " + std::to_string(done + 1) + " of " +
                                std::to_string(total) + ": " + plan.name);
    nlohmann::json figures = ComputeOrResumeMap(plan, cache, context);
    ++done;
    LOG_INFO << "dense: depth map " << done << "/" << total << " " << plan.name << ": "
             << plan.working.width << "x" << plan.working.height << ", " << plan.NumSources()
             << " sources, " << std::lround(100 * figures["depth_fraction"].get<double>())
             << " % of pixels, noise " << figures.value("noise_stddev", 0.0) << " grey levels, "
             << (figures.value("resumed", false)
                     ? std::string("kept from an earlier attempt")
                     : std::to_string(figures["seconds"].get<double>()) + " s");
    maps.push_back(std::move(figures));
    context.progress.Advance();
  }
  return maps;
}

// The stage's figures for the maps and the cloud; also writes quality/<id>.png.
struct Fused {
  DenseCloud cloud;
  std::map<int, double> fused_fraction;  // Per image id: share of pixels with quality >= min.
  // Per image id: FusionResult::neighbor_agreement (NaN where nothing overlaps).
  std::map<int, double> agreement;
};

Fused FuseMaps(const std::vector<ViewPlan>& plans, ViewCache* cache, StageContext& context) {
  std::vector<const ViewPlan*> fused_plans;
  for (const ViewPlan& plan : plans)
    if (fs::exists(MapPath(context.stage_dir, plan.image_id))) fused_plans.push_back(&plan);
  std::map<int, int> index_of;
  for (std::size_t k = 0; k < fused_plans.size(); ++k) index_of[fused_plans[k]->image_id] = k;

  std::vector<DepthMap> maps(fused_plans.size());
  std::vector<FusionView> views(fused_plans.size());
  for (std::size_t k = 0; k < fused_plans.size(); ++k) {
    context.cancel.ThrowIfCanceled();
    const ViewPlan& plan = *fused_plans[k];
    auto map = ReadDepthMapBinary(MapPath(context.stage_dir, plan.image_id));
    if (!map.ok()) throw std::runtime_error(map.status().message());
    maps[k] = std::move(*map);
    views[k].map = &maps[k];
    views[k].color = cache->Get(plan.image_id)->color;
    views[k].camera = plan.working;
    views[k].cam_from_world = plan.cam_from_world;
    views[k].image_id = plan.image_id;
    for (const ViewNeighbor& n : plan.neighbors)
      if (index_of.count(n.image_id)) views[k].neighbors.push_back(index_of.at(n.image_id));
  }
  FusionOptions options;
  options.min_views = context.options.dense_min_views;
  options.num_threads = context.options.num_threads;
  FusionResult result = FuseDepthMaps(views, options, context.cancel);

  Fused fused;
  fs::create_directories(context.stage_dir / "quality");
  for (std::size_t k = 0; k < fused_plans.size(); ++k) {
    const cv::Mat& quality = result.quality[k];
    fused.agreement[fused_plans[k]->image_id] = result.neighbor_agreement[k];
    fused.fused_fraction[fused_plans[k]->image_id] =
        static_cast<double>(cv::countNonZero(quality >= options.min_views)) / quality.total();
    const fs::path png =
        context.stage_dir / "quality" / (std::to_string(fused_plans[k]->image_id) + ".png");
    if (!cv::imwrite(png.string(), quality))
      throw std::runtime_error("cannot write " + png.string());
  }
  fused.cloud = std::move(result.cloud);
  // Visibility as positions in cameras.json's image list: the registered photos in increasing
  // id, as in the model (plans follow the model's order).
  std::map<int, int> position;
  for (const ViewPlan& plan : plans) position.emplace(plan.image_id, position.size());
  for (int& id : fused.cloud.visibility) id = position.at(id);
  return fused;
}

// The median distance from the sparse points seen by three or more photos to the nearest dense
// point, and the scene depth it is measured against (the median over those points of the
// distance to the nearest camera centre): the consistency figure of the issue.
nlohmann::json SparseToDense(const Reconstruction& model, const DenseCloud& cloud) {
  std::vector<Eigen::Vector3d> points;
  std::vector<double> scene_depths;
  for (const auto& [id, point] : model.points) {
    if (point.observations.size() < 3) continue;
    points.push_back(point.xyz_in_world);
    double nearest = INFINITY;
    for (const auto& [image_id, image] : model.images)
      nearest =
          std::min(nearest, (image.cam_from_world.CenterInWorld() - point.xyz_in_world).norm());
    scene_depths.push_back(nearest);
  }
  if (points.empty()) return nullptr;
  const double scene_depth = Median(scene_depths);
  // Distances beyond 1 % of the scene depth count as "far" (+inf): the figure's target is 0.1 %.
  const double median = Median(NearestDistancesWithin(cloud.positions, points, 0.01 * scene_depth));
  return {
      {"sparse_points", points.size()},
      {"scene_depth", scene_depth},
      {"median_distance", std::isfinite(median) ? nlohmann::json(median) : nullptr},
      {"median_relative", std::isfinite(median) ? nlohmann::json(median / scene_depth) : nullptr}};
}

}  // namespace

StageResult DenseStage::Run(StageContext& context) const {
  if (!context.options.dense_matching)
    return StageResult::Skipped("dense", "turned off (option dense_matching)");
  auto sparse = ReadReconstructionJson(context.workspace.StageDir("sparse") / "model_0.json");
  if (!sparse.ok()) return StageResult::Failed(sparse.status().message());
  auto images = ReadIngestedImages(context.workspace);
  if (!images.ok()) return StageResult::Failed(images.status().message());
  const std::vector<std::string>& held_out = context.options.held_out_photos;
  std::vector<std::string> names;
  for (const IngestedImage& image : *images) names.push_back(image.name);
  if (Status s = CheckHeldOutPhotos(held_out, names); !s.ok())
    return StageResult::Failed(s.message());
  const Reconstruction model = WithoutHeldOutPhotos(*sparse, held_out);
  if (model.images.size() < 2) {
    return StageResult::Skipped(
        "dense", held_out.empty() ? "fewer than two photos have cameras: nothing to match"
                                  : "fewer than two photos that are not held out have "
                                    "cameras: nothing to match");
  }
  std::map<int, fs::path> paths;
  for (const IngestedImage& image : *images) paths[image.index] = image.path;

  const std::vector<ViewPlan> plans = PlanViews(model, context.options.dense_max_image_side);
  nlohmann::json views = nlohmann::json::array();
  std::size_t matchable = 0;
  for (const ViewPlan& plan : plans) {
    views.push_back(ViewPlanJson(plan));
    matchable += plan.Matchable();
  }
  const Status written =
      WriteFileAtomically(context.stage_dir / "views.json", views.dump(1) + "\n");
  if (!written.ok()) return StageResult::Failed(written.message());
  if (matchable == 0)
    return StageResult::Skipped("dense",
                                "no photo shares enough sparse points with another to match them");

  fs::create_directories(context.stage_dir / "maps");
  context.progress.Restart(matchable + 1, "depth maps");
  ViewCache cache(model, std::move(paths), context.options);
  const Timer maps_timer;
  nlohmann::json maps = ComputeMaps(plans, &cache, context);
  const double maps_seconds = maps_timer.ElapsedSeconds();

  context.progress.SetMessage("fusing the depth maps");
  const Timer fusion_timer;
  Fused fused = FuseMaps(plans, &cache, context);
  std::vector<double> agreements;
  for (nlohmann::json& map : maps) {
    const int id = map["image_id"].get<int>();
    map["fused_fraction"] = fused.fused_fraction[id];
    const double agreement = fused.agreement.count(id) ? fused.agreement[id] : NAN;
    map["neighbor_agreement"] =
        std::isnan(agreement) ? nlohmann::json() : nlohmann::json(agreement);
    if (!std::isnan(agreement)) agreements.push_back(agreement);
  }
  nlohmann::json summary = {
      {"maps", maps},
      {"depth_maps", maps.size()},
      {"points", fused.cloud.size()},
      {"depth_maps_seconds", maps_seconds},
      {"fusion_seconds", fusion_timer.ElapsedSeconds()},
      // Median over the maps of the share of their depths within 1 % of
      // their neighbours' where they overlap (FusionResult).
      {"neighbor_agreement_median",
       agreements.empty() ? nlohmann::json() : nlohmann::json(Median(agreements))},
      {"sparse_to_dense", SparseToDense(model, fused.cloud)}};
  if (fused.cloud.size() == 0) {
    return StageResult::Skipped("dense",
                                "no surface was confirmed by " +
                                    std::to_string(context.options.dense_min_views) +
                                    " photos (plain, textureless surfaces?)",
                                std::move(summary));
  }
  const Status ply = WriteDenseCloudPly(context.stage_dir / "dense.ply", fused.cloud);
  if (!ply.ok()) return StageResult::Failed(ply.message());
  context.progress.Advance();
  LOG_INFO << "dense: " << fused.cloud.size() << " points from " << maps.size()
           << " depth maps; depth maps " << maps_seconds << " s, fusion "
           << summary["fusion_seconds"].get<double>() << " s";
  return StageResult::Success(std::move(summary));
}

std::vector<std::string> PerPhotoFileNames(const std::vector<std::string>& names,
                                           const std::vector<int>& indices) {
  THROW_CHECK_EQ(names.size(), indices.size());
  std::vector<std::string> stems;
  std::map<std::string, int> count;
  for (const std::string& name : names) {
    std::string stem = fs::path(name).filename().stem().string();
    for (char& c : stem) {
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') c = '_';
    }
    if (stem.empty()) stem = "photo";
    ++count[stem];
    stems.push_back(std::move(stem));
  }
  for (std::size_t i = 0; i < stems.size(); ++i) {
    if (count[stems[i]] > 1) stems[i] += "_" + std::to_string(indices[i] + 1);
  }
  return stems;
}

std::map<int, std::string> PerPhotoFileNames(const Reconstruction& model) {
  std::vector<std::string> names;
  std::vector<int> ids;
  for (const auto& [id, image] : model.images) {
    names.push_back(image.name);
    ids.push_back(id);
  }
  const std::vector<std::string> stems = PerPhotoFileNames(names, ids);
  std::map<int, std::string> by_id;
  for (std::size_t k = 0; k < ids.size(); ++k) by_id[ids[k]] = stems[k];
  return by_id;
}

namespace {

Status WritePicture(const fs::path& path, const cv::Mat& image) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (ec || !cv::imwrite(path.string(), image))
    return Status::Internal("cannot write " + path.string());
  return Status::Ok();
}

// One photo's depth and quality files and previews; appends what it wrote to `files`.
Status ExportPhoto(const fs::path& work,
                   const fs::path& out,
                   const nlohmann::json& view,
                   const Rigid3d& cam_from_world,
                   const std::string& file_name,
                   std::vector<std::string>* files) {
  const int id = view.at("image_id").get<int>();
  auto map = ReadDepthMapBinary(MapPath(work, id));
  if (!map.ok()) return Status::Ok();  // No map for this photo (too few neighbours).
  const cv::Mat quality =
      cv::imread((work / "quality" / (std::to_string(id) + ".png")).string(), cv::IMREAD_UNCHANGED);
  if (quality.empty())
    return Status::Internal("quality map of image " + std::to_string(id) + " missing");
  std::error_code ec;
  fs::create_directories(out / "depth", ec);
  Status s =
      WriteDepthPng(out / "depth" / (file_name + ".png"), out / "depth" / (file_name + ".json"),
                    map->depth, CameraFromJson(view.at("camera")), cam_from_world);
  if (s.ok()) s = WritePicture(out / "quality" / (file_name + ".png"), quality);
  const fs::path previews = out / "report" / "dense";
  if (s.ok())
    s = WritePicture(previews / (file_name + "_depth.jpg"),
                     RenderDepthPreview(map->depth, kPreviewSide));
  if (s.ok()) {
    s = WritePicture(previews / (file_name + "_quality.png"),
                     RenderQualityPreview(quality, kMaxSources + 1, kPreviewSide));
  }
  if (!s.ok()) return s;
  for (const std::string& f :
       {"depth/" + file_name + ".png", "depth/" + file_name + ".json",
        "quality/" + file_name + ".png", "report/dense/" + file_name + "_depth.jpg",
        "report/dense/" + file_name + "_quality.png"})
    files->push_back(f);
  return Status::Ok();
}

}  // namespace

Result<std::vector<std::string>> ExportDenseResults(const Workspace& workspace,
                                                    const fs::path& out) {
  const fs::path work = workspace.StageDir("dense");
  if (!fs::exists(work / "dense.ply")) return std::vector<std::string>{};  // Skipped.
  std::error_code ec;
  fs::copy_file(work / "dense.ply", out / "dense.ply", fs::copy_options::overwrite_existing, ec);
  if (ec) return Status::Internal("cannot copy dense.ply: " + ec.message());
  std::vector<std::string> files{"dense.ply"};

  auto model = ReadReconstructionJson(workspace.StageDir("sparse") / "model_0.json");
  if (!model.ok()) return model.status();
  auto views_text = ReadFile(work / "views.json");
  if (!views_text.ok()) return views_text.status();
  const nlohmann::json views = nlohmann::json::parse(*views_text);
  std::vector<std::string> names;
  std::vector<int> ids;
  for (const nlohmann::json& view : views) {
    names.push_back(view.at("name").get<std::string>());
    ids.push_back(view.at("image_id").get<int>());
  }
  const std::vector<std::string> file_names = PerPhotoFileNames(names, ids);
  for (std::size_t k = 0; k < views.size(); ++k) {
    const Status s = ExportPhoto(work, out, views[k], model->images.at(ids[k]).cam_from_world,
                                 file_names[k], &files);
    if (!s.ok()) return s;
  }
  return files;
}

}  // namespace reconduit
