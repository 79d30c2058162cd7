#include "core/pipeline/stages/left_out.h"

#include <set>

namespace reconduit {
namespace {

// Names shown in the note before "and N more"; the JSON lists keep every name.
constexpr std::size_t kNamesInNote = 6;

std::string NameList(const std::vector<std::string>& names) {
  std::string text;
  for (std::size_t i = 0; i < names.size() && i < kNamesInNote; ++i) {
    if (i > 0) text += ", ";
    text += names[i];
  }
  if (names.size() > kNamesInNote)
    text += " and " + std::to_string(names.size() - kNamesInNote) + " more";
  return text;
}

std::string Photos(std::size_t n) { return std::to_string(n) + (n == 1 ? " photo" : " photos"); }

}  // namespace

LeftOutPhotos FindLeftOutPhotos(const MapperInput& input,
                                const std::vector<Reconstruction>& models) {
  LeftOutPhotos left;
  left.photos = static_cast<int>(input.images.size());
  left.registered = models.empty() ? 0 : static_cast<int>(models.front().images.size());
  std::set<int> placed;
  for (std::size_t m = 0; m < models.size(); ++m) {
    std::vector<std::string> names;
    for (const auto& [id, image] : models[m].images) {
      placed.insert(id);
      if (m > 0 && input.images.contains(id)) names.push_back(input.images.at(id).name);
    }
    if (m > 0 && !names.empty()) left.other_groups.push_back(std::move(names));
  }
  std::set<int> matched;
  for (const MapperPair& pair : input.pairs) {
    matched.insert(pair.image1);
    matched.insert(pair.image2);
  }
  for (const auto& [id, image] : input.images) {
    if (placed.contains(id)) continue;
    (matched.contains(id) ? left.not_placed : left.unmatched).push_back(image.name);
  }
  return left;
}

std::string LeftOutPhotos::Note() const {
  if (empty()) return "";
  std::string note = std::to_string(registered) + " of " + Photos(photos) + " are in the model.";
  for (const std::vector<std::string>& group : other_groups) {
    note += " A separate group of " + Photos(group.size()) + " (" + NameList(group) +
            ") was placed on its own: it shares too few reliable matches with the model's "
            "photos to join it.";
  }
  if (!unmatched.empty()) {
    note += " " + Photos(unmatched.size()) + " (" + NameList(unmatched) +
            ") matched no other photo: check that each shows the same scene and is sharp.";
  }
  if (!not_placed.empty()) {
    note += " " + Photos(not_placed.size()) + " (" + NameList(not_placed) +
            ") matched other photos but could not be placed: too few of their matches reach "
            "points of the model.";
  }
  note +=
      " More photos taken between these views, each overlapping its neighbours by about two "
      "thirds, would bring them in.";
  return note;
}

nlohmann::json LeftOutPhotos::ToJson() const {
  return {{"other_groups", other_groups},
          {"unmatched", unmatched},
          {"not_placed", not_placed},
          {"note", Note()}};
}

}  // namespace reconduit
