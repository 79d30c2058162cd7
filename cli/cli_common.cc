#include "cli/cli_common.h"

#include "core/io/file_util.h"

#include <algorithm>

namespace reconduit {

Result<PipelineOptions> LoadPipelineOptions(const std::string& options_file, int threads) {
  Result<PipelineOptions> options = PipelineOptions();
  if (!options_file.empty()) {
    auto text = ReadFile(options_file);
    if (!text.ok()) return text.status();
    options = ParsePipelineOptionsText(*text);
    if (!options.ok()) {
      return Status::InvalidArgument(options_file + ": " + options.status().message());
    }
  }
  if (threads >= 0) {
    nlohmann::json json = PipelineOptionsToJson(*options);
    json["num_threads"] = threads;
    options = ParsePipelineOptions(json);
  }
  return options;
}

std::vector<InputImage> ListInputImages(const std::filesystem::path& folder) {
  std::vector<InputImage> images;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    if (name.empty() || name[0] == '.' || !entry.is_regular_file()) continue;
    images.push_back({entry.path(), name});
  }
  std::sort(images.begin(), images.end(),
            [](const InputImage& a, const InputImage& b) { return a.name < b.name; });
  return images;
}

}  // namespace reconduit
