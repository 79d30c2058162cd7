// Checks that throw instead of aborting, and a small leveled logger with a replaceable sink.
//
// A violated precondition in core/ is a programming or input error that must not take down the
// process that embeds the library (a worker runs many jobs): THROW_CHECK raises
// reconduit::CheckError with the failed expression, its source location and any streamed
// context, in the spirit of COLMAP's THROW_CHECK. Algorithmic failure (no model found) is not a
// check failure: it is reported as a value (a Report or Status).
//
//   THROW_CHECK(models != nullptr);
//   THROW_CHECK_EQ(points1.size(), points2.size()) << "for image " << name;
//
// Logging: LOG_INFO << "registered " << n << " images"; The sink defaults to stderr with a
// time stamp; the worker replaces it to record job events. The sink is process-wide and
// thread-safe (calls are serialised).
#ifndef RECONDUIT_CORE_UTIL_LOGGING_H_
#define RECONDUIT_CORE_UTIL_LOGGING_H_

#include <functional>
#include <optional>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

namespace reconduit {

// Thrown by THROW_CHECK*; what() holds "file:line Check failed: expr (a vs. b) context".
class CheckError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace internal {

// Collects the streamed context and throws CheckError when destroyed at the end of the
// full expression. The destructor is noexcept(false) on purpose: that is what lets the
// `<< context` syntax work.
class CheckFailure {
 public:
  CheckFailure(const char* file, int line, std::string_view condition);
  CheckFailure(const CheckFailure&) = delete;
  CheckFailure& operator=(const CheckFailure&) = delete;
  [[noreturn]] ~CheckFailure() noexcept(false);

  template <typename T>
  CheckFailure& operator<<(const T& value) {
    if (!has_context_) {
      stream_ << ": ";
      has_context_ = true;
    }
    stream_ << value;
    return *this;
  }

 private:
  std::ostringstream stream_;
  bool has_context_ = false;
};

// Streams a value when it can be streamed, so checks work on any comparable type.
template <typename T>
void FormatOperand(std::ostream& os, const T& value) {
  if constexpr (requires { os << value; }) {
    os << value;
  } else {
    os << "(unprintable)";
  }
}

// Integers are compared with std::cmp_* so that `size() == 7` neither warns nor misleads
// with signed/unsigned conversion.
template <typename T>
constexpr bool kSafeCmpInt =
    std::is_integral_v<T> && !std::is_same_v<T, bool> && !std::is_same_v<T, char> &&
    !std::is_same_v<T, wchar_t> && !std::is_same_v<T, char8_t> && !std::is_same_v<T, char16_t> &&
    !std::is_same_v<T, char32_t>;

#define RECONDUIT_DEFINE_CMP(name, op, safe)            \
  struct name {                                         \
    template <typename A, typename B>                   \
    bool operator()(const A& a, const B& b) const {     \
      if constexpr (kSafeCmpInt<A> && kSafeCmpInt<B>) { \
        return safe(a, b);                              \
      } else {                                          \
        return a op b;                                  \
      }                                                 \
    }                                                   \
  };
RECONDUIT_DEFINE_CMP(CmpEq, ==, std::cmp_equal)
RECONDUIT_DEFINE_CMP(CmpNe, !=, std::cmp_not_equal)
RECONDUIT_DEFINE_CMP(CmpLt, <, std::cmp_less)
RECONDUIT_DEFINE_CMP(CmpLe, <=, std::cmp_less_equal)
RECONDUIT_DEFINE_CMP(CmpGt, >, std::cmp_greater)
RECONDUIT_DEFINE_CMP(CmpGe, >=, std::cmp_greater_equal)
#undef RECONDUIT_DEFINE_CMP

// Evaluates each operand once; returns the failure text, or nothing when the check holds.
template <typename Cmp, typename A, typename B>
std::optional<std::string> CheckOp(const A& a, const B& b, const char* expression) {
  if (Cmp()(a, b)) return std::nullopt;
  std::ostringstream s;
  s << expression << " (";
  FormatOperand(s, a);
  s << " vs. ";
  FormatOperand(s, b);
  s << ")";
  return s.str();
}

// Turns the streamed expression into void so the macro works in `cond ? (void)0 : ...`.
struct Voidify {
  void operator&(const CheckFailure&) {}
};

}  // namespace internal

enum class LogLevel { kDebug = 0, kInfo = 1, kWarning = 2, kError = 3 };

// Receives every log line at or above the minimum level.
using LogSink = std::function<void(LogLevel, std::string_view message)>;

// Replaces the process-wide sink; an empty function restores the default (stderr).
// Returns the previous sink so a caller can restore it.
LogSink SetLogSink(LogSink sink);
// Lines below this level are dropped; default kInfo (env RECONDUIT_LOG_LEVEL=debug|info|...).
void SetMinLogLevel(LogLevel level);
LogLevel MinLogLevel();
void LogMessage(LogLevel level, std::string_view message);
std::string_view LogLevelName(LogLevel level);

namespace internal {
// Streams a line and hands it to the sink when destroyed.
class LogLine {
 public:
  explicit LogLine(LogLevel level) : level_(level) {}
  LogLine(const LogLine&) = delete;
  LogLine& operator=(const LogLine&) = delete;
  ~LogLine() { LogMessage(level_, stream_.str()); }
  template <typename T>
  LogLine& operator<<(const T& value) {
    stream_ << value;
    return *this;
  }

 private:
  LogLevel level_;
  std::ostringstream stream_;
};
}  // namespace internal

}  // namespace reconduit

#define RECONDUIT_LOG(level)                                     \
  if (::reconduit::LogLevel::level < ::reconduit::MinLogLevel()) \
    ;                                                            \
  else                                                           \
    ::reconduit::internal::LogLine(::reconduit::LogLevel::level)

#define LOG_DEBUG RECONDUIT_LOG(kDebug)
#define LOG_INFO RECONDUIT_LOG(kInfo)
#define LOG_WARNING RECONDUIT_LOG(kWarning)
#define LOG_ERROR RECONDUIT_LOG(kError)

#define THROW_CHECK(condition)                     \
  (condition) ? (void)0                            \
              : ::reconduit::internal::Voidify() & \
                    ::reconduit::internal::CheckFailure(__FILE__, __LINE__, #condition)

#define RECONDUIT_THROW_CHECK_OP(a, b, cmp, op)                                                    \
  if (auto reconduit_check_failure_ =                                                              \
          ::reconduit::internal::CheckOp<::reconduit::internal::cmp>((a), (b), #a " " #op " " #b); \
      !reconduit_check_failure_)                                                                   \
    ;                                                                                              \
  else                                                                                             \
    ::reconduit::internal::Voidify() &                                                             \
        ::reconduit::internal::CheckFailure(__FILE__, __LINE__, *reconduit_check_failure_)

#define THROW_CHECK_EQ(a, b) RECONDUIT_THROW_CHECK_OP(a, b, CmpEq, ==)
#define THROW_CHECK_NE(a, b) RECONDUIT_THROW_CHECK_OP(a, b, CmpNe, !=)
#define THROW_CHECK_LT(a, b) RECONDUIT_THROW_CHECK_OP(a, b, CmpLt, <)
#define THROW_CHECK_LE(a, b) RECONDUIT_THROW_CHECK_OP(a, b, CmpLe, <=)
#define THROW_CHECK_GT(a, b) RECONDUIT_THROW_CHECK_OP(a, b, CmpGt, >)
#define THROW_CHECK_GE(a, b) RECONDUIT_THROW_CHECK_OP(a, b, CmpGe, >=)
#define THROW_CHECK_NOTNULL(p) THROW_CHECK((p) != nullptr)

#endif  // RECONDUIT_CORE_UTIL_LOGGING_H_
