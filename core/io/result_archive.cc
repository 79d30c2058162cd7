#include "core/io/result_archive.h"

#include "core/io/file_util.h"

#include <nlohmann/json.hpp>
#include <zip.h>

#include <algorithm>

namespace reconduit {
namespace {

bool IsCompressed(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".glb" || ext == ".zip";
}

std::string ZipError(zip_t* archive) { return zip_strerror(archive); }

bool IsExcluded(const std::string& name, const ArchiveExclusions& excluded) {
  return std::any_of(excluded.begin(), excluded.end(), [&](const std::string& entry) {
    return entry.ends_with('/') ? name.starts_with(entry) : name == entry;
  });
}

}  // namespace

Result<std::vector<std::string>> ListResultFiles(const std::filesystem::path& folder,
                                                 const ArchiveExclusions& excluded) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    return Status::NotFound("result folder '" + folder.string() + "' does not exist");
  }
  std::vector<std::string> names;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) {
    // Symlinks (even to regular files) and special files are never packed.
    if (entry.is_symlink() || !entry.is_regular_file()) continue;
    const std::string name = fs::relative(entry.path(), folder).generic_string();
    if (name == "manifest.json" || IsExcluded(name, excluded)) continue;
    names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

Result<ResultArchiveSummary> WriteResultArchive(const std::filesystem::path& folder,
                                                const std::filesystem::path& zip_path,
                                                const CancelToken& cancel,
                                                const ArchiveExclusions& excluded) {
  namespace fs = std::filesystem;
  std::error_code ec;
  auto names = ListResultFiles(folder, excluded);
  if (!names.ok()) return names.status();

  ResultArchiveSummary summary;
  nlohmann::json manifest = {{"files", nlohmann::json::array()}};
  for (const std::string& name : *names) {
    cancel.ThrowIfCanceled();
    ManifestEntry file;
    file.name = name;
    file.bytes = static_cast<std::int64_t>(fs::file_size(folder / name));
    auto sha = Sha256OfFile(folder / name);
    if (!sha.ok()) return sha.status();
    file.sha256 = *sha;
    manifest["files"].push_back(
        {{"name", file.name}, {"bytes", file.bytes}, {"sha256", file.sha256}});
    summary.files.push_back(std::move(file));
  }
  const std::string manifest_text = manifest.dump(2) + "\n";
  if (Status s = WriteFileAtomically(folder / "manifest.json", manifest_text); !s.ok()) return s;
  summary.files.push_back(
      {"manifest.json", static_cast<std::int64_t>(manifest_text.size()), Sha256Hex(manifest_text)});

  const fs::path temp = zip_path.string() + ".tmp";
  fs::remove(temp, ec);
  int error_code = 0;
  zip_t* archive = zip_open(temp.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error_code);
  if (archive == nullptr) {
    zip_error_t error;
    zip_error_init_with_code(&error, error_code);
    const std::string message = zip_error_strerror(&error);
    zip_error_fini(&error);
    return Status::Internal("cannot create '" + temp.string() + "': " + message);
  }
  auto fail = [&](const std::string& message) -> Status {
    zip_discard(archive);
    fs::remove(temp, ec);
    return Status::Internal(message);
  };
  for (const ManifestEntry& file : summary.files) {
    const fs::path source = folder / file.name;
    zip_source_t* zip_source =
        zip_source_file(archive, source.c_str(), 0, -1);  // -1: to the end (libzip 1.7).
    if (zip_source == nullptr)
      return fail("cannot read '" + source.string() + "': " + ZipError(archive));
    const zip_int64_t index =
        zip_file_add(archive, file.name.c_str(), zip_source, ZIP_FL_OVERWRITE | ZIP_FL_ENC_UTF_8);
    if (index < 0) {
      zip_source_free(zip_source);
      return fail("cannot add '" + file.name + "': " + ZipError(archive));
    }
    zip_set_file_compression(archive, index, IsCompressed(source) ? ZIP_CM_STORE : ZIP_CM_DEFLATE,
                             0);
  }
  if (cancel.IsCanceled()) {
    zip_discard(archive);
    fs::remove(temp, ec);
    throw CanceledError();
  }
  if (zip_close(archive) != 0) {
    const std::string message = ZipError(archive);
    zip_discard(archive);
    fs::remove(temp, ec);
    return Status::Internal("cannot write '" + temp.string() + "': " + message);
  }
  if (Status s = CommitFile(temp, zip_path); !s.ok()) return s;
  summary.archive_bytes = static_cast<std::int64_t>(fs::file_size(zip_path));
  auto sha = Sha256OfFile(zip_path);
  if (!sha.ok()) return sha.status();
  summary.archive_sha256 = *sha;
  return summary;
}

}  // namespace reconduit
