// Test helper shared by the tests that read a result.zip (core/io, core/pipeline, worker,
// tests/): every entry of a zip file, read with libzip.
#ifndef RECONDUIT_CORE_IO_ZIP_TEST_UTIL_H_
#define RECONDUIT_CORE_IO_ZIP_TEST_UTIL_H_

#include <zip.h>

#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>

namespace reconduit::testing_util {

// The entries of a zip file: name -> bytes. Throws when it cannot be read.
inline std::map<std::string, std::string> ReadZipEntries(const std::filesystem::path& zip) {
  int error = 0;
  zip_t* archive = zip_open(zip.c_str(), ZIP_RDONLY, &error);
  if (archive == nullptr) throw std::runtime_error("cannot open " + zip.string());
  std::map<std::string, std::string> entries;
  for (zip_int64_t i = 0; i < zip_get_num_entries(archive, 0); ++i) {
    zip_stat_t st;
    zip_stat_init(&st);
    zip_file_t* file = nullptr;
    if (zip_stat_index(archive, i, 0, &st) != 0 ||
        (file = zip_fopen_index(archive, i, 0)) == nullptr) {
      zip_discard(archive);
      throw std::runtime_error("cannot read entry " + std::to_string(i) + " of " + zip.string());
    }
    std::string data(st.size, '\0');
    const zip_int64_t read = zip_fread(file, data.data(), st.size);
    zip_fclose(file);
    if (read != static_cast<zip_int64_t>(st.size)) {
      zip_discard(archive);
      throw std::runtime_error("short read in " + zip.string());
    }
    entries[st.name] = std::move(data);
  }
  zip_discard(archive);
  return entries;
}

}  // namespace reconduit::testing_util

#endif  // RECONDUIT_CORE_IO_ZIP_TEST_UTIL_H_
