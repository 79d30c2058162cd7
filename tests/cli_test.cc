// The `reconduit` command line as a user runs it: bad input gets exit status 2 and a message
// that names the problem; the benchmark compares only the ground-truth cameras of the photos
// it was given.
#include "core/eval/ground_truth.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <utility>
#include <vector>

#ifndef RECONDUIT_CLI_BINARY
#error "RECONDUIT_CLI_BINARY must name the reconduit executable"
#endif

namespace reconduit {
namespace {

namespace fs = std::filesystem;

struct Outcome {
  int exit_status = -1;
  std::string output;  // stdout and stderr together.
};

Outcome RunCli(const std::string& arguments) {
  const std::string command = std::string(RECONDUIT_CLI_BINARY) + " " + arguments + " 2>&1";
  Outcome outcome;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return outcome;
  char buffer[4096];
  for (std::size_t n; (n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0;) {
    outcome.output.append(buffer, n);
  }
  const int status = pclose(pipe);
  if (WIFEXITED(status)) outcome.exit_status = WEXITSTATUS(status);
  return outcome;
}

// A Strecha .camera file: K, distortion, world-from-camera rotation, centre, size.
void WriteStrechaCamera(const fs::path& path) {
  std::ofstream(path) << "500 0 99.5\n0 500 74.5\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                         "0 0 0\n200 150\n";
}

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("reconduit_cli_test_" + std::to_string(getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_ / "images");
    fs::create_directories(root_ / "gt");
    cv::Mat noise(150, 200, CV_8UC3);
    cv::randu(noise, 0, 255);
    for (const char* name : {"a.jpg", "b.jpg"}) {
      ASSERT_TRUE(cv::imwrite((root_ / "images" / name).string(), noise));
    }
  }
  void TearDown() override { fs::remove_all(root_); }

  std::string Quoted(const fs::path& path) const { return "'" + path.string() + "'"; }

  fs::path root_;
};

TEST_F(CliTest, NoCommandPrintsUsage) {
  const Outcome outcome = RunCli("");
  EXPECT_EQ(outcome.exit_status, 2);
  EXPECT_NE(outcome.output.find("Usage:"), std::string::npos) << outcome.output;
}

TEST_F(CliTest, ReconstructRejectsMissingFolder) {
  const Outcome outcome =
      RunCli("reconstruct " + Quoted(root_ / "no-such-folder") + " " + Quoted(root_ / "out"));
  EXPECT_EQ(outcome.exit_status, 2);
  EXPECT_NE(outcome.output.find("no-such-folder"), std::string::npos) << outcome.output;
  EXPECT_FALSE(fs::exists(root_ / "out"));
}

// Both commands parse their flags the same way (boost::program_options): a message naming the
// problem, the usage, exit status 2, and nothing written.
TEST_F(CliTest, BadFlagsGiveMessageUsageAndStatus2) {
  const std::string images = Quoted(root_ / "images");
  const std::string out = Quoted(root_ / "out");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"reconstruct " + images + " " + out + " --colour blue", "unrecognised option '--colour'"},
      {"reconstruct " + images + " " + out + " --threads many", "'many'"},
      {"reconstruct " + images + " " + out + " --until", "--until"},
      {"reconstruct " + images, "reconstruct needs <images_dir> and <out_dir>"},
      {"benchmark " + images + " --resume --colour", "unrecognised option '--colour'"},
      {"benchmark " + images + " " + out, "benchmark needs one <images_dir>"},
      {"benchmark " + images + " --threads 2x", "'2x'"},
      {"frobnicate", "unknown command 'frobnicate'"},
  };
  for (const auto& [arguments, expected] : cases) {
    SCOPED_TRACE(arguments);
    const Outcome outcome = RunCli(arguments);
    EXPECT_EQ(outcome.exit_status, 2);
    EXPECT_NE(outcome.output.find(expected), std::string::npos) << outcome.output;
    EXPECT_NE(outcome.output.find("Usage:"), std::string::npos) << outcome.output;
  }
  EXPECT_FALSE(fs::exists(root_ / "out"));
  const Outcome help = RunCli("benchmark --help");
  EXPECT_EQ(help.exit_status, 0);
  EXPECT_NE(help.output.find("reconduit benchmark <images_dir>"), std::string::npos);
}

TEST_F(CliTest, BenchmarkRejectsUnreadableGroundTruth) {
  const Outcome outcome = RunCli("benchmark " + Quoted(root_ / "images") + " --gt " +
                                 Quoted(root_ / "gt") + " --work " + Quoted(root_ / "work"));
  EXPECT_EQ(outcome.exit_status, 2);  // An empty folder: no .camera files.
  EXPECT_NE(outcome.output.find("ground truth"), std::string::npos) << outcome.output;
}

TEST_F(CliTest, BenchmarkRejectsGroundTruthOfOtherPhotos) {
  WriteStrechaCamera(root_ / "gt" / "other.jpg.camera");
  const Outcome outcome = RunCli("benchmark " + Quoted(root_ / "images") + " --gt " +
                                 Quoted(root_ / "gt") + " --work " + Quoted(root_ / "work"));
  EXPECT_EQ(outcome.exit_status, 2);
  EXPECT_NE(outcome.output.find("describes none of the photos"), std::string::npos)
      << outcome.output;
}

TEST_F(CliTest, BenchmarkComparesOnlyTheGivenPhotos) {
  for (const char* name : {"a.jpg", "b.jpg", "c.jpg"}) {
    WriteStrechaCamera(root_ / "gt" / (std::string(name) + ".camera"));
  }
  const Outcome outcome =
      RunCli("benchmark " + Quoted(root_ / "images") + " --gt " + Quoted(root_ / "gt") +
             " --until ingest --work " + Quoted(root_ / "work"));
  EXPECT_EQ(outcome.exit_status, 0) << outcome.output;
  EXPECT_NE(outcome.output.find("2 of its 3 cameras"), std::string::npos) << outcome.output;
  EXPECT_NE(outcome.output.find("ingest"), std::string::npos) << outcome.output;
}

// `synthetic` renders a small survey: one JPEG per camera and their exact cameras, which the
// benchmark reads back; it refuses a folder that holds anything, and bad values.
TEST_F(CliTest, SyntheticWritesPhotosAndTheirCameras) {
  const fs::path out = root_ / "survey";
  const Outcome outcome = RunCli("synthetic " + Quoted(out) +
                                 " --rows 2 --cols 3 --width 160 --height 120 --focal 140");
  ASSERT_EQ(outcome.exit_status, 0) << outcome.output;
  auto cameras = ReadMiddleburyPar(out / "cameras_par.txt");
  ASSERT_TRUE(cameras.ok()) << cameras.status();
  ASSERT_EQ(cameras->size(), 6u);
  for (const GroundTruthCamera& camera : *cameras) {
    const cv::Mat photo = cv::imread((out / "images" / camera.name).string());
    ASSERT_FALSE(photo.empty()) << camera.name;
    EXPECT_EQ(photo.cols, 160);
    EXPECT_EQ(photo.rows, 120);
    EXPECT_DOUBLE_EQ(camera.K(0, 0), 140.0);
    EXPECT_NEAR(camera.cam_from_world.CenterInWorld().z(), 10.0, 0.5 + 1e-9);
  }
  const Outcome again = RunCli("synthetic " + Quoted(out));
  EXPECT_EQ(again.exit_status, 2);
  EXPECT_NE(again.output.find("is not empty"), std::string::npos) << again.output;
  const Outcome bad = RunCli("synthetic " + Quoted(root_ / "other") + " --rows 0");
  EXPECT_EQ(bad.exit_status, 2);
  EXPECT_NE(bad.output.find("rows must be >= 1"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(root_ / "other"));
}

}  // namespace
}  // namespace reconduit
