#include "server/http/router.h"

#include <gtest/gtest.h>

namespace reconduit::server {
namespace {

Handler Named(std::string name) {
  return [name](RequestContext&) { return Response::Text(name); };
}

std::string Call(const RouteMatch& match) {
  RequestContext context;
  return match.route->handler(context).body();
}

TEST(Router, MatchesLiteralRoutes) {
  Router router;
  router.Add(HttpVerb::get, "/healthz", Named("health"));
  router.Add(HttpVerb::get, "/api/v1/jobs", Named("list"));
  router.Add(HttpVerb::post, "/api/v1/jobs", Named("create"));

  RouteMatch match = router.Match(HttpVerb::get, "/healthz");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  EXPECT_EQ(Call(match), "health");
  EXPECT_TRUE(match.path_params.empty());

  match = router.Match(HttpVerb::post, "/api/v1/jobs");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  EXPECT_EQ(Call(match), "create");
}

TEST(Router, ExtractsAndDecodesParameters) {
  Router router;
  router.Add(HttpVerb::get, "/api/v1/jobs/{id}/files/{name}", Named("file"));
  RouteMatch match = router.Match(HttpVerb::get, "/api/v1/jobs/abc123/files/model%20v2.glb");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  const KeyValues expected = {{"id", "abc123"}, {"name", "model v2.glb"}};
  EXPECT_EQ(match.path_params, expected);

  // An encoded slash stays inside the parameter; it cannot add a segment.
  match = router.Match(HttpVerb::get, "/api/v1/jobs/abc/files/..%2F..%2Fetc");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  EXPECT_EQ(match.path_params[1].second, "../../etc");
}

TEST(Router, ParameterNeedsANonEmptySegment) {
  Router router;
  router.Add(HttpVerb::get, "/jobs/{id}", Named("job"));
  EXPECT_EQ(router.Match(HttpVerb::get, "/jobs/").kind, RouteMatch::Kind::kNotFound);
  EXPECT_EQ(router.Match(HttpVerb::get, "/jobs").kind, RouteMatch::Kind::kNotFound);
  EXPECT_EQ(router.Match(HttpVerb::get, "/jobs/1/extra").kind, RouteMatch::Kind::kNotFound);
}

TEST(Router, TailParameterTakesTheRestOfThePath) {
  Router router;
  router.Add(HttpVerb::get, "/jobs/{id}/files/{name...}", Named("file"));
  router.Add(HttpVerb::get, "/jobs/{id}/files", Named("files"));

  RouteMatch match = router.Match(HttpVerb::get, "/jobs/7/files/report/similarity%20map.png");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  const KeyValues expected = {{"id", "7"}, {"name", "report/similarity map.png"}};
  EXPECT_EQ(match.path_params, expected);

  match = router.Match(HttpVerb::get, "/jobs/7/files/model.glb");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  EXPECT_EQ(match.path_params[1].second, "model.glb");

  match = router.Match(HttpVerb::get, "/jobs/7/files");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  EXPECT_EQ(Call(match), "files");

  // Empty segments and encoded slashes never match, so '/' in the value are real separators.
  EXPECT_EQ(router.Match(HttpVerb::get, "/jobs/7/files/a//b").kind, RouteMatch::Kind::kNotFound);
  EXPECT_EQ(router.Match(HttpVerb::get, "/jobs/7/files/a/").kind, RouteMatch::Kind::kNotFound);
  EXPECT_EQ(router.Match(HttpVerb::get, "/jobs/7/files/a%2Fb").kind, RouteMatch::Kind::kNotFound);
}

TEST(Router, TailParameterMustBeLast) {
  Router router;
  EXPECT_THROW(router.Add(HttpVerb::get, "/files/{name...}/x", Named("x")), CheckError);
  EXPECT_THROW(router.Add(HttpVerb::get, "/files/{...}", Named("x")), CheckError);
  EXPECT_THROW(router.Add(HttpVerb::get, "/files/{a}/{a...}", Named("x")), CheckError);
}

TEST(Router, LiteralBeatsParameterWhateverTheOrder) {
  Router router;
  router.Add(HttpVerb::get, "/jobs/{id}", Named("job"));
  router.Add(HttpVerb::get, "/jobs/stats", Named("stats"));
  RouteMatch match = router.Match(HttpVerb::get, "/jobs/stats");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  EXPECT_EQ(Call(match), "stats");
  match = router.Match(HttpVerb::get, "/jobs/42");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  EXPECT_EQ(Call(match), "job");
}

TEST(Router, UnknownPathIsNotFound) {
  Router router;
  router.Add(HttpVerb::get, "/healthz", Named("health"));
  EXPECT_EQ(router.Match(HttpVerb::get, "/nope").kind, RouteMatch::Kind::kNotFound);
  EXPECT_EQ(router.Match(HttpVerb::get, "/healthz/").kind, RouteMatch::Kind::kNotFound);
  EXPECT_EQ(router.Match(HttpVerb::get, "/").kind, RouteMatch::Kind::kNotFound);
}

TEST(Router, WrongVerbIsMethodNotAllowedWithAllow) {
  Router router;
  router.Add(HttpVerb::get, "/api/v1/jobs/{id}", Named("get"));
  router.Add(HttpVerb::delete_, "/api/v1/jobs/{id}", Named("delete"));
  RouteMatch match = router.Match(HttpVerb::post, "/api/v1/jobs/7");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kMethodNotAllowed);
  EXPECT_EQ(match.allow, "DELETE, GET, HEAD");
}

TEST(Router, HeadFallsBackToGet) {
  Router router;
  router.Add(HttpVerb::get, "/healthz", Named("health"));
  RouteMatch match = router.Match(HttpVerb::head, "/healthz");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  EXPECT_EQ(Call(match), "health");
}

TEST(Router, FallbackOnlyForGetAndHeadOfUnknownPaths) {
  Router router;
  router.Add(HttpVerb::post, "/upload", Named("upload"));
  router.SetFallback(Named("static"));
  EXPECT_EQ(router.Match(HttpVerb::get, "/index.html").kind, RouteMatch::Kind::kFallback);
  EXPECT_EQ(router.Match(HttpVerb::head, "/").kind, RouteMatch::Kind::kFallback);
  EXPECT_EQ(router.Match(HttpVerb::post, "/index.html").kind, RouteMatch::Kind::kNotFound);
  // A known path keeps its 405 even with a fallback.
  EXPECT_EQ(router.Match(HttpVerb::get, "/upload").kind, RouteMatch::Kind::kMethodNotAllowed);
}

TEST(Router, MalformedPathIsBadPath) {
  Router router;
  router.Add(HttpVerb::get, "/jobs/{id}", Named("job"));
  EXPECT_EQ(router.Match(HttpVerb::get, "/jobs/%zz").kind, RouteMatch::Kind::kBadPath);
  EXPECT_EQ(router.Match(HttpVerb::get, "jobs/1").kind, RouteMatch::Kind::kBadPath);
}

TEST(Router, StreamingRoutesMatchToo) {
  Router router;
  router.AddStreaming(HttpVerb::post, "/api/v1/jobs",
                      [](RequestContext&) -> StreamStart { return Response(HttpStatus::created); });
  RouteMatch match = router.Match(HttpVerb::post, "/api/v1/jobs");
  ASSERT_EQ(match.kind, RouteMatch::Kind::kFound);
  EXPECT_TRUE(match.route->streaming_handler != nullptr);
  EXPECT_TRUE(match.route->handler == nullptr);
}

TEST(Router, RejectsMalformedPatternsAndDuplicates) {
  Router router;
  EXPECT_THROW(router.Add(HttpVerb::get, "healthz", Named("x")), CheckError);
  EXPECT_THROW(router.Add(HttpVerb::get, "/jobs/{}", Named("x")), CheckError);
  EXPECT_THROW(router.Add(HttpVerb::get, "/jobs/{id", Named("x")), CheckError);
  EXPECT_THROW(router.Add(HttpVerb::get, "/jobs/x{id}", Named("x")), CheckError);
  EXPECT_THROW(router.Add(HttpVerb::get, "/jobs/{id}/{id}", Named("x")), CheckError);
  EXPECT_THROW(router.Add(HttpVerb::get, "/jobs", nullptr), CheckError);
  router.Add(HttpVerb::get, "/jobs/{id}", Named("x"));
  EXPECT_THROW(router.Add(HttpVerb::get, "/jobs/{id}", Named("y")), CheckError);
  router.Add(HttpVerb::delete_, "/jobs/{id}", Named("z"));  // Other verb: fine.
}

TEST(RequestContext, LooksUpHeadersQueryAndParams) {
  RequestContext context;
  context.headers = {{"Content-Type", "text/plain"}, {"X-A", "1"}, {"x-a", "2"}};
  context.query = {{"after", "5"}};
  context.path_params = {{"id", "abc"}};
  EXPECT_EQ(context.Header("content-type"), "text/plain");
  EXPECT_EQ(context.Header("X-A"), "1");
  EXPECT_EQ(context.Header("missing"), std::nullopt);
  EXPECT_EQ(context.Query("after"), "5");
  EXPECT_EQ(context.Query("After"), std::nullopt);
  EXPECT_EQ(context.PathParam("id"), "abc");
  EXPECT_EQ(context.PathParam("name"), "");
}

}  // namespace
}  // namespace reconduit::server
