#include "core/pipeline/held_out.h"

#include <algorithm>

namespace reconduit {

Status CheckHeldOutPhotos(const std::vector<std::string>& held_out,
                          const std::vector<std::string>& photo_names) {
  std::string unknown;
  for (const std::string& name : held_out) {
    if (std::find(photo_names.begin(), photo_names.end(), name) == photo_names.end())
      unknown += (unknown.empty() ? "'" : ", '") + name + "'";
  }
  if (!unknown.empty()) {
    return Status::InvalidArgument("option 'held_out_photos' names " + unknown +
                                   ", not among the photos (names as uploaded, e.g. '" +
                                   (photo_names.empty() ? "0001.jpg" : photo_names[0]) + "')");
  }
  if (photo_names.size() < held_out.size() + 2) {
    return Status::InvalidArgument("option 'held_out_photos' holds " +
                                   std::to_string(held_out.size()) + " of " +
                                   std::to_string(photo_names.size()) +
                                   " photos: at least two must remain for dense matching");
  }
  return Status::Ok();
}

bool IsHeldOut(const std::vector<std::string>& held_out, const std::string& name) {
  return std::find(held_out.begin(), held_out.end(), name) != held_out.end();
}

Reconstruction WithoutHeldOutPhotos(const Reconstruction& model,
                                    const std::vector<std::string>& held_out) {
  Reconstruction kept = model;
  for (const auto& [id, image] : model.images) {
    if (IsHeldOut(held_out, image.name)) kept.DeleteImage(id);
  }
  return kept;
}

}  // namespace reconduit
