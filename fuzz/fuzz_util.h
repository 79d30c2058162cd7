// Helpers shared by the libFuzzer targets in this folder (see CMakeLists.txt).
#ifndef RECONDUIT_FUZZ_FUZZ_UTIL_H_
#define RECONDUIT_FUZZ_FUZZ_UTIL_H_

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <string_view>
#include <unistd.h>

namespace reconduit::fuzz {

// A property every input must keep; a violation aborts, which libFuzzer reports as a finding
// (with the input saved as an artifact).
#define RECONDUIT_FUZZ_CHECK(condition)                                                       \
  do {                                                                                        \
    if (!(condition)) {                                                                       \
      std::fprintf(stderr, "%s:%d: fuzz check failed: %s\n", __FILE__, __LINE__, #condition); \
      std::abort();                                                                           \
    }                                                                                         \
  } while (false)

inline std::string_view AsText(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// One file per process for the parsers that read a path (zip reader, configuration file),
// rewritten for every input: in $RECONDUIT_FUZZ_SCRATCH (a folder scripts/fuzz.sh creates in
// /dev/shm and removes afterwards: libFuzzer ends with _Exit, so nothing here can clean up),
// else in /dev/shm or $TMPDIR.
inline const std::string& ScratchPath(std::string_view suffix) {
  static const std::string path = [&] {
    const char* dir = std::getenv("RECONDUIT_FUZZ_SCRATCH");
    if (dir == nullptr) dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : std::getenv("TMPDIR");
    return std::string(dir ? dir : "/tmp") + "/reconduit-fuzz-" + std::to_string(getpid()) +
           std::string(suffix);
  }();
  return path;
}

inline const std::string& WriteScratch(const std::uint8_t* data,
                                       std::size_t size,
                                       std::string_view suffix) {
  const std::string& path = ScratchPath(suffix);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

}  // namespace reconduit::fuzz

#endif  // RECONDUIT_FUZZ_FUZZ_UTIL_H_
