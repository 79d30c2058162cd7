// Serving a folder of static files (the web/ page and its assets) safely.
//
// The request path is mapped onto the root folder segment by segment after percent-decoding.
// Anything that could leave the root is refused before the file system is touched: ".." and "."
// segments (also when encoded as %2e%2e), segments containing '/' or '\' after decoding (%2f,
// %5c), empty segments ("//etc/passwd"), NUL bytes, and hidden names starting with '.'. As a
// second line of defence the resolved file's canonical path must lie inside the canonical root,
// so a symlink inside web/ cannot point outside it either.
#ifndef RECONDUIT_SERVER_HTTP_STATIC_FILES_H_
#define RECONDUIT_SERVER_HTTP_STATIC_FILES_H_

#include "core/util/status.h"
#include "server/http/router.h"

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit::server {

// Maps a raw request path ("/", "/js/app.js", "/docs/") to a path below `root`; a path ending in
// '/' maps to its index.html. Returns kInvalidArgument for a path that tries to escape the root
// (see above) and kNotFound when the file does not exist or is not a regular file. Does not
// require `root` to exist (then everything is kNotFound).
Result<std::filesystem::path> ResolveStaticPath(const std::filesystem::path& root,
                                                std::string_view raw_path);

// A GET/HEAD handler serving files below `root` (use as Router::SetFallback). Escape attempts
// get a 400 JSON error, missing files a 404 JSON error; files are streamed with the MIME type of
// their extension and `Cache-Control: no-cache` (revalidate, since the page changes with
// releases and carries no version in its URLs).
// HTML files also carry a Content-Security-Policy (ContentSecurityPolicy below); every response
// of the server carries X-Content-Type-Options: nosniff (the transport adds it).
Handler MakeStaticFileHandler(std::filesystem::path root);

// The request paths of the files MakeStaticFileHandler(root) serves, as a browser writes them
// (percent-encoded where a name needs it), sorted: "/" and "/<folder>/" for each index.html, and
// "/<relative path>" for every regular file below `root` that ResolveStaticPath accepts (no
// hidden names, nothing that leaves the root). A snapshot: files added later are not listed.
// The server makes these public when it requires a bearer token, since a browser cannot send
// the token with a navigation or a script, style or module load (server/main.cc).
std::vector<std::string> StaticFilePaths(const std::filesystem::path& root);

// The Content-Security-Policy of an HTML page: scripts, styles, fetches and everything else
// from the page's own origin only (module scripts and WebGL need nothing more); images also
// from data: and blob: URLs and fetches of them (three.js decodes a model's embedded textures
// through blob: URLs); no plugins, no <base>, no framing by other sites. Inline <script>
// elements without src (an import map) are allowed by the SHA-256 hash of their text, computed
// from `html`; no other inline script or style is.
std::string ContentSecurityPolicy(std::string_view html);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_STATIC_FILES_H_
