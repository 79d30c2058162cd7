#include "core/pipeline/report_html.h"

#include <cmath>
#include <cstdio>
#include <map>
#include <optional>

namespace reconduit {
namespace {

using nlohmann::json;

// Tolerant accessors: report.json is ours, but a page that throws on an unexpected field
// would cost the whole result.zip, so wrong types read as absent.
const json& Field(const json& object, std::string_view key) {
  static const json kAbsent;
  if (!object.is_object()) return kAbsent;
  const auto it = object.find(key);
  return it == object.end() ? kAbsent : *it;
}

// `value` when it is an array, else an empty one (to loop over).
const json& Items(const json& value) {
  static const json kEmpty = json::array();
  return value.is_array() ? value : kEmpty;
}

std::optional<double> Number(const json& value) {
  if (!value.is_number()) return std::nullopt;
  return value.get<double>();
}

std::string Text(const json& value) {
  if (value.is_string()) return value.get<std::string>();
  if (value.is_boolean()) return value.get<bool>() ? "true" : "false";
  if (value.is_number_integer()) return std::to_string(value.get<std::int64_t>());
  if (value.is_number()) return value.dump();
  return "";
}

std::string Fixed(std::optional<double> value, int digits, std::string_view unit = "") {
  if (!value || !std::isfinite(*value)) return "&mdash;";
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", digits, *value);
  return std::string(text) + std::string(unit);
}

std::string Count(const json& value) {
  const std::optional<double> n = Number(value);
  if (!n) return "&mdash;";
  return std::to_string(static_cast<std::int64_t>(std::llround(*n)));
}

std::string Bytes(const json& value) {
  const std::optional<double> n = Number(value);
  if (!n || *n <= 0) return "&mdash;";
  if (*n >= 1e9) return Fixed(*n / 1e9, 2, " GB");
  if (*n >= 1e6) return Fixed(*n / 1e6, 1, " MB");
  return Fixed(*n / 1e3, 1, " kB");
}

std::string Seconds(const json& value) {
  const std::optional<double> s = Number(value);
  return Fixed(s, s && *s < 10 ? 2 : 1, " s");
}

std::string Percent(const json& value) {
  const std::optional<double> share = Number(value);
  return share ? Fixed(100.0 * *share, 1, " %") : "&mdash;";
}

// A path inside the archive as a relative URL: bytes outside the unreserved set (and '/')
// percent-encoded, then escaped for the attribute.
std::string Url(std::string_view path) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string url;
  for (const unsigned char c : path) {
    if (std::isalnum(c) || c == '-' || c == '.' || c == '_' || c == '~' || c == '/') {
      url += static_cast<char>(c);
    } else {
      url += '%';
      url += kHex[c >> 4];
      url += kHex[c & 15];
    }
  }
  // "./" keeps a first segment with a colon from reading as a URL scheme.
  return HtmlEscape("./" + url);
}

// The summary of the stage named `name` when it ran to success (skipped included), else null.
const json* StageSummary(const json& report, std::string_view name) {
  for (const json& stage : Items(Field(report, "stages"))) {
    if (Text(Field(stage, "name")) == name && Text(Field(stage, "status")) == "success")
      return &Field(stage, "summary");
  }
  return nullptr;
}

// A figure from stage `name`'s summary along `keys`, absent when the stage did not run or
// was skipped.
const json& StageFigure(const json& report,
                        std::string_view name,
                        std::initializer_list<std::string_view> keys) {
  static const json kAbsent;
  const json* summary = StageSummary(report, name);
  if (summary == nullptr || Field(*summary, "skipped_reason").is_string()) return kAbsent;
  const json* value = summary;
  for (std::string_view key : keys) value = &Field(*value, key);
  return *value;
}

class Page {
 public:
  explicit Page(const ReportHtmlInput& input) : input_(input) {}

  std::string Render();

 private:
  void Counts();
  void Stages();
  void Cameras();
  void Matching();
  void Renders();
  void Photos();
  void PhotoRow(const ReportPhoto& photo,
                const std::map<int, const json*>& maps,
                const std::map<int, const json*>& renders);
  void Files();
  void Options();

  bool Has(const std::string& path) const { return !path.empty() && input_.files.count(path); }
  std::string LeftOutBy(const std::string& path) const;
  // An <img> (linked to the full picture) when the archive holds `path`, else a note.
  std::string Picture(const std::string& path,
                      const std::string& alt,
                      int max_width,
                      bool caption = true) const;
  // A link when the archive holds `path`, else why not.
  std::string Link(const std::string& path, const std::string& label) const;

  const ReportHtmlInput& input_;
  std::string html_;
};

constexpr std::string_view kStyle = R"(
body { font: 14px/1.45 system-ui, sans-serif; margin: 24px auto; max-width: 1200px;
       padding: 0 16px; color: #222; }
h1 { font-size: 24px; } h2 { font-size: 18px; margin-top: 32px; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 8px 0; }
th, td { border: 1px solid #ddd; padding: 3px 8px; text-align: left; vertical-align: top; }
td.n { text-align: right; font-variant-numeric: tabular-nums; }
th { background: #f3f3f3; }
figure { display: inline-block; margin: 4px 12px 12px 0; vertical-align: top; }
figcaption { font-size: 12px; color: #555; max-width: 520px; }
img { display: block; border: 1px solid #ccc; background: #eee; }
.note { color: #8a5a00; } .skipped { color: #8a5a00; } .failed { color: #b00020; }
.pair { display: flex; gap: 12px; flex-wrap: wrap; align-items: flex-start; }
)";

std::string Page::Render() {
  html_ += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  // No network: nothing may be fetched but the archive's own files.
  html_ +=
      "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; img-src 'self' "
      "file:; style-src 'unsafe-inline'\">\n";
  html_ += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
  html_ += "<title>Reconduit report</title>\n<style>" + std::string(kStyle) + "</style>\n";
  html_ += "</head>\n<body>\n<h1>Reconduit report</h1>\n";
  html_ += "<p>" + Count(Field(input_.report, "image_count")) + " photos, " +
           Seconds(Field(input_.report, "total_seconds")) + " in all, peak memory " +
           Bytes(Field(input_.report, "peak_memory_bytes")) + ". " +
           Link("model.glb", "model.glb") + " &middot; " + Link("cameras.json", "cameras.json") +
           " &middot; " + Link("report.json", "report.json") + "</p>\n";
  Counts();
  Stages();
  Cameras();
  Matching();
  Renders();
  Photos();
  Files();
  Options();
  html_ += "</body>\n</html>\n";
  return html_;
}

void Page::Counts() {
  const json& r = input_.report;
  const json& unseen = StageFigure(r, "texture", {"texture", "unseen_faces"});
  const json& faces = StageFigure(r, "texture", {"texture", "faces"});
  std::string unseen_text = Count(unseen);
  if (Number(unseen) && Number(faces) && *Number(faces) > 0)
    unseen_text += " (" + Percent(*Number(unseen) / *Number(faces)) + ")";
  const std::pair<std::string, std::string> rows[] = {
      {"photos", Count(Field(r, "image_count"))},
      {"usable photos", Count(StageFigure(r, "ingest", {"accepted"}))},
      {"registered photos", Count(StageFigure(r, "sparse", {"registered"}))},
      {"sparse points", Count(StageFigure(r, "sparse", {"points"}))},
      {"mean reprojection error",
       Fixed(Number(StageFigure(r, "sparse", {"mean_reprojection_error_px"})), 3, " px")},
      {"dense points", Count(StageFigure(r, "dense", {"points"}))},
      {"mesh faces", Count(StageFigure(r, "mesh", {"faces"}))},
      {"mesh vertices", Count(StageFigure(r, "mesh", {"vertices"}))},
      {"texture charts", Count(StageFigure(r, "texture", {"texture", "charts"}))},
      {"texture pages", Count(StageFigure(r, "texture", {"texture", "pages"}))},
      {"faces no photo sees", unseen_text},
      {"model.glb", Bytes(StageFigure(r, "texture", {"model", "bytes"}))},
  };
  html_ += "<h2>Counts</h2>\n<table>\n";
  for (const auto& [label, value] : rows)
    html_ += "<tr><th>" + label + "</th><td class=\"n\">" + value + "</td></tr>\n";
  html_ += "</table>\n";
}

void Page::Stages() {
  html_ +=
      "<h2>Stages</h2>\n<table>\n<tr><th>stage</th><th>status</th><th>time</th>"
      "<th>stage peak memory</th><th>process peak memory</th><th>note</th></tr>\n";
  const json& stages = Field(input_.report, "stages");
  for (const json& stage : Items(stages)) {
    const json& summary = Field(stage, "summary");
    std::string status = Text(Field(stage, "status"));
    std::string note = Text(Field(stage, "message"));
    std::string css = status == "success" ? "" : "failed";
    if (Field(summary, "skipped_reason").is_string()) {
      status = "skipped";
      css = "skipped";
      note = Text(Field(summary, "skipped_reason"));
    }
    // The stage's own peak is the process's when the kernel's mark could not be reset.
    std::string own = Bytes(Field(stage, "stage_peak_memory_bytes"));
    if (Field(stage, "stage_peak_memory_own") != json(true)) own += " (the process's)";
    html_ += "<tr><td>" + HtmlEscape(Text(Field(stage, "name"))) + "</td><td class=\"" + css +
             "\">" + HtmlEscape(status) + "</td><td class=\"n\">" +
             Seconds(Field(stage, "seconds")) + "</td><td class=\"n\">" + own +
             "</td><td class=\"n\">" + Bytes(Field(stage, "peak_memory_bytes")) + "</td><td>" +
             HtmlEscape(note) + "</td></tr>\n";
  }
  html_ += "</table>\n";
}

void Page::Cameras() {
  const json* sparse = StageSummary(input_.report, "sparse");
  if (sparse == nullptr) return;
  html_ += "<h2>Cameras</h2>\n<p>Mean reprojection error " +
           Fixed(Number(Field(*sparse, "mean_reprojection_error_px")), 3, " px") + " over " +
           Count(Field(*sparse, "points")) + " points; " + Count(Field(*sparse, "registered")) +
           " of " + Count(Field(*sparse, "photos")) + " usable photos registered in the model (" +
           Count(Field(*sparse, "models")) + " model(s)).</p>\n";
  const std::string left_out = Text(Field(Field(*sparse, "left_out"), "note"));
  if (!left_out.empty()) html_ += "<p class=\"skipped\">" + HtmlEscape(left_out) + "</p>\n";
  const json& cameras = Field(*sparse, "cameras");
  if (!cameras.is_array() || cameras.empty()) return;
  html_ +=
      "<table>\n<tr><th>camera</th><th>size</th><th>photos</th><th>initial focal</th>"
      "<th>self-calibrated</th><th>final focal &plusmn; 1&sigma;</th></tr>\n";
  for (const json& camera : cameras) {
    const json& stddev = Field(Field(camera, "stddev"), "focal");
    html_ += "<tr><td class=\"n\">" + Count(Field(camera, "camera_id")) + "</td><td>" +
             Count(Field(camera, "width")) + " &times; " + Count(Field(camera, "height")) +
             "</td><td class=\"n\">" + Count(Field(camera, "photos")) + "</td><td>" +
             Fixed(Number(Field(camera, "initial_focal")), 1, " px") + " (" +
             HtmlEscape(Text(Field(camera, "initial_focal_source"))) + ")</td><td class=\"n\">" +
             Fixed(Number(Field(camera, "self_calibrated_focal")), 1, " px") +
             "</td><td class=\"n\">" + Fixed(Number(Field(camera, "final_focal")), 2) +
             " &plusmn; " + Fixed(Number(stddev), 2, " px") + "</td></tr>\n";
  }
  html_ += "</table>\n";
}

void Page::Matching() {
  html_ += "<h2>Which photos match</h2>\n";
  html_ += Picture("report/similarity.png", "similarity of every pair of photos", 520);
  html_ += Picture("report/match_graph.png",
                   "pairs that matched (green: epipolar, orange: planar or rotation-only)", 520);
  html_ += "\n";
}

void Page::Renders() {
  const json& renders = StageFigure(input_.report, "texture", {"renders"});
  if (!renders.is_array()) return;
  html_ +=
      "<h2>The model against the photos</h2>\n<p>The textured model rendered through a photo's "
      "camera (left) beside the photo (right). Covered: the share of the photo the model "
      "covers; difference: the mean absolute colour difference over the covered pixels "
      "(0-255). Every photo's figures are in the table below.</p>\n";
  for (const json& render : renders) {
    const std::string picture = Text(Field(render, "render_picture"));
    const std::string photo = Text(Field(render, "photo_picture"));
    if (picture.empty() && photo.empty()) continue;
    const std::string name = HtmlEscape(Text(Field(render, "name")));
    const std::string held_out = Field(render, "held_out") == json(true)
                                     ? " (held out of dense matching and texturing)"
                                     : "";
    html_ += "<h3>" + name + held_out + ": covered " + Percent(Field(render, "covered")) +
             ", difference " + Fixed(Number(Field(render, "mean_abs_diff")), 1) +
             "</h3>\n<div class=\"pair\">" +
             Picture(picture, "the model seen from " + Text(Field(render, "name")), 512) +
             Picture(photo, Text(Field(render, "name")), 512) + "</div>\n";
  }
}

void Page::Photos() {
  std::map<int, const json*> maps, renders;
  const json& map_list = StageFigure(input_.report, "dense", {"maps"});
  for (const json& map : Items(map_list)) {
    if (Number(Field(map, "image_id"))) maps[Field(map, "image_id").get<int>()] = &map;
  }
  const json& render_list = StageFigure(input_.report, "texture", {"renders"});
  for (const json& render : Items(render_list)) {
    if (Number(Field(render, "image_id"))) renders[Field(render, "image_id").get<int>()] = &render;
  }
  html_ +=
      "<h2>Photos</h2>\n<p>Depth: red near, blue far, black no depth. Quality: dark red only "
      "this photo has the depth (fusion drops it), orange to green 2 to 7 photos agree.</p>\n"
      "<table>\n<tr><th>photo</th><th>name</th><th>status</th><th>depth</th><th>quality</th>"
      "<th>dense</th><th>model</th></tr>\n";
  for (const ReportPhoto& photo : input_.photos) PhotoRow(photo, maps, renders);
  html_ += "</table>\n";
}

void Page::PhotoRow(const ReportPhoto& photo,
                    const std::map<int, const json*>& maps,
                    const std::map<int, const json*>& renders) {
  std::string status = "<td>registered</td>";
  if (!photo.accepted) {
    status = "<td class=\"failed\">refused: " + HtmlEscape(photo.refusal) + "</td>";
  } else if (!photo.registered) {
    status = "<td class=\"skipped\">not registered</td>";
  }
  std::string dense = "&mdash;";
  if (const auto it = maps.find(photo.index); photo.registered && it != maps.end()) {
    const json& map = *it->second;
    dense = Percent(Field(map, "depth_fraction")) + " with depth, " +
            Percent(Field(map, "fused_fraction")) + " fused, " + Seconds(Field(map, "seconds"));
    if (Has(photo.depth_map) || !LeftOutBy(photo.depth_map).empty())
      dense += "<br>" + Link(photo.depth_map, "depth") + ", " + Link(photo.quality_map, "quality");
  }
  std::string model = "&mdash;";
  if (const auto it = renders.find(photo.index); photo.registered && it != renders.end()) {
    model = Percent(Field(*it->second, "covered")) + " covered, difference " +
            Fixed(Number(Field(*it->second, "mean_abs_diff")), 1);
  }
  const bool dense_row = photo.registered && maps.count(photo.index);
  html_ += "<tr><td>" + Picture(photo.thumbnail, photo.name, 160, false) + "</td><td>" +
           HtmlEscape(photo.name) + "</td>" + status + "<td>" +
           (dense_row ? Picture(photo.depth_preview, photo.name + ": depth", 160, false) : "") +
           "</td><td>" +
           (dense_row ? Picture(photo.quality_preview, photo.name + ": quality", 160, false) : "") +
           "</td><td>" + dense + "</td><td>" + model + "</td></tr>\n";
}

void Page::Files() {
  html_ += "<h2>Files</h2>\n";
  if (!input_.left_out.empty()) {
    std::string list;
    for (const std::string& entry : input_.left_out)
      list += (list.empty() ? "" : ", ") + HtmlEscape(entry);
    html_ += "<p class=\"note\">Left out of this archive (option " +
             HtmlEscape(input_.left_out_option) + "): " + list +
             ". The service still serves them one by one with the job's files.</p>\n";
  }
  html_ += "<ul>\n";
  for (const std::string& file : input_.files)
    html_ += "<li><a href=\"" + Url(file) + "\">" + HtmlEscape(file) + "</a></li>\n";
  html_ += "</ul>\n";
}

void Page::Options() {
  const json& options = Field(input_.report, "options");
  if (!options.is_object()) return;
  html_ += "<h2>Options</h2>\n<table>\n";
  for (const auto& [name, value] : options.items()) {
    html_ += "<tr><th>" + HtmlEscape(name) + "</th><td>" + HtmlEscape(Text(value)) + "</td></tr>\n";
  }
  html_ += "</table>\n";
}

std::string Page::LeftOutBy(const std::string& path) const {
  if (path.empty()) return "";
  for (const std::string& entry : input_.left_out) {
    if (entry.ends_with('/') ? path.starts_with(entry) : path == entry)
      return input_.left_out_option;
  }
  return "";
}

std::string Page::Picture(const std::string& path,
                          const std::string& alt,
                          int max_width,
                          bool caption) const {
  if (!Has(path)) {
    const std::string option = LeftOutBy(path);
    if (!option.empty()) return "<span class=\"note\">left out (" + HtmlEscape(option) + ")</span>";
    return "<span class=\"note\">no picture" +
           (path.empty() ? std::string() : ": " + HtmlEscape(path) + " is not in this archive") +
           "</span>";
  }
  return "<figure><a href=\"" + Url(path) + "\"><img src=\"" + Url(path) + "\" alt=\"" +
         HtmlEscape(alt) + "\" style=\"max-width:" + std::to_string(max_width) + "px\"></a>" +
         (caption ? "<figcaption>" + HtmlEscape(alt) + "</figcaption>" : "") + "</figure>";
}

std::string Page::Link(const std::string& path, const std::string& label) const {
  if (Has(path)) return "<a href=\"" + Url(path) + "\">" + HtmlEscape(label) + "</a>";
  const std::string option = LeftOutBy(path);
  if (!option.empty()) return HtmlEscape(label) + " left out (" + HtmlEscape(option) + ")";
  return HtmlEscape(label) + " absent";
}

}  // namespace

std::string HtmlEscape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string RenderReportHtml(const ReportHtmlInput& input) { return Page(input).Render(); }

}  // namespace reconduit
