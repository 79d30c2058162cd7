// URL and header-value helpers (server/http/url.h): percent-decoding, request targets, query
// strings, path segments and `type; key=value` header parameters, all straight from clients.
#include "server/http/url.h"

#include "fuzz/fuzz_util.h"
#include <cstddef>
#include <cstdint>

using namespace reconduit::server;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = reconduit::fuzz::AsText(data, size);

  for (const bool plus_as_space : {false, true}) {
    if (const auto decoded = PercentDecode(text, plus_as_space)) {
      RECONDUIT_FUZZ_CHECK(decoded->size() <= text.size());
    }
  }

  if (const auto parts = SplitTarget(text); parts.ok()) {
    RECONDUIT_FUZZ_CHECK(!parts->path.empty() && parts->path.front() == '/');
    RECONDUIT_FUZZ_CHECK(parts->path.size() + parts->query.size() <= text.size());
    if (auto segments = DecodePathSegments(parts->path); segments.ok()) {
      RECONDUIT_FUZZ_CHECK(!segments->empty());
    }
    (void)ParseQuery(parts->query);
  }
  if (const auto query = ParseQuery(text); query.ok()) {
    for (const auto& [name, value] : *query) {
      RECONDUIT_FUZZ_CHECK(name.size() + value.size() <= text.size());
    }
  }
  (void)DecodePathSegments(text);

  if (const auto header = ParseHeaderValue(text); header.ok()) {
    for (const auto& [name, value] : header->params) {
      RECONDUIT_FUZZ_CHECK(ToLowerAscii(name) == name);
      RECONDUIT_FUZZ_CHECK(header->Param(name).has_value());
    }
  }

  const std::string_view left = text.substr(0, text.size() / 2);
  const std::string_view right = text.substr(text.size() / 2);
  RECONDUIT_FUZZ_CHECK(EqualsIgnoreCase(left, right) ==
                       (ToLowerAscii(left) == ToLowerAscii(right)));
  RECONDUIT_FUZZ_CHECK(ConstantTimeEquals(left, right) == (left == right));
  return 0;
}
