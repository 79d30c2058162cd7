#include "config/config.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

namespace reconduit::config {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A program with a string, an integer, a double, a switch and a renamed environment variable.
ProgramSettings TestProgram() {
  ProgramSettings program;
  program.program = "test-program";
  program.section = "worker";
  program.usage = "Usage: test-program [options]\n";
  program.epilogue = "The end.\n";
  // clang-format off
  program.options.add_options()
      ("data", po::value<std::string>()->default_value("data"), "Data folder.")
      ("threads", po::value<int>()->default_value(0), "Threads.")
      ("lease", po::value<double>()->default_value(60.0), "Lease in seconds.")
      ("once", po::bool_switch(), "Run once.");
  // clang-format on
  program.environment = {{"data", "RECONDUIT_DATA"},
                         {"threads", "RECONDUIT_WORKER_THREADS"},
                         {"lease", "RECONDUIT_LEASE_SECONDS"}};
  return program;
}

class ConfigTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("reconduit_config_test_" + std::to_string(getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string WriteFile(const std::string& text) {
    const fs::path path = dir_ / ("c" + std::to_string(++files_) + ".conf");
    std::ofstream(path) << text;
    return path.string();
  }

  // Parses `args` with `environment`; the exit status when the program would stop.
  std::optional<int> Parse(const std::vector<std::string>& args,
                           const std::map<std::string, std::string>& environment = {}) {
    out_.str("");
    err_.str("");
    settings_ = Settings();
    const GetEnv getenv = [environment](const std::string& name) -> std::optional<std::string> {
      const auto it = environment.find(name);
      if (it == environment.end()) return std::nullopt;
      return it->second;
    };
    return ParseSettings(program_, args, &settings_, out_, err_, getenv);
  }

  fs::path dir_;
  int files_ = 0;
  ProgramSettings program_ = TestProgram();
  Settings settings_;
  std::ostringstream out_, err_;
};

TEST(EnvironmentNameTest, UpperCaseWithUnderscores) {
  EXPECT_EQ(EnvironmentName("max-upload-bytes"), "RECONDUIT_MAX_UPLOAD_BYTES");
  po::options_description options;
  options.add_options()("port", po::value<int>(), "")("shutdown-grace", po::value<int>(), "");
  EXPECT_EQ(DefaultEnvironment(options),
            (std::map<std::string, std::string>{{"port", "RECONDUIT_PORT"},
                                                {"shutdown-grace", "RECONDUIT_SHUTDOWN_GRACE"}}));
}

TEST_F(ConfigTest, DefaultsWhenNothingIsGiven) {
  EXPECT_EQ(Parse({}), std::nullopt) << err_.str();
  EXPECT_EQ(settings_.values["data"].as<std::string>(), "data");
  EXPECT_EQ(settings_.values["threads"].as<int>(), 0);
  EXPECT_FALSE(settings_.values["once"].as<bool>());
  EXPECT_EQ(settings_.From("data"), "");
  EXPECT_EQ(settings_.Invalid("threads", "too few"), "invalid value for 'threads': too few");
}

TEST_F(ConfigTest, FlagsOverEnvironmentOverFileOverDefaults) {
  const std::string file = WriteFile("data = file-data\nthreads = 3\nlease = 5\nonce = true\n");
  ASSERT_EQ(Parse({"--config", file, "--threads", "7"},
                  {{"RECONDUIT_WORKER_THREADS", "8"}, {"RECONDUIT_LEASE_SECONDS", "9"}}),
            std::nullopt)
      << err_.str();
  EXPECT_EQ(settings_.values["threads"].as<int>(), 7);
  EXPECT_EQ(settings_.values["lease"].as<double>(), 9.0);
  EXPECT_EQ(settings_.values["data"].as<std::string>(), "file-data");
  EXPECT_TRUE(settings_.values["once"].as<bool>());
  EXPECT_EQ(settings_.From("threads"), " (from --threads)");
  EXPECT_EQ(settings_.From("lease"), " (from RECONDUIT_LEASE_SECONDS)");
  EXPECT_EQ(settings_.From("data"), " (from 'data' in config file '" + file + "')");
  EXPECT_EQ(settings_.Invalid("lease", "too long"),
            "invalid value '9' for RECONDUIT_LEASE_SECONDS: too long");
}

TEST_F(ConfigTest, ConfigFileFromTheEnvironmentAndEmptyVariablesUnset) {
  const std::string file = WriteFile("threads = 3\n");
  ASSERT_EQ(Parse({}, {{"RECONDUIT_CONFIG", file}, {"RECONDUIT_WORKER_THREADS", ""}}), std::nullopt)
      << err_.str();
  EXPECT_EQ(settings_.values["threads"].as<int>(), 3);
  // Only the listed variables count: RECONDUIT_THREADS is not this program's name.
  ASSERT_EQ(Parse({}, {{"RECONDUIT_THREADS", "5"}}), std::nullopt);
  EXPECT_EQ(settings_.values["threads"].as<int>(), 0);
}

TEST_F(ConfigTest, HelpPrintsUsageOptionsAndEpilogue) {
  EXPECT_EQ(Parse({"--threads", "bad", "--help"}), 0);
  EXPECT_THAT(out_.str(), HasSubstr("Usage: test-program"));
  EXPECT_THAT(out_.str(), HasSubstr("--lease"));
  EXPECT_THAT(out_.str(), HasSubstr("--config"));
  EXPECT_THAT(out_.str(), HasSubstr("The end."));
  EXPECT_EQ(Parse({"-h"}), 0);
}

TEST_F(ConfigTest, BadFlagsAndVariablesStopWithStatus2) {
  EXPECT_EQ(Parse({"--colour", "blue"}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("test-program: unrecognised option '--colour'"));
  EXPECT_EQ(Parse({"--threads", "many"}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("invalid value 'many' for --threads"));
  EXPECT_EQ(Parse({"--threads"}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("--threads"));
  EXPECT_EQ(Parse({"--threads", "1", "--threads", "2"}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("cannot be specified more than once"));
  EXPECT_EQ(Parse({}, {{"RECONDUIT_LEASE_SECONDS", "soon"}}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("invalid value 'soon' for RECONDUIT_LEASE_SECONDS"));
  // A bad value is an error even where a stronger place overrides it.
  EXPECT_EQ(Parse({"--lease", "3"}, {{"RECONDUIT_LEASE_SECONDS", "soon"}}), 2);
}

TEST_F(ConfigTest, BadFileStopsWithStatus2NamingFileAndName) {
  struct Case {
    std::string text;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {"threads = 1\ncolour = blue\n", "unrecognised option 'colour'"},
      {"threads = few\n", "invalid value 'few' for 'threads' in config file"},
      {"once = perhaps\n", "invalid value 'perhaps' for 'once'"},
      {"threads = 1\nthreads = 2\n", "'threads' cannot be specified more than once"},
      {"threads = 1\n[worker]\nthreads = 2\n", "'threads' cannot be specified more than once"},
      {"[worker]\ncolour = blue\n", "unrecognised option 'worker.colour'"},
      {"[worker]\nlease = soon\n", "invalid value 'soon' for 'worker.lease' in config file"},
      {"[wroker]\nlease = 1\n", "unknown section [wroker]"},
      {"config = other.conf\n", "unrecognised option 'config'"},
      {"help = true\n", "unrecognised option 'help'"},
      {"threads 1\n", "invalid line 'threads 1'"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    const std::string file = WriteFile(c.text);
    EXPECT_EQ(Parse({"--config", file}), 2);
    EXPECT_THAT(err_.str(), HasSubstr("test-program: "));
    EXPECT_THAT(err_.str(), HasSubstr("config file '" + file + "'"));
    EXPECT_THAT(err_.str(), HasSubstr(c.expected));
  }
  const std::string missing = (dir_ / "missing.conf").string();
  EXPECT_EQ(Parse({}, {{"RECONDUIT_CONFIG", missing}}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("cannot read the config file '" + missing + "'"));
}

// Found by fuzz/config_fuzzer.cc (corpus: fuzz/corpus/config/invalid-utf8): a value that is
// not valid UTF-8 threw out of ParseSettings instead of being taken as the bytes it is.
TEST_F(ConfigTest, ValuesThatAreNotUtf8AreKeptAsBytes) {
  const std::string latin1 = "caf\xe9-\xd9\xd9";
  const std::string file = WriteFile("data = " + latin1 + "\n");
  ASSERT_EQ(Parse({"--config", file}), std::nullopt) << err_.str();
  EXPECT_EQ(settings_.values["data"].as<std::string>(), latin1);
  ASSERT_EQ(Parse({"--data", latin1}), std::nullopt) << err_.str();
  EXPECT_EQ(settings_.values["data"].as<std::string>(), latin1);
  ASSERT_EQ(Parse({}, {{"RECONDUIT_DATA", latin1}}), std::nullopt) << err_.str();
  EXPECT_EQ(settings_.values["data"].as<std::string>(), latin1);
  EXPECT_EQ(Parse({"--threads", "\xd9"}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("invalid value"));
}

// Found by fuzz/config_fuzzer.cc (corpus: fuzz/corpus/config/placeholder-loop): Boost fills in
// a message's placeholders until none is left, so a value holding one never returned.
TEST_F(ConfigTest, ValuesLookingLikeMessagePlaceholdersAreQuotedAsTheyAre) {
  const std::string file = WriteFile("x '%invalid_line%'\n");
  EXPECT_EQ(Parse({"--config", file}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("invalid line 'x '%invalid_line%''"));
  EXPECT_EQ(Parse({"--%canonical_option%"}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("'--%canonical_option%'"));
  EXPECT_EQ(Parse({"--threads", "1", "--threads=%value%"}), 2);
}

TEST_F(ConfigTest, SectionsOfOtherProgramsAreSkipped) {
  const std::string file = WriteFile(
      "data = shared\n"
      "[server]\nport = 8080\ncolour = anything\nthreads = 64\n"
      "[worker]\nthreads = 2\nlease = 4.5\n");
  ASSERT_EQ(Parse({"--config", file}), std::nullopt) << err_.str();
  EXPECT_EQ(settings_.values["data"].as<std::string>(), "shared");
  EXPECT_EQ(settings_.values["threads"].as<int>(), 2);
  EXPECT_EQ(settings_.values["lease"].as<double>(), 4.5);
  EXPECT_EQ(settings_.From("threads"), " (from 'worker.threads' in config file '" + file + "')");
  EXPECT_EQ(settings_.Invalid("lease", "too short"),
            "invalid value '4.5' for 'worker.lease' in config file '" + file + "': too short");
}

}  // namespace
}  // namespace reconduit::config
