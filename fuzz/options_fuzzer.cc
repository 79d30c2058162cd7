// The job options JSON (core/options/pipeline_options.h): the `options` part or query
// parameter of an upload (parsed as server/api/upload.cc does: JSON without exceptions, then
// ParsePipelineOptions) and the command line's options file (ParsePipelineOptionsText). Both
// must agree, and what they accept must be in range and survive a round trip.
#include "core/options/pipeline_options.h"

#include "fuzz/fuzz_util.h"
#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reconduit::fuzz::AsText(data, size));
  const reconduit::Result<reconduit::PipelineOptions> options =
      reconduit::ParsePipelineOptionsText(text);
  const nlohmann::json parsed = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!parsed.is_discarded() && parsed.is_object()) {
    RECONDUIT_FUZZ_CHECK(reconduit::ParsePipelineOptions(parsed).ok() == options.ok());
  }
  if (!options.ok()) {
    RECONDUIT_FUZZ_CHECK(!options.status().message().empty());
    return 0;
  }
  std::string error;
  RECONDUIT_FUZZ_CHECK(options->Check(&error));
  const nlohmann::json json = reconduit::PipelineOptionsToJson(*options);
  const reconduit::Result<reconduit::PipelineOptions> again = reconduit::ParsePipelineOptions(json);
  RECONDUIT_FUZZ_CHECK(again.ok());
  RECONDUIT_FUZZ_CHECK(reconduit::PipelineOptionsToJson(*again) == json);
  return 0;
}
