#include "server/api/safe_names.h"

#include <cstdint>
#include <cstdio>

namespace reconduit::server {
namespace {

// Length of the valid UTF-8 sequence starting at s[i] (1-4), or 0 when it is invalid
// (overlong forms, surrogates and code points past U+10FFFF included).
std::size_t Utf8SequenceLength(std::string_view s, std::size_t i) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = byte(i);
  if (c < 0x80) return 1;
  std::size_t length = 0;
  std::uint32_t code = 0;
  if ((c & 0xE0) == 0xC0) {
    length = 2;
    code = c & 0x1F;
  } else if ((c & 0xF0) == 0xE0) {
    length = 3;
    code = c & 0x0F;
  } else if ((c & 0xF8) == 0xF0) {
    length = 4;
    code = c & 0x07;
  } else {
    return 0;
  }
  if (i + length > s.size()) return 0;
  for (std::size_t k = 1; k < length; ++k) {
    if ((byte(i + k) & 0xC0) != 0x80) return 0;
    code = (code << 6) | (byte(i + k) & 0x3F);
  }
  static constexpr std::uint32_t kMinimum[] = {0, 0, 0x80, 0x800, 0x10000};
  if (code < kMinimum[length] || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return 0;
  return length;
}

bool IsControl(unsigned char c) { return c < 0x20 || c == 0x7F; }

// True for a valid UTF-8 sequence that is a C1 control (U+0080-U+009F) or a bidirectional
// control: U+061C, U+200E, U+200F, U+202A-U+202E (U+202E, RIGHT-TO-LEFT OVERRIDE, makes
// "photo\u202Egpj.exe" display as "photoexe.jpg") and U+2066-U+2069.
bool IsInvisibleControl(std::string_view sequence) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(sequence[k]); };
  if (sequence.size() == 2) {
    return (byte(0) == 0xC2 && byte(1) <= 0x9F) || (byte(0) == 0xD8 && byte(1) == 0x9C);
  }
  if (sequence.size() != 3 || byte(0) != 0xE2) return false;
  if (byte(1) == 0x80)
    return byte(2) == 0x8E || byte(2) == 0x8F || (byte(2) >= 0xAA && byte(2) <= 0xAE);
  return byte(1) == 0x81 && byte(2) >= 0xA6 && byte(2) <= 0xA9;
}

}  // namespace

std::string SanitizeDisplayName(std::string_view client_name, std::string_view fallback) {
  const std::size_t separator = client_name.find_last_of("/\\");
  std::string_view base =
      separator == std::string_view::npos ? client_name : client_name.substr(separator + 1);

  std::string clean;
  for (std::size_t i = 0; i < base.size();) {
    const std::size_t length = Utf8SequenceLength(base, i);
    if (length == 0) {
      clean += '?';
      ++i;
      continue;
    }
    const std::string_view sequence = base.substr(i, length);
    if (!(length == 1 && IsControl(static_cast<unsigned char>(base[i]))) &&
        !IsInvisibleControl(sequence)) {
      if (clean.size() + length > kMaxDisplayNameBytes) break;
      clean.append(base.substr(i, length));
    }
    i += length;
  }
  const std::size_t first = clean.find_first_not_of(" \t");
  if (first == std::string::npos) return std::string(fallback);
  const std::size_t last = clean.find_last_not_of(" \t");
  clean = clean.substr(first, last - first + 1);
  if (clean == "." || clean == "..") return std::string(fallback);
  return clean;
}

std::string StoredPhotoName(int index, std::string_view extension) {
  char digits[16];
  std::snprintf(digits, sizeof(digits), "%04d", index + 1);
  return std::string(digits) + "." + std::string(extension);
}

Status CheckRelativePath(std::string_view path, bool allow_trailing_slash) {
  auto refuse = [&](std::string_view why) {
    return Status::InvalidArgument("unsafe name " + QuoteForMessage(path) + ": " +
                                   std::string(why));
  };
  if (path.empty()) return refuse("empty");
  if (path.size() > 1024) return refuse("longer than 1024 bytes");
  if (path.front() == '/') return refuse("absolute path");
  if (path.size() >= 2 && path[1] == ':') return refuse("drive letter");
  for (const char c : path) {
    if (c == '\\') return refuse("contains a backslash");
    if (IsControl(static_cast<unsigned char>(c))) return refuse("contains a control character");
  }
  std::string_view rest = path;
  if (allow_trailing_slash && rest.back() == '/') rest.remove_suffix(1);
  while (true) {
    const std::size_t slash = rest.find('/');
    const std::string_view segment = rest.substr(0, slash);
    if (segment.empty()) return refuse("empty path segment");
    if (segment == "..") return refuse("contains '..'");
    if (segment == ".") return refuse("contains '.'");
    if (slash == std::string_view::npos) break;
    rest.remove_prefix(slash + 1);
  }
  return Status::Ok();
}

std::string QuoteForMessage(std::string_view text) {
  std::string quoted = "\"";
  for (const char c : text.substr(0, 300)) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      quoted += '\\';
      quoted += c;
    } else if (IsControl(u)) {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\x%02x", u);
      quoted += escaped;
    } else {
      quoted += c;
    }
  }
  if (text.size() > 300) quoted += "...";
  return quoted + "\"";
}

}  // namespace reconduit::server
