// The zip reader of uploads (server/api/zip_reader.h): the archive is opened and checked from
// its central directory, then every photo is extracted. An extracted photo never produces more
// than its declared size, nor the archive more than its limit.
#include "server/api/zip_reader.h"

#include "fuzz/fuzz_util.h"
#include <cstddef>
#include <cstdint>

using namespace reconduit;
using namespace reconduit::server;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& path = reconduit::fuzz::WriteScratch(data, size, ".zip");
  ZipLimits limits;
  limits.max_entries = 256;
  limits.max_photos = 64;
  limits.max_entry_bytes = 1 << 20;
  limits.max_total_bytes = 4 << 20;
  limits.ratio_min_bytes = 64 << 10;
  Result<std::unique_ptr<ZipPhotoArchive>> archive = ZipPhotoArchive::Open(path, limits);
  if (!archive.ok()) {
    RECONDUIT_FUZZ_CHECK(!archive.status().message().empty());
    return 0;
  }
  ZipPhotoArchive& zip = **archive.operator->();
  RECONDUIT_FUZZ_CHECK(zip.photos().size() <= static_cast<std::size_t>(limits.max_photos));
  std::uint64_t total = 0;
  for (const ZipPhotoEntry& entry : zip.photos()) {
    RECONDUIT_FUZZ_CHECK(!IsSkippedZipEntry(entry.name));
    RECONDUIT_FUZZ_CHECK(entry.size <= limits.max_entry_bytes);
    std::uint64_t produced = 0;
    const Status status = zip.Extract(entry, [&](std::string_view piece) {
      RECONDUIT_FUZZ_CHECK(piece.size() <= 64 * 1024);
      produced += piece.size();
      return Status::Ok();
    });
    RECONDUIT_FUZZ_CHECK(produced <= entry.size);
    total += produced;
    RECONDUIT_FUZZ_CHECK(total <= limits.max_total_bytes);
    if (!status.ok()) RECONDUIT_FUZZ_CHECK(!status.message().empty());
  }
  return 0;
}
