// Result downloads: result.zip (ETag, If-None-Match, single Range) and the single files of
// <data>/jobs/<id>/output/. Both exist once the job has succeeded (409 before).
#include "core/util/logging.h"
#include "server/api/api.h"
#include "server/api/request_params.h"
#include "server/api/safe_names.h"
#include "server/http/range.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <string>
#include <system_error>

namespace reconduit::server {
namespace {

namespace fs = std::filesystem;

// The job if it has succeeded; otherwise the response to send (404, 409).
Result<Job> SucceededJob(ApiServices* services, std::string_view id, Response* refusal) {
  Result<Job> job = services->store->GetJob(id);
  if (!job.ok()) {
    *refusal = ResponseFromStatus(job.status(), services->retry_after_seconds);
    return job.status();
  }
  if (job->state != JobState::kSucceeded) {
    const Status status = Status::FailedPrecondition("job " + std::string(id) + " is " +
                                                     std::string(JobStateName(job->state)) +
                                                     "; its results exist once it has succeeded");
    *refusal = ResponseFromStatus(status);
    return status;
  }
  return job;
}

Response ResultZip(ApiServices* services, RequestContext& context, std::string_view id) {
  Response refusal;
  Result<Job> job = SucceededJob(services, id, &refusal);
  if (!job.ok()) return refusal;
  const fs::path path = services->layout().ResultZip(id);
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) {
    LOG_WARNING << "job " << id << " succeeded but " << path << " is unreadable: " << ec.message();
    return ErrorResponse(HttpStatus::not_found,
                         "result.zip of job " + std::string(id) + " is missing");
  }

  // The stored SHA-256 is a strong validator: it changes whenever the bytes do.
  const std::string etag = "\"" + job->result_sha256 + "\"";
  auto with_validators = [&](Response response) {
    response.SetHeader("ETag", etag);
    response.SetHeader("Accept-Ranges", "bytes");
    response.SetHeader("Cache-Control", "no-cache");
    return response;
  };
  if (const std::optional<std::string_view> match = context.Header("If-None-Match"); match) {
    if (!job->result_sha256.empty() && EntityTagListMatches(*match, etag)) {
      return with_validators(Response(HttpStatus::not_modified));
    }
  }

  RangeRequest range;
  if (const std::optional<std::string_view> header = context.Header("Range"); header) {
    // If-Range: serve the range only when the client's copy is still current.
    const std::optional<std::string_view> if_range = context.Header("If-Range");
    if (!if_range || IfRangeMatches(*if_range, etag)) range = ParseRangeHeader(*header, size);
  }
  if (range.kind == RangeRequest::Kind::kUnsatisfiable) {
    Response response =
        ErrorResponse(HttpStatus::range_not_satisfiable,
                      "the range lies outside result.zip (" + std::to_string(size) + " bytes)");
    response.SetHeader("Content-Range", "bytes */" + std::to_string(size));
    return with_validators(std::move(response));
  }
  Response response = Response::File(path, "application/zip");
  response.SetHeader("Content-Disposition",
                     "attachment; filename=\"reconduit-" + std::string(id.substr(0, 8)) + ".zip\"");
  if (range.kind == RangeRequest::Kind::kPartial) {
    response.set_status(HttpStatus::partial_content);
    response.set_file_slice(range.slice);
    response.SetHeader("Content-Range", ContentRangeHeader(range.slice, size));
  }
  return with_validators(std::move(response));
}

Response ListFiles(ApiServices* services, RequestContext&, std::string_view id) {
  Response refusal;
  Result<Job> job = SucceededJob(services, id, &refusal);
  if (!job.ok()) return refusal;
  const fs::path output = services->layout().OutputDir(id);
  nlohmann::json files = nlohmann::json::array();
  std::error_code ec;
  std::vector<std::pair<std::string, std::uintmax_t>> found;
  for (fs::recursive_directory_iterator it(output, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_regular_file(ec) || it->is_symlink(ec)) continue;
    const std::string name = fs::relative(it->path(), output, ec).generic_string();
    if (ec || !CheckRelativePath(name).ok()) continue;
    found.emplace_back(name, it->file_size(ec));
  }
  std::sort(found.begin(), found.end());
  const std::string base = "/api/v1/jobs/" + std::string(id) + "/files/";
  for (const auto& [name, bytes] : found) {
    files.push_back({{"name", name},
                     {"bytes", bytes},
                     {"type", std::string(MimeTypeForPath(name))},
                     {"url", base + name}});
  }
  return Response::Json({{"files", std::move(files)}});
}

Response GetFile(ApiServices* services, RequestContext& context, std::string_view id) {
  const std::string_view name = context.PathParam("name");
  if (Status status = CheckRelativePath(name); !status.ok()) {
    return ErrorResponse(HttpStatus::bad_request, status.message());
  }
  Response refusal;
  Result<Job> job = SucceededJob(services, id, &refusal);
  if (!job.ok()) return refusal;
  const fs::path output = services->layout().OutputDir(id);
  const fs::path path = output / fs::path(std::string(name));
  // Second line of defence: the file's real location must be inside output/ (no symlink out).
  std::error_code ec;
  const fs::path real = fs::canonical(path, ec);
  const fs::path real_output = ec ? fs::path() : fs::canonical(output, ec);
  const auto inside = [&] {
    auto it = real.begin();
    for (const fs::path& part : real_output) {
      if (it == real.end() || *it != part) return false;
      ++it;
    }
    return true;
  };
  if (ec || !fs::is_regular_file(real, ec) || !inside()) {
    return ErrorResponse(HttpStatus::not_found,
                         "job " + std::string(id) + " has no file " + QuoteForMessage(name));
  }
  Response response = Response::File(real, MimeTypeForPath(name));
  response.SetHeader("Cache-Control", "no-cache");
  return response;
}

}  // namespace

void AddArtifactRoutes(Router* router, ApiServices* services) {
  router->Add(HttpVerb::get, "/api/v1/jobs/{id}/result.zip", WithJobId(services, ResultZip));
  router->Add(HttpVerb::get, "/api/v1/jobs/{id}/files", WithJobId(services, ListFiles));
  router->Add(HttpVerb::get, "/api/v1/jobs/{id}/files/{name...}", WithJobId(services, GetFile));
}

}  // namespace reconduit::server
