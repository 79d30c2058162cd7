// Pieces shared by the `reconduit` commands (reconstruct, benchmark): the usage text, the
// command-line parser (boost::program_options, as reconduit-server and reconduit-worker use
// through config/), the flags both commands take, and their inputs.
#ifndef RECONDUIT_CLI_CLI_COMMON_H_
#define RECONDUIT_CLI_CLI_COMMON_H_

#include "core/options/pipeline_options.h"
#include "core/pipeline/stage.h"

#include <boost/program_options.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {

// The usage of every command, with the pipeline's stage names filled in.
std::string Usage();

// Prints "reconduit: <message>" and the usage to stderr; returns 2, the exit status for bad
// input.
int UsageError(const std::string& message);

// The flags `reconstruct` and `benchmark` share.
struct RunFlags {
  std::string until;
  std::string options_file;
  std::string work;
  int threads = -1;        // -1: as the options say.
  bool keep_work = false;  // reconstruct: keep the work folder after a complete run.
};

// --until, --options, --work, --threads and --keep-work, bound to *flags.
boost::program_options::options_description RunOptions(RunFlags* flags);

// Parses a command's arguments (after the command's name) with `options`; the arguments that
// are not options go to *positional. Returns an error message, or "" when the arguments are
// valid (the bound variables are then set).
std::string ParseCommandArguments(const std::vector<std::string>& args,
                                  const boost::program_options::options_description& options,
                                  std::vector<std::string>* positional);

// Pipeline options from a JSON file (empty: the defaults), then `threads` when >= 0.
// InvalidArgument naming the file or the field for bad input.
Result<PipelineOptions> LoadPipelineOptions(const std::string& options_file, int threads);

// The pipeline inputs for files listed by ListImageFiles (core/image/ingest.h): each file under
// its own name.
std::vector<InputImage> ToInputImages(const std::vector<std::filesystem::path>& files);

}  // namespace reconduit

#endif  // RECONDUIT_CLI_CLI_COMMON_H_
