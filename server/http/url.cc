#include "server/http/url.h"

#include <cstddef>

namespace reconduit::server {
namespace {

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool IsTokenChar(char c) {
  // RFC 9110 tchar.
  if ((c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z')) return true;
  switch (c) {
    case '!':
    case '#':
    case '$':
    case '%':
    case '&':
    case '\'':
    case '*':
    case '+':
    case '-':
    case '.':
    case '^':
    case '_':
    case '`':
    case '|':
    case '~':
      return true;
    default:
      return false;
  }
}

std::string_view TrimOws(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

}  // namespace

std::optional<std::string> PercentDecode(std::string_view in, bool plus_as_space) {
  std::string out;
  out.reserve(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    const char c = in[i];
    if (c == '%') {
      if (i + 2 >= in.size()) return std::nullopt;  // Fewer than two characters follow.
      const int hi = HexValue(in[i + 1]);
      const int lo = HexValue(in[i + 2]);
      if (hi < 0 || lo < 0) return std::nullopt;
      const char decoded = static_cast<char>(hi * 16 + lo);
      if (decoded == '\0') return std::nullopt;
      out.push_back(decoded);
      i += 2;
    } else if (c == '+' && plus_as_space) {
      out.push_back(' ');
    } else {
      out.push_back(c);
    }
  }
  return out;
}

Result<TargetParts> SplitTarget(std::string_view target) {
  if (target.empty() || target.front() != '/') {
    return Status::InvalidArgument("request target must be an absolute path (origin form)");
  }
  TargetParts parts;
  const std::size_t question = target.find('?');
  if (question == std::string_view::npos) {
    parts.path = std::string(target);
  } else {
    parts.path = std::string(target.substr(0, question));
    parts.query = std::string(target.substr(question + 1));
  }
  // A fragment is never sent by conforming clients; drop one defensively.
  if (const std::size_t hash = parts.query.find('#'); hash != std::string::npos) {
    parts.query.resize(hash);
  }
  return parts;
}

Result<KeyValues> ParseQuery(std::string_view query) {
  KeyValues out;
  while (!query.empty()) {
    const std::size_t amp = query.find('&');
    const std::string_view pair = query.substr(0, amp);
    query = amp == std::string_view::npos ? std::string_view() : query.substr(amp + 1);
    if (pair.empty()) continue;
    const std::size_t eq = pair.find('=');
    const std::string_view raw_name = pair.substr(0, eq);
    const std::string_view raw_value =
        eq == std::string_view::npos ? std::string_view() : pair.substr(eq + 1);
    std::optional<std::string> name = PercentDecode(raw_name, /*plus_as_space=*/true);
    std::optional<std::string> value = PercentDecode(raw_value, /*plus_as_space=*/true);
    if (!name || !value) {
      return Status::InvalidArgument("malformed percent-encoding in query parameter '" +
                                     std::string(raw_name) + "'");
    }
    out.emplace_back(std::move(*name), std::move(*value));
  }
  return out;
}

Result<std::vector<std::string>> DecodePathSegments(std::string_view raw_path) {
  if (raw_path.empty() || raw_path.front() != '/') {
    return Status::InvalidArgument("path must start with '/'");
  }
  std::vector<std::string> segments;
  std::string_view rest = raw_path.substr(1);
  while (true) {
    const std::size_t slash = rest.find('/');
    std::optional<std::string> segment = PercentDecode(rest.substr(0, slash));
    if (!segment) return Status::InvalidArgument("malformed percent-encoding in path");
    segments.push_back(std::move(*segment));
    if (slash == std::string_view::npos) break;
    rest = rest.substr(slash + 1);
  }
  return segments;
}

std::optional<std::string> HeaderValue::Param(std::string_view name) const {
  for (const auto& [key, value] : params) {
    if (EqualsIgnoreCase(key, name)) return value;
  }
  return std::nullopt;
}

Result<HeaderValue> ParseHeaderValue(std::string_view header) {
  HeaderValue result;
  std::size_t i = 0;
  const std::size_t semicolon = header.find(';');
  result.value = ToLowerAscii(TrimOws(header.substr(0, semicolon)));
  if (semicolon == std::string_view::npos) return result;
  i = semicolon + 1;
  while (i < header.size()) {
    // Skip whitespace and stray separators ("a; ;b=1" is tolerated).
    while (i < header.size() && (header[i] == ' ' || header[i] == '\t' || header[i] == ';')) ++i;
    if (i >= header.size()) break;
    const std::size_t name_start = i;
    while (i < header.size() && IsTokenChar(header[i])) ++i;
    const std::string_view name = header.substr(name_start, i - name_start);
    while (i < header.size() && (header[i] == ' ' || header[i] == '\t')) ++i;
    if (name.empty() || i >= header.size() || header[i] != '=') {
      return Status::InvalidArgument("malformed header parameter in '" + std::string(header) + "'");
    }
    ++i;  // '='
    while (i < header.size() && (header[i] == ' ' || header[i] == '\t')) ++i;
    std::string value;
    if (i < header.size() && header[i] == '"') {
      ++i;
      bool closed = false;
      while (i < header.size()) {
        const char c = header[i];
        if (c == '"') {
          closed = true;
          ++i;
          break;
        }
        if (c == '\\' && i + 1 < header.size() && (header[i + 1] == '"' || header[i + 1] == '\\')) {
          value.push_back(header[i + 1]);
          i += 2;
          continue;
        }
        value.push_back(c);
        ++i;
      }
      if (!closed) {
        return Status::InvalidArgument("unterminated quoted string in header '" +
                                       std::string(header) + "'");
      }
    } else {
      const std::size_t value_start = i;
      while (i < header.size() && header[i] != ';') ++i;
      value = std::string(TrimOws(header.substr(value_start, i - value_start)));
    }
    result.params.emplace_back(ToLowerAscii(name), std::move(value));
    // Anything up to the next ';' after a quoted string is ignored whitespace.
    while (i < header.size() && header[i] != ';') ++i;
  }
  return result;
}

bool EqualsIgnoreCase(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    char x = a[i];
    char y = b[i];
    if (x >= 'A' && x <= 'Z') x = static_cast<char>(x - 'A' + 'a');
    if (y >= 'A' && y <= 'Z') y = static_cast<char>(y - 'A' + 'a');
    if (x != y) return false;
  }
  return true;
}

std::string ToLowerAscii(std::string_view s) {
  std::string out(s);
  for (char& c : out) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return out;
}

bool ConstantTimeEquals(std::string_view a, std::string_view b) {
  // Every byte of `a` is examined whatever the content; a length mismatch is folded in instead
  // of returning early, so only the lengths leak through timing.
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const unsigned char other = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= static_cast<unsigned char>(static_cast<unsigned char>(a[i]) ^ other);
  }
  return diff == 0;
}

}  // namespace reconduit::server
