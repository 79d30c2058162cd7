#include "cli/benchmark.h"

#include "core/eval/camera_evaluation.h"
#include "core/image/ingest.h"
#include "core/io/colmap_text.h"
#include "core/io/file_util.h"
#include "core/io/reconstruction_json.h"
#include "core/pipeline/default_stages.h"
#include "core/pipeline/runner.h"
#include "core/util/logging.h"
#include "core/util/timer.h"

#include <nlohmann/json.hpp>

#include "cli/cli_common.h"
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

struct ChildRun {
  int exit_code = -1;
  double seconds = 0.0;
  std::int64_t peak_memory_bytes = 0;
};

// Runs a program (no shell), output to `log`, and measures it with wait4's rusage.
ChildRun RunChild(const std::vector<std::string>& argv, const fs::path& log) {
  ChildRun run;
  const Timer timer;
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* out = std::fopen(log.c_str(), "a");
    if (out != nullptr) {
      dup2(fileno(out), STDOUT_FILENO);
      dup2(fileno(out), STDERR_FILENO);
    }
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execvp(args[0], args.data());
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  run.seconds = timer.ElapsedSeconds();
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  run.peak_memory_bytes = static_cast<std::int64_t>(usage.ru_maxrss) * 1024;
  return run;
}

double MiB(std::int64_t bytes) { return bytes / (1024.0 * 1024.0); }

// A row: name, status, seconds, the process's peak MiB and, when known, the stage's own peak
// MiB (our stages; COLMAP's steps are processes of their own, so their peak is their own).
void PrintRow(const std::string& name,
              const std::string& status,
              double seconds,
              double mib,
              std::optional<double> stage_mib = std::nullopt) {
  std::cout << "  " << std::left << std::setw(20) << name << std::setw(12) << status << std::right
            << std::fixed << std::setprecision(2) << std::setw(10) << seconds << std::setw(12)
            << std::setprecision(1) << mib;
  if (stage_mib) std::cout << std::setw(12) << *stage_mib;
  std::cout << "\n";
}

void PrintHeader(bool with_stage_peak) {
  std::cout << "  " << std::left << std::setw(32) << "" << std::right << std::setw(10) << "seconds"
            << std::setw(12) << "peak MiB";
  if (with_stage_peak) std::cout << std::setw(12) << "own MiB";
  std::cout << "\n";
}

// Per camera id, the focal length's standard deviation that the sparse stage recorded in
// calibration.json (empty when absent or unreadable: the benchmark then prints no +-).
std::map<int, double> ReadFocalStddev(const fs::path& calibration_json) {
  std::map<int, double> stddev;
  std::ifstream in(calibration_json);
  const nlohmann::json calibration = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (!calibration.is_object() || !calibration.contains("cameras")) return stddev;
  for (const nlohmann::json& camera : calibration["cameras"]) {
    if (camera.contains("camera_id") && camera.contains("stddev")) {
      stddev[camera["camera_id"].get<int>()] = camera["stddev"].value("focal", 0.0);
    }
  }
  return stddev;
}

void PrintModel(const Reconstruction& model,
                int total_photos,
                const std::optional<std::vector<GroundTruthCamera>>& ground_truth,
                const std::map<int, double>& focal_stddev = {}) {
  std::cout << "  registered          " << model.images.size() << "/" << total_photos << "\n"
            << "  points              " << model.points.size() << "\n"
            << "  mean reprojection   " << std::setprecision(3) << model.MeanReprojectionError()
            << " px\n";
  for (const auto& [id, camera] : model.cameras) {
    std::cout << "  camera " << id << "            f " << std::setprecision(2) << camera.focal;
    if (focal_stddev.contains(id) && focal_stddev.at(id) > 0.0) {
      std::cout << " +- " << focal_stddev.at(id);
    }
    std::cout << " px, k1 " << std::setprecision(4) << camera.k1 << ", k2 " << camera.k2 << "\n";
  }
  if (ground_truth) {
    std::istringstream report(EvaluateCameras(model, *ground_truth).Report());
    for (std::string line; std::getline(report, line);) std::cout << "  " << line << "\n";
  }
}

struct ColmapResult {
  double seconds = 0.0;
  std::int64_t peak_memory_bytes = 0;
  std::optional<Reconstruction> model;
};

std::optional<ColmapResult> RunColmap(const fs::path& images,
                                      const fs::path& work,
                                      int total_photos,
                                      const std::optional<std::vector<GroundTruthCamera>>& gt) {
  const fs::path dir = work / "colmap";
  fs::remove_all(dir);
  fs::create_directories(dir / "sparse");
  const fs::path log = dir / "colmap.log";
  const std::string db = (dir / "database.db").string();
  struct Step {
    std::string name;
    std::vector<std::string> argv;
  };
  const std::vector<Step> steps = {
      {"features",
       {"colmap", "feature_extractor", "--database_path", db, "--image_path", images.string(),
        "--ImageReader.single_camera", "1", "--SiftExtraction.use_gpu", "0"}},
      {"matching",
       {"colmap", "exhaustive_matcher", "--database_path", db, "--SiftMatching.use_gpu", "0"}},
      {"mapping",
       {"colmap", "mapper", "--database_path", db, "--image_path", images.string(), "--output_path",
        (dir / "sparse").string()}},
  };
  std::cout << "\nCOLMAP (" << log.string() << ")\n";
  PrintHeader(/*with_stage_peak=*/false);
  ColmapResult result;
  for (const Step& step : steps) {
    const ChildRun run = RunChild(step.argv, log);
    if (run.exit_code == 127) {
      std::cout << "  colmap is not installed: apt-get install colmap\n";
      return std::nullopt;
    }
    PrintRow(step.name, run.exit_code == 0 ? "success" : "exit " + std::to_string(run.exit_code),
             run.seconds, MiB(run.peak_memory_bytes));
    result.seconds += run.seconds;
    result.peak_memory_bytes = std::max(result.peak_memory_bytes, run.peak_memory_bytes);
    if (run.exit_code != 0) return result;
  }
  PrintRow("total", "", result.seconds, MiB(result.peak_memory_bytes));
  // The largest model is "0"; convert it to text and read it back.
  const fs::path text = dir / "text";
  fs::create_directories(text);
  const ChildRun convert =
      RunChild({"colmap", "model_converter", "--input_path", (dir / "sparse" / "0").string(),
                "--output_path", text.string(), "--output_type", "TXT"},
               log);
  if (convert.exit_code != 0) {
    std::cout << "  no COLMAP model to evaluate\n";
    return result;
  }
  auto model = ReadColmapText(text);
  if (!model.ok()) {
    std::cout << "  cannot read COLMAP's model: " << model.status() << "\n";
    return result;
  }
  PrintModel(*model, total_photos, gt);
  result.model = std::move(*model);
  return result;
}

// `benchmark`'s arguments, checked.
struct BenchmarkArgs {
  fs::path images;
  std::string gt_path;
  bool colmap = false;
  bool resume = false;
  RunFlags flags;
};

// Returns the exit status when the command should stop (bad arguments).
std::optional<int> ParseBenchmarkArgs(const std::vector<std::string>& args, BenchmarkArgs* parsed) {
  namespace po = boost::program_options;
  parsed->flags.until = "sparse";
  po::options_description options = RunOptions(&parsed->flags);
  options.add_options()("gt", po::value(&parsed->gt_path))(
      "colmap", po::bool_switch(&parsed->colmap))("resume", po::bool_switch(&parsed->resume));
  std::vector<std::string> positional;
  const std::string error = ParseCommandArguments(args, options, &positional);
  if (!error.empty()) return UsageError(error);
  if (positional.size() != 1) return UsageError("benchmark needs one <images_dir>");
  parsed->images = positional[0];
  std::error_code ec;
  if (!fs::is_directory(parsed->images, ec)) {
    std::cerr << "reconduit: '" << parsed->images.string() << "' is not a folder\n";
    return 2;
  }
  return std::nullopt;
}

// The ground truth of `gt_path` for the photos given: a ground-truth file may describe a larger
// set (one Middlebury _par.txt for every view) of which the folder holds a subset. Empty
// (nullopt) without --gt; the exit status when it cannot be used.
std::optional<int> LoadGroundTruth(const BenchmarkArgs& args,
                                   const std::vector<InputImage>& images,
                                   std::optional<std::vector<GroundTruthCamera>>* ground_truth) {
  if (args.gt_path.empty()) return std::nullopt;
  auto read = ReadGroundTruth(args.gt_path);
  if (!read.ok()) {
    std::cerr << "reconduit: ground truth: " << read.status() << "\n";
    return 2;
  }
  std::vector<GroundTruthCamera> cameras = std::move(read).value();
  std::set<std::string> names;
  for (const InputImage& image : images) names.insert(image.name);
  const std::size_t described = cameras.size();
  std::erase_if(cameras,
                [&](const GroundTruthCamera& camera) { return !names.contains(camera.name); });
  if (cameras.empty()) {
    std::cerr << "reconduit: ground truth '" << args.gt_path
              << "' describes none of the photos in '" << args.images.string() << "'\n";
    return 2;
  }
  if (cameras.size() < described) {
    std::cout << "Ground truth: " << cameras.size() << " of its " << described
              << " cameras are photos of this folder; comparing those\n";
  }
  *ground_truth = std::move(cameras);
  return std::nullopt;
}

// OpenMVS DensifyPointCloud on fountain-P11 at its defaults (half resolution) on this 2-core
// machine: 654 s and 842 s in two runs (issue 10; OpenMVS is not in Debian, so it cannot run
// beside us here). The smaller figure is the reference for the dense stage's time.
constexpr double kOpenMvsFountainDenseSeconds = 654.0;

// The dense stage's figures from its record: points, maps, time per map, the sparse-to-dense
// consistency, and the time against OpenMVS's on fountain-P11.
void PrintDense(const PipelineResult& result) {
  for (const StageRecord& record : result.stages) {
    if (record.name != "dense" || record.status != StageStatus::kSuccess) continue;
    const nlohmann::json& s = record.summary;
    if (s.contains("skipped_reason")) {
      std::cout << "  dense               skipped: " << s["skipped_reason"].get<std::string>()
                << "\n";
      return;
    }
    std::vector<double> seconds;
    for (const nlohmann::json& map : s.value("maps", nlohmann::json::array()))
      seconds.push_back(map.value("seconds", 0.0));
    std::sort(seconds.begin(), seconds.end());
    std::cout << std::setprecision(4) << "  dense points        " << s.value("points", 0) << "\n"
              << "  depth maps          " << seconds.size() << " in "
              << s.value("depth_maps_seconds", 0.0) << " s";
    if (!seconds.empty()) {
      std::cout << " (per map " << seconds.front() << " / " << seconds[seconds.size() / 2] << " / "
                << seconds.back() << " s min / median / max)";
    }
    std::cout << ", fusion " << s.value("fusion_seconds", 0.0) << " s\n";
    if (s.value("neighbor_agreement_median", nlohmann::json()).is_number()) {
      std::cout << "  maps agreeing       " << 100.0 * s["neighbor_agreement_median"].get<double>()
                << " % of depths within 1 % of the neighbours' (median over the maps)\n";
    }
    const nlohmann::json& consistency = s.value("sparse_to_dense", nlohmann::json());
    if (consistency.is_object() && consistency["median_relative"].is_number()) {
      std::cout << "  sparse to dense     median "
                << 100.0 * consistency["median_relative"].get<double>() << " % of the scene depth ("
                << consistency["sparse_points"] << " points)\n";
    }
    std::cout << "  dense / OpenMVS     " << record.seconds / kOpenMvsFountainDenseSeconds
              << " (its " << static_cast<int>(kOpenMvsFountainDenseSeconds)
              << " s on fountain-P11 on this machine; meaningful for that set only)\n";
  }
}

// OpenMVS ReconstructMesh on fountain-P11 at its defaults on this machine (issue 11).
constexpr double kOpenMvsFountainMeshSeconds = 117.0;

// The mesh stage's figures: points kept, tetrahedra, lines of sight, faces, time per step.
void PrintMesh(const PipelineResult& result) {
  for (const StageRecord& record : result.stages) {
    if (record.name != "mesh" || record.status != StageStatus::kSuccess) continue;
    const nlohmann::json& s = record.summary;
    if (s.contains("skipped_reason")) {
      std::cout << "  mesh                skipped: " << s["skipped_reason"].get<std::string>()
                << "\n";
      return;
    }
    const nlohmann::json& surface = s.value("surface", nlohmann::json::object());
    const nlohmann::json& t = surface.value("seconds", nlohmann::json::object());
    std::cout << std::setprecision(4) << "  mesh                " << s.value("faces", 0)
              << " faces, " << s.value("vertices", 0) << " vertices (from "
              << surface.value("cut_faces", 0) << " on the cut, "
              << surface.value("trimmed_faces", 0) << " trimmed)\n"
              << "  mesh input          " << surface.value("kept_points", 0) << " of "
              << surface.value("input_points", 0) << " points, " << surface.value("tetrahedra", 0)
              << " tetrahedra, " << surface.value("lines_of_sight", 0) << " lines of sight\n"
              << "  mesh steps          decimation " << t.value("decimation", 0.0)
              << " s, delaunay " << t.value("delaunay", 0.0) << " s, visibility "
              << t.value("visibility", 0.0) << " s, cut " << t.value("cut", 0.0)
              << " s, extraction " << t.value("extraction", 0.0) << " s, cleaning + simplification "
              << s.value("simplification", nlohmann::json::object()).value("seconds", 0.0) << " s\n"
              << "  mesh / OpenMVS      " << record.seconds / kOpenMvsFountainMeshSeconds
              << " (its ReconstructMesh " << static_cast<int>(kOpenMvsFountainMeshSeconds)
              << " s on fountain-P11 on this machine; meaningful for that set only)\n";
  }
}

// The texture stage's figures and how the model compares with the first photo.
void PrintTexture(const PipelineResult& result) {
  for (const StageRecord& record : result.stages) {
    if (record.name != "texture" || record.status != StageStatus::kSuccess) continue;
    const nlohmann::json& s = record.summary;
    if (s.contains("skipped_reason")) {
      std::cout << "  texture             skipped: " << s["skipped_reason"].get<std::string>()
                << "\n";
      return;
    }
    const nlohmann::json& t = s.value("texture", nlohmann::json::object());
    std::cout << std::setprecision(4) << "  texture             " << t.value("charts", 0)
              << " charts on " << t.value("pages", 0) << " pages, " << t.value("unseen_faces", 0)
              << " of " << t.value("faces", 0) << " faces unseen; model.glb "
              << s.value("model", nlohmann::json::object()).value("bytes", 0) << " bytes\n";
    bool first = true;  // The first photo in sample: the figure.
    for (const nlohmann::json& render : s.value("renders", nlohmann::json::array())) {
      const bool held_out = render.value("held_out", false);
      if (!render["mean_abs_diff"].is_number() || (!held_out && !first)) continue;
      first = first && held_out;
      std::cout << "  model vs " << render["name"].get<std::string>()
                << (held_out ? " (held out)   " : "   ") << 100.0 * render["covered"].get<double>()
                << " % covered, mean abs. difference " << render["mean_abs_diff"].get<double>()
                << " (1024 px wide)\n";
    }
    for (const char* group : {"in_sample", "held_out"}) {
      const nlohmann::json& mean = s.value(group, nlohmann::json());
      if (!mean.is_object() || !mean["mean_abs_diff"].is_number()) continue;
      std::cout << "  model vs photos "
                << (group == std::string("held_out") ? "held out " : "in sample") << "  mean over "
                << mean["photos"].get<int>() << ": " << 100.0 * mean["covered"].get<double>()
                << " % covered, mean abs. difference " << mean["mean_abs_diff"].get<double>()
                << "\n";
    }
  }
}

// Time and peak memory of our stages (the package stage's time aside).
struct OurRun {
  PipelineResult result;
  double seconds = 0.0;
  std::int64_t peak_memory_bytes = 0;
};

// Runs the stages in `workspace` and prints a row per stage and the model's figures.
OurRun RunOurs(const std::vector<std::unique_ptr<Stage>>& stages,
               const Workspace& workspace,
               const PipelineOptions& options,
               const std::optional<std::vector<GroundTruthCamera>>& ground_truth) {
  OurRun run;
  run.result = RunPipeline(stages, workspace, options, CancelToken());
  // "peak": the process's so far; "own": the stage's own high-water mark (StagePeakMemory),
  // absent where the kernel's mark could not be reset.
  PrintHeader(/*with_stage_peak=*/true);
  for (const StageRecord& record : run.result.stages) {
    PrintRow(record.name, std::string(StageStatusName(record.status)), record.seconds,
             MiB(record.peak_memory_bytes),
             record.stage_peak_memory_own
                 ? std::optional<double>(MiB(record.stage_peak_memory_bytes))
                 : std::nullopt);
    if (record.name != "package") run.seconds += record.seconds;
    run.peak_memory_bytes = std::max(run.peak_memory_bytes, record.peak_memory_bytes);
  }
  PrintRow("total", "", run.seconds, MiB(run.peak_memory_bytes));
  if (run.result.status != StageStatus::kSuccess) {
    std::cout << "  failed at " << run.result.failed_stage << ": " << run.result.message << "\n";
  }
  auto model = ReadReconstructionJson(workspace.StageDir("sparse") / "model_0.json");
  if (model.ok()) {
    PrintModel(*model, static_cast<int>(workspace.images.size()), ground_truth,
               ReadFocalStddev(workspace.StageDir("sparse") / "calibration.json"));
  }
  PrintDense(run.result);
  PrintMesh(run.result);
  PrintTexture(run.result);
  return run;
}

}  // namespace

int RunBenchmark(const std::vector<std::string>& arguments) {
  BenchmarkArgs args;
  if (const std::optional<int> status = ParseBenchmarkArgs(arguments, &args)) return *status;
  const Result<std::vector<fs::path>> files = ListImageFiles(args.images);
  if (!files.ok()) return UsageError(files.status().message());
  Workspace workspace;
  workspace.images = ToInputImages(*files);
  std::optional<std::vector<GroundTruthCamera>> ground_truth;
  if (const std::optional<int> status = LoadGroundTruth(args, workspace.images, &ground_truth)) {
    return *status;
  }
  const Result<PipelineOptions> options =
      LoadPipelineOptions(args.flags.options_file, args.flags.threads);
  if (!options.ok()) return UsageError(options.status().ToString());
  auto stages = CreatePipelineStages(args.flags.until);
  if (!stages.ok()) return UsageError(stages.status().ToString());

  const fs::path work_dir = args.flags.work.empty()
                                ? fs::temp_directory_path() / "reconduit-benchmark"
                                : fs::path(args.flags.work);
  // Measure from scratch unless asked to reuse the finished stages of an earlier run (for
  // tuning a late stage: delete its folder under work/ and run again with --resume).
  std::error_code ec;
  if (!args.resume) fs::remove_all(work_dir / "reconduit", ec);
  workspace.work_dir = work_dir / "reconduit" / "work";
  workspace.output_dir = work_dir / "reconduit" / "output";
  fs::create_directories(workspace.work_dir);
  SetMinLogLevel(LogLevel::kWarning);

  std::cout << "Reconduit on " << args.images.string() << " (" << workspace.images.size()
            << " files, work folder " << work_dir.string() << ")\n";
  const OurRun ours = RunOurs(*stages, workspace, *options, ground_truth);
  if (args.colmap) {
    const auto theirs =
        RunColmap(args.images, work_dir, static_cast<int>(workspace.images.size()), ground_truth);
    if (theirs && theirs->seconds > 0) {
      std::cout << "\nRatio Reconduit / COLMAP\n"
                << "  time                " << std::setprecision(2)
                << ours.seconds / theirs->seconds << "\n"
                << "  peak memory         "
                << static_cast<double>(ours.peak_memory_bytes) / theirs->peak_memory_bytes << "\n";
    }
  }
  return ours.result.status == StageStatus::kSuccess ? 0 : 1;
}

}  // namespace reconduit
