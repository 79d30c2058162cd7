// Held-out photos (option held_out_photos): photos that get cameras in the sparse stage but are
// left out of dense matching and texturing, so that the model rendered through their cameras
// can be compared with photos it was not made from (the texture stage's "renders").
//
// Why they stay in the sparse stage: their cameras are what the comparison renders through,
// and registering a photo needs its features. Its pixels then shape the sparse points that seed
// dense matching (as they would for any photo the model is later checked against in a survey),
// but no depth map, fused point, line of sight or texel comes from it.
#ifndef RECONDUIT_CORE_PIPELINE_HELD_OUT_H_
#define RECONDUIT_CORE_PIPELINE_HELD_OUT_H_

#include "core/scene/reconstruction.h"
#include "core/util/status.h"

#include <string>
#include <vector>

namespace reconduit {

// InvalidArgument naming every held-out name that is not one of `photo_names` (the names as
// uploaded), or when fewer than two photos would remain.
Status CheckHeldOutPhotos(const std::vector<std::string>& held_out,
                          const std::vector<std::string>& photo_names);

// True when `name` is one of `held_out`.
bool IsHeldOut(const std::vector<std::string>& held_out, const std::string& name);

// `model` without the held-out photos' images and their observations (Reconstruction::
// DeleteImage): what the dense stage matches.
Reconstruction WithoutHeldOutPhotos(const Reconstruction& model,
                                    const std::vector<std::string>& held_out);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_HELD_OUT_H_
