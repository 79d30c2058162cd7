// The JSON shapes of the job API: jobs, photos, events, and the ETA estimate.
//
// Times are ISO 8601 UTC strings with milliseconds ("2025-01-31T12:00:00.123Z"); durations are
// seconds. Field names are snake_case, like the store's and the pipeline options'.
#ifndef RECONDUIT_SERVER_API_JOB_JSON_H_
#define RECONDUIT_SERVER_API_JOB_JSON_H_

#include <nlohmann/json.hpp>

#include "store/job_store.h"
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit::server {

// Seconds left for a job that has made `progress` (0-1) in `elapsed_seconds` of its current
// run, assuming the rate so far holds: elapsed * (1 - progress) / progress. nullopt until the
// estimate means something (progress below 1 %, less than a second elapsed) and for progress
// outside (0, 1). 0 when progress is 1.
std::optional<double> EstimateEtaSeconds(double progress, double elapsed_seconds);

// "2025-01-31T12:00:00.123Z" for Unix epoch milliseconds.
std::string FormatTimestamp(std::int64_t epoch_ms);

// "/api/v1/jobs/<id>" and the links of a job: self, events, result, files, cancel, restart.
std::string JobPath(std::string_view id);
nlohmann::json JobLinks(std::string_view id);

// A job as served by GET /api/v1/jobs/{id} and the list, without the photo list:
//   id, state, stage, progress, stages (per-stage progress and seconds), finished_stages,
//   created_at, queued_at, started_at, finished_at, updated_at, elapsed_seconds, eta_seconds,
//   attempts, max_attempts, cancel_requested, counts, error {message, stage} or null,
//   options, result {bytes, sha256} or null, links.
// `now_ms` is the current time, for the elapsed time and the ETA of a running job.
nlohmann::json JobToJson(const Job& job, std::int64_t now_ms);

// The photos of a job: {"accepted": n, "rejected": m, "items": [{index, name, stored_name,
// status, bytes, width, height, exif_focal_px, make, model, reason}]} (absent fields omitted).
nlohmann::json ImagesToJson(const std::vector<JobImageRecord>& images);

// One event: {id, time, stage, level, message, progress}.
nlohmann::json EventToJson(const JobEvent& event);

// Milliseconds since the Unix epoch, from the system clock.
std::int64_t NowMs();

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_JOB_JSON_H_
