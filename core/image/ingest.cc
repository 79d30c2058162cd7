#include "core/image/ingest.h"

#include "core/util/logging.h"
#include "core/util/parallel.h"
#include "core/util/timer.h"

#include <algorithm>
#include <system_error>

namespace reconduit {

bool IngestOptions::Check(std::string* error) const {
  if (!reader.Check(error)) return false;
  if (num_threads < 0) {
    if (error != nullptr) {
      *error = "IngestOptions: num_threads = " + std::to_string(num_threads) +
               "; it must be 0 (all cores) or positive";
    }
    return false;
  }
  return true;
}

Result<std::vector<std::filesystem::path>> ListImageFiles(const std::filesystem::path& directory) {
  std::error_code error;
  std::filesystem::directory_iterator it(directory, error);
  if (error) {
    return Status::NotFound("cannot list " + directory.string() + " (" + error.message() + ")");
  }
  std::vector<std::filesystem::path> files;
  for (const std::filesystem::directory_entry& entry : it) {
    const std::string name = entry.path().filename().string();
    if (name.empty() || name.front() == '.') continue;
    std::error_code type_error;
    if (!entry.is_regular_file(type_error)) continue;
    files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end(), [](const auto& a, const auto& b) {
    return a.filename().string() < b.filename().string();
  });
  return files;
}

IngestReport IngestImages(const std::vector<std::filesystem::path>& files,
                          const IngestOptions& options,
                          Progress& progress,
                          const CancelToken& cancel) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  const Timer timer;
  IngestReport report;
  report.images.resize(files.size());
  progress.Restart(files.size(), "Inspecting photos");
  ParallelFor(
      0, files.size(),
      [&](std::size_t i) {
        cancel.ThrowIfCanceled();
        report.images[i] = InspectImage(files[i], options.reader);
        progress.Advance();
      },
      options.num_threads);
  progress.Finish();

  for (const ImageRecord& record : report.images) {
    if (record.accepted()) {
      ++report.num_accepted;
    } else {
      ++report.num_rejected;
      LOG_DEBUG << "ingest: rejected " << record.status.message();
    }
  }
  report.elapsed_seconds = timer.ElapsedSeconds();
  LOG_INFO << "ingest: " << report.num_accepted << " of " << files.size() << " photos accepted, "
           << report.num_rejected << " rejected, in " << report.elapsed_seconds << " s";
  return report;
}

Result<IngestReport> IngestDirectory(const std::filesystem::path& directory,
                                     const IngestOptions& options,
                                     Progress& progress,
                                     const CancelToken& cancel) {
  Result<std::vector<std::filesystem::path>> files = ListImageFiles(directory);
  if (!files.ok()) return files.status();
  return IngestImages(*files, options, progress, cancel);
}

}  // namespace reconduit
