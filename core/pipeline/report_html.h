// report.html: the job's report as a page that opens from the extracted result.zip.
//
// The page shows what report.json records (counts, each stage's time, its own peak memory and
// the process's, skipped stages with their reasons, the cameras and the reprojection error,
// the options) with the report's pictures: the similarity matrix and the match graph, a
// thumbnail of every photo, the depth and quality previews, and the model rendered through a
// few photos' cameras beside those photos.
//
// It must open with no server and no network: the style is inline, there is no script and no
// font to fetch, and every picture and link is a relative path to a file of the same archive.
// Pictures are referenced, not embedded as data URIs: they already are files of the zip (the
// page and the API serve them one by one), so embedding would store them twice and make the
// page itself several megabytes of base64 on large photo sets. Chromium and Firefox load
// <img> from file:// pages relative to the page, which is all the page needs.
//
// Every string that can come from a user (photo names above all) is HTML-escaped; paths are
// percent-encoded too. A picture or file the archive does not hold is never linked: the page
// says it is absent (or left out of the zip by an option) instead.
#ifndef RECONDUIT_CORE_PIPELINE_REPORT_HTML_H_
#define RECONDUIT_CORE_PIPELINE_REPORT_HTML_H_

#include <nlohmann/json.hpp>

#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit {

// One photo's row in the page.
struct ReportPhoto {
  int index = -1;           // Position in the upload; the image id when registered.
  std::string name;         // As uploaded (shown escaped).
  bool accepted = false;    // Usable (ingest).
  std::string refusal;      // Ingest's reason when not accepted.
  bool registered = false;  // Has a camera in the delivered model.
  // Paths inside the archive ('/'-separated), empty when there is none for this photo. Only
  // those in ReportHtmlInput::files are shown or linked.
  std::string thumbnail;        // report/photos/<name>.jpg
  std::string depth_preview;    // report/dense/<name>_depth.jpg
  std::string quality_preview;  // report/dense/<name>_quality.png
  std::string depth_map;        // depth/<name>.png
  std::string quality_map;      // quality/<name>.png
};

struct ReportHtmlInput {
  // report.json's content: "image_count", "options", "stages" (StageRecord::ToJson each),
  // "total_seconds", "peak_memory_bytes". Missing fields are shown as absent, never guessed.
  nlohmann::json report = nlohmann::json::object();
  std::vector<ReportPhoto> photos;  // In upload order.
  // Every file the archive holds (report.html and manifest.json included), '/'-separated.
  std::set<std::string> files;
  // What an option left out of the archive: files ("dense.ply") or folders ending in '/'
  // ("depth/"), and the option that did it, for the note the page shows instead of links.
  std::vector<std::string> left_out;
  std::string left_out_option;
};

// `text` with & < > " ' replaced by character references: safe in element content and in
// quoted attribute values.
std::string HtmlEscape(std::string_view text);

// The whole page, UTF-8. Never throws for odd report content (wrong types read as absent).
std::string RenderReportHtml(const ReportHtmlInput& input);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_REPORT_HTML_H_
