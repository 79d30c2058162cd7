#include "cli/synthetic.h"

#include "core/eval/ground_truth.h"
#include "core/io/file_util.h"
#include "core/scene/render.h"
#include "core/scene/survey.h"
#include "core/util/timer.h"

#include <opencv2/imgcodecs.hpp>

#include "cli/cli_common.h"
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <unistd.h>

namespace reconduit {

namespace fs = std::filesystem;
namespace po = boost::program_options;

int RunSynthetic(const std::vector<std::string>& args) {
  SurveyOptions survey_options;
  po::options_description flags;
  flags.add_options()("rows", po::value(&survey_options.rows))(
      "cols", po::value(&survey_options.cols))("seed", po::value(&survey_options.seed))(
      "width", po::value(&survey_options.width))("height", po::value(&survey_options.height))(
      "focal", po::value(&survey_options.focal));
  std::vector<std::string> positional;
  if (const std::string error = ParseCommandArguments(args, flags, &positional); !error.empty()) {
    return UsageError(error);
  }
  if (positional.size() != 1) return UsageError("synthetic needs <out_dir>");
  if (std::string error; !survey_options.Check(&error)) return UsageError(error);
  const fs::path out_dir = positional[0];
  std::error_code ec;
  if (fs::exists(out_dir, ec) && !fs::is_empty(out_dir, ec)) {
    std::cerr << "reconduit: " << out_dir << " exists and is not empty; give a new folder\n";
    return 2;
  }
  fs::create_directories(out_dir / "images", ec);
  if (ec) {
    std::cerr << "reconduit: cannot create " << out_dir / "images"
              << ": " << ec.message() << "\n";
    return 1;
  }

  const Survey survey = MakeSurvey(survey_options);
  const std::size_t n = survey.cams_from_world.size();
  std::cerr << "rendering " << n << " photos (" << survey_options.rows << " x "
            << survey_options.cols << ", " << survey_options.width << " x " << survey_options.height
            << " px) of a terrain of " << survey.scene.height_fields.size() << " tiles to "
            << out_dir << "\n";
  std::vector<GroundTruthCamera> truth;
  const Timer timer;
  const bool tty = ::isatty(STDERR_FILENO) != 0;  // Rewrite one line, or a line every 10.
  for (std::size_t i = 0; i < n; ++i) {
    const RenderedView view = RenderScene(survey.scene, survey.camera, survey.cams_from_world[i]);
    char name[32];
    std::snprintf(name, sizeof(name), "%04zu.jpg", i);
    std::vector<unsigned char> jpeg;
    if (!cv::imencode(".jpg", view.image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95})) {
      std::cerr << "reconduit: JPEG encoding failed for " << name << "\n";
      return 1;
    }
    const Status written = WriteFileAtomically(
        out_dir / "images" / name,
        std::string_view(reinterpret_cast<const char*>(jpeg.data()), jpeg.size()));
    if (!written.ok()) {
      std::cerr << "reconduit: " << written.message() << "\n";
      return 1;
    }
    GroundTruthCamera camera;
    camera.name = name;
    camera.K = survey.camera.K();
    camera.cam_from_world = survey.cams_from_world[i];
    truth.push_back(camera);
    if (tty || (i + 1) % 10 == 0 || i + 1 == n) {
      std::fprintf(stderr, "%s%zu/%zu photos (%.2f s a photo)%s", tty ? "\r" : "", i + 1, n,
                   timer.ElapsedSeconds() / static_cast<double>(i + 1), tty ? "" : "\n");
    }
  }
  if (tty) std::cerr << "\n";
  const Status written =
      WriteFileAtomically(out_dir / "cameras_par.txt", FormatMiddleburyPar(truth));
  if (!written.ok()) {
    std::cerr << "reconduit: " << written.message() << "\n";
    return 1;
  }
  std::cout << out_dir / "images"
            << ": " << n << " photos; cameras in " << out_dir / "cameras_par.txt"
            << " (reconduit benchmark " << (out_dir / "images").string() << " --gt "
            << (out_dir / "cameras_par.txt").string() << ")\n";
  return 0;
}

}  // namespace reconduit
