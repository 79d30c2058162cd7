#include "core/pipeline/stages/pairs_stage.h"

#include "core/io/file_util.h"
#include "core/pipeline/stages/features_stage.h"
#include "core/pipeline/stages/ingest_stage.h"

#include <opencv2/imgcodecs.hpp>

namespace reconduit {

StageResult PairsStage::Run(StageContext& context) const {
  auto images = ReadIngestedImages(context.workspace);
  if (!images.ok()) return StageResult::Failed(images.status().message());
  std::vector<int> indices;
  std::vector<FeatureSet> features;
  for (const IngestedImage& image : *images) {
    if (!image.photo.accepted) continue;
    auto f = ReadImageFeatures(context.workspace, image.index);
    if (!f.ok()) return StageResult::Failed(f.status().message());
    indices.push_back(image.index);
    features.push_back(std::move(*f));
  }
  if (indices.size() < 2) return StageResult::Failed("need at least 2 photos with features");
  std::vector<const FeatureSet*> pointers;
  for (const FeatureSet& f : features) pointers.push_back(&f);

  GlobalComparisonOptions options;
  options.num_threads = context.options.num_threads;
  const GlobalComparisonResult result =
      CompareImages(pointers, options, context.progress, context.cancel);

  nlohmann::json pairs = nlohmann::json::array();
  for (const ImagePair& p : result.pairs) {
    pairs.push_back(
        {{"image1", indices[p.image1]}, {"image2", indices[p.image2]}, {"score", p.score}});
  }
  nlohmann::json similarity = nlohmann::json::array();
  for (Eigen::Index i = 0; i < result.similarity.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index j = 0; j < result.similarity.cols(); ++j)
      row.push_back(result.similarity(i, j));
    similarity.push_back(row);
  }
  const nlohmann::json json = {
      {"method", result.method}, {"images", indices}, {"pairs", pairs}, {"similarity", similarity}};
  if (Status s = WriteFileAtomically(context.stage_dir / "pairs.json", json.dump() + "\n");
      !s.ok()) {
    return StageResult::Failed(s.message());
  }

  const std::filesystem::path report_dir = context.workspace.output_dir / "report";
  std::filesystem::create_directories(report_dir);
  const int cell = std::clamp(480 / std::max<int>(1, indices.size()), 2, 32);
  std::vector<std::uint8_t> png;
  cv::imencode(".png", RenderSimilarityMatrix(result, cell), png);
  if (Status s = WriteFileAtomically(
          report_dir / "similarity.png",
          std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
      !s.ok()) {
    return StageResult::Failed(s.message());
  }
  const std::size_t n = indices.size();
  return StageResult::Success(
      {{"method", result.method}, {"pairs", result.pairs.size()}, {"all_pairs", n * (n - 1) / 2}});
}

Result<std::vector<ImagePair>> ReadImagePairs(const Workspace& workspace) {
  auto text = ReadFile(workspace.StageDir("pairs") / "pairs.json");
  if (!text.ok()) return text.status();
  try {
    std::vector<ImagePair> pairs;
    const nlohmann::json json = nlohmann::json::parse(*text);  // Outlives the loop.
    for (const auto& p : json.at("pairs")) {
      pairs.push_back(
          {p.at("image1").get<int>(), p.at("image2").get<int>(), p.at("score").get<double>()});
    }
    return pairs;
  } catch (const std::exception& e) {
    return Status::Internal(std::string("unreadable pairs/pairs.json: ") + e.what());
  }
}

}  // namespace reconduit
