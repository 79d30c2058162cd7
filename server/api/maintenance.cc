#include "server/api/maintenance.h"

#include "core/util/logging.h"

#include <filesystem>
#include <system_error>

namespace reconduit::server {

namespace fs = std::filesystem;

Result<StartupReport> PrepareDataFolder(const DataLayout& layout, JobStore* store) {
  StartupReport report;
  std::error_code ec;
  for (const fs::path& folder : {layout.JobsDir(), layout.TempDir()}) {
    fs::create_directories(folder, ec);
    if (ec) return Status::Internal("cannot create " + folder.string() + ": " + ec.message());
  }

  for (fs::directory_iterator it(layout.TempDir(), ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code remove_error;
    const std::uintmax_t removed = fs::remove_all(it->path(), remove_error);
    if (remove_error) {
      LOG_WARNING << "cannot remove the orphaned upload " << it->path() << ": "
                  << remove_error.message();
      continue;
    }
    ++report.removed_temp_entries;
    LOG_INFO << "removed the orphaned upload " << it->path() << " (" << removed
             << " files and folders) left by an earlier run";
  }
  if (ec) return Status::Internal("cannot list " + layout.TempDir().string() + ": " + ec.message());

  for (fs::directory_iterator it(layout.JobsDir(), ec), end; !ec && it != end; it.increment(ec)) {
    const std::string id = it->path().filename().string();
    if (!IsValidJobId(id)) continue;  // Not ours: leave it alone.
    Result<Job> job = store->GetJob(id);
    if (job.ok()) continue;
    if (job.status().code() != StatusCode::kNotFound) return job.status();
    std::error_code remove_error;
    fs::remove_all(it->path(), remove_error);
    if (remove_error) {
      LOG_WARNING << "cannot remove the orphaned job folder " << it->path() << ": "
                  << remove_error.message();
      continue;
    }
    ++report.removed_orphan_jobs;
    LOG_INFO << "removed the job folder " << it->path() << ": no job row refers to it";
  }
  if (ec) return Status::Internal("cannot list " + layout.JobsDir().string() + ": " + ec.message());

  Result<SweepResult> sweep = store->SweepExpiredLeases();
  if (!sweep.ok()) return sweep.status();
  report.sweep = *sweep;
  if (sweep->requeued + sweep->failed + sweep->canceled > 0) {
    LOG_INFO << "expired leases: " << sweep->requeued << " job(s) requeued, " << sweep->failed
             << " failed, " << sweep->canceled << " canceled";
  }
  return report;
}

LeaseSweeper::LeaseSweeper(JobStore* store, std::chrono::milliseconds interval)
    : store_(store), interval_(interval), thread_([this] { Loop(); }) {}

LeaseSweeper::~LeaseSweeper() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void LeaseSweeper::Loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (!wake_.wait_for(lock, interval_, [this] { return stop_; })) {
    lock.unlock();
    Result<SweepResult> sweep = store_->SweepExpiredLeases();
    if (!sweep.ok()) {
      LOG_WARNING << "lease sweep failed: " << sweep.status();
    } else if (sweep->requeued + sweep->failed + sweep->canceled > 0) {
      LOG_INFO << "expired leases: " << sweep->requeued << " job(s) requeued, " << sweep->failed
               << " failed, " << sweep->canceled << " canceled";
    }
    lock.lock();
  }
}

}  // namespace reconduit::server
