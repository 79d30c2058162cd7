// Where the server and the workers keep a job's files in the shared data folder.
//
//   <data>/reconduit.db                  the SQLite job store (WAL files beside it)
//   <data>/jobs/<id>/input/<stored>      uploaded photos under generated names (0001.jpg ...);
//                                        the uploaded names live only in the images table
//   <data>/jobs/<id>/work/<stage>/       each pipeline stage's outputs and stage.json marker
//   <data>/jobs/<id>/output/             the deliverables, laid out exactly as in result.zip
//   <data>/jobs/<id>/result.zip          written as result.zip.tmp, fsynced, then renamed
//   <data>/tmp/                          uploads in progress; anything here at server start
//                                        is an orphan of a crash and is removed
//
// The server writes input/ (and fsyncs it) before it inserts the job row; the worker writes
// work/, output/ and result.zip; deleting a job removes <data>/jobs/<id>/ whole.
#ifndef RECONDUIT_STORE_DATA_LAYOUT_H_
#define RECONDUIT_STORE_DATA_LAYOUT_H_

#include <filesystem>
#include <string_view>

namespace reconduit {

class DataLayout {
 public:
  explicit DataLayout(std::filesystem::path root) : root_(std::move(root)) {}

  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path DatabasePath() const { return root_ / "reconduit.db"; }
  std::filesystem::path TempDir() const { return root_ / "tmp"; }
  std::filesystem::path JobsDir() const { return root_ / "jobs"; }
  // `job_id` must be a valid id (IsValidJobId): it becomes a folder name.
  std::filesystem::path JobDir(std::string_view job_id) const { return JobsDir() / job_id; }
  std::filesystem::path InputDir(std::string_view job_id) const { return JobDir(job_id) / "input"; }
  std::filesystem::path WorkDir(std::string_view job_id) const { return JobDir(job_id) / "work"; }
  std::filesystem::path OutputDir(std::string_view job_id) const {
    return JobDir(job_id) / "output";
  }
  std::filesystem::path ResultZip(std::string_view job_id) const {
    return JobDir(job_id) / "result.zip";
  }

 private:
  std::filesystem::path root_;
};

}  // namespace reconduit

#endif  // RECONDUIT_STORE_DATA_LAYOUT_H_
