// Client-supplied names made harmless: display names of uploaded photos, entry names inside an
// uploaded zip, and the {name...} of GET /api/v1/jobs/{id}/files/{name...}.
//
// A client's file name is display-only: photos are stored under generated names (0001.jpg ...),
// so a name like "../../etc/passwd" or "C:\photos\a.jpg" can never become a path. The display
// name keeps what a person recognises (the base name) and drops what could confuse a log line
// or a terminal (control characters, invalid UTF-8).
//
// Pure string functions; thread-safe.
#ifndef RECONDUIT_SERVER_API_SAFE_NAMES_H_
#define RECONDUIT_SERVER_API_SAFE_NAMES_H_

#include "core/util/status.h"

#include <cstddef>
#include <string>
#include <string_view>

namespace reconduit::server {

// Longest display name kept, in bytes (cut at a UTF-8 character boundary).
inline constexpr std::size_t kMaxDisplayNameBytes = 200;

// The base name of a client file name for display: the part after the last '/' or '\', with
// control characters (C0, DEL) removed, invalid UTF-8 bytes replaced by '?', surrounding white
// space trimmed and at most kMaxDisplayNameBytes bytes. Returns `fallback` when nothing
// printable remains or the result is "." or "..".
//   "../../etc/passwd" -> "passwd"; "C:\\photos\\IMG 1.jpg" -> "IMG 1.jpg"; "/" -> fallback
std::string SanitizeDisplayName(std::string_view client_name, std::string_view fallback);

// The generated stored name of the photo at 0-based `index`: "0001.jpg" for index 0 and
// extension "jpg"; more digits past 9999 ("10000.jpg").
std::string StoredPhotoName(int index, std::string_view extension);

// Checks a relative path taken from a client (a zip entry name, a result file name):
// '/'-separated, non-empty segments that are not "." or "..", no '\', no NUL or other control
// characters, not absolute, no drive letter ("C:"), at most 1024 bytes. Returns OK or
// kInvalidArgument with a message that quotes the name.
// A trailing '/' (a zip directory entry) is allowed when `allow_trailing_slash`.
Status CheckRelativePath(std::string_view path, bool allow_trailing_slash = false);

// `text` in double quotes with control characters escaped, for messages that echo client
// input.
std::string QuoteForMessage(std::string_view text);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_SAFE_NAMES_H_
