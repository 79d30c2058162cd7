#include "server/api/events_stream.h"

#include "core/util/logging.h"
#include "server/api/job_json.h"

#include <nlohmann/json.hpp>

#include <memory>

namespace reconduit::server {
namespace {

using Clock = std::chrono::steady_clock;

// Events read per store call, and calls per poll (so one poll catches up 1000 events).
constexpr int kPageSize = 100;
constexpr int kPagesPerPoll = 10;

std::string Dump(const nlohmann::json& json) {
  return json.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

// What one stream remembers between polls.
class EventStream {
 public:
  EventStream(ApiServices* services, std::string job_id, std::int64_t after)
      : services_(services),
        job_id_(std::move(job_id)),
        after_(after),
        started_(Clock::now()),
        last_sent_(started_) {}

  StreamStep Next() {
    StreamStep step;
    if (first_) {
      // Reconnect after 3 s if the connection drops.
      step.data = "retry: 3000\n\n";
      first_ = false;
    }
    // The job first, then its events: a job that was final before the events were read has
    // all of its events in the store already, so "end" never overtakes an event.
    Result<Job> job = services_->store->GetJob(job_id_);
    if (!job.ok()) {
      if (job.status().code() == StatusCode::kNotFound) {
        step.data += End("deleted");
        step.done = true;
      } else {
        LOG_WARNING << "event stream of job " << job_id_ << ": " << job.status();
      }
      return Finish(std::move(step));
    }
    bool complete = false;
    for (int page = 0; page < kPagesPerPoll; ++page) {
      Result<std::vector<JobEvent>> events =
          services_->store->ListEvents(job_id_, after_, kPageSize);
      if (!events.ok()) {
        LOG_WARNING << "event stream of job " << job_id_ << ": " << events.status();
        return Finish(std::move(step));
      }
      for (const JobEvent& event : *events) {
        step.data += FormatServerSentEvent(event);
        after_ = event.id;
      }
      if (static_cast<int>(events->size()) < kPageSize) {
        complete = true;
        break;
      }
    }
    if (complete && IsFinalState(job->state)) {
      step.data += End(JobStateName(job->state));
      step.done = true;
    } else if (Clock::now() - started_ > kMaxStreamDuration) {
      step.done = true;
    } else if (step.data.empty() && Clock::now() - last_sent_ > kKeepAliveInterval) {
      step.data = ": keep-alive\n\n";
    }
    return Finish(std::move(step));
  }

 private:
  std::string End(std::string_view state) const {
    return "event: end\ndata: " + Dump({{"id", job_id_}, {"state", std::string(state)}}) + "\n\n";
  }

  StreamStep Finish(StreamStep step) {
    if (!step.data.empty()) last_sent_ = Clock::now();
    return step;
  }

  ApiServices* services_;
  const std::string job_id_;
  std::int64_t after_;
  const Clock::time_point started_;
  Clock::time_point last_sent_;
  bool first_ = true;
};

}  // namespace

bool AcceptsEventStream(const RequestContext& context) {
  const std::optional<std::string_view> accept = context.Header("Accept");
  return accept && ToLowerAscii(*accept).find("text/event-stream") != std::string::npos;
}

std::string FormatServerSentEvent(const JobEvent& event) {
  // JSON has no raw newlines, so the data fits one "data:" line.
  return "id: " + std::to_string(event.id) + "\ndata: " + Dump(EventToJson(event)) + "\n\n";
}

Response MakeEventStream(ApiServices* services, std::string job_id, std::int64_t after) {
  // Unknown jobs get a plain 404 before the stream starts.
  Result<Job> job = services->store->GetJob(job_id);
  if (!job.ok()) return ResponseFromStatus(job.status(), services->retry_after_seconds);
  auto stream = std::make_shared<EventStream>(services, std::move(job_id), after);
  Response response = Response::Stream([stream] { return stream->Next(); }, kEventPollInterval,
                                       "text/event-stream; charset=utf-8");
  response.SetHeader("Cache-Control", "no-store");
  // Tells reverse proxies (nginx) not to buffer the stream.
  response.SetHeader("X-Accel-Buffering", "no");
  return response;
}

}  // namespace reconduit::server
