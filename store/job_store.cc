#include "store/job_store.h"

#include <cstdint>
#include <optional>
#include <random>

namespace reconduit {

std::string_view JobStateName(JobState state) {
  switch (state) {
    case JobState::kQueued:
      return "queued";
    case JobState::kRunning:
      return "running";
    case JobState::kSucceeded:
      return "succeeded";
    case JobState::kFailed:
      return "failed";
    case JobState::kCanceled:
      return "canceled";
  }
  return "unknown";
}

std::optional<JobState> ParseJobState(std::string_view name) {
  for (int i = 0; i < kNumJobStates; ++i) {
    const auto state = static_cast<JobState>(i);
    if (JobStateName(state) == name) return state;
  }
  return std::nullopt;
}

bool IsFinalState(JobState state) {
  return state == JobState::kSucceeded || state == JobState::kFailed ||
         state == JobState::kCanceled;
}

std::string NewJobId() {
  // A fresh random_device per call: it is cheap (reads the kernel's CSPRNG) and keeps the
  // function thread-safe without a lock. 4 x 32 bits = 128 bits.
  std::random_device device;
  static constexpr char kHex[] = "0123456789abcdef";
  std::string id;
  id.reserve(32);
  for (int word = 0; word < 4; ++word) {
    const std::uint32_t bits = device();
    for (int shift = 28; shift >= 0; shift -= 4) id.push_back(kHex[(bits >> shift) & 0xf]);
  }
  return id;
}

bool IsValidJobId(std::string_view id) {
  if (id.size() != 32) return false;
  for (const char c : id) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  }
  return true;
}

std::string_view ImageStatusName(bool accepted) { return accepted ? "accepted" : "rejected"; }

std::string_view EventLevelName(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return "debug";
    case LogLevel::kInfo:
      return "info";
    case LogLevel::kWarning:
      return "warning";
    case LogLevel::kError:
      return "error";
  }
  return "info";
}

namespace {

// JobCounts' fields and their names in JSON (the API's names).
struct CountField {
  const char* name;
  std::optional<std::int64_t> JobCounts::*field;
};
constexpr CountField kCountFields[] = {
    {"images", &JobCounts::images},
    {"rejected_images", &JobCounts::rejected_images},
    {"features", &JobCounts::features},
    {"candidate_pairs", &JobCounts::candidate_pairs},
    {"matched_pairs", &JobCounts::matched_pairs},
    {"inlier_matches", &JobCounts::inlier_matches},
    {"registered", &JobCounts::registered},
    {"points", &JobCounts::points},
    {"faces", &JobCounts::faces},
    {"models", &JobCounts::models},
    {"result_files", &JobCounts::result_files},
};

}  // namespace

bool JobCounts::empty() const { return *this == JobCounts(); }

void JobCounts::Merge(const JobCounts& patch) {
  for (const CountField& f : kCountFields) {
    if (patch.*f.field) this->*f.field = patch.*f.field;
  }
}

nlohmann::json JobCounts::ToJson() const {
  nlohmann::json json = nlohmann::json::object();
  for (const CountField& f : kCountFields) {
    if (this->*f.field) json[f.name] = *(this->*f.field);
  }
  return json;
}

JobCounts JobCounts::FromJson(const nlohmann::json& json) {
  JobCounts counts;
  if (!json.is_object()) return counts;
  for (const CountField& f : kCountFields) {
    const auto it = json.find(f.name);
    if (it != json.end() && it->is_number_integer()) counts.*f.field = it->get<std::int64_t>();
  }
  return counts;
}

}  // namespace reconduit
