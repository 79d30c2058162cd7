#include "core/util/logging.h"

#include "core/util/default_log_sink.h"

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <iostream>
#include <mutex>

namespace reconduit {
namespace internal {

CheckFailure::CheckFailure(const char* file, int line, std::string_view condition) {
  // Keep only the path below the repository root for readable messages.
  std::string_view path(file);
  if (const auto pos = path.rfind("core/"); pos != std::string_view::npos) path = path.substr(pos);
  stream_ << path << ":" << line << " Check failed: " << condition;
}

CheckFailure::~CheckFailure() noexcept(false) { throw CheckError(stream_.str()); }

}  // namespace internal

namespace {

struct LogState {
  std::mutex mutex;
  LogSink sink;
  std::atomic<LogLevel> min_level = LogLevel::kInfo;
  LogState() {
    if (const char* env = std::getenv("RECONDUIT_LOG_LEVEL")) {
      const std::string_view v(env);
      if (v == "debug") min_level = LogLevel::kDebug;
      if (v == "warning") min_level = LogLevel::kWarning;
      if (v == "error") min_level = LogLevel::kError;
    }
  }
};

LogState& State() {
  static LogState state;
  return state;
}

}  // namespace

LogSink SetLogSink(LogSink sink) {
  std::lock_guard lock(State().mutex);
  LogSink previous = std::move(State().sink);
  State().sink = std::move(sink);
  return previous;
}

void SetMinLogLevel(LogLevel level) { State().min_level = level; }

LogLevel MinLogLevel() { return State().min_level; }

void DefaultLogSink(LogLevel level, std::string_view message) {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y-%m-%dT%H:%M:%SZ", &tm);
  std::cerr << stamp << ' ' << LogLevelName(level) << ' ' << message << '\n';
}

std::string_view LogLevelName(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return "DEBUG";
    case LogLevel::kInfo:
      return "INFO";
    case LogLevel::kWarning:
      return "WARNING";
    case LogLevel::kError:
      return "ERROR";
  }
  return "?";
}

void LogMessage(LogLevel level, std::string_view message) {
  std::lock_guard lock(State().mutex);
  if (level < State().min_level) return;
  if (State().sink) {
    State().sink(level, message);
  } else {
    DefaultLogSink(level, message);
  }
}

}  // namespace reconduit
