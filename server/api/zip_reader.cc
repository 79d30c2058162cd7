#include "server/api/zip_reader.h"

#include "server/api/safe_names.h"

#include <zip.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <sstream>
#include <sys/stat.h>

namespace reconduit::server {

struct ZipPhotoArchive::Handle {
  zip_t* archive = nullptr;
  ~Handle() {
    if (archive != nullptr) zip_discard(archive);
  }
};

namespace {

std::string ZipErrorText(int code) {
  zip_error_t error;
  zip_error_init_with_code(&error, code);
  std::string text = zip_error_strerror(&error);
  zip_error_fini(&error);
  return text;
}

std::string FormatRatio(double ratio) {
  std::ostringstream out;
  out.precision(1);
  out << std::fixed << ratio;
  return out.str();
}

}  // namespace

bool IsSkippedZipEntry(std::string_view name) {
  if (name.empty() || name.back() == '/') return true;
  if (name.rfind("__MACOSX/", 0) == 0) return true;
  const std::size_t slash = name.rfind('/');
  const std::string_view base = slash == std::string_view::npos ? name : name.substr(slash + 1);
  if (!base.empty() && base.front() == '.') return true;
  std::string lower(base);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return lower == "thumbs.db" || lower == "desktop.ini" ||
         (lower.size() > 4 && lower.compare(lower.size() - 4, 4, ".zip") == 0);
}

ZipPhotoArchive::ZipPhotoArchive(std::unique_ptr<Handle> handle) : handle_(std::move(handle)) {}
ZipPhotoArchive::~ZipPhotoArchive() = default;

Result<std::unique_ptr<ZipPhotoArchive>> ZipPhotoArchive::Open(const std::filesystem::path& path,
                                                               const ZipLimits& limits) {
  int error_code = 0;
  auto handle = std::make_unique<Handle>();
  handle->archive = zip_open(path.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &error_code);
  if (handle->archive == nullptr) {
    return Status::InvalidArgument("the body is not a readable zip archive: " +
                                   ZipErrorText(error_code));
  }
  std::unique_ptr<ZipPhotoArchive> archive(new ZipPhotoArchive(std::move(handle)));
  zip_t* zip = archive->handle_->archive;

  const zip_int64_t count = zip_get_num_entries(zip, 0);
  if (count < 0) return Status::InvalidArgument("the zip archive's directory is unreadable");
  if (count > limits.max_entries) {
    return Status::ResourceExhausted("the zip archive has " + std::to_string(count) +
                                     " entries; at most " + std::to_string(limits.max_entries) +
                                     " are accepted");
  }
  archive->max_total_bytes_ = limits.max_total_bytes;
  std::uint64_t total = 0;
  std::uint64_t total_compressed = 0;
  for (zip_int64_t i = 0; i < count; ++i) {
    const auto index = static_cast<zip_uint64_t>(i);
    zip_stat_t stat;
    zip_stat_init(&stat);
    if (zip_stat_index(zip, index, ZIP_FL_ENC_GUESS, &stat) != 0 ||
        (stat.valid & ZIP_STAT_NAME) == 0) {
      return Status::InvalidArgument("zip entry " + std::to_string(i) + " is unreadable");
    }
    const std::string name = stat.name;
    if (Status status = CheckRelativePath(name, /*allow_trailing_slash=*/true); !status.ok()) {
      return Status::InvalidArgument("zip entry refused: " + status.message());
    }
    zip_uint8_t opsys = 0;
    zip_uint32_t attributes = 0;
    if (zip_file_get_external_attributes(zip, index, 0, &opsys, &attributes) == 0 &&
        opsys == ZIP_OPSYS_UNIX) {
      const mode_t mode = static_cast<mode_t>(attributes >> 16);
      if (S_ISLNK(mode)) {
        return Status::InvalidArgument("zip entry " + QuoteForMessage(name) +
                                       " is a symbolic link; links are not accepted");
      }
      const mode_t type = mode & S_IFMT;
      if (type != 0 && type != S_IFREG && type != S_IFDIR) {
        return Status::InvalidArgument("zip entry " + QuoteForMessage(name) +
                                       " is not a regular file");
      }
    }
    if (IsSkippedZipEntry(name)) {
      if (name.back() != '/') archive->skipped_.push_back(name);
      continue;
    }
    if ((stat.valid & ZIP_STAT_ENCRYPTION_METHOD) != 0 && stat.encryption_method != ZIP_EM_NONE) {
      return Status::InvalidArgument("zip entry " + QuoteForMessage(name) +
                                     " is encrypted; encrypted archives are not accepted");
    }
    if ((stat.valid & ZIP_STAT_SIZE) == 0 || (stat.valid & ZIP_STAT_COMP_SIZE) == 0) {
      return Status::InvalidArgument("zip entry " + QuoteForMessage(name) +
                                     " does not declare its size");
    }
    if (static_cast<std::int64_t>(archive->photos_.size()) >= limits.max_photos) {
      return Status::ResourceExhausted("the zip archive holds more than " +
                                       std::to_string(limits.max_photos) +
                                       " photos, the limit per job");
    }
    if (stat.size > limits.max_entry_bytes) {
      return Status::ResourceExhausted(
          "zip entry " + QuoteForMessage(name) + " would extract to " + std::to_string(stat.size) +
          " bytes; a photo may have at most " + std::to_string(limits.max_entry_bytes));
    }
    total += stat.size;
    if (total > limits.max_total_bytes) {
      return Status::ResourceExhausted("the zip archive would extract to more than " +
                                       std::to_string(limits.max_total_bytes) +
                                       " bytes (decompression bomb?)");
    }
    if (stat.size > limits.ratio_min_bytes) {
      const double ratio = static_cast<double>(stat.size) /
                           static_cast<double>(std::max<zip_uint64_t>(1, stat.comp_size));
      if (ratio > limits.max_ratio) {
        return Status::ResourceExhausted("zip entry " + QuoteForMessage(name) +
                                         " has a compression ratio of " + FormatRatio(ratio) +
                                         ":1, over the limit of " + FormatRatio(limits.max_ratio) +
                                         ":1 (decompression bomb?)");
      }
    }
    total_compressed += stat.comp_size;
    archive->photos_.push_back({index, name, stat.size});
  }
  if (total > limits.ratio_min_bytes) {
    const double ratio = static_cast<double>(total) /
                         static_cast<double>(std::max<std::uint64_t>(1, total_compressed));
    if (ratio > limits.max_ratio) {
      return Status::ResourceExhausted("the zip archive's photos have a compression ratio of " +
                                       FormatRatio(ratio) + ":1 together, over the limit of " +
                                       FormatRatio(limits.max_ratio) + ":1 (decompression bomb?)");
    }
  }
  return archive;
}

Status ZipPhotoArchive::Extract(const ZipPhotoEntry& entry,
                                const std::function<Status(std::string_view data)>& sink) {
  zip_file_t* file = zip_fopen_index(handle_->archive, entry.index, 0);
  if (file == nullptr) {
    return Status::InvalidArgument("zip entry " + QuoteForMessage(entry.name) +
                                   " cannot be opened: " + zip_strerror(handle_->archive));
  }
  std::array<char, 64 * 1024> buffer;
  std::uint64_t produced = 0;
  Status status = Status::Ok();
  while (true) {
    const zip_int64_t n = zip_fread(file, buffer.data(), buffer.size());
    if (n < 0) {
      status = Status::InvalidArgument("zip entry " + QuoteForMessage(entry.name) +
                                       " is corrupt: " + zip_file_strerror(file));
      break;
    }
    if (n == 0) break;
    produced += static_cast<std::uint64_t>(n);
    extracted_ += static_cast<std::uint64_t>(n);
    if (extracted_ > max_total_bytes_) {
      status = Status::ResourceExhausted("the zip archive extracts to more than " +
                                         std::to_string(max_total_bytes_) + " bytes");
      break;
    }
    if (produced > entry.size) {
      status = Status::ResourceExhausted("zip entry " + QuoteForMessage(entry.name) +
                                         " extracts to more than its declared " +
                                         std::to_string(entry.size) + " bytes");
      break;
    }
    status = sink(std::string_view(buffer.data(), static_cast<std::size_t>(n)));
    if (!status.ok()) break;
  }
  zip_fclose(file);
  if (status.ok() && produced != entry.size) {
    status = Status::InvalidArgument("zip entry " + QuoteForMessage(entry.name) + " is truncated");
  }
  return status;
}

}  // namespace reconduit::server
