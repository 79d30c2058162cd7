#include "server/http/static_files.h"

#include "server/http/url.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <iterator>
#include <openssl/evp.h>
#include <openssl/sha.h>
#include <system_error>

namespace reconduit::server {
namespace fs = std::filesystem;

Result<fs::path> ResolveStaticPath(const fs::path& root, std::string_view raw_path) {
  Result<std::vector<std::string>> segments = DecodePathSegments(raw_path);
  if (!segments.ok()) return segments.status();
  fs::path relative;
  for (std::size_t i = 0; i < segments->size(); ++i) {
    const std::string& segment = (*segments)[i];
    const bool last = i + 1 == segments->size();
    if (segment.empty()) {
      // Only the final segment may be empty ("/" or "/docs/"): it names the folder's index.
      if (!last) return Status::InvalidArgument("empty path segment");
      relative /= "index.html";
      break;
    }
    if (segment.front() == '.') {
      // "..", "." and hidden files such as .git or .env.
      return Status::InvalidArgument("path segment starting with '.'");
    }
    if (segment.find_first_of("/\\") != std::string::npos) {
      return Status::InvalidArgument("encoded path separator in path segment");
    }
    if (segment.find('\0') != std::string::npos) {
      return Status::InvalidArgument("NUL byte in path");
    }
    relative /= segment;
  }
  if (relative.is_absolute() || relative.has_root_name()) {
    return Status::InvalidArgument("absolute path");
  }

  std::error_code ec;
  const fs::path canonical_root = fs::canonical(root, ec);
  if (ec) return Status::NotFound("static folder does not exist");
  const fs::path candidate = fs::canonical(canonical_root / relative, ec);
  if (ec) return Status::NotFound("no such file");
  // The canonical file must be below the canonical root (symlinks resolved).
  const auto [root_end, ignored] = std::mismatch(canonical_root.begin(), canonical_root.end(),
                                                 candidate.begin(), candidate.end());
  if (root_end != canonical_root.end()) {
    return Status::InvalidArgument("path leaves the static folder");
  }
  if (!fs::is_regular_file(candidate, ec)) return Status::NotFound("no such file");
  return candidate;
}

namespace {

// A path's characters as a browser sends them: RFC 3986 pchar and '/' as they are, every other
// byte (space, '%', '?', '#', non-ASCII) as %XX.
std::string PercentEncodePath(std::string_view path) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  static constexpr std::string_view kKept = "-._~!$&'()*+,;=:@/";
  std::string out;
  for (const char c : path) {
    const auto byte = static_cast<unsigned char>(c);
    if (std::isalnum(byte) != 0 || kKept.find(c) != std::string_view::npos) {
      out += c;
    } else {
      out += '%';
      out += kHex[byte >> 4];
      out += kHex[byte & 0xF];
    }
  }
  return out;
}

// "'sha256-<base64>'" of `text`, as CSP source expressions name inline scripts.
std::string Sha256Source(std::string_view text) {
  unsigned char digest[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(text.data()), text.size(), digest);
  unsigned char encoded[4 * ((SHA256_DIGEST_LENGTH + 2) / 3) + 1];
  const int length = EVP_EncodeBlock(encoded, digest, SHA256_DIGEST_LENGTH);
  return "'sha256-" + std::string(reinterpret_cast<const char*>(encoded), length) + "'";
}

}  // namespace

std::string ContentSecurityPolicy(std::string_view html) {
  std::string lower(html);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  std::string script_sources = "'self'";
  std::size_t at = 0;
  while ((at = lower.find("<script", at)) != std::string::npos) {
    const std::size_t tag_end = lower.find('>', at);
    if (tag_end == std::string::npos) break;
    const std::size_t close = lower.find("</script", tag_end);
    if (close == std::string::npos) break;
    const std::string_view tag(lower.data() + at, tag_end - at);
    if (tag.find(" src=") == std::string_view::npos) {
      script_sources += " " + Sha256Source(html.substr(tag_end + 1, close - tag_end - 1));
    }
    at = close;
  }
  return "default-src 'self'; script-src " + script_sources +
         "; style-src 'self'; img-src 'self' data: blob:; connect-src 'self' data: blob:; "
         "object-src 'none'; base-uri 'none'; frame-ancestors 'none'; form-action 'self'";
}

std::vector<std::string> StaticFilePaths(const fs::path& root) {
  std::vector<std::string> paths;
  std::error_code ec;
  fs::recursive_directory_iterator it(root, ec);
  for (const fs::recursive_directory_iterator end; !ec && it != end; it.increment(ec)) {
    const fs::path relative = it->path().lexically_relative(root);
    if (relative.filename().string().front() == '.') {
      // Hidden names are never served: skip a hidden folder's whole tree (web/.deps).
      if (it->is_directory(ec)) it.disable_recursion_pending();
      continue;
    }
    if (!it->is_regular_file(ec)) continue;
    const std::string path = PercentEncodePath("/" + relative.generic_string());
    if (!ResolveStaticPath(root, path).ok()) continue;
    paths.push_back(path);
    if (relative.filename() == "index.html") {
      paths.push_back(path.substr(0, path.size() - std::string_view("index.html").size()));
    }
  }
  std::sort(paths.begin(), paths.end());
  return paths;
}

Handler MakeStaticFileHandler(fs::path root) {
  return [root = std::move(root)](RequestContext& context) -> Response {
    Result<fs::path> file = ResolveStaticPath(root, context.path);
    if (!file.ok()) {
      if (file.status().code() == StatusCode::kInvalidArgument) {
        return ErrorResponse(HttpStatus::bad_request, "invalid path: " + file.status().message());
      }
      return ErrorResponse(HttpStatus::not_found, "no such file: " + context.path);
    }
    Response response = Response::File(*file);
    response.SetHeader("Cache-Control", "no-cache");
    if (file->extension() == ".html") {
      std::ifstream in(*file, std::ios::binary);
      const std::string html((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
      response.SetHeader("Content-Security-Policy", ContentSecurityPolicy(html));
    }
    return response;
  };
}

}  // namespace reconduit::server
