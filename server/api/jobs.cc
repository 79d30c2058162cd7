// The job routes: create (upload.cc does the work), list, status, events, cancel, restart,
// delete. Thin: parse and validate the request, call the JobStore, map its Status to HTTP
// (ResponseFromStatus: kNotFound 404, kFailedPrecondition 409, kResourceExhausted 503).
#include "core/util/logging.h"
#include "server/api/api.h"
#include "server/api/events_stream.h"
#include "server/api/job_json.h"
#include "server/api/request_params.h"
#include "server/api/upload.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <limits>
#include <string>
#include <system_error>

namespace reconduit::server {
namespace {

namespace fs = std::filesystem;

// Pages of events in one plain (non-streaming) response.
constexpr int kDefaultEventLimit = 100;
constexpr int kMaxEventLimit = 1000;

Response GetJobResponse(ApiServices* services, std::string_view id, HttpStatus status) {
  Result<Job> job = services->store->GetJob(id);
  if (!job.ok()) return ResponseFromStatus(job.status(), services->retry_after_seconds);
  Result<std::vector<JobImageRecord>> images = services->store->ListImages(id);
  if (!images.ok()) return ResponseFromStatus(images.status(), services->retry_after_seconds);
  nlohmann::json body = JobToJson(*job, NowMs());
  body["images"] = ImagesToJson(*images);
  Response response = Response::Json(body, status);
  response.SetHeader("Cache-Control", "no-store");
  return response;
}

Response ListJobs(ApiServices* services, RequestContext& context) {
  JobListQuery query;
  Result<std::int64_t> limit = IntegerParam(context, "limit", 50, 1, 1000);
  if (!limit.ok()) return ResponseFromStatus(limit.status());
  Result<std::int64_t> offset =
      IntegerParam(context, "offset", 0, 0, std::numeric_limits<std::int64_t>::max());
  if (!offset.ok()) return ResponseFromStatus(offset.status());
  query.limit = static_cast<int>(*limit);
  query.offset = *offset;
  if (const std::optional<std::string_view> state = context.Query("state"); state) {
    query.state = ParseJobState(*state);
    if (!query.state) {
      return ErrorResponse(HttpStatus::bad_request,
                           "query parameter `state` must be one of queued, running, succeeded, "
                           "failed, canceled");
    }
  }
  Result<JobPage> page = services->store->ListJobs(query);
  if (!page.ok()) return ResponseFromStatus(page.status(), services->retry_after_seconds);
  const std::int64_t now = NowMs();
  nlohmann::json jobs = nlohmann::json::array();
  for (const Job& job : page->jobs) jobs.push_back(JobToJson(job, now));
  nlohmann::json body = {{"jobs", std::move(jobs)},
                         {"total", page->total},
                         {"limit", query.limit},
                         {"offset", query.offset}};
  Response response = Response::Json(body);
  response.SetHeader("Cache-Control", "no-store");
  return response;
}

Response ListEvents(ApiServices* services, RequestContext& context, std::string_view id) {
  Result<std::int64_t> after =
      IntegerParam(context, "after", 0, 0, std::numeric_limits<std::int64_t>::max());
  if (!after.ok()) return ResponseFromStatus(after.status());
  if (AcceptsEventStream(context)) {
    // EventSource reconnects with the id of the last event it saw.
    std::int64_t start = *after;
    if (const std::optional<std::string_view> last = context.Header("Last-Event-ID"); last) {
      Result<std::int64_t> parsed =
          ParseInteger(*last, "Last-Event-ID", 0, std::numeric_limits<std::int64_t>::max());
      if (!parsed.ok()) return ResponseFromStatus(parsed.status());
      start = *parsed;
    }
    return MakeEventStream(services, std::string(id), start);
  }
  Result<std::int64_t> limit =
      IntegerParam(context, "limit", kDefaultEventLimit, 1, kMaxEventLimit);
  if (!limit.ok()) return ResponseFromStatus(limit.status());
  Result<Job> job = services->store->GetJob(id);
  if (!job.ok()) return ResponseFromStatus(job.status(), services->retry_after_seconds);
  Result<std::vector<JobEvent>> events =
      services->store->ListEvents(id, *after, static_cast<int>(*limit));
  if (!events.ok()) return ResponseFromStatus(events.status(), services->retry_after_seconds);

  // JSON lines: one event object per line, oldest first.
  std::string body;
  std::int64_t last_id = *after;
  for (const JobEvent& event : *events) {
    body += EventToJson(event).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    body += '\n';
    last_id = event.id;
  }
  Response response = Response::Text(std::move(body), HttpStatus::ok, "application/x-ndjson");
  response.SetHeader("Cache-Control", "no-store");
  // For the next poll (?after=<this>), and whether more may follow.
  response.SetHeader("X-Last-Event-Id", std::to_string(last_id));
  response.SetHeader("X-Job-State", JobStateName(job->state));
  response.SetHeader("X-More-Events",
                     static_cast<std::int64_t>(events->size()) == *limit ? "true" : "false");
  return response;
}

Response CancelJob(ApiServices* services, std::string_view id) {
  Result<JobState> state = services->store->RequestCancel(id);
  if (!state.ok()) return ResponseFromStatus(state.status(), services->retry_after_seconds);
  LOG_INFO << "job " << id << ": cancel requested (now " << JobStateName(*state) << ")";
  return GetJobResponse(services, id, HttpStatus::ok);
}

Response RestartJob(ApiServices* services, std::string_view id) {
  Result<Job> job = services->store->RestartJob(id);
  if (!job.ok()) return ResponseFromStatus(job.status(), services->retry_after_seconds);
  LOG_INFO << "job " << id << ": restarted";
  return GetJobResponse(services, id, HttpStatus::ok);
}

Response DeleteJob(ApiServices* services, std::string_view id) {
  Result<JobState> state = services->store->DeleteJob(id);
  if (!state.ok()) return ResponseFromStatus(state.status(), services->retry_after_seconds);
  // The rows are gone, so nothing refers to the folder any more. A folder that cannot be
  // removed now is an orphan that the next start-up removes.
  std::error_code ec;
  const fs::path job_dir = services->layout().JobDir(id);
  fs::remove_all(job_dir, ec);
  if (ec) {
    LOG_WARNING << "job " << id << " deleted but " << job_dir << " stays: " << ec.message();
  }
  LOG_INFO << "job " << id << ": deleted (was " << JobStateName(*state) << ")";
  return Response::Json(
      {{"id", std::string(id)}, {"deleted", true}, {"state", std::string(JobStateName(*state))}});
}

}  // namespace

void AddJobRoutes(Router* router, ApiServices* services) {
  router->AddStreaming(HttpVerb::post, "/api/v1/jobs", [services](RequestContext& context) {
    return StartUpload(context, services);
  });
  router->Add(HttpVerb::get, "/api/v1/jobs",
              [services](RequestContext& context) { return ListJobs(services, context); });
  router->Add(HttpVerb::get, "/api/v1/jobs/{id}",
              WithJobId(services, [](ApiServices* s, RequestContext&, std::string_view id) {
                return GetJobResponse(s, id, HttpStatus::ok);
              }));
  router->Add(HttpVerb::get, "/api/v1/jobs/{id}/events",
              WithJobId(services, [](ApiServices* s, RequestContext& c, std::string_view id) {
                return ListEvents(s, c, id);
              }));
  router->AddBlocking(HttpVerb::post, "/api/v1/jobs/{id}/cancel",
                      WithJobId(services, [](ApiServices* s, RequestContext&, std::string_view id) {
                        return CancelJob(s, id);
                      }));
  router->AddBlocking(HttpVerb::post, "/api/v1/jobs/{id}/restart",
                      WithJobId(services, [](ApiServices* s, RequestContext&, std::string_view id) {
                        return RestartJob(s, id);
                      }));
  router->AddBlocking(HttpVerb::delete_, "/api/v1/jobs/{id}",
                      WithJobId(services, [](ApiServices* s, RequestContext&, std::string_view id) {
                        return DeleteJob(s, id);
                      }));
}

}  // namespace reconduit::server
