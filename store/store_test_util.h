// Helpers shared by the storage tests (header-only; not part of reconduit_store).
#ifndef RECONDUIT_STORE_STORAGE_TEST_UTIL_H_
#define RECONDUIT_STORE_STORAGE_TEST_UTIL_H_

#include <gtest/gtest.h>

#include "store/job_store.h"
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdlib.h>
#include <string>
#include <vector>

namespace reconduit {
namespace testing_util {

// A fresh directory under the system temp folder, removed with everything in it on destruction.
class TempDir {
 public:
  TempDir() {
    std::string pattern =
        (std::filesystem::temp_directory_path() / "reconduit-storage-XXXXXX").string();
    std::vector<char> buffer(pattern.begin(), pattern.end());
    buffer.push_back('\0');
    if (mkdtemp(buffer.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = buffer.data();
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  const std::filesystem::path& path() const { return path_; }
  std::string File(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

// A clock the test moves by hand; shared with the store through SqliteJobStoreOptions::now_ms.
class FakeClock {
 public:
  explicit FakeClock(std::int64_t start_ms = 1'700'000'000'000) : now_ms_(start_ms) {}
  std::int64_t Now() const { return now_ms_.load(); }
  void Advance(std::int64_t ms) { now_ms_ += ms; }
  std::function<std::int64_t()> AsFunction() {
    return [this] { return now_ms_.load(); };
  }

 private:
  std::atomic<std::int64_t> now_ms_;
};

// A job with `accepted` accepted photos named 0000.jpg, 0001.jpg, ...
inline NewJob MakeNewJob(int accepted = 2, int max_attempts = 3) {
  NewJob job;
  job.options = {{"quality", "fast"}};
  job.max_attempts = max_attempts;
  for (int i = 0; i < accepted; ++i) {
    JobImageRecord image;
    image.index = i;
    image.original_name = "IMG_" + std::to_string(i) + ".JPG";
    char stored[16];
    std::snprintf(stored, sizeof(stored), "%04d.jpg", i);
    image.stored_name = stored;
    image.photo.bytes = 1000 + i;
    image.photo.width = 640;
    image.photo.height = 480;
    job.images.push_back(image);
  }
  return job;
}

// Opens a store or fails the test.
inline std::unique_ptr<JobStore> OpenOrDie(const std::string& path,
                                           const SqliteJobStoreOptions& options = {}) {
  Result<std::unique_ptr<JobStore>> store = OpenSqliteJobStore(path, options);
  if (!store.ok()) throw std::runtime_error(store.status().ToString());
  return std::move(store).value();
}

}  // namespace testing_util
}  // namespace reconduit

#endif  // RECONDUIT_STORE_STORAGE_TEST_UTIL_H_
