#include "server/api/request_params.h"

#include "server/api/safe_names.h"

#include <charconv>
#include <string>

namespace reconduit::server {

Result<std::int64_t> ParseInteger(std::string_view text,
                                  std::string_view name,
                                  std::int64_t min,
                                  std::int64_t max) {
  std::int64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size() || value < min ||
      value > max) {
    return Status::InvalidArgument(std::string(name) + " must be an integer in [" +
                                   std::to_string(min) + ", " + std::to_string(max) + "], got " +
                                   QuoteForMessage(text));
  }
  return value;
}

Result<std::int64_t> IntegerParam(const RequestContext& context,
                                  std::string_view name,
                                  std::int64_t fallback,
                                  std::int64_t min,
                                  std::int64_t max) {
  const std::optional<std::string_view> text = context.Query(name);
  if (!text) return fallback;
  return ParseInteger(*text, "query parameter `" + std::string(name) + "`", min, max);
}

Response JobNotFoundResponse(std::string_view id) {
  return ErrorResponse(HttpStatus::not_found, "no job " + QuoteForMessage(id));
}

}  // namespace reconduit::server
