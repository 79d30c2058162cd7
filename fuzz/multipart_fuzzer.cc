// The streaming multipart/form-data parser (server/http/multipart.h) and the boundary of the
// Content-Type header. Input: the Content-Type value up to the first '\n', one byte that picks
// a chunk size, then the body. The body is parsed twice, whole and in chunks of that size: a
// chunk border may fall anywhere, so both must report the same parts and the same outcome.
#include "server/http/multipart.h"

#include "fuzz/fuzz_util.h"
#include <cstddef>
#include <cstdint>
#include <string>

using namespace reconduit;
using namespace reconduit::server;

namespace {

struct Outcome {
  std::string log;  // Every callback in order, part contents included.
  bool ok = false;
  std::size_t parts = 0;
};

Outcome Parse(const std::string& boundary, std::string_view body, std::size_t chunk) {
  Outcome outcome;
  bool in_part = false;
  MultipartParser::Callbacks callbacks;
  callbacks.on_part_begin = [&](const MultipartPart& part) {
    RECONDUIT_FUZZ_CHECK(!in_part);
    in_part = true;
    outcome.log +=
        "begin " + part.name + "|" + part.filename.value_or("-") + "|" + part.content_type + "\n";
    return Status::Ok();
  };
  callbacks.on_part_data = [&](std::string_view data) {
    RECONDUIT_FUZZ_CHECK(in_part);
    RECONDUIT_FUZZ_CHECK(!data.empty());
    outcome.log.append(data);
    return Status::Ok();
  };
  callbacks.on_part_end = [&] {
    RECONDUIT_FUZZ_CHECK(in_part);
    in_part = false;
    outcome.log += "\nend\n";
    return Status::Ok();
  };
  MultipartParser parser(boundary, callbacks, {.max_header_bytes = 512, .max_parts = 64});
  Status status = Status::Ok();
  for (std::size_t at = 0; at < body.size() && status.ok(); at += chunk) {
    status = parser.Feed(body.substr(at, chunk));
  }
  if (status.ok()) status = parser.Finish();
  if (!status.ok()) {
    // A failed parser stays failed with the same status.
    RECONDUIT_FUZZ_CHECK(parser.Feed("x").message() == status.message());
    RECONDUIT_FUZZ_CHECK(!status.message().empty());
  } else {
    RECONDUIT_FUZZ_CHECK(parser.done() && !in_part);
  }
  outcome.ok = status.ok();
  outcome.parts = parser.part_count();
  return outcome;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view text = reconduit::fuzz::AsText(data, size);
  const std::size_t newline = text.find('\n');
  if (newline == std::string_view::npos || newline + 1 >= text.size()) return 0;
  const Result<std::string> boundary = MultipartBoundary(text.substr(0, newline));
  if (!boundary.ok()) return 0;
  RECONDUIT_FUZZ_CHECK(!boundary->empty() && boundary->size() <= 70);
  const std::size_t chunk = 1 + static_cast<std::uint8_t>(text[newline + 1]) % 97;
  const std::string_view body = text.substr(newline + 2);

  const Outcome whole = Parse(*boundary, body, body.size() + 1);
  const Outcome chunked = Parse(*boundary, body, chunk);
  RECONDUIT_FUZZ_CHECK(whole.ok == chunked.ok);
  if (whole.ok) {
    RECONDUIT_FUZZ_CHECK(whole.log == chunked.log);
    RECONDUIT_FUZZ_CHECK(whole.parts == chunked.parts);
  }
  return 0;
}
