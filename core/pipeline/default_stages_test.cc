#include "core/pipeline/default_stages.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace reconduit {
namespace {

using ::testing::ElementsAre;

std::vector<std::string> NamesOf(const std::vector<std::unique_ptr<Stage>>& stages) {
  std::vector<std::string> names;
  for (const auto& stage : stages) names.emplace_back(stage->Name());
  return names;
}

TEST(DefaultStages, UntilNamesTheWorkStagesOnly) {
  EXPECT_THAT(PipelineStageNames(), ElementsAre("ingest", "features", "pairs", "matching", "sparse",
                                                "dense", "mesh", "texture"));
}

TEST(DefaultStages, ExportAndPackagingAlwaysRunLast) {
  auto all = CreatePipelineStages();
  ASSERT_TRUE(all.ok()) << all.status();
  EXPECT_THAT(NamesOf(*all), ElementsAre("ingest", "features", "pairs", "matching", "sparse",
                                         "dense", "mesh", "texture", "export", "package"));
  // `--until sparse` still delivers the sparse files.
  auto sparse = CreatePipelineStages("sparse");
  ASSERT_TRUE(sparse.ok()) << sparse.status();
  EXPECT_THAT(NamesOf(*sparse), ElementsAre("ingest", "features", "pairs", "matching", "sparse",
                                            "export", "package"));
  auto features = CreatePipelineStages("features");
  ASSERT_TRUE(features.ok()) << features.status();
  EXPECT_THAT(NamesOf(*features), ElementsAre("ingest", "features", "export", "package"));
}

TEST(DefaultStages, UnknownStageListsTheKnownOnes) {
  auto stages = CreatePipelineStages("export");
  ASSERT_FALSE(stages.ok());
  EXPECT_EQ(stages.status().message(),
            "unknown stage 'export'; stages: ingest, features, pairs, matching, sparse, dense, "
            "mesh, texture");
}

}  // namespace
}  // namespace reconduit
