// Which photos the delivered model left out, and why, in words a user can act on (issue 13).
//
// The sparse stage delivers its largest model. A photo can be missing from it for three
// reasons, and each asks for a different remedy:
//   - it sits in another, smaller model: a group of photos placed together that shares no
//     reliable matches with the delivered one (photos taken in between would join them);
//   - it matched no other photo at all (a blurred, unrelated or very different view);
//   - it matched photos but could not be placed (too few of its matches reach the model's
//     points, or its geometry was refused).
// The sparse stage's summary carries the lists and one plain sentence; the job page and
// report.html show the sentence, cameras.json keeps listing the unregistered photos.
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_LEFT_OUT_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_LEFT_OUT_H_

#include "core/scene/reconstruction.h"
#include "core/sfm/incremental_mapper.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace reconduit {

struct LeftOutPhotos {
  int photos = 0;      // Photos given to the mapper.
  int registered = 0;  // In the delivered (first) model.
  // Each other model's photo names (largest first, names in id order).
  std::vector<std::vector<std::string>> other_groups;
  std::vector<std::string> unmatched;   // No verified pair with any photo.
  std::vector<std::string> not_placed;  // Matched, but in no model.

  bool empty() const { return other_groups.empty() && unmatched.empty() && not_placed.empty(); }
  // {"other_groups": [[...]], "unmatched": [...], "not_placed": [...], "note": "..."}.
  nlohmann::json ToJson() const;
  // One plain paragraph; empty when every photo is in the delivered model.
  std::string Note() const;
};

// `models` as the mapper returned them: the delivered model first.
LeftOutPhotos FindLeftOutPhotos(const MapperInput& input,
                                const std::vector<Reconstruction>& models);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_LEFT_OUT_H_
