#include "server/http/router.h"

#include "core/util/logging.h"

#include <algorithm>
#include <set>

namespace reconduit::server {
namespace {

bool IsParam(std::string_view segment) {
  return segment.size() >= 2 && segment.front() == '{' && segment.back() == '}';
}

// "{name...}": a parameter that takes the rest of the path.
bool IsTailParam(std::string_view segment) {
  return IsParam(segment) && segment.size() > 5 && segment.substr(segment.size() - 4) == "...}";
}

// The parameter name of "{name}" or "{name...}".
std::string ParamName(std::string_view segment) {
  std::string_view name = segment.substr(1, segment.size() - 2);
  if (IsTailParam(segment)) name.remove_suffix(3);
  return std::string(name);
}

std::vector<std::string> ParsePattern(std::string_view pattern) {
  THROW_CHECK(!pattern.empty() && pattern.front() == '/')
      << "route pattern must start with '/': " << pattern;
  std::vector<std::string> segments;
  std::set<std::string, std::less<>> names;
  std::string_view rest = pattern.substr(1);
  while (true) {
    const std::size_t slash = rest.find('/');
    const std::string_view segment = rest.substr(0, slash);
    const bool has_brace =
        segment.find('{') != std::string_view::npos || segment.find('}') != std::string_view::npos;
    if (has_brace) {
      THROW_CHECK(IsParam(segment) && segment.size() > 2 &&
                  segment.substr(1, segment.size() - 2).find_first_of("{}") ==
                      std::string_view::npos)
          << "malformed parameter segment '" << segment << "' in route pattern " << pattern;
      THROW_CHECK(names.insert(ParamName(segment)).second)
          << "duplicate parameter " << segment << " in route pattern " << pattern;
      THROW_CHECK(!IsTailParam(segment) || slash == std::string_view::npos)
          << "tail parameter " << segment << " must be the last segment of " << pattern;
      THROW_CHECK(!ParamName(segment).empty() && ParamName(segment).find('.') == std::string::npos)
          << "malformed parameter name in segment '" << segment << "' of " << pattern;
    }
    segments.emplace_back(segment);
    if (slash == std::string_view::npos) break;
    rest = rest.substr(slash + 1);
  }
  return segments;
}

std::string VerbName(HttpVerb verb) {
  const auto name = boost::beast::http::to_string(verb);
  return std::string(name.data(), name.size());
}

// Matches decoded path segments against a pattern; fills `params` on success.
bool MatchSegments(const Route& route, const std::vector<std::string>& path, KeyValues* params) {
  const bool has_tail = !route.segments.empty() && IsTailParam(route.segments.back());
  if (has_tail ? path.size() < route.segments.size() : route.segments.size() != path.size()) {
    return false;
  }
  params->clear();
  for (std::size_t i = 0; i < route.segments.size(); ++i) {
    const std::string& pattern_segment = route.segments[i];
    if (IsTailParam(pattern_segment)) {
      // The rest of the path: non-empty segments without an encoded '/', joined with '/'.
      std::string value;
      for (std::size_t j = i; j < path.size(); ++j) {
        if (path[j].empty() || path[j].find('/') != std::string::npos) return false;
        if (j > i) value += '/';
        value += path[j];
      }
      params->emplace_back(ParamName(pattern_segment), std::move(value));
      return true;
    }
    if (IsParam(pattern_segment)) {
      if (path[i].empty()) return false;
      params->emplace_back(ParamName(pattern_segment), path[i]);
    } else if (pattern_segment != path[i]) {
      return false;
    }
  }
  return true;
}

// True when `a` is more specific than `b`: a literal at the first segment where they differ.
bool MoreSpecific(const Route& a, const Route& b) {
  for (std::size_t i = 0; i < a.segments.size() && i < b.segments.size(); ++i) {
    const bool a_literal = !IsParam(a.segments[i]);
    const bool b_literal = !IsParam(b.segments[i]);
    if (a_literal != b_literal) return a_literal;
  }
  return false;
}

}  // namespace

void Router::Add(HttpVerb verb, std::string_view pattern, Handler handler) {
  AddHandler(verb, pattern, std::move(handler), /*blocking=*/false);
}

void Router::AddBlocking(HttpVerb verb, std::string_view pattern, Handler handler) {
  AddHandler(verb, pattern, std::move(handler), /*blocking=*/true);
}

void Router::AddHandler(HttpVerb verb, std::string_view pattern, Handler handler, bool blocking) {
  THROW_CHECK(handler != nullptr) << "null handler for " << pattern;
  auto route = std::make_unique<Route>();
  route->verb = verb;
  route->pattern = std::string(pattern);
  route->handler = std::move(handler);
  route->blocking = blocking;
  AddRoute(std::move(route));
}

void Router::AddStreaming(HttpVerb verb, std::string_view pattern, StreamingHandler handler) {
  THROW_CHECK(handler != nullptr) << "null streaming handler for " << pattern;
  auto route = std::make_unique<Route>();
  route->verb = verb;
  route->pattern = std::string(pattern);
  route->streaming_handler = std::move(handler);
  AddRoute(std::move(route));
}

void Router::AddRoute(std::unique_ptr<Route> route) {
  THROW_CHECK(route->verb != HttpVerb::unknown) << "unknown verb for " << route->pattern;
  route->segments = ParsePattern(route->pattern);
  for (const auto& existing : routes_) {
    THROW_CHECK(!(existing->verb == route->verb && existing->segments == route->segments))
        << "duplicate route " << VerbName(route->verb) << " " << route->pattern;
  }
  routes_.push_back(std::move(route));
}

void Router::SetFallback(Handler handler) { fallback_ = std::move(handler); }

RouteMatch Router::Match(HttpVerb verb, std::string_view raw_path) const {
  RouteMatch result;
  Result<std::vector<std::string>> path = DecodePathSegments(raw_path);
  if (!path.ok()) {
    result.kind = RouteMatch::Kind::kBadPath;
    return result;
  }

  // Every route whose pattern matches the path, whatever its verb.
  const Route* best = nullptr;
  const Route* best_get = nullptr;  // For HEAD requests without an explicit HEAD route.
  KeyValues best_params;
  KeyValues best_get_params;
  std::set<std::string> allowed;
  KeyValues params;
  for (const auto& route : routes_) {
    if (!MatchSegments(*route, *path, &params)) continue;
    allowed.insert(VerbName(route->verb));
    if (route->verb == HttpVerb::get) allowed.insert("HEAD");
    if (route->verb == verb && (best == nullptr || MoreSpecific(*route, *best))) {
      best = route.get();
      best_params = params;
    }
    if (verb == HttpVerb::head && route->verb == HttpVerb::get &&
        (best_get == nullptr || MoreSpecific(*route, *best_get))) {
      best_get = route.get();
      best_get_params = params;
    }
  }
  if (best == nullptr && best_get != nullptr) {
    best = best_get;
    best_params = std::move(best_get_params);
  }
  if (best != nullptr) {
    result.kind = RouteMatch::Kind::kFound;
    result.route = best;
    result.path_params = std::move(best_params);
    return result;
  }
  if (!allowed.empty()) {
    result.kind = RouteMatch::Kind::kMethodNotAllowed;
    for (const std::string& name : allowed) {
      if (!result.allow.empty()) result.allow += ", ";
      result.allow += name;
    }
    return result;
  }
  if (fallback_ && (verb == HttpVerb::get || verb == HttpVerb::head)) {
    result.kind = RouteMatch::Kind::kFallback;
    return result;
  }
  result.kind = RouteMatch::Kind::kNotFound;
  return result;
}

}  // namespace reconduit::server
