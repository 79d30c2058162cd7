#include "core/image/image_header.h"

#include <climits>
#include <cstring>
#include <string>
#include <vector>

namespace reconduit {
namespace {

std::uint32_t ReadBigEndian16(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 8) | std::uint32_t{p[1]};
}

std::uint32_t ReadBigEndian32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         std::uint32_t{p[3]};
}

Status Invalid(std::string message) { return Status::InvalidArgument(std::move(message)); }

Status CheckDeclaredSize(std::uint64_t width, std::uint64_t height, ImageHeader* header) {
  if (width == 0 || height == 0 || width > INT_MAX || height > INT_MAX) {
    return Invalid("the " + std::string(ImageFormatName(header->format)) +
                   " header declares an invalid size of " + std::to_string(width) + "x" +
                   std::to_string(height) + " pixels");
  }
  header->width = static_cast<int>(width);
  header->height = static_cast<int>(height);
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// JPEG (ITU-T T.81, Annex B): SOI, then marker segments FF xx [length(2) payload]; a scan
// (SOS) is followed by entropy-coded data in which FF is escaped as FF 00 and restart markers
// FF D0..D7 may appear; the next other marker ends the scan. The image ends with EOI (FF D9).

bool IsJpegFrameMarker(std::uint8_t marker) {
  // SOF0..SOF15 except DHT (C4), JPG (C8) and DAC (CC).
  return marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
}

constexpr char kJpegTruncated[] = "truncated: the JPEG data ends before its end-of-image marker";

// Walks the JPEG's segments from SOI. With `header` non-null, stops at the first frame header
// and fills the size; otherwise walks to EOI to check completeness.
Status WalkJpeg(std::span<const std::uint8_t> bytes, ImageHeader* header) {
  const std::size_t n = bytes.size();
  const std::uint8_t* data = bytes.data();
  const auto ends_early = [&]() {
    return header != nullptr ? Invalid("the JPEG data ends before its frame header (SOF)")
                             : Invalid(kJpegTruncated);
  };
  std::size_t pos = 2;  // After SOI.
  while (true) {
    if (pos >= n) return ends_early();
    if (data[pos] != 0xFF) {
      return Invalid("not a valid JPEG: expected a marker at byte " + std::to_string(pos));
    }
    while (pos < n && data[pos] == 0xFF) ++pos;  // A marker may be preceded by fill bytes.
    if (pos >= n) return ends_early();
    const std::uint8_t marker = data[pos++];
    if (marker == 0xD9) {  // EOI.
      if (header != nullptr) return Invalid("the JPEG has no frame header (SOF)");
      return Status::Ok();
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD8)) continue;  // No payload.
    if (marker == 0x00) {
      return Invalid("not a valid JPEG: stray FF 00 at byte " + std::to_string(pos - 2));
    }
    if (pos + 2 > n) return ends_early();
    const std::size_t length = ReadBigEndian16(data + pos);
    if (length < 2) {
      return Invalid("not a valid JPEG: bad segment length at byte " + std::to_string(pos));
    }
    if (pos + length > n) return ends_early();
    if (header != nullptr && IsJpegFrameMarker(marker)) {
      // Payload: precision(1) height(2) width(2) components(1) ...
      if (length < 8) return Invalid("not a valid JPEG: frame header too short");
      return CheckDeclaredSize(ReadBigEndian16(data + pos + 5), ReadBigEndian16(data + pos + 3),
                               header);
    }
    pos += length;
    if (marker != 0xDA) continue;  // Not SOS.
    if (header != nullptr) return Invalid("the JPEG has a scan before its frame header (SOF)");
    // Skip the entropy-coded data up to the next marker that is not RSTn or an escaped FF.
    while (true) {
      const void* found = std::memchr(data + pos, 0xFF, n - pos);
      if (found == nullptr) return Invalid(kJpegTruncated);
      pos = static_cast<std::size_t>(static_cast<const std::uint8_t*>(found) - data);
      if (pos + 1 >= n) return Invalid(kJpegTruncated);
      const std::uint8_t next = data[pos + 1];
      if (next == 0x00 || (next >= 0xD0 && next <= 0xD7)) {
        pos += 2;
      } else if (next == 0xFF) {
        ++pos;  // Fill byte before a marker.
      } else {
        break;  // A marker: handled by the outer loop.
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// PNG (ISO/IEC 15948): signature(8), then chunks length(4, big-endian) type(4) data CRC(4);
// the first chunk is IHDR (width(4) height(4) ...), the last is IEND.

constexpr std::size_t kPngSignatureBytes = 8;

Status ReadPngHeader(std::span<const std::uint8_t> bytes, ImageHeader* header) {
  const std::uint8_t* data = bytes.data();
  if (bytes.size() < kPngSignatureBytes + 16) {
    return Invalid("the PNG data ends before its header chunk (IHDR)");
  }
  if (std::memcmp(data + kPngSignatureBytes + 4, "IHDR", 4) != 0 ||
      ReadBigEndian32(data + kPngSignatureBytes) < 8) {
    return Invalid("not a valid PNG: the first chunk is not IHDR");
  }
  return CheckDeclaredSize(ReadBigEndian32(data + kPngSignatureBytes + 8),
                           ReadBigEndian32(data + kPngSignatureBytes + 12), header);
}

Status CheckPngComplete(std::span<const std::uint8_t> bytes) {
  const std::size_t n = bytes.size();
  std::size_t pos = kPngSignatureBytes;
  while (pos + 8 <= n) {
    const std::uint64_t length = ReadBigEndian32(bytes.data() + pos);
    if (length > 0x7FFFFFFFu) {
      return Invalid("not a valid PNG: bad chunk length at byte " + std::to_string(pos));
    }
    const bool is_end = std::memcmp(bytes.data() + pos + 4, "IEND", 4) == 0;
    const std::uint64_t chunk_end = pos + 12 + length;
    if (chunk_end > n) return Invalid("truncated: the PNG data ends inside a chunk");
    if (is_end) return Status::Ok();
    pos = static_cast<std::size_t>(chunk_end);
  }
  return Invalid("truncated: the PNG data ends before its IEND chunk");
}

// ---------------------------------------------------------------------------------------------
// TIFF 6.0: byte order "II"/"MM", 42, offset of IFD0; an IFD is count(2) entries(12 each)
// next(4); an entry is tag(2) type(2) count(4) value-or-offset(4).

class TiffReader {
 public:
  explicit TiffReader(std::span<const std::uint8_t> bytes)
      : bytes_(bytes), little_endian_(bytes.size() >= 2 && bytes[0] == 'I') {}

  struct Entry {
    std::uint32_t type = 0;
    std::uint32_t count = 0;
    std::size_t value_pos = 0;  // Position of the 4-byte value-or-offset field.
  };

  // Lists IFD0's entries as (tag, entry); fails when IFD0 does not fit in the bytes.
  Status ReadIfd0(std::vector<std::pair<std::uint32_t, Entry>>* entries) const {
    if (bytes_.size() < 8) return Invalid("the TIFF data ends before its header");
    const std::uint64_t ifd = U32(4);
    if (ifd + 2 > bytes_.size())
      return Invalid("truncated: the TIFF data ends before its first directory");
    const std::uint32_t count = U16(static_cast<std::size_t>(ifd));
    if (ifd + 2 + 12ull * count > bytes_.size()) {
      return Invalid("truncated: the TIFF data ends inside its first directory");
    }
    for (std::uint32_t i = 0; i < count; ++i) {
      const auto pos = static_cast<std::size_t>(ifd + 2 + 12ull * i);
      entries->push_back({U16(pos), Entry{U16(pos + 2), U32(pos + 4), pos + 8}});
    }
    return Status::Ok();
  }

  // Reads the values of a SHORT (3) or LONG (4) entry; fails for other types or when the
  // values lie outside the bytes.
  Status Values(const Entry& entry, std::vector<std::uint64_t>* values) const {
    std::size_t size = 0;
    if (entry.type == 3) {
      size = 2;
    } else if (entry.type == 4) {
      size = 4;
    } else {
      return Invalid("not a valid TIFF: unexpected field type " + std::to_string(entry.type));
    }
    const std::uint64_t total = std::uint64_t{entry.count} * size;
    const std::uint64_t start = total <= 4 ? entry.value_pos : U32(entry.value_pos);
    if (start + total > bytes_.size())
      return Invalid("truncated: the TIFF data ends inside a directory field");
    values->clear();
    for (std::uint32_t i = 0; i < entry.count; ++i) {
      const auto pos = static_cast<std::size_t>(start + i * size);
      values->push_back(size == 2 ? U16(pos) : U32(pos));
    }
    return Status::Ok();
  }

 private:
  std::uint32_t U16(std::size_t pos) const {
    const std::uint8_t* p = bytes_.data() + pos;
    return little_endian_ ? (std::uint32_t{p[1]} << 8) | p[0] : ReadBigEndian16(p);
  }
  std::uint32_t U32(std::size_t pos) const {
    const std::uint8_t* p = bytes_.data() + pos;
    return little_endian_ ? (std::uint32_t{p[3]} << 24) | (std::uint32_t{p[2]} << 16) |
                                (std::uint32_t{p[1]} << 8) | p[0]
                          : ReadBigEndian32(p);
  }

  std::span<const std::uint8_t> bytes_;
  bool little_endian_;
};

constexpr std::uint32_t kTiffImageWidth = 256;
constexpr std::uint32_t kTiffImageLength = 257;
constexpr std::uint32_t kTiffStripOffsets = 273;
constexpr std::uint32_t kTiffStripByteCounts = 279;
constexpr std::uint32_t kTiffTileOffsets = 324;
constexpr std::uint32_t kTiffTileByteCounts = 325;

// Reads the single value of `tag` from IFD0 entries; 0 when absent.
Status TiffSingleValue(const TiffReader& reader,
                       const std::vector<std::pair<std::uint32_t, TiffReader::Entry>>& entries,
                       std::uint32_t tag,
                       std::uint64_t* value) {
  *value = 0;
  std::vector<std::uint64_t> values;
  for (const auto& [entry_tag, entry] : entries) {
    if (entry_tag != tag) continue;
    if (Status status = reader.Values(entry, &values); !status.ok()) return status;
    if (!values.empty()) *value = values[0];
  }
  return Status::Ok();
}

Status ReadTiffHeader(std::span<const std::uint8_t> bytes, ImageHeader* header) {
  const TiffReader reader(bytes);
  std::vector<std::pair<std::uint32_t, TiffReader::Entry>> entries;
  if (Status status = reader.ReadIfd0(&entries); !status.ok()) return status;
  std::uint64_t width = 0;
  std::uint64_t height = 0;
  if (Status status = TiffSingleValue(reader, entries, kTiffImageWidth, &width); !status.ok()) {
    return status;
  }
  if (Status status = TiffSingleValue(reader, entries, kTiffImageLength, &height); !status.ok()) {
    return status;
  }
  return CheckDeclaredSize(width, height, header);
}

Status CheckTiffComplete(std::span<const std::uint8_t> bytes) {
  const TiffReader reader(bytes);
  std::vector<std::pair<std::uint32_t, TiffReader::Entry>> entries;
  if (Status status = reader.ReadIfd0(&entries); !status.ok()) return status;
  const TiffReader::Entry* offsets = nullptr;
  const TiffReader::Entry* counts = nullptr;
  for (const auto& [tag, entry] : entries) {
    if (tag == kTiffStripOffsets || tag == kTiffTileOffsets) offsets = &entry;
    if (tag == kTiffStripByteCounts || tag == kTiffTileByteCounts) counts = &entry;
  }
  if (offsets == nullptr || counts == nullptr) {
    return Invalid("not a valid TIFF: the first directory has no image data");
  }
  std::vector<std::uint64_t> offset_values;
  std::vector<std::uint64_t> count_values;
  if (Status status = reader.Values(*offsets, &offset_values); !status.ok()) return status;
  if (Status status = reader.Values(*counts, &count_values); !status.ok()) return status;
  if (offset_values.size() != count_values.size()) {
    return Invalid("not a valid TIFF: strip offsets and byte counts differ in number");
  }
  for (std::size_t i = 0; i < offset_values.size(); ++i) {
    if (offset_values[i] + count_values[i] > bytes.size()) {
      return Invalid("truncated: the TIFF image data extends past the end of the file");
    }
  }
  return Status::Ok();
}

}  // namespace

Result<ImageHeader> ReadImageHeader(std::span<const std::uint8_t> bytes) {
  ImageHeader header;
  header.format = DetectImageFormat(bytes);
  Status status;
  switch (header.format) {
    case ImageFormat::kJpeg:
      status = WalkJpeg(bytes, &header);
      break;
    case ImageFormat::kPng:
      status = ReadPngHeader(bytes, &header);
      break;
    case ImageFormat::kTiff:
      status = ReadTiffHeader(bytes, &header);
      break;
    case ImageFormat::kUnknown:
      status = Invalid("not a JPEG, PNG or TIFF image");
      break;
  }
  if (!status.ok()) return status;
  return header;
}

Status CheckImageComplete(std::span<const std::uint8_t> bytes) {
  switch (DetectImageFormat(bytes)) {
    case ImageFormat::kJpeg:
      return WalkJpeg(bytes, nullptr);
    case ImageFormat::kPng:
      return CheckPngComplete(bytes);
    case ImageFormat::kTiff:
      return CheckTiffComplete(bytes);
    case ImageFormat::kUnknown:
      break;
  }
  return Invalid("not a JPEG, PNG or TIFF image");
}

}  // namespace reconduit
