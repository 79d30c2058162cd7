// The facts about one photo that every later reader needs: its size, EXIF camera and focal
// prior, and whether it was accepted (with the reason when not).
//
// One definition shared by the inspection (ImageRecord::Metadata in image_check.h fills it),
// the ingest stage's records (IngestedImage, work/ingest/images.json) and the job store's
// images rows (JobImageRecord, store/job_store.h). Header-only and std-only, so the store uses
// it without linking core's image libraries.
#ifndef RECONDUIT_CORE_IMAGE_PHOTO_METADATA_H_
#define RECONDUIT_CORE_IMAGE_PHOTO_METADATA_H_

#include <cstdint>
#include <optional>
#include <string>

namespace reconduit {

struct PhotoMetadata {
  // File size in bytes.
  std::int64_t bytes = 0;
  // Size in pixels as displayed, i.e. after EXIF orientation; 0 when unknown (the header could
  // not be read).
  int width = 0;
  int height = 0;
  // Focal length prior in pixels of the width x height image, from EXIF; absent without one.
  std::optional<double> exif_focal_px;
  // How exif_focal_px was derived (FocalSourceName in exif.h), or "".
  std::string focal_source;
  // EXIF camera make and model; empty when unknown.
  std::string make;
  std::string model;
  // Whether the photo is usable; when not, why (e.g. "truncated: the JPEG data ends before its
  // end-of-image marker"), without the file name, which callers show next to a name of their
  // own. Empty for accepted photos.
  bool accepted = true;
  std::string reason;

  friend bool operator==(const PhotoMetadata&, const PhotoMetadata&) = default;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_PHOTO_METADATA_H_
