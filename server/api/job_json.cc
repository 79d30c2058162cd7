#include "server/api/job_json.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>

namespace reconduit::server {
namespace {

nlohmann::json OptionalTime(const std::optional<std::int64_t>& ms) {
  return ms ? nlohmann::json(FormatTimestamp(*ms)) : nlohmann::json(nullptr);
}

double Seconds(std::int64_t ms) { return static_cast<double>(ms) / 1000.0; }

}  // namespace

std::optional<double> EstimateEtaSeconds(double progress, double elapsed_seconds) {
  if (!(progress > 0.0) || progress > 1.0 || !(elapsed_seconds >= 0.0)) return std::nullopt;
  if (progress >= 1.0) return 0.0;
  if (progress < 0.01 || elapsed_seconds < 1.0) return std::nullopt;
  return elapsed_seconds * (1.0 - progress) / progress;
}

std::string FormatTimestamp(std::int64_t epoch_ms) {
  std::int64_t seconds = epoch_ms / 1000;
  std::int64_t millis = epoch_ms % 1000;
  if (millis < 0) {
    millis += 1000;
    seconds -= 1;
  }
  const std::time_t time = static_cast<std::time_t>(seconds);
  std::tm utc{};
  gmtime_r(&time, &utc);
  char buffer[96];
  std::snprintf(buffer, sizeof(buffer), "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", utc.tm_year + 1900,
                utc.tm_mon + 1, utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec,
                static_cast<int>(millis));
  return buffer;
}

std::string JobPath(std::string_view id) { return "/api/v1/jobs/" + std::string(id); }

nlohmann::json JobLinks(std::string_view id) {
  const std::string self = JobPath(id);
  return {{"self", self},
          {"events", self + "/events"},
          {"result", self + "/result.zip"},
          {"files", self + "/files"},
          {"cancel", self + "/cancel"},
          {"restart", self + "/restart"}};
}

nlohmann::json JobToJson(const Job& job, std::int64_t now_ms) {
  nlohmann::json json;
  json["id"] = job.id;
  json["state"] = std::string(JobStateName(job.state));
  json["stage"] = job.stage.empty() ? nlohmann::json(nullptr) : nlohmann::json(job.stage);
  json["progress"] = job.progress;
  json["stages"] = job.stage_progress.is_object() ? job.stage_progress : nlohmann::json::object();
  json["finished_stages"] = job.finished_stages;
  json["created_at"] = FormatTimestamp(job.created_at_ms);
  json["queued_at"] = FormatTimestamp(job.queued_at_ms);
  json["started_at"] = OptionalTime(job.started_at_ms);
  json["finished_at"] = OptionalTime(job.finished_at_ms);
  json["updated_at"] = FormatTimestamp(job.updated_at_ms);

  std::optional<double> elapsed;
  std::optional<double> eta;
  if (job.started_at_ms) {
    if (job.state == JobState::kRunning) {
      elapsed = Seconds(std::max<std::int64_t>(0, now_ms - *job.started_at_ms));
      eta = EstimateEtaSeconds(job.progress, *elapsed);
    } else if (job.finished_at_ms && IsFinalState(job.state)) {
      elapsed = Seconds(std::max<std::int64_t>(0, *job.finished_at_ms - *job.started_at_ms));
    }
  }
  json["elapsed_seconds"] = elapsed ? nlohmann::json(*elapsed) : nlohmann::json(nullptr);
  json["eta_seconds"] = eta ? nlohmann::json(*eta) : nlohmann::json(nullptr);
  json["attempts"] = job.attempts;
  json["max_attempts"] = job.max_attempts;
  json["cancel_requested"] = job.cancel_requested;

  nlohmann::json counts = {{"images", job.image_count}};
  counts.update(job.counts.ToJson());
  json["counts"] = counts;

  if (job.state == JobState::kFailed || !job.error.empty()) {
    json["error"] = {{"message", job.error},
                     {"stage", job.error_stage.empty() ? nlohmann::json(nullptr)
                                                       : nlohmann::json(job.error_stage)}};
  } else {
    json["error"] = nullptr;
  }
  json["options"] = job.options.is_object() ? job.options : nlohmann::json::object();
  if (job.state == JobState::kSucceeded && job.result_bytes) {
    json["result"] = {{"bytes", *job.result_bytes}, {"sha256", job.result_sha256}};
  } else {
    json["result"] = nullptr;
  }
  json["links"] = JobLinks(job.id);
  return json;
}

nlohmann::json ImagesToJson(const std::vector<JobImageRecord>& images) {
  int accepted = 0;
  int rejected = 0;
  nlohmann::json items = nlohmann::json::array();
  for (const JobImageRecord& image : images) {
    const PhotoMetadata& photo = image.photo;
    nlohmann::json item = {{"index", image.index},
                           {"name", image.original_name},
                           {"stored_name", image.stored_name},
                           {"status", std::string(ImageStatusName(photo.accepted))},
                           {"bytes", photo.bytes}};
    if (photo.width > 0 && photo.height > 0) {
      item["width"] = photo.width;
      item["height"] = photo.height;
    }
    if (photo.exif_focal_px) item["exif_focal_px"] = *photo.exif_focal_px;
    if (!photo.make.empty()) item["make"] = photo.make;
    if (!photo.model.empty()) item["model"] = photo.model;
    if (!photo.accepted) {
      item["reason"] = photo.reason;
      ++rejected;
    } else {
      ++accepted;
    }
    items.push_back(std::move(item));
  }
  return {{"accepted", accepted}, {"rejected", rejected}, {"items", std::move(items)}};
}

nlohmann::json EventToJson(const JobEvent& event) {
  return {{"id", event.id},
          {"time", FormatTimestamp(event.time_ms)},
          {"stage", event.stage.empty() ? nlohmann::json(nullptr) : nlohmann::json(event.stage)},
          {"level", std::string(EventLevelName(event.level))},
          {"message", event.message},
          {"progress", event.progress ? nlohmann::json(*event.progress) : nlohmann::json(nullptr)}};
}

std::int64_t NowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace reconduit::server
