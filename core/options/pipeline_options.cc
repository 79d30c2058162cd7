#include "core/options/pipeline_options.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace reconduit {
namespace {

std::string FormatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string RangeText(const OptionSpec& spec) {
  return "[" + FormatNumber(*spec.minimum) + ", " + FormatNumber(*spec.maximum) + "]";
}

// An integer field of any width, range-checked.
template <typename T>
OptionSpec IntegerOption(
    std::string name, T PipelineOptions::*field, double minimum, double maximum, std::string help) {
  OptionSpec spec{std::move(name), "integer", std::move(help), minimum, maximum, {}, {}, {}};
  spec.get = [field](const PipelineOptions& o) { return nlohmann::json(o.*field); };
  spec.set = [field, spec](const nlohmann::json& j, PipelineOptions* o) -> std::string {
    const bool integral = j.is_number_integer() ||
                          (j.is_number_float() && std::floor(j.get<double>()) == j.get<double>());
    const double v = j.is_number() ? j.get<double>() : 0.0;
    if (!integral || v < *spec.minimum || v > *spec.maximum) {
      return "option '" + spec.name + "' must be an integer in " + RangeText(spec) + ", got " +
             j.dump();
    }
    o->*field = static_cast<T>(v);
    return "";
  };
  return spec;
}

OptionSpec BooleanOption(std::string name, bool PipelineOptions::*field, std::string help) {
  OptionSpec spec{
      std::move(name), "boolean", std::move(help), std::nullopt, std::nullopt, {}, {}, {}};
  spec.get = [field](const PipelineOptions& o) { return nlohmann::json(o.*field); };
  spec.set = [field, name = spec.name](const nlohmann::json& j, PipelineOptions* o) -> std::string {
    if (!j.is_boolean()) return "option '" + name + "' must be true or false, got " + j.dump();
    o->*field = j.get<bool>();
    return "";
  };
  return spec;
}

// A string field that takes one of `choices`.
OptionSpec ChoiceOption(std::string name,
                        std::string PipelineOptions::*field,
                        std::vector<std::string> choices,
                        std::string help) {
  OptionSpec spec{std::move(name),
                  "string",
                  std::move(help),
                  std::nullopt,
                  std::nullopt,
                  std::move(choices),
                  {},
                  {}};
  spec.get = [field](const PipelineOptions& o) { return nlohmann::json(o.*field); };
  spec.set = [field, spec](const nlohmann::json& j, PipelineOptions* o) -> std::string {
    if (j.is_string()) {
      for (const std::string& choice : spec.choices) {
        if (j.get<std::string>() == choice) {
          o->*field = choice;
          return "";
        }
      }
    }
    std::string list;
    for (const std::string& choice : spec.choices) list += (list.empty() ? "" : ", ") + choice;
    return "option '" + spec.name + "' must be one of " + list + "; got " + j.dump();
  };
  return spec;
}

// A list of names (strings of 1 to 255 bytes), at most `max_items`, no duplicates.
OptionSpec NameListOption(std::string name,
                          std::vector<std::string> PipelineOptions::*field,
                          std::size_t max_items,
                          std::string help) {
  OptionSpec spec{
      std::move(name), "array", std::move(help), std::nullopt, std::nullopt, {}, {}, {}};
  spec.get = [field](const PipelineOptions& o) { return nlohmann::json(o.*field); };
  spec.set = [field, name = spec.name, max_items](const nlohmann::json& j,
                                                  PipelineOptions* o) -> std::string {
    const std::string expected = "option '" + name + "' must be a list of at most " +
                                 std::to_string(max_items) + " distinct names";
    if (!j.is_array() || j.size() > max_items) return expected + ", got " + j.dump();
    std::vector<std::string> names;
    for (const nlohmann::json& item : j) {
      if (!item.is_string() || item.get<std::string>().empty() ||
          item.get<std::string>().size() > 255) {
        return expected + " (strings of 1 to 255 bytes), got " + item.dump();
      }
      if (std::find(names.begin(), names.end(), item.get<std::string>()) != names.end())
        return expected + "; " + item.dump() + " appears twice";
      names.push_back(item.get<std::string>());
    }
    o->*field = std::move(names);
    return "";
  };
  return spec;
}

std::vector<OptionSpec> MakeSpecs() {
  std::vector<OptionSpec> specs;
  specs.push_back(IntegerOption("min_image_side", &PipelineOptions::min_image_side, 16, 10000,
                                "Photos whose shorter side has fewer pixels are rejected."));
  specs.push_back(IntegerOption(
      "max_image_pixels", &PipelineOptions::max_image_pixels, 1e4, 1e9,
      "Photos with more pixels are rejected before decoding (protects against decompression "
      "bombs)."));
  specs.push_back(BooleanOption(
      "use_exif", &PipelineOptions::use_exif,
      "Start from the EXIF focal length when a photo has one. Self-calibration still checks it."));
  specs.push_back(IntegerOption(
      "max_image_side", &PipelineOptions::max_image_side, 256, 20000,
      "Features are found on a copy of each photo whose longer side is at most this many "
      "pixels; results are always in the original photo's pixels."));
  specs.push_back(IntegerOption("max_features", &PipelineOptions::max_features, kMinMaxFeatures,
                                kMaxMaxFeatures,
                                "At most this many features per photo, spread over the whole "
                                "photo."));
  specs.push_back(IntegerOption(
      "min_features", &PipelineOptions::min_features, 0, kMaxMaxFeatures,
      "A photo that yields fewer features than this (a dim photo, a small object on a plain "
      "background) is searched again at lower contrast, then at twice its size when it is "
      "smaller than 1000 px. 0 turns it off."));
  specs.push_back(ChoiceOption(
      "principal_point", &PipelineOptions::principal_point, {"auto", "center", "refine"},
      "The principal point of models with 8 or more photos: 'auto' refines it in the final "
      "bundle adjustment when the photos clearly show it is off the image centre, 'center' "
      "keeps the image centre, 'refine' always refines it."));
  specs.push_back(BooleanOption(
      "dense_matching", &PipelineOptions::dense_matching,
      "Compute a depth map for every photo and fuse them into a dense point cloud (dense.ply). "
      "Off, the result holds the cameras and the sparse points only."));
  specs.push_back(IntegerOption(
      "dense_max_image_side", &PipelineOptions::dense_max_image_side, 256, 20000,
      "Depth maps are computed on copies of the photos whose longer side is at most this many "
      "pixels. Larger is more detailed and slower: time grows with the number of pixels."));
  specs.push_back(IntegerOption(
      "dense_min_views", &PipelineOptions::dense_min_views, 2, 32,
      "A dense point is kept only where at least this many photos agree on its depth; more "
      "gives fewer, more reliable points."));
  specs.push_back(BooleanOption(
      "mesh", &PipelineOptions::mesh,
      "Build a surface from the dense points (the mesh of model.glb). Off, the result ends with "
      "the dense point cloud."));
  specs.push_back(IntegerOption(
      "mesh_max_faces", &PipelineOptions::mesh_max_faces, 1000, 20000000,
      "The surface is simplified to at most this many triangles; flat parts lose theirs first. "
      "500,000 keep a façade's carvings and load in a phone's browser."));
  specs.push_back(BooleanOption(
      "texture", &PipelineOptions::texture,
      "Texture the surface from the photos (model.glb's texture). Off, model.glb is coloured by "
      "the mesh's vertices."));
  specs.push_back(IntegerOption(
      "texture_page_size", &PipelineOptions::texture_page_size, 256, 16384,
      "Largest side of a texture page, pixels; more pages rather than one huge image. 4096 is "
      "what phone browsers still display."));
  specs.push_back(NameListOption(
      "held_out_photos", &PipelineOptions::held_out_photos, 1000,
      "Photos (names as uploaded) that get cameras but are left out of dense matching and "
      "texturing; the model rendered through their cameras is compared with them in the "
      "report, which shows how well the model predicts a view it was not made from."));
  specs.push_back(BooleanOption(
      "keep_work_files", &PipelineOptions::keep_work_files,
      "Keep the intermediate files (features, matches, depth maps) after the job succeeds, "
      "e.g. to rerun later stages with other options without starting over. By default they "
      "are removed once result.zip is written."));
  specs.push_back(BooleanOption(
      "package_dense_files", &PipelineOptions::package_dense_files,
      "Put dense.ply and the full-size depth and quality maps (depth/, quality/) in result.zip. "
      "Off, result.zip is much smaller: the model, the cameras and the report with its "
      "previews; the left-out files can still be downloaded one by one from the job's files."));
  specs.push_back(IntegerOption(
      "num_threads", &PipelineOptions::num_threads, 0, 256,
      "Threads for parallel stages; 0 uses every core. A worker grants at most its --threads."));
  return specs;
}

}  // namespace

const std::vector<OptionSpec>& PipelineOptionSpecs() {
  static const std::vector<OptionSpec> specs = MakeSpecs();
  return specs;
}

bool PipelineOptions::Check(std::string* error) const {
  // Range checks live in the spec table: round-trip every field through it.
  for (const OptionSpec& spec : PipelineOptionSpecs()) {
    PipelineOptions scratch;
    const std::string message = spec.set(spec.get(*this), &scratch);
    if (!message.empty()) {
      if (error != nullptr) *error = message;
      return false;
    }
  }
  return true;
}

nlohmann::json DescribePipelineOptions() {
  const PipelineOptions defaults;
  nlohmann::json list = nlohmann::json::array();
  for (const OptionSpec& spec : PipelineOptionSpecs()) {
    nlohmann::json item = {{"name", spec.name},
                           {"type", spec.type},
                           {"default", spec.get(defaults)},
                           {"help", spec.help}};
    if (spec.minimum) item["minimum"] = *spec.minimum;
    if (spec.maximum) item["maximum"] = *spec.maximum;
    if (!spec.choices.empty()) item["enum"] = spec.choices;
    list.push_back(std::move(item));
  }
  return {{"options", list}};
}

Result<PipelineOptions> ParsePipelineOptions(const nlohmann::json& json) {
  PipelineOptions options;
  if (json.is_null()) return options;
  if (!json.is_object()) {
    return Status::InvalidArgument("options must be a JSON object, got " + json.dump());
  }
  for (const auto& [name, value] : json.items()) {
    const OptionSpec* found = nullptr;
    for (const OptionSpec& spec : PipelineOptionSpecs()) {
      if (spec.name == name) found = &spec;
    }
    if (found == nullptr) {
      return Status::InvalidArgument("unknown option '" + name +
                                     "' (GET /api/v1/options lists them)");
    }
    if (std::string message = found->set(value, &options); !message.empty()) {
      return Status::InvalidArgument(message);
    }
  }
  return options;
}

Result<PipelineOptions> ParsePipelineOptionsText(const std::string& text) {
  nlohmann::json json;
  try {
    json = text.empty() ? nlohmann::json::object() : nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    // parse_error for bad syntax, and out_of_range for a number that overflows a double
    // ("1e999"), which escaped as an exception before (found by fuzzing).
    return Status::InvalidArgument(std::string("options are not valid JSON: ") + e.what());
  }
  return ParsePipelineOptions(json);
}

bool OptionAffectsResults(const std::string& name) {
  return name != "num_threads" && name != "keep_work_files" && name != "package_dense_files";
}

nlohmann::json PipelineOptionsToJson(const PipelineOptions& options) {
  nlohmann::json json = nlohmann::json::object();
  for (const OptionSpec& spec : PipelineOptionSpecs()) json[spec.name] = spec.get(options);
  return json;
}

}  // namespace reconduit
