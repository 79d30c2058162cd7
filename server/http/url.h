// URL and header-value helpers for the HTTP layer: percent-decoding, query strings, path
// segments and `type; key=value` header parameters.
//
// Everything here is pure string processing with no Beast dependency, so it is cheap to include
// and easy to unit-test. Decoding failures are reported as values (std::nullopt or a non-OK
// Status), never as exceptions, because every input comes straight from a client.
#ifndef RECONDUIT_SERVER_HTTP_URL_H_
#define RECONDUIT_SERVER_HTTP_URL_H_

#include "core/util/status.h"

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace reconduit::server {

// Ordered name/value pairs (query parameters, header parameters). Order and duplicates are kept.
using KeyValues = std::vector<std::pair<std::string, std::string>>;

// Decodes %XX escapes. With `plus_as_space` (query strings, RFC 1866 form encoding) '+' becomes
// ' '. Returns std::nullopt for a malformed escape ('%' not followed by two hex digits) and for
// an encoded NUL byte, which no legitimate path or parameter contains.
std::optional<std::string> PercentDecode(std::string_view in, bool plus_as_space = false);

// The path and the query of a request target in origin form ("/a/b?x=1" -> "/a/b", "x=1").
// The path is returned raw (still percent-encoded). Targets that do not start with '/' (absolute
// form, authority form, "*") are rejected with kInvalidArgument.
struct TargetParts {
  std::string path;
  std::string query;
};
Result<TargetParts> SplitTarget(std::string_view target);

// Parses "a=1&b=x%20y&flag" into {{"a","1"},{"b","x y"},{"flag",""}}. Empty pairs ("a=1&&b=2")
// are skipped. Returns kInvalidArgument when a name or value has a malformed escape.
Result<KeyValues> ParseQuery(std::string_view query);

// Splits a raw path into percent-decoded segments: "/a/b%2Fc/" -> {"a", "b/c", ""}; "/" -> {""}.
// An encoded '/' stays inside its segment, so decoding can never create new segments. Returns
// kInvalidArgument when the path does not start with '/' or a segment has a malformed escape.
Result<std::vector<std::string>> DecodePathSegments(std::string_view raw_path);

// A header value of the shape `token *( ";" name "=" ( token | quoted-string ) )`, as used by
// Content-Type and Content-Disposition (RFC 9110 5.6.6, RFC 6266).
struct HeaderValue {
  // The leading token, lower-cased ("multipart/form-data", "form-data").
  std::string value;
  // Parameters in order; names lower-cased, values unquoted with backslash escapes of '"' and
  // '\' resolved (other backslashes are kept, because browsers send Windows paths unescaped).
  KeyValues params;
  // The first parameter called `name` (case-insensitive), if any.
  std::optional<std::string> Param(std::string_view name) const;
};
// Returns kInvalidArgument for an unterminated quoted string or a parameter without '='.
Result<HeaderValue> ParseHeaderValue(std::string_view header);

// ASCII case-insensitive equality, for header and parameter names.
bool EqualsIgnoreCase(std::string_view a, std::string_view b);
std::string ToLowerAscii(std::string_view s);

// Compares two secrets in time that depends only on their lengths, not on where they differ.
bool ConstantTimeEquals(std::string_view a, std::string_view b);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_URL_H_
