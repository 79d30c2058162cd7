#include "server/http/response.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace reconduit::server {
namespace {

nlohmann::json Body(const Response& response) { return nlohmann::json::parse(response.body()); }

TEST(Response, JsonSetsTypeAndBody) {
  Response response = Response::Json({{"status", "ok"}});
  EXPECT_EQ(response.status(), HttpStatus::ok);
  ASSERT_NE(response.FindHeader("content-type"), nullptr);
  EXPECT_EQ(*response.FindHeader("Content-Type"), "application/json");
  EXPECT_EQ(Body(response), (nlohmann::json{{"status", "ok"}}));
}

TEST(Response, JsonReplacesInvalidUtf8InsteadOfThrowing) {
  Response response = Response::Json({{"name", std::string("a\xff"
                                                           "b")}});
  // The invalid byte becomes U+FFFD (EF BF BD in UTF-8); the valid ones around it stay.
  EXPECT_EQ(response.body(),
            "{\"name\":\"a\xEF\xBF\xBD"
            "b\"}");
  nlohmann::json body;
  ASSERT_NO_THROW(body = Body(response));
  EXPECT_EQ(body["name"].get<std::string>(),
            "a\xEF\xBF\xBD"
            "b");
}

TEST(Response, SetHeaderReplacesCaseInsensitively) {
  Response response;
  response.SetHeader("X-Thing", "1");
  response.SetHeader("x-thing", "2");
  ASSERT_EQ(response.headers().size(), 1u);
  EXPECT_EQ(*response.FindHeader("X-THING"), "2");
  EXPECT_EQ(response.FindHeader("missing"), nullptr);
}

TEST(Response, FileGuessesContentType) {
  Response response = Response::File("/srv/web/index.html");
  ASSERT_TRUE(response.file().has_value());
  EXPECT_EQ(*response.FindHeader("Content-Type"), "text/html; charset=utf-8");
  EXPECT_EQ(*Response::File("/x/model.glb").FindHeader("Content-Type"), "model/gltf-binary");
  EXPECT_EQ(*Response::File("/x/data.bin", "application/x-custom").FindHeader("Content-Type"),
            "application/x-custom");
}

TEST(ErrorResponse, HasTheJsonErrorShape) {
  Response response = ErrorResponse(HttpStatus::not_found, "job 42 does not exist");
  EXPECT_EQ(response.status(), HttpStatus::not_found);
  EXPECT_EQ(*response.FindHeader("Content-Type"), "application/json");
  const nlohmann::json body = Body(response);
  EXPECT_EQ(body["error"]["code"], "not_found");
  EXPECT_EQ(body["error"]["message"], "job 42 does not exist");

  EXPECT_EQ(Body(ErrorResponse(HttpStatus::conflict, "m", "job_finished"))["error"]["code"],
            "job_finished");
}

TEST(ErrorResponse, DefaultCodes) {
  EXPECT_EQ(DefaultErrorCode(HttpStatus::bad_request), "bad_request");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::unauthorized), "unauthorized");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::method_not_allowed), "method_not_allowed");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::conflict), "conflict");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::payload_too_large), "payload_too_large");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::unsupported_media_type), "unsupported_media_type");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::too_many_requests), "too_many_requests");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::internal_server_error), "internal");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::service_unavailable), "unavailable");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::gateway_timeout), "internal");
  EXPECT_EQ(DefaultErrorCode(HttpStatus::failed_dependency), "bad_request");
}

TEST(ErrorResponse, SpecialisedHelpersSetTheirHeaders) {
  Response unauthorized = UnauthorizedResponse("token required");
  EXPECT_EQ(unauthorized.status(), HttpStatus::unauthorized);
  ASSERT_NE(unauthorized.FindHeader("WWW-Authenticate"), nullptr);
  EXPECT_EQ(unauthorized.FindHeader("WWW-Authenticate")->rfind("Bearer", 0), 0u);

  Response not_allowed = MethodNotAllowedResponse("GET, HEAD");
  EXPECT_EQ(not_allowed.status(), HttpStatus::method_not_allowed);
  EXPECT_EQ(*not_allowed.FindHeader("Allow"), "GET, HEAD");

  Response busy = RetryLaterResponse(HttpStatus::too_many_requests, "slow down", 7);
  EXPECT_EQ(busy.status(), HttpStatus::too_many_requests);
  EXPECT_EQ(*busy.FindHeader("Retry-After"), "7");
}

TEST(HttpStatusFor, MapsEveryStatusCode) {
  EXPECT_EQ(HttpStatusFor(StatusCode::kOk), HttpStatus::ok);
  EXPECT_EQ(HttpStatusFor(StatusCode::kInvalidArgument), HttpStatus::bad_request);
  EXPECT_EQ(HttpStatusFor(StatusCode::kNotFound), HttpStatus::not_found);
  EXPECT_EQ(HttpStatusFor(StatusCode::kFailedPrecondition), HttpStatus::conflict);
  EXPECT_EQ(HttpStatusFor(StatusCode::kAlreadyExists), HttpStatus::conflict);
  EXPECT_EQ(HttpStatusFor(StatusCode::kDegenerate), HttpStatus::unprocessable_entity);
  EXPECT_EQ(HttpStatusFor(StatusCode::kResourceExhausted), HttpStatus::service_unavailable);
  EXPECT_EQ(HttpStatusFor(StatusCode::kCanceled), HttpStatus::service_unavailable);
  EXPECT_EQ(HttpStatusFor(StatusCode::kInternal), HttpStatus::internal_server_error);
  EXPECT_EQ(HttpStatusFor(StatusCode::kNotRun), HttpStatus::internal_server_error);
}

TEST(ResponseFromStatus, CarriesCodeAndMessage) {
  Response response = ResponseFromStatus(Status::FailedPrecondition("job already finished"));
  EXPECT_EQ(response.status(), HttpStatus::conflict);
  EXPECT_EQ(Body(response)["error"]["code"], "failed_precondition");
  EXPECT_EQ(Body(response)["error"]["message"], "job already finished");
  EXPECT_EQ(response.FindHeader("Retry-After"), nullptr);

  response = ResponseFromStatus(Status::InvalidArgument("bad option 'focal'"));
  EXPECT_EQ(response.status(), HttpStatus::bad_request);
  EXPECT_EQ(Body(response)["error"]["code"], "bad_request");
}

TEST(ResponseFromStatus, ResourceExhaustedSaysWhenToRetry) {
  Response response = ResponseFromStatus(Status::ResourceExhausted("queue full"), 9);
  EXPECT_EQ(response.status(), HttpStatus::service_unavailable);
  ASSERT_NE(response.FindHeader("Retry-After"), nullptr);
  EXPECT_EQ(*response.FindHeader("Retry-After"), "9");
}

TEST(ResponseFromStatus, InternalErrorsDoNotLeakDetails) {
  Response response = ResponseFromStatus(Status::Internal("sqlite: disk I/O error at /srv/db"));
  EXPECT_EQ(response.status(), HttpStatus::internal_server_error);
  EXPECT_EQ(Body(response)["error"]["code"], "internal");
  EXPECT_EQ(response.body().find("/srv/db"), std::string::npos);
}

TEST(MimeTypeForPath, KnowsTheWebAndResultTypes) {
  EXPECT_EQ(MimeTypeForPath("index.html"), "text/html; charset=utf-8");
  EXPECT_EQ(MimeTypeForPath("app.JS"), "text/javascript; charset=utf-8");
  EXPECT_EQ(MimeTypeForPath("style.css"), "text/css; charset=utf-8");
  EXPECT_EQ(MimeTypeForPath("a/b/photo.jpeg"), "image/jpeg");
  EXPECT_EQ(MimeTypeForPath("result.zip"), "application/zip");
  EXPECT_EQ(MimeTypeForPath("icon.svg"), "image/svg+xml");
  EXPECT_EQ(MimeTypeForPath("noextension"), "application/octet-stream");
  EXPECT_EQ(MimeTypeForPath("weird.xyz"), "application/octet-stream");
}

}  // namespace
}  // namespace reconduit::server
