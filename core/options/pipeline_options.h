// Pipeline options: one struct, one table of specs.
//
// The table (PipelineOptionSpecs) is the single source of truth for every option's name, type,
// default, range and help text. The server serves it as GET /api/v1/options and validates the
// `options` part of an upload with ParsePipelineOptions; the worker and the command line parse
// the same JSON with the same function, so a value the API accepted is a value the pipeline
// runs with. Names are the C++ field names (snake_case), so error messages match the API.
//
// Only options that change what the pipeline does today are listed; a stage adds its options
// here when it lands.
#ifndef RECONDUIT_CORE_OPTIONS_PIPELINE_OPTIONS_H_
#define RECONDUIT_CORE_OPTIONS_PIPELINE_OPTIONS_H_

#include "core/options/feature_limits.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace reconduit {

struct PipelineOptions {
  // Photos with a shorter side than this (pixels) are rejected at ingest. [16, 10000]
  int min_image_side = 100;
  // Photos with more pixels than this are rejected before decoding (decompression bombs).
  // [1e4, 1e9]
  std::int64_t max_image_pixels = 100'000'000;
  // Use the EXIF focal length, when present, as the initial focal length. [bool]
  bool use_exif = true;
  // Features are detected on a copy of each photo no larger than this (long side, pixels).
  // [256, 20000]
  int max_image_side = 3200;
  // At most this many features per photo. [256, 65536]
  int max_features = kDefaultMaxFeatures;
  // A photo with fewer SIFT candidates than this (capped at max_features) is detected again
  // at lower contrast thresholds, then, when smaller than 1000 px, at twice its size
  // (core/feature/sift.h). 0 turns it off. [0, 65536]
  int min_features = kDefaultMinFeatures;
  // The principal point in the final bundle adjustment of models with 8 or more photos:
  // "auto" refines it when the data clearly support an off-centre point (model selection,
  // see core/sfm/incremental_mapper.h), "center" keeps the image centre, "refine" always
  // refines it. ["auto", "center", "refine"]
  std::string principal_point = "auto";
  // Dense matching (the dense stage): depth maps of every registered photo fused into a dense
  // cloud. Off: the job ends with the cameras and the sparse points. [bool]
  bool dense_matching = true;
  // Depth maps are computed on copies of the photos whose longer side is at most this
  // (pixels). [256, 20000]
  int dense_max_image_side = 1600;
  // A dense point needs this many photos whose depths agree on it. [2, 32]
  int dense_min_views = 2;
  // The surface (the mesh stage): Delaunay tetrahedra of the dense points labelled by their
  // lines of sight, cleaned and simplified. Off: the job ends with the dense cloud. [bool]
  bool mesh = true;
  // The mesh is simplified to at most this many triangles. [1000, 20000000]
  int mesh_max_faces = 500000;
  // The texture (the texture stage): one photo per face baked into atlas pages; off, model.glb
  // has the mesh's vertex colours. [bool]
  bool texture = true;
  // Largest side of an atlas page, pixels. [256, 16384]
  int texture_page_size = 4096;
  // Photos (names as uploaded, e.g. "0004.jpg") that get cameras but are left out of dense
  // matching and texturing, so that the model rendered through their cameras shows how well it
  // predicts a view it was not made from (the texture stage's "renders", report.json). At most
  // 1000 names. [list of photo names]
  std::vector<std::string> held_out_photos;
  // Keep the intermediate work files (features, matches, depth maps, ...) after a job succeeds;
  // by default they are removed then (a failed or canceled job keeps them, to resume). [bool]
  bool keep_work_files = false;
  // Put the heavy dense files in result.zip: dense.ply and the full-size depth/ and quality/
  // maps. Off, result.zip keeps the model, the cameras and the report (with the small depth
  // and quality previews); the service still serves the left-out files one by one. [bool]
  bool package_dense_files = true;
  // Worker threads for parallel stages; 0 = all cores. [0, 256]
  int num_threads = 0;

  // False, with a message naming the field, when a value is out of range.
  bool Check(std::string* error) const;
};

// One option's metadata and accessors.
struct OptionSpec {
  std::string name;
  // "integer", "number", "boolean", "string" or "array" (of strings) (JSON Schema names).
  std::string type;
  std::string help;
  std::optional<double> minimum;     // Inclusive, for numbers.
  std::optional<double> maximum;     // Inclusive, for numbers.
  std::vector<std::string> choices;  // The allowed values of a string option; empty: any.
  std::function<nlohmann::json(const PipelineOptions&)> get;
  // Sets the field from JSON; returns an error message (naming the field) or "" on success.
  std::function<std::string(const nlohmann::json&, PipelineOptions*)> set;
};

const std::vector<OptionSpec>& PipelineOptionSpecs();

// False for options that change how fast, not what, the pipeline computes (num_threads),
// what is kept afterwards (keep_work_files), or only what the packaging stage packs
// (package_dense_files; it runs every time): changing them does not invalidate finished
// stages.
bool OptionAffectsResults(const std::string& name);

// {"options": [{"name", "type", "default", "minimum", "maximum", "enum", "help"}, ...]}
nlohmann::json DescribePipelineOptions();

// Parses a JSON object of options over the defaults. Unknown names, wrong types and values
// out of range are InvalidArgument errors whose message names the field, e.g.
// "option 'min_image_side' must be an integer in [16, 10000], got 3".
Result<PipelineOptions> ParsePipelineOptions(const nlohmann::json& json);
Result<PipelineOptions> ParsePipelineOptionsText(const std::string& text);

// All options with their values.
nlohmann::json PipelineOptionsToJson(const PipelineOptions& options);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_OPTIONS_PIPELINE_OPTIONS_H_
