// GET /api/v1/jobs/{id}/events with `Accept: text/event-stream`: the job's events as live
// Server-Sent Events (https://html.spec.whatwg.org/multipage/server-sent-events.html).
//
// The response stays open: every poll_interval the store is asked for events after the last one
// sent, and each new event is sent as
//   id: <event id>
//   data: {"id":..,"time":..,"stage":..,"level":..,"message":..,"progress":..}
// (the default "message" event type, so EventSource's onmessage sees it). A comment line
// (": keep-alive") goes out when nothing was sent for 15 s, so dead clients are noticed. Once
// the job is final and every event has been sent, a last event
//   event: end
//   data: {"id":..,"state":"succeeded"}
// closes the stream. The stream also ends, without "end", after kMaxStreamDuration or when
// the server shuts down; EventSource then reconnects with Last-Event-ID and continues where it
// stopped. A job deleted while streaming ends the stream with state "deleted".
#ifndef RECONDUIT_SERVER_API_EVENTS_STREAM_H_
#define RECONDUIT_SERVER_API_EVENTS_STREAM_H_

#include "server/api/api.h"

#include "store/job_store.h"
#include <chrono>
#include <cstdint>
#include <string>

namespace reconduit::server {

inline constexpr std::chrono::milliseconds kEventPollInterval{500};
inline constexpr std::chrono::seconds kKeepAliveInterval{15};
inline constexpr std::chrono::minutes kMaxStreamDuration{30};

// True when the Accept header asks for text/event-stream.
bool AcceptsEventStream(const RequestContext& context);

// One event in the Server-Sent Events format, ending with the blank line.
std::string FormatServerSentEvent(const JobEvent& event);

// The streamed response for job `job_id`, starting after event id `after`.
Response MakeEventStream(ApiServices* services, std::string job_id, std::int64_t after);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_EVENTS_STREAM_H_
