#include "core/feature/features.h"

#include "core/io/file_util.h"

#include <cstring>
#include <fstream>

namespace reconduit {
namespace {

constexpr char kMagic[4] = {'R', 'C', 'F', 'T'};
constexpr std::uint32_t kVersion = 1;

struct Header {
  char magic[4];
  std::uint32_t version;
  std::int32_t width;
  std::int32_t height;
  std::uint64_t count;
};

}  // namespace

Status WriteFeatures(const std::filesystem::path& path, const FeatureSet& features) {
  THROW_CHECK_EQ(features.descriptors.rows, static_cast<int>(features.keypoints.size()));
  THROW_CHECK(features.descriptors.empty() ||
              (features.descriptors.cols == 128 && features.descriptors.type() == CV_8U));
  Header header{};
  std::memcpy(header.magic, kMagic, 4);
  header.version = kVersion;
  header.width = features.image_width;
  header.height = features.image_height;
  header.count = features.keypoints.size();
  std::string bytes(sizeof(Header), '\0');
  std::memcpy(bytes.data(), &header, sizeof(Header));
  bytes.append(reinterpret_cast<const char*>(features.keypoints.data()),
               features.keypoints.size() * sizeof(Keypoint));
  for (int r = 0; r < features.descriptors.rows; ++r) {
    bytes.append(reinterpret_cast<const char*>(features.descriptors.ptr(r)), 128);
  }
  return WriteFileAtomically(path, bytes);
}

Result<FeatureSet> ReadFeatures(const std::filesystem::path& path) {
  auto bytes = ReadFile(path);
  if (!bytes.ok()) return bytes.status();
  Header header{};
  if (bytes->size() < sizeof(Header)) return Status::Internal(path.string() + ": truncated");
  std::memcpy(&header, bytes->data(), sizeof(Header));
  if (std::memcmp(header.magic, kMagic, 4) != 0 || header.version != kVersion) {
    return Status::Internal(path.string() + ": not a Reconduit feature file (version 1)");
  }
  const std::size_t expected = sizeof(Header) + header.count * (sizeof(Keypoint) + 128);
  if (bytes->size() != expected) {
    return Status::Internal(path.string() + ": size " + std::to_string(bytes->size()) +
                            " does not match " + std::to_string(header.count) + " features");
  }
  FeatureSet features;
  features.image_width = header.width;
  features.image_height = header.height;
  features.keypoints.resize(header.count);
  const char* cursor = bytes->data() + sizeof(Header);
  if (header.count > 0) {  // memcpy from or to a null pointer is undefined even for 0 bytes.
    std::memcpy(features.keypoints.data(), cursor, header.count * sizeof(Keypoint));
  }
  cursor += header.count * sizeof(Keypoint);
  features.descriptors.create(static_cast<int>(header.count), 128, CV_8U);
  if (header.count > 0) std::memcpy(features.descriptors.data, cursor, header.count * 128);
  return features;
}

}  // namespace reconduit
