// Helpers shared by the core/image tests (header-only, not part of reconduit_image).
#ifndef RECONDUIT_CORE_IMAGE_TEST_UTIL_H_
#define RECONDUIT_CORE_IMAGE_TEST_UTIL_H_

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <system_error>
#include <unistd.h>
#include <vector>

namespace reconduit {
namespace testing_util {

// A fresh directory under the system temp directory, removed with its contents on destruction.
class ScopedTempDir {
 public:
  ScopedTempDir() {
    std::random_device random;
    path_ = std::filesystem::temp_directory_path() /
            ("reconduit_image_test_" + std::to_string(::getpid()) + "_" + std::to_string(random()));
    std::filesystem::create_directories(path_);
  }
  ~ScopedTempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  ScopedTempDir(const ScopedTempDir&) = delete;
  ScopedTempDir& operator=(const ScopedTempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// A deterministic textured BGR image of the given size (so JPEG data is not trivially small).
inline cv::Mat TestPattern(int width, int height) {
  cv::Mat image(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<std::uint8_t>((x * 7 + y * 3) % 256),
                                            static_cast<std::uint8_t>((x * x + y) % 251),
                                            static_cast<std::uint8_t>((x ^ y) & 0xFF));
    }
  }
  return image;
}

// Encodes `image` with cv::imencode; `extension` is ".jpg", ".png" or ".tif".
inline std::vector<std::uint8_t> Encode(const cv::Mat& image, const std::string& extension) {
  std::vector<std::uint8_t> bytes;
  if (!cv::imencode(extension, image, bytes)) bytes.clear();
  return bytes;
}

inline void WriteBytes(const std::filesystem::path& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file.write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
}

inline void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file << text;
}

// PNG bytes with a valid signature and IHDR claiming `width` x `height` 8-bit RGB pixels,
// followed by an empty IEND chunk and no image data. CRCs are left zero.
inline std::vector<std::uint8_t> PngHeaderOnly(std::uint32_t width, std::uint32_t height) {
  std::vector<std::uint8_t> bytes = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  const auto put32 = [&bytes](std::uint32_t v) {
    for (int shift = 24; shift >= 0; shift -= 8) bytes.push_back((v >> shift) & 0xFF);
  };
  put32(13);
  for (char c : std::string("IHDR")) bytes.push_back(static_cast<std::uint8_t>(c));
  put32(width);
  put32(height);
  for (std::uint8_t b : {8, 2, 0, 0, 0}) bytes.push_back(b);  // Depth, RGB, no interlace.
  put32(0);                                                   // CRC.
  put32(0);
  for (char c : std::string("IEND")) bytes.push_back(static_cast<std::uint8_t>(c));
  put32(0);
  return bytes;
}

}  // namespace testing_util
}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_TEST_UTIL_H_
