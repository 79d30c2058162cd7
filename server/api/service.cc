// GET /api/v1/options (the pipeline options table and the server's upload limits) and
// GET /metrics (Prometheus text exposition format 0.0.4).
#include "core/options/pipeline_options.h"
#include "core/util/logging.h"
#include "server/api/api.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>
#include <string>

namespace reconduit::server {
namespace {

// Stage durations are summarised over this many most recently created succeeded jobs.
constexpr int kStageDurationJobs = 100;

std::string EscapeLabel(std::string_view value) {
  std::string escaped;
  for (const char c : value) {
    if (c == '\\' || c == '"') escaped += '\\';
    if (c == '\n') {
      escaped += "\\n";
      continue;
    }
    escaped += c;
  }
  return escaped;
}

class MetricsWriter {
 public:
  void Family(std::string_view name, std::string_view type, std::string_view help) {
    out_ << "# HELP " << name << " " << help << "\n# TYPE " << name << " " << type << "\n";
  }
  template <class Value>
  void Sample(std::string_view name, Value value, std::string_view labels = {}) {
    out_ << name;
    if (!labels.empty()) out_ << "{" << labels << "}";
    out_ << " " << value << "\n";
  }
  std::string str() const { return out_.str(); }

 private:
  std::ostringstream out_;
};

Response Metrics(ApiServices* services) {
  MetricsWriter metrics;
  Result<QueueStats> stats = services->store->GetQueueStats();
  if (!stats.ok()) return ResponseFromStatus(stats.status(), services->retry_after_seconds);

  metrics.Family("reconduit_jobs", "gauge", "Jobs in the store by state.");
  for (int state = 0; state < kNumJobStates; ++state) {
    metrics.Sample("reconduit_jobs", stats->jobs_by_state[state],
                   "state=\"" + std::string(JobStateName(static_cast<JobState>(state))) + "\"");
  }
  metrics.Family("reconduit_queue_length", "gauge", "Jobs waiting for a worker.");
  metrics.Sample("reconduit_queue_length", stats->QueueLength());
  metrics.Family("reconduit_queue_oldest_age_seconds", "gauge",
                 "How long the oldest queued job has waited (0 when none waits).");
  const std::int64_t now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                                  std::chrono::system_clock::now().time_since_epoch())
                                  .count();
  const double oldest =
      stats->oldest_queued_at_ms
          ? std::max<double>(0.0, static_cast<double>(now_ms - *stats->oldest_queued_at_ms) / 1e3)
          : 0.0;
  metrics.Sample("reconduit_queue_oldest_age_seconds", oldest);

  const UploadCounters& uploads = services->uploads;
  metrics.Family("reconduit_upload_bytes_total", "counter",
                 "Request body bytes received by POST /api/v1/jobs.");
  metrics.Sample("reconduit_upload_bytes_total", uploads.bytes_total.load());
  metrics.Family("reconduit_uploads_total", "counter",
                 "Uploads by outcome: accepted (a job was created) or refused (refused, aborted "
                 "or failed).");
  metrics.Sample("reconduit_uploads_total", uploads.accepted_total.load(), "result=\"accepted\"");
  metrics.Sample("reconduit_uploads_total", uploads.refused_total.load(), "result=\"refused\"");
  metrics.Family("reconduit_uploads_in_progress", "gauge", "Uploads being received now.");
  metrics.Sample("reconduit_uploads_in_progress", uploads.in_progress.load());

  if (services->http_metrics != nullptr) {
    metrics.Family("reconduit_http_requests_total", "counter",
                   "HTTP responses sent, by status code.");
    for (const auto& [status, count] : services->http_metrics->ResponsesByStatus()) {
      metrics.Sample("reconduit_http_requests_total", count,
                     "code=\"" + std::to_string(status) + "\"");
    }
  }

  // Stage durations as recorded by the workers (stage_progress.<stage>.seconds).
  JobListQuery query;
  query.limit = kStageDurationJobs;
  query.state = JobState::kSucceeded;
  Result<JobPage> page = services->store->ListJobs(query);
  if (page.ok()) {
    struct Summary {
      double sum = 0.0;
      double max = 0.0;
      int count = 0;
    };
    std::map<std::string, Summary> stages;
    for (const Job& job : page->jobs) {
      if (!job.stage_progress.is_object()) continue;
      for (const auto& [stage, progress] : job.stage_progress.items()) {
        if (!progress.is_object() || !progress.contains("seconds") ||
            !progress["seconds"].is_number()) {
          continue;
        }
        const double seconds = progress["seconds"].get<double>();
        if (!std::isfinite(seconds) || seconds < 0.0) continue;
        Summary& summary = stages[stage];
        summary.sum += seconds;
        summary.max = std::max(summary.max, seconds);
        ++summary.count;
      }
    }
    metrics.Family("reconduit_stage_seconds_mean", "gauge",
                   "Mean duration of each pipeline stage over the last 100 succeeded jobs.");
    for (const auto& [stage, summary] : stages) {
      metrics.Sample("reconduit_stage_seconds_mean", summary.sum / summary.count,
                     "stage=\"" + EscapeLabel(stage) + "\"");
    }
    metrics.Family("reconduit_stage_seconds_max", "gauge",
                   "Longest duration of each pipeline stage over the last 100 succeeded jobs.");
    for (const auto& [stage, summary] : stages) {
      metrics.Sample("reconduit_stage_seconds_max", summary.max,
                     "stage=\"" + EscapeLabel(stage) + "\"");
    }
  } else {
    LOG_WARNING << "metrics: cannot list succeeded jobs: " << page.status();
  }

  Response response =
      Response::Text(metrics.str(), HttpStatus::ok, "text/plain; version=0.0.4; charset=utf-8");
  response.SetHeader("Cache-Control", "no-store");
  return response;
}

Response Options(ApiServices* services) {
  nlohmann::json body = DescribePipelineOptions();
  const UploadLimits& limits = services->limits;
  body["limits"] = {{"max_upload_bytes", limits.max_upload_bytes},
                    {"max_photos", limits.max_photos},
                    {"max_pixels", limits.max_pixels},
                    {"max_photo_bytes", limits.max_photo_bytes},
                    {"max_concurrent_uploads", limits.max_concurrent_uploads},
                    {"max_queued_jobs", limits.max_queued_jobs},
                    {"formats", {"JPEG", "PNG", "TIFF"}}};
  return Response::Json(body);
}

}  // namespace

void AddServiceRoutes(Router* router, ApiServices* services) {
  router->Add(HttpVerb::get, "/api/v1/options",
              [services](RequestContext&) { return Options(services); });
  router->Add(HttpVerb::get, "/metrics", [services](RequestContext&) { return Metrics(services); });
}

}  // namespace reconduit::server
