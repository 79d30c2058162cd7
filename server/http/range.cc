#include "server/http/range.h"

#include "server/http/url.h"

#include <algorithm>
#include <charconv>
#include <optional>

namespace reconduit::server {
namespace {

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// A non-empty run of decimal digits that fits in 64 bits.
std::optional<std::uint64_t> ParseDecimal(std::string_view s) {
  if (s.empty()) return std::nullopt;
  std::uint64_t value = 0;
  const auto [end, error] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (error != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return value;
}

// Removes a weak-validator prefix: W/"x" and "x" compare equal weakly.
std::string_view StripWeak(std::string_view tag) {
  if (tag.size() >= 2 && tag[0] == 'W' && tag[1] == '/') tag.remove_prefix(2);
  return tag;
}

}  // namespace

RangeRequest ParseRangeHeader(std::string_view header, std::uint64_t size) {
  RangeRequest whole;
  std::string_view value = Trim(header);
  constexpr std::string_view kUnit = "bytes=";
  if (value.size() < kUnit.size() || !EqualsIgnoreCase(value.substr(0, kUnit.size()), kUnit)) {
    return whole;
  }
  value = Trim(value.substr(kUnit.size()));
  if (value.find(',') != std::string_view::npos) return whole;  // Several ranges: not served.
  const std::size_t dash = value.find('-');
  if (dash == std::string_view::npos) return whole;
  const std::string_view first_text = Trim(value.substr(0, dash));
  const std::string_view last_text = Trim(value.substr(dash + 1));

  RangeRequest result;
  if (first_text.empty()) {
    // Suffix range: the last N bytes.
    const std::optional<std::uint64_t> suffix = ParseDecimal(last_text);
    if (!suffix) return whole;
    if (*suffix == 0 || size == 0) {
      result.kind = RangeRequest::Kind::kUnsatisfiable;
      return result;
    }
    const std::uint64_t length = std::min(*suffix, size);
    result.kind = RangeRequest::Kind::kPartial;
    result.slice = {size - length, length};
    return result;
  }
  const std::optional<std::uint64_t> first = ParseDecimal(first_text);
  if (!first) return whole;
  std::optional<std::uint64_t> last;
  if (!last_text.empty()) {
    last = ParseDecimal(last_text);
    if (!last || *last < *first) return whole;
  }
  if (*first >= size) {
    result.kind = RangeRequest::Kind::kUnsatisfiable;
    return result;
  }
  const std::uint64_t end = last ? std::min(*last, size - 1) : size - 1;
  result.kind = RangeRequest::Kind::kPartial;
  result.slice = {*first, end - *first + 1};
  return result;
}

std::string ContentRangeHeader(const FileSlice& slice, std::uint64_t size) {
  return "bytes " + std::to_string(slice.offset) + "-" +
         std::to_string(slice.offset + slice.length - 1) + "/" + std::to_string(size);
}

bool IfRangeMatches(std::string_view header, std::string_view etag) {
  const std::string_view presented = Trim(header);
  const std::string_view current = Trim(etag);
  const bool weak = presented.rfind("W/", 0) == 0 || current.rfind("W/", 0) == 0;
  return !weak && presented.size() >= 2 && presented.front() == '"' && presented == current;
}

bool EntityTagListMatches(std::string_view header, std::string_view etag) {
  const std::string_view wanted = StripWeak(Trim(etag));
  std::string_view rest = header;
  while (!rest.empty()) {
    const std::size_t comma = rest.find(',');
    const std::string_view item = Trim(rest.substr(0, comma));
    if (item == "*") return true;
    if (!item.empty() && StripWeak(item) == wanted) return true;
    if (comma == std::string_view::npos) break;
    rest.remove_prefix(comma + 1);
  }
  return false;
}

}  // namespace reconduit::server
