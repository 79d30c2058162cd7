#include "core/pipeline/stages/texture_stage.h"

#include "core/image/image_reader.h"
#include "core/io/gltf.h"
#include "core/io/mesh_ply.h"
#include "core/io/reconstruction_json.h"
#include "core/pipeline/held_out.h"
#include "core/pipeline/stages/dense_stage.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/texture/render_textured_mesh.h"
#include "core/texture/texture_mesh.h"
#include "core/util/logging.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <tuple>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// The registered photos as glTF camera nodes, in increasing image id (cameras.json's order).
std::vector<GltfCameraView> GltfCameras(const Reconstruction& model) {
  std::vector<GltfCameraView> cameras;
  for (const auto& [id, image] : model.images)
    cameras.push_back({image.name, model.cameras.at(image.camera_id), image.cam_from_world});
  return cameras;
}

nlohmann::json GltfJson(const GltfSummary& s) {
  return {{"vertices", s.num_vertices},     {"faces", s.num_faces},
          {"primitives", s.num_primitives}, {"images", s.num_images},
          {"cameras", s.num_cameras},       {"bytes", s.file_bytes}};
}

nlohmann::json TextureJson(const TextureSummary& s) {
  return {{"faces", s.num_faces},
          {"textured_faces", s.num_textured_faces},
          {"unseen_faces", s.num_unseen_faces},
          {"charts_greedy", s.num_charts_greedy},
          {"charts", s.num_charts},
          {"pages", s.num_pages},
          {"seam_difference_before", s.seam_difference_before},
          {"seam_difference_after", s.seam_difference_after},
          {"seam_border_vertices", s.seam_border_vertices},
          {"seam_vertex_difference", s.seam_vertex_difference},
          {"seam_blended_faces", s.seam_blended_faces},
          {"seconds",
           {{"visibility", s.visibility_seconds},
            {"labelling", s.labelling_seconds},
            {"atlas", s.atlas_seconds},
            {"bake", s.bake_seconds},
            {"levelling", s.levelling_seconds},
            {"blending", s.blending_seconds}}}};
}

// The photos as TextureView, each loading its original pixels when asked.
Result<std::vector<TextureView>> TextureViews(const Workspace& workspace,
                                              const Reconstruction& model,
                                              const PipelineOptions& options) {
  auto images = ReadIngestedImages(workspace);
  if (!images.ok()) return images.status();
  std::map<int, fs::path> paths;
  for (const IngestedImage& image : *images) paths[image.index] = image.path;
  ImageReaderOptions reader;
  reader.min_side = options.min_image_side;
  reader.max_pixels = options.max_image_pixels;
  reader.read_exif = false;  // As the features and dense stages read them.
  std::vector<TextureView> views;
  for (const auto& [id, image] : model.images) {
    if (!paths.count(id))
      return Status::Internal("no ingested photo for image " + std::to_string(id));
    const fs::path path = paths.at(id);
    views.push_back(
        {image.name, model.cameras.at(image.camera_id), image.cam_from_world, [path, reader]() {
           auto pixels = ReadImage(path, reader);
           if (!pixels.ok()) throw std::runtime_error("texture: " + pixels.status().message());
           return *pixels;
         }});
  }
  return views;
}

// Width of the renders that compare the model with each photo (the 1024 px).
constexpr int kCompareWidth = 1024;

// report.html shows the render beside its photo for the first photo and up to
// kReportPictures - 1 more spread over the others: a few are enough to judge the model, and
// each pair costs about 60 kB of result.zip (JPEG at kReportJpegQuality, kReportWidth wide).
constexpr std::size_t kReportPictures = 4;
constexpr int kReportWidth = 512;
constexpr int kReportJpegQuality = 85;

bool ShowsInReport(std::size_t view, std::size_t num_views) {
  const std::size_t shown = std::min(kReportPictures, num_views);
  for (std::size_t k = 0; k < shown; ++k) {
    if (view == k * num_views / shown) return true;
  }
  return false;
}

// The render and the photo (the same size; the render carries the camera's distortion, so
// they line up without undistorting the photo) as <stem>_render.jpg and <stem>_photo.jpg in
// `dir` (the stage's report/ folder, which the export copies to output/report/texture/), and
// their paths in result.zip in `entry`.
Status WriteReportPictures(const cv::Mat& render,
                           const cv::Mat& photo,
                           const fs::path& dir,
                           const std::string& stem,
                           nlohmann::json* entry) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  const double scale = std::min(1.0, static_cast<double>(kReportWidth) / render.cols);
  const cv::Size size(std::max(1, static_cast<int>(std::lround(render.cols * scale))),
                      std::max(1, static_cast<int>(std::lround(render.rows * scale))));
  for (const auto& [image, suffix, key] : {std::tuple{&render, "_render.jpg", "render_picture"},
                                           std::tuple{&photo, "_photo.jpg", "photo_picture"}}) {
    cv::Mat small;
    cv::resize(*image, small, size, 0, 0, cv::INTER_AREA);
    const fs::path path = dir / (stem + suffix);
    if (ec || !cv::imwrite(path.string(), small, {cv::IMWRITE_JPEG_QUALITY, kReportJpegQuality}))
      return Status::Internal("cannot write " + path.string());
    (*entry)[key] = "report/texture/" + stem + suffix;
  }
  return Status::Ok();
}

// The model rendered through each photo's camera at kCompareWidth pixels wide, against the
// photo resized to that size: the share of the photo the model covers, and the mean absolute
// difference of the covered pixels (grey levels 0-255, mean over the three channels). Both are
// per photo in report.json; the same figures for photos held out of texturing will tell how
// well the model predicts a view it was not made from. `ids` are the views' image ids; a few
// renders are kept as pictures in `picture_dir` (WriteReportPictures): the spread ones and the
// first kReportPictures held-out photos.
Result<nlohmann::json> CompareWithPhotos(const TriangleMesh& mesh,
                                         const std::vector<TextureView>& views,
                                         const std::vector<std::string>& held_out,
                                         const std::vector<int>& ids,
                                         const std::map<int, std::string>& stems,
                                         const fs::path& picture_dir,
                                         const CancelToken& cancel) {
  std::size_t held_out_pictures = 0;
  nlohmann::json renders = nlohmann::json::array();
  for (std::size_t k = 0; k < views.size(); ++k) {
    const TextureView& view = views[k];
    cancel.ThrowIfCanceled();
    const double scale = static_cast<double>(kCompareWidth) / view.camera.width;
    const Camera camera = view.camera.Scaled(scale);
    const MeshRender render = RenderTexturedMesh(mesh, camera, view.cam_from_world);
    cv::Mat photo;
    cv::resize(view.load(), photo, cv::Size(camera.width, camera.height), 0, 0, cv::INTER_AREA);
    if (photo.channels() == 1) cv::cvtColor(photo, photo, cv::COLOR_GRAY2BGR);
    cv::Mat difference;
    cv::absdiff(photo, render.image, difference);
    const int covered = cv::countNonZero(render.coverage);
    const cv::Scalar sum = cv::sum(difference.setTo(cv::Scalar::all(0), render.coverage == 0));
    const double mad = covered > 0 ? (sum[0] + sum[1] + sum[2]) / (3.0 * covered) : NAN;
    const bool is_held_out = IsHeldOut(held_out, view.name);
    nlohmann::json entry = {{"name", view.name},
                            {"image_id", ids[k]},
                            {"held_out", is_held_out},
                            {"covered", static_cast<double>(covered) / render.coverage.total()},
                            {"mean_abs_diff", std::isfinite(mad) ? nlohmann::json(mad) : nullptr}};
    const bool held_out_picture = is_held_out && held_out_pictures < kReportPictures;
    if (ShowsInReport(k, views.size()) || held_out_picture) {
      held_out_pictures += held_out_picture;
      const Status s =
          WriteReportPictures(render.image, photo, picture_dir, stems.at(ids[k]), &entry);
      if (!s.ok()) return s;
    }
    renders.push_back(std::move(entry));
  }
  return renders;
}

// Mean covered share and mean absolute difference of the renders of the photos that were
// (held_out true) or were not left out of texturing; null when there are none.
nlohmann::json MeanRender(const nlohmann::json& renders, bool held_out) {
  double covered = 0.0, difference = 0.0;
  int count = 0, with_difference = 0;
  for (const nlohmann::json& render : renders) {
    if (render["held_out"].get<bool>() != held_out) continue;
    ++count;
    covered += render["covered"].get<double>();
    if (render["mean_abs_diff"].is_number()) {
      difference += render["mean_abs_diff"].get<double>();
      ++with_difference;
    }
  }
  if (count == 0) return nullptr;
  return {{"photos", count},
          {"covered", covered / count},
          {"mean_abs_diff",
           with_difference > 0 ? nlohmann::json(difference / with_difference) : nullptr}};
}

}  // namespace

StageResult TextureStage::Run(StageContext& context) const {
  if (!context.options.texture)
    return StageResult::Skipped("texture", "turned off (option texture)");
  const fs::path mesh_path = context.workspace.StageDir("mesh") / "mesh.ply";
  if (!fs::exists(mesh_path))
    return StageResult::Skipped("texture", "no mesh (the mesh stage skipped)");
  auto mesh = ReadMeshPly(mesh_path);
  if (!mesh.ok()) return StageResult::Failed(mesh.status().message());
  auto model = ReadReconstructionJson(context.workspace.StageDir("sparse") / "model_0.json");
  if (!model.ok()) return StageResult::Failed(model.status().message());
  auto views = TextureViews(context.workspace, *model, context.options);
  if (!views.ok()) return StageResult::Failed(views.status().message());

  const std::vector<std::string>& held_out = context.options.held_out_photos;
  std::vector<TextureView> sources;
  for (const TextureView& view : *views) {
    if (!IsHeldOut(held_out, view.name)) sources.push_back(view);
  }

  TextureOptions options;
  options.page_size = context.options.texture_page_size;
  options.num_threads = context.options.num_threads;
  TextureResult textured = TextureMesh(*mesh, sources, options, &context.progress, context.cancel);
  context.progress.SetMessage("writing model.glb");
  GltfSummary gltf;
  const Status written = WriteModelGlb(context.stage_dir / "model.glb", textured.mesh,
                                       GltfCameras(*model), GltfOptions(), &gltf);
  if (!written.ok()) return StageResult::Failed(written.message());
  context.progress.SetMessage("comparing the model with the photos");
  std::vector<int> ids;
  for (const auto& [id, image] : model->images) ids.push_back(id);  // The views' order.
  const auto found =
      CompareWithPhotos(textured.mesh, *views, held_out, ids, PerPhotoFileNames(*model),
                        context.stage_dir / "report", context.cancel);
  if (!found.ok()) return StageResult::Failed(found.status().message());
  const nlohmann::json& renders = *found;
  LOG_INFO << "texture: " << textured.summary.num_charts << " charts on "
           << textured.summary.num_pages << " pages, " << textured.summary.num_unseen_faces
           << " of " << textured.summary.num_faces << " faces unseen; model.glb " << gltf.file_bytes
           << " bytes";
  return StageResult::Success({{"texture", TextureJson(textured.summary)},
                               {"model", GltfJson(gltf)},
                               {"renders", renders},
                               {"in_sample", MeanRender(renders, false)},
                               {"held_out", MeanRender(renders, true)}});
}

Result<std::vector<std::string>> ExportTexturedModel(const Workspace& workspace,
                                                     const fs::path& out) {
  const fs::path model = workspace.StageDir("texture") / "model.glb";
  if (!fs::exists(model)) return std::vector<std::string>{};  // Skipped.
  std::error_code ec;
  fs::copy_file(model, out / "model.glb", fs::copy_options::overwrite_existing, ec);
  if (ec) return Status::Internal("cannot copy model.glb: " + ec.message());
  std::vector<std::string> files = {"model.glb"};
  // The renders beside their photos (CompareWithPhotos), replacing those of an earlier run.
  const fs::path pictures = out / "report" / "texture";
  fs::remove_all(pictures, ec);
  for (const auto& entry : fs::directory_iterator(workspace.StageDir("texture") / "report", ec)) {
    fs::create_directories(pictures, ec);
    if (!ec) fs::copy_file(entry.path(), pictures / entry.path().filename(), ec);
    if (ec) return Status::Internal("cannot copy " + entry.path().string() + ": " + ec.message());
    files.push_back("report/texture/" + entry.path().filename().string());
  }
  return files;
}

Result<std::vector<std::string>> ExportUntexturedModel(const Workspace& workspace,
                                                       const fs::path& out) {
  const fs::path mesh_path = workspace.StageDir("mesh") / "mesh.ply";
  if (!fs::exists(mesh_path)) return std::vector<std::string>{};  // Skipped.
  auto mesh = ReadMeshPly(mesh_path);
  if (!mesh.ok()) return mesh.status();
  auto model = ReadReconstructionJson(workspace.StageDir("sparse") / "model_0.json");
  if (!model.ok()) return model.status();
  GltfSummary gltf;
  const Status written =
      WriteModelGlb(out / "model.glb", *mesh, GltfCameras(*model), GltfOptions(), &gltf);
  if (!written.ok()) return written;
  return std::vector<std::string>{"model.glb"};
}

}  // namespace reconduit
