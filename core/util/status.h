// Status and Result<T>: how core/ reports an expected failure as a value.
//
// Exceptions (CheckError) are for broken preconditions; a Status is for outcomes a caller is
// expected to handle: a photo that does not decode, a degenerate pair, a canceled stage.
// Following Ceres's Summary, a default-constructed Status is not OK: a result nobody filled
// in reads as a failure ("not run"), never as a silent success.
#ifndef RECONDUIT_CORE_UTIL_STATUS_H_
#define RECONDUIT_CORE_UTIL_STATUS_H_

#include "core/util/logging.h"

#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <utility>

namespace reconduit {

enum class StatusCode {
  kOk = 0,
  kNotRun,              // Default: the operation never ran or never set its status.
  kInvalidArgument,     // Bad input (a file that is not an image, an option out of range).
  kNotFound,            // A file or record that does not exist.
  kDegenerate,          // Input is valid but geometry cannot be recovered from it.
  kCanceled,            // A cancel request was honoured.
  kFailedPrecondition,  // Wrong state for this request (cancel a finished job).
  kAlreadyExists,       // Something with this identity exists already.
  kResourceExhausted,   // A limit was reached (queue full, disk full, too many uploads).
  kInternal,            // Anything else: a bug or an environment failure (I/O, memory).
};

std::string_view StatusCodeName(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;  // kNotRun.
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return Status(StatusCode::kOk, ""); }
  static Status InvalidArgument(std::string m) {
    return Status(StatusCode::kInvalidArgument, std::move(m));
  }
  static Status NotFound(std::string m) { return Status(StatusCode::kNotFound, std::move(m)); }
  static Status Degenerate(std::string m) { return Status(StatusCode::kDegenerate, std::move(m)); }
  static Status Canceled(std::string m = "canceled") {
    return Status(StatusCode::kCanceled, std::move(m));
  }
  static Status FailedPrecondition(std::string m) {
    return Status(StatusCode::kFailedPrecondition, std::move(m));
  }
  static Status AlreadyExists(std::string m) {
    return Status(StatusCode::kAlreadyExists, std::move(m));
  }
  static Status ResourceExhausted(std::string m) {
    return Status(StatusCode::kResourceExhausted, std::move(m));
  }
  static Status Internal(std::string m) { return Status(StatusCode::kInternal, std::move(m)); }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "INVALID_ARGUMENT: not an image" or "OK".
  std::string ToString() const;

  friend bool operator==(const Status&, const Status&) = default;

 private:
  StatusCode code_ = StatusCode::kNotRun;
  std::string message_ = "not run";
};

std::ostream& operator<<(std::ostream& os, const Status& status);

// Either a value or a non-OK Status.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)), status_(Status::Ok()) {}  // NOLINT: implicit.
  Result(Status status) : status_(std::move(status)) {                  // NOLINT: implicit.
    THROW_CHECK(!status_.ok()) << "a Result built from a Status must carry an error";
  }

  bool ok() const { return status_.ok(); }
  const Status& status() const { return status_; }

  // Accessing the value of a failed Result is a programming error: it throws CheckError.
  const T& value() const& {
    THROW_CHECK(ok()) << status_.ToString();
    return *value_;
  }
  T& value() & {
    THROW_CHECK(ok()) << status_.ToString();
    return *value_;
  }
  T&& value() && {
    THROW_CHECK(ok()) << status_.ToString();
    return std::move(*value_);
  }
  const T& operator*() const& { return value(); }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_UTIL_STATUS_H_
