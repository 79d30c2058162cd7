// The last stage: report.json, report.html, manifest.json and result.zip.
//
// report.json records every earlier stage (status, seconds, peak memory, its summary counts),
// the options the run used, and the totals. report.html shows the same with the report's
// pictures (core/pipeline/report_html.h), linking only files the archive holds. The output
// folder is then packed into the workspace's archive (when one is set) with a manifest of
// sizes and SHA-256 sums; with package_dense_files off, dense.ply, depth/ and quality/ stay in
// the folder but out of the archive and its manifest (summary "left_out"). The stage's result
// then carries the archive as a PackageResult (its summary keeps the figures for the job's
// stage status and the log).
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_PACKAGE_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_PACKAGE_STAGE_H_

#include "core/pipeline/stage.h"

namespace reconduit {

class PackageStage : public Stage {
 public:
  std::string_view Name() const override { return "package"; }
  std::string_view Title() const override { return "Packing the results"; }
  double Weight() const override { return 0.2; }
  bool Resumable() const override { return false; }
  StageResult Run(StageContext& context) const override;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_PACKAGE_STAGE_H_
