// POST /api/v1/jobs: receiving a photo set and turning it into a queued job.
//
// Two body formats:
//   * multipart/form-data with one or more `images` parts (also accepted: `images[]`, `image`)
//     and at most one `options` part (a JSON object of pipeline options, <= 64 KiB);
//   * a single application/zip body (also application/x-zip-compressed) whose entries are the
//     photos (zip_reader.h says what is checked and skipped).
// Options may also be given as the `options` query parameter (URL-encoded JSON), which is the
// only way for zip bodies; giving them twice is an error.
//
// What happens, in order:
//   1. Before any body byte is read: Content-Type (415), the options query (400), the queue
//      length (503 + Retry-After), the number of uploads in progress (429 + Retry-After).
//   2. While the body streams in: each photo goes to <data>/tmp/<upload-id>/input/<NNNN>.part
//      as it arrives (nothing is held in memory); its first bytes must be JPEG, PNG or TIFF
//      (415 naming the file); the photo count (413) and per-photo size (413) are enforced, the
//      options part is validated as soon as it ends (400 naming the field). A zip body goes to
//      <data>/tmp/<upload-id>/upload.zip and is checked and extracted the same way at the end;
//      entries that are not photos but what real archives carry (Thumbs.db, .DS_Store,
//      __MACOSX/, nested zips; zip_reader.h) are skipped and listed in the answer's `skipped`.
//   3. At the end: every photo is renamed to its generated name (0001.jpg, 0002.png, ... by
//      detected type) and checked from its header (photo_check.h: format, header size limits,
//      truncation, EXIF; no decoding on this I/O thread: ingest refuses undecodable photos);
//      rejected photos stay listed with their reason, and when none is usable the answer is 400
//      listing the reasons. The files and the folder are fsynced, the folder is renamed to
//      <data>/jobs/<id>/input (atomic, same file system), and only then the job and its photo
//      rows are inserted in one transaction. 201 with the job (and its photos) and Location.
// Any failure, a disconnect or a crash leaves no job row; the temporary folder is removed when
// the request ends, or at the next start after a crash.
//
// Client file names are display-only (SanitizeDisplayName); they never become paths.
#ifndef RECONDUIT_SERVER_API_UPLOAD_H_
#define RECONDUIT_SERVER_API_UPLOAD_H_

#include "server/api/api.h"
#include "server/http/router.h"

namespace reconduit::server {

// Largest `options` part or query parameter, in bytes.
inline constexpr std::size_t kMaxOptionsBytes = 64 * 1024;

// The streaming handler of POST /api/v1/jobs: refuses the request at once or returns the sink
// that receives its body.
StreamStart StartUpload(RequestContext& context, ApiServices* services);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_UPLOAD_H_
