// reconduit: the pipeline on the command line, without server or database.
//
//   reconduit reconstruct <images_dir> <out_dir> [--until STAGE] [--options FILE]
//                         [--work DIR] [--threads N]
//   reconduit options            (every pipeline option, as JSON)
//
// The output folder receives exactly the files result.zip would hold. Intermediate files go
// to a work folder (default "<out_dir>.work"); running the same command again resumes after
// the last finished stage. Ctrl-C cancels cleanly. Exit status: 0 success, 1 the pipeline
// failed, 2 bad command line, 130 canceled.
#include "core/io/file_util.h"
#include "core/pipeline/default_stages.h"
#include "core/pipeline/runner.h"
#include "core/util/logging.h"

#include "cli/benchmark.h"
#include "cli/cli_common.h"
#include <algorithm>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <string>
#include <unistd.h>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

constexpr char kUsage[] =
    "Usage:\n"
    "  reconduit reconstruct <images_dir> <out_dir> [--until STAGE] [--options FILE]\n"
    "                        [--work DIR] [--threads N]\n"
    "  reconduit options\n"
    "  reconduit benchmark <images_dir> [--gt PATH] [--colmap] [--until STAGE] [--options FILE]\n"
    "                      [--work DIR] [--threads N] [--resume]\n"
    "\n"
    "reconstruct  runs the pipeline on every file in <images_dir> (files that are not usable\n"
    "             photos are reported and skipped) and writes the results to <out_dir>.\n"
    "  --until STAGE   stop after this stage (then pack what exists); stages: {stages}\n"
    "  --options FILE  pipeline options as a JSON object (see `reconduit options`)\n"
    "  --work DIR      intermediate files (default <out_dir>.work); rerunning resumes there\n"
    "  --threads N     threads for parallel stages (default: all cores)\n"
    "options      prints every pipeline option with its type, default, range and help.\n"
    "benchmark    runs the stages up to --until (default sparse) from scratch and prints "
    "per-stage\n"
    "             time and peak memory, counts, and with --gt (Strecha .camera folder or\n"
    "             Middlebury *_par.txt) the camera accuracy; --colmap also runs COLMAP (CPU) on\n"
    "             the same photos and prints the ratios. Ground truth of photos not in\n"
    "             <images_dir> is ignored. --resume reuses the finished stages of the last\n"
    "             run in the same --work folder (those whose options did not change).\n";

CancelToken g_cancel;
void OnSignal(int) { g_cancel.RequestCancel(); }

std::string Usage() {
  std::string text = kUsage, stages;
  for (const std::string& name : PipelineStageNames())
    stages += (stages.empty() ? "" : ", ") + name;
  text.replace(text.find("{stages}"), 8, stages.empty() ? "(package only)" : stages);
  return text;
}

int UsageError(const std::string& message) {
  std::cerr << "reconduit: " << message << "\n\n" << Usage();
  return 2;
}

// One line per update, rewritten in place on a terminal.
class ProgressPrinter {
 public:
  ProgressPrinter() : tty_(::isatty(STDERR_FILENO) != 0) {}
  void Update(const Stage& stage, const ProgressUpdate& update, double overall) {
    std::ostringstream line;
    line << "[" << std::setw(3) << static_cast<int>(overall * 100) << "%] " << stage.Title();
    if (!update.message.empty()) line << ": " << update.message;
    if (update.total > 0) line << " (" << update.done << "/" << update.total << ")";
    if (tty_) {
      constexpr int kWidth = 24;
      const int filled = static_cast<int>(overall * kWidth);
      std::cerr << "\r\033[K[" << std::string(filled, '#') << std::string(kWidth - filled, ' ')
                << "] " << line.str() << std::flush;
    } else if (line.str() != last_) {
      std::cerr << line.str() << "\n";
    }
    last_ = line.str();
  }
  void EndLine() {
    if (tty_) std::cerr << "\r\033[K" << std::flush;
  }

 private:
  bool tty_;
  std::string last_;
};

int Reconstruct(const std::vector<std::string>& args) {
  std::vector<std::string> positional;
  std::string until, options_file, work;
  int threads = -1;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    auto value = [&](std::string* out) {
      if (i + 1 >= args.size()) return false;
      *out = args[++i];
      return true;
    };
    std::string text;
    if (arg == "--until") {
      if (!value(&until)) return UsageError("--until needs a stage name");
    } else if (arg == "--options") {
      if (!value(&options_file)) return UsageError("--options needs a file");
    } else if (arg == "--work") {
      if (!value(&work)) return UsageError("--work needs a folder");
    } else if (arg == "--threads") {
      if (!value(&text)) return UsageError("--threads needs a number");
      try {
        threads = std::stoi(text);
      } catch (const std::exception&) {
        return UsageError("--threads needs a number, got '" + text + "'");
      }
    } else if (!arg.empty() && arg[0] == '-') {
      return UsageError("unknown option '" + arg + "'");
    } else {
      positional.push_back(arg);
    }
  }
  if (positional.size() != 2) return UsageError("reconstruct needs <images_dir> and <out_dir>");
  const fs::path images_dir = positional[0], out_dir = positional[1];
  std::error_code ec;
  if (!fs::is_directory(images_dir, ec)) {
    std::cerr << "reconduit: '" << images_dir.string() << "' is not a folder\n";
    return 2;
  }

  const Result<PipelineOptions> options = LoadPipelineOptions(options_file, threads);
  if (!options.ok()) return UsageError(options.status().message());
  auto stages = CreatePipelineStages(until);
  if (!stages.ok()) return UsageError(stages.status().message());

  Workspace workspace;
  workspace.images = ListInputImages(images_dir);
  if (workspace.images.empty()) {
    std::cerr << "reconduit: no files in '" << images_dir.string() << "'\n";
    return 2;
  }
  workspace.output_dir = out_dir;
  workspace.work_dir = work.empty() ? fs::path(out_dir.string() + ".work") : fs::path(work);
  fs::create_directories(workspace.output_dir, ec);
  fs::create_directories(workspace.work_dir, ec);
  if (ec) {
    std::cerr << "reconduit: cannot create the output folders: " << ec.message() << "\n";
    return 1;
  }

  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  ProgressPrinter printer;
  // Log lines would tear the progress bar: end the bar line before each.
  SetLogSink([&](LogLevel level, std::string_view message) {
    printer.EndLine();
    std::cerr << LogLevelName(level) << ' ' << message << '\n';
  });
  PipelineCallbacks callbacks;
  callbacks.on_progress = [&](const Stage& s, const ProgressUpdate& u, double overall) {
    printer.Update(s, u, overall);
  };
  std::cerr << "reconduit: " << workspace.images.size() << " files from " << images_dir.string()
            << " -> " << out_dir.string() << " (work folder " << workspace.work_dir.string()
            << ")\n";
  const PipelineResult result = RunPipeline(*stages, workspace, *options, g_cancel, callbacks);
  printer.EndLine();
  SetLogSink({});

  std::cout << "\n"
            << std::left << std::setw(12) << "stage" << std::setw(12) << "status" << std::right
            << std::setw(10) << "seconds" << std::setw(16) << "peak memory MiB"
            << "\n";
  for (const StageRecord& record : result.stages) {
    std::cout << std::left << std::setw(12) << record.name << std::setw(12)
              << (record.resumed ? "resumed" : std::string(StageStatusName(record.status)))
              << std::right << std::setw(10) << std::fixed << std::setprecision(2) << record.seconds
              << std::setw(16) << std::setprecision(1)
              << record.peak_memory_bytes / (1024.0 * 1024.0) << "\n";
  }
  std::cout << std::left << std::setw(24) << "total" << std::right << std::setw(10)
            << std::setprecision(2) << result.seconds << "\n";
  if (result.status == StageStatus::kSuccess) {
    std::cout << "results in " << out_dir.string() << "\n";
    return 0;
  }
  std::cerr << "reconduit: stage " << result.failed_stage << " " << StageStatusName(result.status)
            << ": " << result.message << "\n";
  return result.status == StageStatus::kCanceled ? 130 : 1;
}

}  // namespace
}  // namespace reconduit

int main(int argc, char** argv) {
  using namespace reconduit;
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    std::cout << Usage();
    return args.empty() ? 2 : 0;
  }
  const std::string command = args[0];
  args.erase(args.begin());
  // `reconduit benchmark --help` and the like: the usage covers every command.
  if (std::find(args.begin(), args.end(), "--help") != args.end() ||
      std::find(args.begin(), args.end(), "-h") != args.end()) {
    std::cout << Usage();
    return 0;
  }
  try {
    if (command == "reconstruct") return Reconstruct(args);
    if (command == "benchmark") return RunBenchmark(args);
    if (command == "options") {
      std::cout << DescribePipelineOptions().dump(2) << "\n";
      return 0;
    }
  } catch (const std::exception& e) {
    std::cerr << "reconduit: " << e.what() << "\n";
    return 1;
  }
  return UsageError("unknown command '" + command + "'");
}
