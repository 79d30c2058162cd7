// The configuration file (config/config.h) of reconduit-server and reconduit-worker, with an
// option table of every value type the programs use. The parser answers with settings, or one
// line on the error stream and exit status 2; it never throws.
#include "config/config.h"
#include "fuzz/fuzz_util.h"
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

using namespace reconduit::config;

namespace {

ProgramSettings Program() {
  static std::string host, data, token;
  static int port = 0, threads = 0;
  static std::uint64_t max_upload = 0;
  static double lease = 0;
  static bool verbose = false;
  ProgramSettings program;
  program.program = "reconduit-fuzz";
  program.section = "server";
  program.options.add_options()                                                      //
      ("host", po::value(&host)->default_value("127.0.0.1"), "address")              //
      ("port", po::value(&port)->default_value(8080), "port")                        //
      ("data", po::value(&data)->default_value("data"), "folder")                    //
      ("token", po::value(&token), "token")                                          //
      ("threads", po::value(&threads)->default_value(2), "threads")                  //
      ("max-upload-bytes", po::value(&max_upload)->default_value(1 << 20), "bytes")  //
      ("lease", po::value(&lease)->default_value(60.0), "seconds")                   //
      ("verbose", po::bool_switch(&verbose), "log more");
  program.environment = DefaultEnvironment(program.options);
  return program;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const ProgramSettings program = Program();
  const std::string& path = reconduit::fuzz::WriteScratch(data, size, ".conf");
  Settings settings;
  std::ostringstream out, err;
  const std::optional<int> status =
      ParseSettings(program, {"--config", path}, &settings, out, err,
                    [](const std::string&) { return std::optional<std::string>(); });
  if (status) {
    RECONDUIT_FUZZ_CHECK(*status == 2);
    const std::string message = err.str();
    RECONDUIT_FUZZ_CHECK(!message.empty() && message.back() == '\n');
    RECONDUIT_FUZZ_CHECK(message.find('\n') == message.size() - 1);
  } else {
    RECONDUIT_FUZZ_CHECK(err.str().empty());
  }
  return 0;
}
