#include "core/pipeline/report_html.h"

#include <gtest/gtest.h>

#include <regex>
#include <set>
#include <string>

namespace reconduit {
namespace {

using nlohmann::json;

json StageJson(const std::string& name, json summary, double seconds = 1.5) {
  return {{"name", name},
          {"status", "success"},
          {"message", ""},
          {"seconds", seconds},
          {"peak_memory_bytes", 2'500'000'000},
          {"stage_peak_memory_bytes", 820'000'000},
          {"stage_peak_memory_own", true},
          {"summary", std::move(summary)},
          {"options", json::object()}};
}

// A report as the package stage writes it: a sparse model, a dense stage with one map, the
// mesh skipped (and so the texture), a photo whose name is markup.
ReportHtmlInput SampleInput() {
  ReportHtmlInput input;
  json sparse = StageJson("sparse", {{"registered", 1},
                                     {"photos", 2},
                                     {"points", 2448},
                                     {"models", 1},
                                     {"mean_reprojection_error_px", 0.4629},
                                     {"cameras", json::array()}});
  sparse["stage_peak_memory_own"] = false;
  input.report = {
      {"image_count", 3},
      {"total_seconds", 31.2},
      {"peak_memory_bytes", 2'500'000'000},
      {"options", {{"dense_max_image_side", 320}, {"package_dense_files", false}}},
      {"stages",
       {StageJson("ingest", {{"accepted", 2}}), sparse,
        StageJson("dense", {{"points", 86827},
                            {"maps",
                             {{{"image_id", 0},
                               {"depth_fraction", 0.765},
                               {"fused_fraction", 0.362},
                               {"seconds", 0.96}}}}}),
        StageJson("mesh", {{"skipped_reason", "no surface <here> & \"there\""}}),
        StageJson("texture", {{"skipped_reason", "no mesh (the mesh stage skipped)"}})}}};
  ReportPhoto first;
  first.index = 0;
  first.name = "<script>alert('x')</script>&b.jpg";
  first.accepted = true;
  first.registered = true;
  first.thumbnail = "report/photos/_script_alert__x____script___b.jpg";
  first.depth_preview = "report/dense/a_depth.jpg";
  first.quality_preview = "report/dense/a_quality.png";  // Not in the archive.
  first.depth_map = "depth/a.png";
  first.quality_map = "quality/a.png";
  ReportPhoto second;
  second.index = 1;
  second.name = "b.jpg";
  second.accepted = true;
  ReportPhoto refused;
  refused.index = 2;
  refused.name = "c.jpg";
  refused.refusal = "shorter side 80 < 100 <px>";
  input.photos = {first, second, refused};
  input.files = {"report.html",
                 "report.json",
                 "manifest.json",
                 "report/similarity.png",
                 "report/dense/a_depth.jpg",
                 "report/photos/_script_alert__x____script___b.jpg"};
  input.left_out = {"dense.ply", "depth/", "quality/"};
  input.left_out_option = "package_dense_files";
  return input;
}

TEST(HtmlEscape, EscapesTheFiveSpecialCharacters) {
  EXPECT_EQ(HtmlEscape("a<b>&\"c'd"), "a&lt;b&gt;&amp;&quot;c&#39;d");
  EXPECT_EQ(HtmlEscape("plain é"), "plain é");
}

TEST(RenderReportHtml, EscapesPhotoNamesAndReasons) {
  const std::string html = RenderReportHtml(SampleInput());
  EXPECT_EQ(html.find("<script"), std::string::npos) << "no script, and no name unescaped";
  EXPECT_NE(html.find("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;&amp;b.jpg"),
            std::string::npos);
  EXPECT_NE(html.find("refused: shorter side 80 &lt; 100 &lt;px&gt;"), std::string::npos);
  EXPECT_NE(html.find("no surface &lt;here&gt; &amp; &quot;there&quot;"), std::string::npos);
}

TEST(RenderReportHtml, ShowsSkippedStagesWithTheirReasons) {
  const std::string html = RenderReportHtml(SampleInput());
  EXPECT_NE(html.find("<td>mesh</td><td class=\"skipped\">skipped</td>"), std::string::npos);
  EXPECT_NE(html.find("<td>texture</td><td class=\"skipped\">skipped</td>"), std::string::npos);
  EXPECT_NE(html.find("no mesh (the mesh stage skipped)"), std::string::npos);
  // Figures of skipped stages read as absent; those of stages that ran are shown.
  EXPECT_NE(html.find("<th>mesh faces</th><td class=\"n\">&mdash;</td>"), std::string::npos);
  EXPECT_NE(html.find("<th>dense points</th><td class=\"n\">86827</td>"), std::string::npos);
  EXPECT_NE(html.find("<th>sparse points</th><td class=\"n\">2448</td>"), std::string::npos);
  EXPECT_NE(html.find("0.463 px"), std::string::npos);
  // Each stage's time, own peak (marked when it is the process's) and the process's peak.
  EXPECT_NE(html.find("1.50 s</td><td class=\"n\">820.0 MB</td><td class=\"n\">2.50 GB"),
            std::string::npos);
  EXPECT_NE(html.find("820.0 MB (the process's)"), std::string::npos) << "the sparse stage";
}

TEST(RenderReportHtml, SaysWhichPhotosTheModelLeftOut) {
  ReportHtmlInput input = SampleInput();
  EXPECT_EQ(RenderReportHtml(input).find("are in the model"), std::string::npos)
      << "nothing said when no photo is left out";
  for (json& stage : input.report["stages"]) {
    if (stage["name"] == "sparse") {
      stage["summary"]["left_out"] = {
          {"unmatched", {"b.jpg"}},
          {"note", "1 of 2 photos are in the model. 1 photo (b.jpg) matched no <other> photo."}};
    }
  }
  EXPECT_NE(RenderReportHtml(input).find("<p class=\"skipped\">1 of 2 photos are in the model. 1 "
                                         "photo (b.jpg) matched no &lt;other&gt; photo.</p>"),
            std::string::npos);
}

TEST(RenderReportHtml, LinksOnlyFilesTheArchiveHolds) {
  const ReportHtmlInput input = SampleInput();
  const std::string html = RenderReportHtml(input);
  const std::regex reference("(src|href)=\"([^\"]*)\"");
  int count = 0;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), reference);
       it != std::sregex_iterator(); ++it) {
    std::string target = (*it)[2].str();
    ASSERT_EQ(target.rfind("./", 0), 0u) << target << ": relative, inside the archive";
    EXPECT_TRUE(input.files.count(target.substr(2))) << target;
    ++count;
  }
  EXPECT_GT(count, 6);
  // The thumbnail and the depth preview are shown; the missing quality preview, the match
  // graph and the left-out maps are not linked, and the page says why.
  EXPECT_NE(html.find("<img src=\"./report/photos/_script_alert__x____script___b.jpg\""),
            std::string::npos);
  EXPECT_NE(html.find("<img src=\"./report/dense/a_depth.jpg\""), std::string::npos);
  EXPECT_NE(html.find("no picture: report/dense/a_quality.png is not in this archive"),
            std::string::npos);
  EXPECT_NE(html.find("no picture: report/match_graph.png is not in this archive"),
            std::string::npos);
  EXPECT_NE(html.find("depth left out (package_dense_files)"), std::string::npos);
  EXPECT_NE(html.find("Left out of this archive (option package_dense_files): dense.ply, "
                      "depth/, quality/"),
            std::string::npos);
  EXPECT_NE(html.find("model.glb absent"), std::string::npos);
  // Nothing to fetch from elsewhere.
  for (const char* external : {"http:", "https:", "<link", "@import", "url("})
    EXPECT_EQ(html.find(external), std::string::npos) << external;
}

TEST(RenderReportHtml, ShowsRendersBesideTheirPhotos) {
  ReportHtmlInput input = SampleInput();
  input.report["stages"][4] =
      StageJson("texture", {{"texture", {{"faces", 1000}, {"unseen_faces", 70}, {"charts", 12}}},
                            {"renders",
                             {{{"name", "a.jpg"},
                               {"image_id", 0},
                               {"held_out", true},
                               {"covered", 0.587},
                               {"mean_abs_diff", 17.34},
                               {"render_picture", "report/texture/a_render.jpg"},
                               {"photo_picture", "report/texture/a_photo.jpg"}},
                              {{"name", "b.jpg"}, {"image_id", 1}, {"covered", 0.5}}}}});
  input.files.insert("report/texture/a_render.jpg");
  input.files.insert("report/texture/a_photo.jpg");
  const std::string html = RenderReportHtml(input);
  EXPECT_NE(html.find("<h3>a.jpg (held out of dense matching and texturing): covered 58.7 %, "
                      "difference 17.3</h3>"),
            std::string::npos);
  const auto render = html.find("<img src=\"./report/texture/a_render.jpg\"");
  const auto photo = html.find("<img src=\"./report/texture/a_photo.jpg\"");
  ASSERT_NE(render, std::string::npos);
  ASSERT_NE(photo, std::string::npos);
  EXPECT_LT(render, photo) << "the render left of its photo";
  EXPECT_EQ(html.find("<h3>b.jpg"), std::string::npos) << "no pictures: figures only";
  EXPECT_NE(html.find("<th>faces no photo sees</th><td class=\"n\">70 (7.0 %)</td>"),
            std::string::npos);
  EXPECT_NE(html.find("58.7 % covered, difference 17.3"), std::string::npos) << "photo row";
}

TEST(RenderReportHtml, OddReportContentReadsAsAbsent) {
  ReportHtmlInput input;
  input.report = {{"stages", {{{"name", 3}, {"summary", "x"}}, "y"}}, {"image_count", "many"}};
  input.photos = {ReportPhoto{}};
  const std::string html = RenderReportHtml(input);
  EXPECT_NE(html.find("<th>photos</th><td class=\"n\">&mdash;</td>"), std::string::npos);
  EXPECT_NE(html.find("</html>"), std::string::npos);
}

}  // namespace
}  // namespace reconduit
