// The default log sink, callable: for sinks that add to a line and still write it to stderr,
// so that every log line of a process has one layout.
//
// Kept apart from logging.h (which nearly every file includes) because only such sinks need
// it; it is defined in logging.cc beside the rest of the logger.
#ifndef RECONDUIT_CORE_UTIL_DEFAULT_LOG_SINK_H_
#define RECONDUIT_CORE_UTIL_DEFAULT_LOG_SINK_H_

#include "core/util/logging.h"

#include <string_view>

namespace reconduit {

// "<UTC time stamp> <LEVEL> <message>" on stderr: what LogMessage does when no sink is set.
void DefaultLogSink(LogLevel level, std::string_view message);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_UTIL_DEFAULT_LOG_SINK_H_
