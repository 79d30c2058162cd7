#include "core/io/file_util.h"

#include <array>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <fstream>
#include <memory>
#include <openssl/evp.h>
#include <random>
#include <sstream>
#include <unistd.h>

namespace reconduit {
namespace {

std::string Errno(const std::string& what, const std::filesystem::path& path) {
  return what + " '" + path.string() + "': " + std::strerror(errno);
}

// The Status for a failed call on `path` with errno set: a full disk (or quota, or file size
// limit) is kResourceExhausted and says so first, since it is what an operator must act on;
// anything else is kInternal.
Status IoError(const std::string& what, const std::filesystem::path& path) {
  const int error = errno;
  if (error == ENOSPC || error == EDQUOT || error == EFBIG) {
    return Status::ResourceExhausted("out of disk space: " + Errno(what, path));
  }
  return Status::Internal(Errno(what, path));
}

std::string ToHex(const unsigned char* data, unsigned int size) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string hex(2 * size, '0');
  for (unsigned int i = 0; i < size; ++i) {
    hex[2 * i] = kDigits[data[i] >> 4];
    hex[2 * i + 1] = kDigits[data[i] & 0xf];
  }
  return hex;
}

struct EvpContextDeleter {
  void operator()(EVP_MD_CTX* ctx) const { EVP_MD_CTX_free(ctx); }
};
using EvpContext = std::unique_ptr<EVP_MD_CTX, EvpContextDeleter>;

EvpContext NewSha256() {
  EvpContext ctx(EVP_MD_CTX_new());
  THROW_CHECK(ctx != nullptr && EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) == 1)
      << "OpenSSL SHA-256 initialisation failed";
  return ctx;
}

std::string FinishHex(EVP_MD_CTX* ctx) {
  std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
  unsigned int size = 0;
  THROW_CHECK(EVP_DigestFinal_ex(ctx, digest.data(), &size) == 1);
  return ToHex(digest.data(), size);
}

}  // namespace

Status SyncPath(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Status::Internal(Errno("cannot open", path));
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) return IoError("cannot fsync", path);
  return Status::Ok();
}

Status CommitFile(const std::filesystem::path& from, const std::filesystem::path& to) {
  if (Status s = SyncPath(from); !s.ok()) return s;
  if (::rename(from.c_str(), to.c_str()) != 0)
    return Status::Internal(Errno("cannot rename", from));
  const std::filesystem::path folder = to.has_parent_path() ? to.parent_path() : ".";
  return SyncPath(folder);
}

Status WriteFileAtomically(const std::filesystem::path& path, std::string_view contents) {
  std::random_device random;
  const std::filesystem::path temp =
      path.string() + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(random());
  {
    const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) return IoError("cannot create a temporary file for", path);
    std::size_t written = 0;
    while (written < contents.size()) {
      const ssize_t n = ::write(fd, contents.data() + written, contents.size() - written);
      if (n < 0) {
        if (errno == EINTR) continue;
        const Status status = IoError("cannot write", path);
        ::close(fd);
        ::unlink(temp.c_str());
        return status;
      }
      written += static_cast<std::size_t>(n);
    }
    // The descriptor is closed whether or not fsync worked; either failing fails the write.
    Status flushed = ::fsync(fd) == 0 ? Status::Ok() : IoError("cannot flush", path);
    if (::close(fd) != 0 && flushed.ok()) flushed = IoError("cannot flush", path);
    if (!flushed.ok()) {
      ::unlink(temp.c_str());
      return flushed;
    }
  }
  if (::rename(temp.c_str(), path.c_str()) != 0) {
    const Status status = Status::Internal(Errno("cannot rename", temp));
    ::unlink(temp.c_str());
    return status;
  }
  return SyncPath(path.has_parent_path() ? path.parent_path() : ".");
}

Result<std::string> ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::NotFound("cannot open '" + path.string() + "'");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) return Status::Internal("cannot read '" + path.string() + "'");
  return buffer.str();
}

Result<std::string> Sha256OfFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::NotFound("cannot open '" + path.string() + "'");
  EvpContext ctx = NewSha256();
  std::array<char, 1 << 16> buffer{};
  while (in) {
    in.read(buffer.data(), buffer.size());
    if (in.gcount() > 0) EVP_DigestUpdate(ctx.get(), buffer.data(), in.gcount());
  }
  if (in.bad()) return Status::Internal("cannot read '" + path.string() + "'");
  return FinishHex(ctx.get());
}

std::string Sha256Hex(std::string_view bytes) {
  EvpContext ctx = NewSha256();
  EVP_DigestUpdate(ctx.get(), bytes.data(), bytes.size());
  return FinishHex(ctx.get());
}

}  // namespace reconduit
