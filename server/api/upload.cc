#include "server/api/upload.h"

#include "core/image/image_format.h"
#include "core/io/file_util.h"
#include "core/options/pipeline_options.h"
#include "core/util/logging.h"
#include "server/api/job_json.h"
#include "server/api/photo_check.h"
#include "server/api/safe_names.h"
#include "server/api/zip_reader.h"
#include "server/http/multipart.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <system_error>
#include <unistd.h>
#include <utility>
#include <vector>

namespace reconduit::server {
namespace {

namespace fs = std::filesystem;

// Holds one of the max_concurrent_uploads places for as long as it lives.
class UploadSlot {
 public:
  // Takes a place, or returns nullopt when all are taken.
  static std::optional<UploadSlot> TryAcquire(ApiServices* services) {
    std::atomic<int>& in_progress = services->uploads.in_progress;
    int current = in_progress.load();
    do {
      if (current >= services->limits.max_concurrent_uploads) return std::nullopt;
    } while (!in_progress.compare_exchange_weak(current, current + 1));
    return UploadSlot(services);
  }
  UploadSlot(UploadSlot&& other) noexcept : services_(std::exchange(other.services_, nullptr)) {}
  UploadSlot& operator=(UploadSlot&&) = delete;
  ~UploadSlot() {
    if (services_ != nullptr) services_->uploads.in_progress.fetch_sub(1);
  }

 private:
  explicit UploadSlot(ApiServices* services) : services_(services) {}
  ApiServices* services_;
};

Response Refuse(HttpStatus status, std::string_view message, std::string_view code = {}) {
  return ErrorResponse(status, message, code);
}

// An I/O failure while storing an upload: a full disk, a quota or a file size limit is the
// server's capacity (503, retry), anything else is internal (logged, 500).
Response StorageFailure(const ApiServices& services, std::string_view what, int error) {
  if (error == ENOSPC || error == EDQUOT || error == EFBIG) {
    LOG_WARNING << "upload refused: " << what << ": " << std::strerror(error);
    return RetryLaterResponse(HttpStatus::service_unavailable,
                              "the server is out of disk space; retry later",
                              services.retry_after_seconds);
  }
  LOG_ERROR << "upload failed: " << what << ": " << std::strerror(error);
  return ErrorResponse(HttpStatus::internal_server_error, "cannot store the upload");
}

// Writes all of `data` to `fd`; returns 0 or the errno.
int WriteAll(int fd, std::string_view data) {
  while (!data.empty()) {
    const ssize_t n = ::write(fd, data.data(), data.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    data.remove_prefix(static_cast<std::size_t>(n));
  }
  return 0;
}

// Parses and validates pipeline options text; the 400 names the field.
Result<nlohmann::json> ParseOptions(std::string_view text, std::string_view source) {
  nlohmann::json json = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (json.is_discarded()) {
    return Status::InvalidArgument(std::string(source) + " is not valid JSON");
  }
  if (!json.is_object()) {
    return Status::InvalidArgument(std::string(source) + " must be a JSON object");
  }
  Result<PipelineOptions> options = ParsePipelineOptions(json);
  if (!options.ok()) {
    return Status::InvalidArgument(std::string(source) + ": " + options.status().message());
  }
  return json;
}

// The photos of one upload in <data>/tmp/<upload-id>/input/, and what turns them into a job.
// Removes the temporary folder when destroyed, whatever happened.
class UploadSession {
 public:
  UploadSession(ApiServices* services, fs::path temp_dir, std::string upload_id)
      : services_(services),
        temp_dir_(std::move(temp_dir)),
        input_dir_(temp_dir_ / "input"),
        upload_id_(std::move(upload_id)) {}
  UploadSession(const UploadSession&) = delete;
  UploadSession& operator=(const UploadSession&) = delete;

  ~UploadSession() {
    ClosePhoto();
    std::error_code ec;
    fs::remove_all(temp_dir_, ec);
    if (ec) {
      LOG_WARNING << "cannot remove " << temp_dir_ << ": " << ec.message();
    }
    if (!committed_) services_->uploads.refused_total.fetch_add(1);
  }

  const fs::path& temp_dir() const { return temp_dir_; }
  const std::string& upload_id() const { return upload_id_; }

  std::optional<Response> SetOptions(nlohmann::json options) {
    if (options_) {
      return Refuse(HttpStatus::bad_request,
                    "options given twice (an `options` part and the `options` query parameter, "
                    "or two parts); send them once");
    }
    options_ = std::move(options);
    return std::nullopt;
  }

  // Names of archive entries that were skipped (Thumbs.db, nested zips...), listed in the
  // answer as display names.
  void SetSkipped(const std::vector<std::string>& names) {
    skipped_.clear();
    for (const std::string& name : names) skipped_.push_back(SanitizeDisplayName(name, "entry"));
  }

  // Starts the next photo; `client_name` is display-only.
  std::optional<Response> BeginPhoto(std::string_view client_name) {
    if (static_cast<int>(photos_.size()) >= services_->limits.max_photos) {
      return Refuse(
          HttpStatus::payload_too_large,
          "too many photos: a job takes at most " + std::to_string(services_->limits.max_photos),
          "too_many_photos");
    }
    const int index = static_cast<int>(photos_.size());
    Photo photo;
    photo.display_name = SanitizeDisplayName(client_name, "photo-" + std::to_string(index + 1));
    photo.part_name = StoredPhotoName(index, "part");
    const fs::path path = input_dir_ / photo.part_name;
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd_ < 0) return StorageFailure(*services_, "create " + path.string(), errno);
    head_.clear();
    photos_.push_back(std::move(photo));
    return std::nullopt;
  }

  std::optional<Response> AppendPhoto(std::string_view data) {
    Photo& photo = photos_.back();
    photo.bytes += static_cast<std::int64_t>(data.size());
    if (photo.bytes > services_->limits.max_photo_bytes) {
      return Refuse(HttpStatus::payload_too_large,
                    QuoteForMessage(photo.display_name) + " is larger than " +
                        std::to_string(services_->limits.max_photo_bytes) +
                        " bytes, the limit per photo");
    }
    // The type is decided by the first bytes, as soon as they are here.
    const std::size_t magic = kImageFormatMagicBytes;
    if (photo.format == ImageFormat::kUnknown && head_.size() < magic) {
      head_.append(data.substr(0, magic - head_.size()));
      if (head_.size() >= magic) {
        if (std::optional<Response> refusal = DecideFormat(); refusal) return refusal;
      }
    }
    if (const int error = WriteAll(fd_, data); error != 0) {
      return StorageFailure(*services_, "write " + photo.part_name, error);
    }
    return std::nullopt;
  }

  // Ends the current photo: type check for short files, fsync, close.
  std::optional<Response> EndPhoto() {
    if (photos_.back().format == ImageFormat::kUnknown) {
      if (std::optional<Response> refusal = DecideFormat(); refusal) return refusal;
    }
    const int fd = std::exchange(fd_, -1);
    const int error = ::fsync(fd) == 0 ? 0 : errno;
    ::close(fd);
    if (error != 0) return StorageFailure(*services_, "fsync " + photos_.back().part_name, error);
    return std::nullopt;
  }

  // Inspects, stores and inserts the job. `options_query` is already in options_ if given.
  Response Commit() {
    if (photos_.empty()) {
      return Refuse(HttpStatus::bad_request,
                    "the upload contains no photos: send one or more `images` parts "
                    "(multipart/form-data) or a zip of photos");
    }
    nlohmann::json options_json = options_.value_or(nlohmann::json::object());
    // Validated when they arrived; parsed again for the values that apply at upload time.
    const Result<PipelineOptions> options = ParsePipelineOptions(options_json);
    if (!options.ok()) return ResponseFromStatus(options.status());

    PhotoCheckOptions check_options;
    check_options.min_side = options->min_image_side;
    check_options.max_pixels = std::min(options->max_image_pixels, services_->limits.max_pixels);
    check_options.max_file_bytes = services_->limits.max_photo_bytes;

    NewJob job;
    job.id = NewJobId();
    job.options = std::move(options_json);
    job.max_queued_jobs = services_->limits.max_queued_jobs;
    std::vector<std::string> reasons;
    std::int64_t total_bytes = 0;
    for (std::size_t i = 0; i < photos_.size(); ++i) {
      const Photo& photo = photos_[i];
      JobImageRecord record;
      record.index = static_cast<int>(i);
      record.original_name = photo.display_name;
      record.stored_name = StoredPhotoName(record.index, ImageFormatExtension(photo.format));
      std::error_code ec;
      fs::rename(input_dir_ / photo.part_name, input_dir_ / record.stored_name, ec);
      if (ec) return StorageFailure(*services_, "rename " + photo.part_name, ec.value());

      record.photo = CheckPhoto(input_dir_ / record.stored_name, check_options);
      // Equal to the file's size; counted here too for the few refusals that cannot open it.
      record.photo.bytes = photo.bytes;
      if (!record.photo.accepted) {
        reasons.push_back(photo.display_name + ": " + record.photo.reason);
      }
      total_bytes += photo.bytes;
      job.images.push_back(std::move(record));
    }
    if (reasons.size() == photos_.size()) {
      std::string message = "no usable photo in the upload:";
      for (const std::string& reason : reasons) message += " " + reason + ";";
      message.pop_back();
      return Refuse(HttpStatus::bad_request, message, "no_usable_photos");
    }

    // Durable before visible: the photos were fsynced as they were closed; now the folder,
    // then the move into jobs/, then the row.
    const DataLayout layout = services_->layout();
    const fs::path job_dir = layout.JobDir(job.id);
    if (Status status = SyncPath(input_dir_); !status.ok()) {
      LOG_ERROR << "upload " << upload_id_ << ": " << status.message();
      return ErrorResponse(HttpStatus::internal_server_error, "cannot store the upload");
    }
    std::error_code ec;
    fs::create_directories(job_dir, ec);
    if (ec) return StorageFailure(*services_, "create " + job_dir.string(), ec.value());
    fs::rename(input_dir_, layout.InputDir(job.id), ec);
    if (ec) {
      fs::remove_all(job_dir, ec);
      return StorageFailure(*services_, "move the photos into " + job_dir.string(), ec.value());
    }
    for (const fs::path& folder : {job_dir, layout.JobsDir()}) {
      if (Status status = SyncPath(folder); !status.ok()) {
        LOG_ERROR << "upload " << upload_id_ << ": " << status.message();
        fs::remove_all(job_dir, ec);
        return ErrorResponse(HttpStatus::internal_server_error, "cannot store the upload");
      }
    }

    Result<Job> created = services_->store->CreateJob(job);
    if (!created.ok()) {
      fs::remove_all(job_dir, ec);
      if (created.status().code() == StatusCode::kInternal) {
        LOG_ERROR << "upload " << upload_id_ << ": CreateJob: " << created.status().message();
      }
      return ResponseFromStatus(created.status(), services_->retry_after_seconds);
    }
    committed_ = true;
    services_->uploads.accepted_total.fetch_add(1);
    LOG_INFO << "upload " << upload_id_ << ": job " << created->id << " queued with "
             << (photos_.size() - reasons.size()) << " photo(s)"
             << (reasons.empty() ? "" : ", " + std::to_string(reasons.size()) + " rejected")
             << (skipped_.empty() ? "" : ", " + std::to_string(skipped_.size()) + " skipped")
             << ", " << total_bytes << " bytes";

    nlohmann::json body = JobToJson(*created, NowMs());
    body["images"] = ImagesToJson(job.images);
    if (!skipped_.empty()) body["skipped"] = skipped_;
    Response response = Response::Json(body, HttpStatus::created);
    response.SetHeader("Location", JobPath(created->id));
    return response;
  }

 private:
  struct Photo {
    std::string display_name;
    std::string part_name;  // "0001.part" while it arrives.
    ImageFormat format = ImageFormat::kUnknown;
    std::int64_t bytes = 0;
  };

  std::optional<Response> DecideFormat() {
    Photo& photo = photos_.back();
    photo.format = DetectImageFormat(std::span<const std::uint8_t>(
        reinterpret_cast<const std::uint8_t*>(head_.data()), head_.size()));
    if (photo.format != ImageFormat::kUnknown) return std::nullopt;
    return Refuse(HttpStatus::unsupported_media_type,
                  QuoteForMessage(photo.display_name) +
                      (photo.bytes == 0 ? " is empty" : " is not a JPEG, PNG or TIFF image") +
                      " (the type is read from the file's first bytes)");
  }

  void ClosePhoto() {
    if (fd_ >= 0) ::close(std::exchange(fd_, -1));
  }

  ApiServices* services_;
  const fs::path temp_dir_;
  const fs::path input_dir_;
  const std::string upload_id_;
  std::vector<Photo> photos_;
  std::optional<nlohmann::json> options_;
  std::vector<std::string> skipped_;
  int fd_ = -1;
  std::string head_;
  bool committed_ = false;
};

// Receives a multipart/form-data body.
class MultipartUploadSink : public BodySink {
 public:
  MultipartUploadSink(ApiServices* services,
                      UploadSlot slot,
                      std::unique_ptr<UploadSession> session,
                      std::string boundary)
      : services_(services),
        slot_(std::move(slot)),
        session_(std::move(session)),
        parser_(std::move(boundary),
                {.on_part_begin = [this](const MultipartPart& part) { return OnPartBegin(part); },
                 .on_part_data = [this](std::string_view data) { return OnPartData(data); },
                 .on_part_end = [this] { return OnPartEnd(); }}) {}

  std::optional<Response> OnData(std::string_view chunk) override {
    services_->uploads.bytes_total.fetch_add(chunk.size());
    const Status status = parser_.Feed(chunk);
    if (refusal_) return std::move(refusal_);
    if (!status.ok()) {
      return Refuse(HttpStatus::bad_request, status.message());
    }
    return std::nullopt;
  }

  Response OnComplete(RequestContext&) override {
    if (Status status = parser_.Finish(); !status.ok()) {
      return Refuse(HttpStatus::bad_request, status.message());
    }
    return session_->Commit();
  }

  void OnAbort(std::string_view reason) override {
    LOG_INFO << "upload " << session_->upload_id() << " abandoned: " << reason;
  }

 private:
  enum class Part { kNone, kPhoto, kOptions };

  // Stops the parser with `refusal` as the answer.
  Status Stop(Response refusal) {
    refusal_ = std::move(refusal);
    return Status::Canceled("upload refused");
  }

  Status OnPartBegin(const MultipartPart& part) {
    if (part.name == "images" || part.name == "images[]" || part.name == "image") {
      part_ = Part::kPhoto;
      if (auto refusal = session_->BeginPhoto(part.filename.value_or("")); refusal) {
        return Stop(std::move(*refusal));
      }
      return Status::Ok();
    }
    if (part.name == "options") {
      part_ = Part::kOptions;
      options_text_.clear();
      return Status::Ok();
    }
    return Stop(Refuse(HttpStatus::bad_request, "unexpected form field " +
                                                    QuoteForMessage(part.name) +
                                                    "; expected `images` parts and an "
                                                    "optional `options` part"));
  }

  Status OnPartData(std::string_view data) {
    if (part_ == Part::kOptions) {
      if (options_text_.size() + data.size() > kMaxOptionsBytes) {
        return Stop(Refuse(
            HttpStatus::bad_request,
            "the `options` part is larger than " + std::to_string(kMaxOptionsBytes) + " bytes"));
      }
      options_text_.append(data);
      return Status::Ok();
    }
    if (auto refusal = session_->AppendPhoto(data); refusal) return Stop(std::move(*refusal));
    return Status::Ok();
  }

  Status OnPartEnd() {
    std::optional<Response> refusal;
    if (part_ == Part::kOptions) {
      Result<nlohmann::json> options = ParseOptions(options_text_, "the `options` part");
      refusal =
          options.ok() ? session_->SetOptions(*options) : ResponseFromStatus(options.status());
    } else {
      refusal = session_->EndPhoto();
    }
    part_ = Part::kNone;
    if (refusal) return Stop(std::move(*refusal));
    return Status::Ok();
  }

  ApiServices* services_;
  UploadSlot slot_;
  std::unique_ptr<UploadSession> session_;
  MultipartParser parser_;
  Part part_ = Part::kNone;
  std::string options_text_;
  std::optional<Response> refusal_;
};

// Receives an application/zip body into upload.zip, then extracts its photos.
class ZipUploadSink : public BodySink {
 public:
  ZipUploadSink(ApiServices* services,
                UploadSlot slot,
                std::unique_ptr<UploadSession> session,
                int fd)
      : services_(services), slot_(std::move(slot)), session_(std::move(session)), fd_(fd) {}
  ~ZipUploadSink() override {
    if (fd_ >= 0) ::close(fd_);
  }

  std::optional<Response> OnData(std::string_view chunk) override {
    services_->uploads.bytes_total.fetch_add(chunk.size());
    if (const int error = WriteAll(fd_, chunk); error != 0) {
      return StorageFailure(*services_, "write upload.zip", error);
    }
    return std::nullopt;
  }

  Response OnComplete(RequestContext&) override {
    ::close(std::exchange(fd_, -1));
    ZipLimits limits;
    limits.max_photos = services_->limits.max_photos;
    limits.max_entry_bytes = static_cast<std::uint64_t>(services_->limits.max_photo_bytes);
    limits.max_total_bytes = services_->limits.max_upload_bytes;
    Result<std::unique_ptr<ZipPhotoArchive>> archive =
        ZipPhotoArchive::Open(session_->temp_dir() / "upload.zip", limits);
    if (!archive.ok()) return ZipRefusal(archive.status());
    if ((*archive)->photos().empty()) {
      return Refuse(HttpStatus::bad_request,
                    "the zip archive contains no photos" +
                        std::string((*archive)->skipped().empty() ? "" : " (only skipped files)"));
    }
    session_->SetSkipped((*archive)->skipped());
    for (const ZipPhotoEntry& entry : (*archive)->photos()) {
      if (auto refusal = session_->BeginPhoto(entry.name); refusal) return std::move(*refusal);
      std::optional<Response> refusal;
      const Status status = (*archive)->Extract(entry, [&](std::string_view data) {
        refusal = session_->AppendPhoto(data);
        return refusal ? Status::Canceled("refused") : Status::Ok();
      });
      if (refusal) return std::move(*refusal);
      if (!status.ok()) return ZipRefusal(status);
      if (auto end_refusal = session_->EndPhoto(); end_refusal) return std::move(*end_refusal);
    }
    std::error_code ec;
    fs::remove(session_->temp_dir() / "upload.zip", ec);
    return session_->Commit();
  }

  void OnAbort(std::string_view reason) override {
    LOG_INFO << "upload " << session_->upload_id() << " (zip) abandoned: " << reason;
  }

 private:
  // Limits (bombs) answer 413, everything else about the archive 400.
  static Response ZipRefusal(const Status& status) {
    if (status.code() == StatusCode::kResourceExhausted) {
      return Refuse(HttpStatus::payload_too_large, status.message(), "zip_too_large");
    }
    return Refuse(HttpStatus::bad_request, status.message(), "bad_zip");
  }

  ApiServices* services_;
  UploadSlot slot_;
  std::unique_ptr<UploadSession> session_;
  int fd_ = -1;
};

}  // namespace

StreamStart StartUpload(RequestContext& context, ApiServices* services) {
  // 1. What the body is.
  const std::string content_type = std::string(context.Header("Content-Type").value_or(""));
  Result<HeaderValue> type = ParseHeaderValue(content_type);
  const std::string media_type = type.ok() ? type->value : "";
  const bool is_zip =
      media_type == "application/zip" || media_type == "application/x-zip-compressed";
  std::string boundary;
  if (!is_zip) {
    Result<std::string> parsed = MultipartBoundary(content_type);
    if (!parsed.ok()) {
      return Refuse(
          HttpStatus::unsupported_media_type,
          "POST /api/v1/jobs takes multipart/form-data (`images` parts, optional "
          "`options`) or application/zip; got " +
              (content_type.empty() ? std::string("no Content-Type")
                                    : QuoteForMessage(content_type)) +
              (media_type == "multipart/form-data" ? ": " + parsed.status().message() : ""));
    }
    boundary = std::move(*parsed);
  }

  // 2. Options in the query string.
  std::optional<nlohmann::json> query_options;
  if (const std::optional<std::string_view> text = context.Query("options"); text) {
    if (text->size() > kMaxOptionsBytes) {
      return Refuse(HttpStatus::bad_request, "the `options` query parameter is too long");
    }
    Result<nlohmann::json> options = ParseOptions(*text, "the `options` query parameter");
    if (!options.ok()) return ResponseFromStatus(options.status());
    query_options = std::move(*options);
  }

  // 3. Capacity: the queue, then the uploads in progress.
  Result<QueueStats> stats = services->store->GetQueueStats();
  if (!stats.ok()) return ResponseFromStatus(stats.status(), services->retry_after_seconds);
  if (stats->QueueLength() >= services->limits.max_queued_jobs) {
    return RetryLaterResponse(HttpStatus::service_unavailable,
                              "the job queue is full (" + std::to_string(stats->QueueLength()) +
                                  " jobs waiting); retry later",
                              services->retry_after_seconds);
  }
  std::optional<UploadSlot> slot = UploadSlot::TryAcquire(services);
  if (!slot) {
    return RetryLaterResponse(HttpStatus::too_many_requests,
                              "too many uploads in progress (" +
                                  std::to_string(services->limits.max_concurrent_uploads) +
                                  "); retry later",
                              services->retry_after_seconds);
  }

  // 4. The temporary folder.
  const std::string upload_id = NewJobId();
  const fs::path temp_dir = services->layout().TempDir() / upload_id;
  std::error_code ec;
  fs::create_directories(temp_dir / "input", ec);
  if (ec) return StorageFailure(*services, "create " + temp_dir.string(), ec.value());
  auto session = std::make_unique<UploadSession>(services, temp_dir, upload_id);
  if (query_options) {
    if (auto refusal = session->SetOptions(std::move(*query_options)); refusal) return *refusal;
  }

  if (is_zip) {
    const fs::path zip_path = temp_dir / "upload.zip";
    const int fd = ::open(zip_path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0) return StorageFailure(*services, "create " + zip_path.string(), errno);
    return std::make_unique<ZipUploadSink>(services, std::move(*slot), std::move(session), fd);
  }
  return std::make_unique<MultipartUploadSink>(services, std::move(*slot), std::move(session),
                                               std::move(boundary));
}

}  // namespace reconduit::server
