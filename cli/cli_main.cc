// reconduit: the pipeline on the command line, without server or database.
//
//   reconduit reconstruct <images_dir> <out_dir> [--until STAGE] [--options FILE]
//                         [--work DIR] [--threads N]
//   reconduit options            (every pipeline option, as JSON)
//   reconduit benchmark ...      (cli/benchmark.h)
//   reconduit synthetic ...      (cli/synthetic.h: a rendered photo set with its cameras)
//
// The output folder receives exactly the files result.zip would hold. Intermediate files go
// to a work folder (default "<out_dir>.work"); running the same command again resumes after
// the last finished stage. Ctrl-C cancels cleanly. Exit status: 0 success, 1 the pipeline
// failed, 2 bad command line, 130 canceled. Each command parses its own flags with
// boost::program_options (ParseCommandArguments in cli_common.h).
#include "core/image/ingest.h"
#include "core/pipeline/default_stages.h"
#include "core/pipeline/runner.h"
#include "core/util/logging.h"

#include "cli/benchmark.h"
#include "cli/cli_common.h"
#include "cli/synthetic.h"
#include <algorithm>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

CancelToken g_cancel;
void OnSignal(int) { g_cancel.RequestCancel(); }

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

// `reconstruct`'s arguments, checked.
struct ReconstructArgs {
  fs::path images_dir;
  fs::path out_dir;
  RunFlags flags;
};

// Returns the exit status when the command should stop (bad arguments).
std::optional<int> ParseReconstructArgs(const std::vector<std::string>& args,
                                        ReconstructArgs* parsed) {
  std::vector<std::string> positional;
  const std::string error = ParseCommandArguments(args, RunOptions(&parsed->flags), &positional);
  if (!error.empty()) return UsageError(error);
  if (positional.size() != 2) return UsageError("reconstruct needs <images_dir> and <out_dir>");
  parsed->images_dir = positional[0];
  parsed->out_dir = positional[1];
  std::error_code ec;
  if (!fs::is_directory(parsed->images_dir, ec)) {
    std::cerr << "reconduit: '" << parsed->images_dir.string() << "' is not a folder\n";
    return 2;
  }
  return std::nullopt;
}

// The photos and the output and work folders (created); the exit status on failure.
std::optional<int> PrepareWorkspace(const ReconstructArgs& args, Workspace* workspace) {
  const Result<std::vector<fs::path>> files = ListImageFiles(args.images_dir);
  if (!files.ok()) return UsageError(files.status().message());
  workspace->images = ToInputImages(*files);
  if (workspace->images.empty()) {
    std::cerr << "reconduit: no files in '" << args.images_dir.string() << "'\n";
    return 2;
  }
  workspace->output_dir = args.out_dir;
  workspace->work_dir = args.flags.work.empty() ? fs::path(args.out_dir.string() + ".work")
                                                : fs::path(args.flags.work);
  std::error_code ec;
  fs::create_directories(workspace->output_dir, ec);
  fs::create_directories(workspace->work_dir, ec);
  if (ec) {
    std::cerr << "reconduit: cannot create the output folders: " << ec.message() << "\n";
    return 1;
  }
  return std::nullopt;
}

// Runs the stages with a progress line on stderr; Ctrl-C cancels.
PipelineResult RunWithProgress(const std::vector<std::unique_ptr<Stage>>& stages,
                               const Workspace& workspace,
                               const PipelineOptions& options) {
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
  const PipelineResult result = RunPipeline(stages, workspace, options, g_cancel, callbacks);
  printer.EndLine();
  SetLogSink({});
  return result;
}

// The table of stages with status, time, the stage's own peak memory and the process's ("-"
// where the stage's own is unknown: the kernel's mark could not be reset, or an old marker).
void PrintStageTable(const PipelineResult& result) {
  std::cout << "\n"
            << std::left << std::setw(12) << "stage" << std::setw(12) << "status" << std::right
            << std::setw(10) << "seconds" << std::setw(16) << "stage peak MiB" << std::setw(18)
            << "process peak MiB"
            << "\n";
  for (const StageRecord& record : result.stages) {
    std::ostringstream stage_peak;
    if (record.stage_peak_memory_own) {
      stage_peak << std::fixed << std::setprecision(1)
                 << record.stage_peak_memory_bytes / (1024.0 * 1024.0);
    } else {
      stage_peak << "-";
    }
    std::cout << std::left << std::setw(12) << record.name << std::setw(12)
              << (record.resumed ? "resumed" : std::string(StageStatusName(record.status)))
              << std::right << std::setw(10) << std::fixed << std::setprecision(2) << record.seconds
              << std::setw(16) << stage_peak.str() << std::setw(18) << std::setprecision(1)
              << record.peak_memory_bytes / (1024.0 * 1024.0) << "\n";
  }
  std::cout << std::left << std::setw(24) << "total" << std::right << std::setw(10)
            << std::setprecision(2) << result.seconds << "\n";
}

int Reconstruct(const std::vector<std::string>& arguments) {
  ReconstructArgs args;
  if (const std::optional<int> status = ParseReconstructArgs(arguments, &args)) return *status;
  const Result<PipelineOptions> options =
      LoadPipelineOptions(args.flags.options_file, args.flags.threads);
  if (!options.ok()) return UsageError(options.status().message());
  auto stages = CreatePipelineStages(args.flags.until);
  if (!stages.ok()) return UsageError(stages.status().message());
  Workspace workspace;
  if (const std::optional<int> status = PrepareWorkspace(args, &workspace)) return *status;

  std::cerr << "reconduit: " << workspace.images.size() << " files from "
            << args.images_dir.string() << " -> " << args.out_dir.string() << " (work folder "
            << workspace.work_dir.string() << ")\n";
  const PipelineResult result = RunWithProgress(*stages, workspace, *options);
  PrintStageTable(result);
  if (result.status == StageStatus::kSuccess) {
    std::cout << "results in " << args.out_dir.string() << "\n";
    // A run that stopped early (--until) is meant to go on from its work folder.
    if (args.flags.until.empty() && !args.flags.keep_work && !options->keep_work_files) {
      std::error_code ec;
      fs::remove_all(workspace.work_dir, ec);
      if (ec) {
        std::cerr << "reconduit: cannot remove the work folder " << workspace.work_dir.string()
                  << ": " << ec.message() << "\n";
      } else {
        std::cout << "work folder " << workspace.work_dir.string()
                  << " removed (--keep-work keeps it)\n";
      }
    }
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
    if (command == "synthetic") return RunSynthetic(args);
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
