#include "cli/cli_common.h"

#include "core/io/file_util.h"
#include "core/pipeline/default_stages.h"

#include <iostream>

namespace reconduit {
namespace {

namespace po = boost::program_options;

constexpr char kUsage[] =
    "Usage:\n"
    "  reconduit reconstruct <images_dir> <out_dir> [--until STAGE] [--options FILE]\n"
    "                        [--work DIR] [--threads N] [--keep-work]\n"
    "  reconduit options\n"
    "  reconduit benchmark <images_dir> [--gt PATH] [--colmap] [--until STAGE] [--options FILE]\n"
    "                      [--work DIR] [--threads N] [--resume]\n"
    "  reconduit synthetic <out_dir> [--rows R] [--cols C] [--seed S] [--width W] [--height H]\n"
    "                      [--focal F]\n"
    "\n"
    "reconstruct  runs the pipeline on every file in <images_dir> (files that are not usable\n"
    "             photos are reported and skipped) and writes the results to <out_dir>.\n"
    "  --until STAGE   stop after this stage (then export and pack what exists); stages: {stages}\n"
    "  --options FILE  pipeline options as a JSON object (see `reconduit options`)\n"
    "  --work DIR      intermediate files (default <out_dir>.work); rerunning resumes there.\n"
    "                  Removed after a complete, successful run (without --until) unless\n"
    "                  --keep-work or the option keep_work_files keeps them.\n"
    "  --threads N     threads for parallel stages (default: all cores)\n"
    "options      prints every pipeline option with its type, default, range and help.\n"
    "benchmark    runs the stages up to --until (default sparse) from scratch and prints "
    "per-stage\n"
    "             time and peak memory, counts, and with --gt (Strecha .camera folder or\n"
    "             Middlebury *_par.txt) the camera accuracy; --colmap also runs COLMAP (CPU) on\n"
    "             the same photos and prints the ratios. Ground truth of photos not in\n"
    "             <images_dir> is ignored. --resume reuses the finished stages of the last\n"
    "             run in the same --work folder (those whose options did not change).\n"
    "             --options, --work and --threads as for reconstruct (default work folder\n"
    "             <tmp>/reconduit-benchmark).\n"
    "synthetic    renders an aerial survey of a hilly terrain (R x C photos, default 5 x 10,\n"
    "             800 x 600 px, focal 700 px, ~75 % overlap along a row) into <out_dir>/images\n"
    "             with its exact cameras in <out_dir>/cameras_par.txt, for `benchmark --gt`.\n"
    "\n"
    "`reconduit <command> --help` prints this text. Exit status: 0 success, 1 the pipeline\n"
    "failed, 2 bad command line, 130 canceled (reconstruct).\n";

}  // namespace

std::string Usage() {
  std::string text = kUsage, stages;
  for (const std::string& name : PipelineStageNames()) {
    stages += (stages.empty() ? "" : ", ") + name;
  }
  text.replace(text.find("{stages}"), 8, stages.empty() ? "(package only)" : stages);
  return text;
}

int UsageError(const std::string& message) {
  std::cerr << "reconduit: " << message << "\n\n" << Usage();
  return 2;
}

po::options_description RunOptions(RunFlags* flags) {
  po::options_description options;
  // The help texts are in Usage(), which lists both commands together.
  options.add_options()("until", po::value(&flags->until))(
      "options", po::value(&flags->options_file))("work", po::value(&flags->work))(
      "threads", po::value(&flags->threads))("keep-work", po::bool_switch(&flags->keep_work));
  return options;
}

std::string ParseCommandArguments(const std::vector<std::string>& args,
                                  const po::options_description& options,
                                  std::vector<std::string>* positional) {
  po::options_description all;
  all.add(options);
  all.add_options()("positional", po::value(positional));
  po::positional_options_description inputs;
  inputs.add("positional", -1);
  try {
    po::variables_map values;
    po::store(po::command_line_parser(args).options(all).positional(inputs).run(), values);
    po::notify(values);
  } catch (const po::error& e) {
    return e.what();
  }
  return "";
}

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

std::vector<InputImage> ToInputImages(const std::vector<std::filesystem::path>& files) {
  std::vector<InputImage> images;
  images.reserve(files.size());
  for (const std::filesystem::path& file : files) {
    images.push_back({file, file.filename().string()});
  }
  return images;
}

}  // namespace reconduit
