// Data-folder housekeeping of reconduit-server: what runs at start-up, and the periodic lease
// sweep.
//
// At start-up (PrepareDataFolder), with the store open:
//   1. <data>/jobs and <data>/tmp are created if missing;
//   2. everything in <data>/tmp is removed: uploads in progress when the previous server died
//      (kill -9, power cut); each removal is logged;
//   3. job folders in <data>/jobs without a job row are removed: a crash between moving an
//      upload into place and inserting its row, or between deleting a row and its folder;
//   4. expired leases are swept (JobStore::SweepExpiredLeases), so status pages are right even
//      before a worker claims again.
// Steps 2 and 3 assume one server per data folder (workers never write tmp/ or create job
// folders).
#ifndef RECONDUIT_SERVER_API_MAINTENANCE_H_
#define RECONDUIT_SERVER_API_MAINTENANCE_H_

#include "store/data_layout.h"
#include "store/job_store.h"
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>

namespace reconduit::server {

struct StartupReport {
  // Entries removed from <data>/tmp.
  int removed_temp_entries = 0;
  // Job folders removed because no job row refers to them.
  int removed_orphan_jobs = 0;
  SweepResult sweep;
};

// Runs the start-up steps above. kInternal when a folder cannot be created or the store fails;
// a single entry that cannot be removed is logged and skipped.
Result<StartupReport> PrepareDataFolder(const DataLayout& layout, JobStore* store);

// Calls store->SweepExpiredLeases() every `interval` on its own thread until destroyed.
class LeaseSweeper {
 public:
  LeaseSweeper(JobStore* store, std::chrono::milliseconds interval);
  ~LeaseSweeper();
  LeaseSweeper(const LeaseSweeper&) = delete;
  LeaseSweeper& operator=(const LeaseSweeper&) = delete;

 private:
  void Loop();

  JobStore* store_;
  const std::chrono::milliseconds interval_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_MAINTENANCE_H_
