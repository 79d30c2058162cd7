#include "core/pipeline/stages/ingest_stage.h"

#include "core/image/ingest.h"
#include "core/io/file_util.h"
#include "core/pipeline/held_out.h"
#include "core/util/logging.h"

namespace reconduit {

nlohmann::json IngestedImage::ToJson() const {
  nlohmann::json json = {{"index", index},          {"name", name},
                         {"path", path.string()},   {"accepted", photo.accepted},
                         {"width", photo.width},    {"height", photo.height},
                         {"camera_key", camera_key}};
  if (!photo.reason.empty()) json["reason"] = photo.reason;
  if (photo.exif_focal_px) {
    json["exif_focal_px"] = *photo.exif_focal_px;
    json["focal_source"] = photo.focal_source;
  }
  if (!photo.make.empty()) json["camera_make"] = photo.make;
  if (!photo.model.empty()) json["camera_model"] = photo.model;
  return json;
}

IngestedImage IngestedImage::FromJson(const nlohmann::json& json) {
  IngestedImage image;
  image.index = json.at("index").get<int>();
  image.name = json.at("name").get<std::string>();
  image.path = json.at("path").get<std::string>();
  image.photo.accepted = json.at("accepted").get<bool>();
  image.photo.reason = json.value("reason", "");
  image.photo.width = json.value("width", 0);
  image.photo.height = json.value("height", 0);
  if (json.contains("exif_focal_px")) {
    image.photo.exif_focal_px = json["exif_focal_px"].get<double>();
  }
  image.photo.focal_source = json.value("focal_source", "");
  image.photo.make = json.value("camera_make", "");
  image.photo.model = json.value("camera_model", "");
  image.camera_key = json.value("camera_key", "");
  return image;
}

StageResult IngestStage::Run(StageContext& context) const {
  const Workspace& workspace = context.workspace;
  // Checked here, before hours of work, and again by the stages that use the option (a resumed
  // job may change it).
  std::vector<std::string> names;
  for (const InputImage& input : workspace.images) names.push_back(input.name);
  if (Status s = CheckHeldOutPhotos(context.options.held_out_photos, names); !s.ok())
    return StageResult::Failed(s.message());
  IngestOptions options;
  options.reader.min_side = context.options.min_image_side;
  options.reader.max_pixels = context.options.max_image_pixels;
  options.reader.read_exif = true;  // Recorded either way; use_exif decides whether it is used.
  options.num_threads = context.options.num_threads;
  std::vector<std::filesystem::path> files;
  for (const InputImage& input : workspace.images) files.push_back(input.path);
  const IngestReport report = IngestImages(files, options, context.progress, context.cancel);
  context.cancel.ThrowIfCanceled();

  nlohmann::json list = nlohmann::json::array();
  std::string refusals;
  int accepted = 0, with_exif_focal = 0;
  for (std::size_t i = 0; i < report.images.size(); ++i) {
    const ImageRecord& record = report.images[i];
    IngestedImage image;
    image.index = static_cast<int>(i);
    image.name = workspace.images[i].name;
    image.path = workspace.images[i].path;
    image.photo = record.Metadata();
    if (image.photo.accepted) {
      ++accepted;
      if (image.photo.exif_focal_px) ++with_exif_focal;
    } else {
      refusals += "\n  " + image.name + ": " + image.photo.reason;
    }
    image.camera_key = image.photo.make + "|" + image.photo.model + "|" +
                       std::to_string(image.photo.width) + "x" + std::to_string(image.photo.height);
    list.push_back(image.ToJson());
  }
  if (Status s = WriteFileAtomically(context.stage_dir / "images.json",
                                     nlohmann::json{{"images", list}}.dump(2) + "\n");
      !s.ok()) {
    return StageResult::Failed(s.message());
  }
  LOG_INFO << "ingest: " << accepted << " of " << report.images.size() << " photos usable, "
           << with_exif_focal << " with an EXIF focal length";
  if (accepted < 2) {
    return StageResult::Failed("need at least 2 usable photos, got " + std::to_string(accepted) +
                               (refusals.empty() ? "" : "; refused:" + refusals));
  }
  return StageResult::Success({{"images", report.images.size()},
                               {"accepted", accepted},
                               {"rejected", report.images.size() - accepted},
                               {"with_exif_focal", with_exif_focal}});
}

Result<std::vector<IngestedImage>> ReadIngestedImages(const Workspace& workspace) {
  auto text = ReadFile(workspace.StageDir("ingest") / "images.json");
  if (!text.ok()) return text.status();
  try {
    std::vector<IngestedImage> images;
    const nlohmann::json json = nlohmann::json::parse(*text);  // Outlives the loop.
    for (const auto& item : json.at("images")) {
      images.push_back(IngestedImage::FromJson(item));
    }
    return images;
  } catch (const std::exception& e) {
    return Status::Internal(std::string("unreadable ingest/images.json: ") + e.what());
  }
}

}  // namespace reconduit
