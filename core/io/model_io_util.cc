#include "core/io/model_io_util.h"

#include <charconv>
#include <cmath>
#include <limits>
#include <system_error>

namespace reconduit::model_io {

void AppendDouble(double value, std::string* out) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  THROW_CHECK(result.ec == std::errc());
  out->append(buffer, result.ptr);
}

void AppendInt(long long value, std::string* out) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  THROW_CHECK(result.ec == std::errc());
  out->append(buffer, result.ptr);
}

bool ParseDouble(std::string_view token, double* value) {
  if (token.empty()) return false;
  // from_chars rejects a leading '+', which some writers emit.
  if (token.front() == '+') token.remove_prefix(1);
  const auto result = std::from_chars(token.data(), token.data() + token.size(), *value);
  return result.ec == std::errc() && result.ptr == token.data() + token.size();
}

bool ParseInt(std::string_view token, int* value) {
  if (token.empty()) return false;
  const auto result = std::from_chars(token.data(), token.data() + token.size(), *value);
  return result.ec == std::errc() && result.ptr == token.data() + token.size();
}

std::vector<std::string_view> SplitWhitespace(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const std::size_t begin = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > begin) tokens.push_back(line.substr(begin, i - begin));
  }
  return tokens;
}

Status CheckReconstruction(const Reconstruction& rec) {
  for (const auto& [camera_id, camera] : rec.cameras) {
    std::string error;
    if (camera_id < 0) return Status::InvalidArgument("camera with negative id");
    if (!camera.Check(&error)) {
      return Status::InvalidArgument("camera " + std::to_string(camera_id) + ": " + error);
    }
  }
  std::size_t assigned_keypoints = 0;
  for (const auto& [image_id, image] : rec.images) {
    const std::string where = "image " + std::to_string(image_id) + " ('" + image.name + "')";
    if (image_id < 0 || image.image_id != image_id) {
      return Status::InvalidArgument(where + ": image_id field " + std::to_string(image.image_id) +
                                     " differs from its key");
    }
    if (!rec.cameras.contains(image.camera_id)) {
      return Status::InvalidArgument(where + ": unknown camera " + std::to_string(image.camera_id));
    }
    if (!AllFinite(image.cam_from_world.rotation.coeffs()) ||
        !AllFinite(image.cam_from_world.translation)) {
      return Status::InvalidArgument(where + ": non-finite pose");
    }
    if (image.point_for_keypoint.size() != image.keypoints.size()) {
      return Status::InvalidArgument(
          where + ": " + std::to_string(image.keypoints.size()) + " keypoints but " +
          std::to_string(image.point_for_keypoint.size()) + " point_for_keypoint entries");
    }
    for (std::size_t k = 0; k < image.keypoints.size(); ++k) {
      if (!AllFinite(image.keypoints[k])) {
        return Status::InvalidArgument(where + ": keypoint " + std::to_string(k) +
                                       " is not finite");
      }
      const int point_id = image.point_for_keypoint[k];
      if (point_id == kInvalidId) continue;
      ++assigned_keypoints;
      if (!rec.points.contains(point_id)) {
        return Status::InvalidArgument(where + ": keypoint " + std::to_string(k) +
                                       " observes missing point " + std::to_string(point_id));
      }
    }
  }
  std::size_t observations = 0;
  for (const auto& [point_id, point] : rec.points) {
    const std::string where = "point " + std::to_string(point_id);
    if (point_id < 0) return Status::InvalidArgument(where + ": negative id");
    if (!AllFinite(point.xyz_in_world)) {
      return Status::InvalidArgument(where + ": non-finite position");
    }
    for (const Observation& o : point.observations) {
      ++observations;
      auto image = rec.images.find(o.image_id);
      if (image == rec.images.end()) {
        return Status::InvalidArgument(where + ": observed in unregistered image " +
                                       std::to_string(o.image_id));
      }
      if (o.keypoint < 0 ||
          o.keypoint >= static_cast<int>(image->second.point_for_keypoint.size()) ||
          image->second.point_for_keypoint[o.keypoint] != point_id) {
        return Status::InvalidArgument(
            where + ": observation (image " + std::to_string(o.image_id) + ", keypoint " +
            std::to_string(o.keypoint) + ") does not match the image's point_for_keypoint");
      }
    }
  }
  if (observations != assigned_keypoints) {
    return Status::InvalidArgument(
        std::to_string(assigned_keypoints) + " keypoints observe a point but the points list " +
        std::to_string(observations) + " observations (duplicates or dangling references)");
  }
  return Status::Ok();
}

Status PointIdRestorer::Add(int id,
                            const Eigen::Vector3d& xyz,
                            const std::vector<Observation>& observations,
                            std::string_view where) {
  const std::string prefix = std::string(where) + "point " + std::to_string(id) + ": ";
  if (id < next_id_ || id == std::numeric_limits<int>::max()) {
    return Status::InvalidArgument(prefix + "ids must be unique, increasing and in [0, " +
                                   std::to_string(std::numeric_limits<int>::max()) + ")");
  }
  // Validate everything AddObservation would THROW_CHECK, so a bad file is a Status.
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const Observation& o = observations[i];
    auto image = rec_->images.find(o.image_id);
    if (image == rec_->images.end()) {
      return Status::InvalidArgument(prefix + "observed in unknown image " +
                                     std::to_string(o.image_id));
    }
    const auto& slots = image->second.point_for_keypoint;
    if (o.keypoint < 0 || o.keypoint >= static_cast<int>(slots.size())) {
      return Status::InvalidArgument(prefix + "keypoint " + std::to_string(o.keypoint) +
                                     " out of range for image " + std::to_string(o.image_id) +
                                     " with " + std::to_string(slots.size()) + " keypoints");
    }
    bool repeated = slots[o.keypoint] != kInvalidId;
    for (std::size_t j = 0; j < i && !repeated; ++j) {
      repeated = observations[j].image_id == o.image_id && observations[j].keypoint == o.keypoint;
    }
    if (repeated) {
      return Status::InvalidArgument(prefix + "keypoint " + std::to_string(o.keypoint) +
                                     " of image " + std::to_string(o.image_id) +
                                     " already observes a point");
    }
  }
  while (next_id_ < id) {
    rec_->DeletePoint(rec_->AddPoint(Eigen::Vector3d::Zero(), {}));
    ++next_id_;
  }
  const int added = rec_->AddPoint(xyz, observations);
  THROW_CHECK_EQ(added, id) << "the Reconstruction had points before PointIdRestorer";
  next_id_ = id + 1;
  return Status::Ok();
}

}  // namespace reconduit::model_io
