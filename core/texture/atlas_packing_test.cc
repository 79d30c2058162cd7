#include "core/texture/atlas_packing.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace reconduit {
namespace {

TEST(PackRectangles, NeverOverlapsAndRespectsThePageSize) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> small(1, 60), large(1, 256);
  std::vector<int> widths, heights;
  for (int i = 0; i < 2000; ++i) {
    const bool big = i % 50 == 0;
    widths.push_back(big ? large(rng) : small(rng));
    heights.push_back(big ? large(rng) : small(rng));
  }
  widths.push_back(256);  // A rectangle of the full page size.
  heights.push_back(256);
  const int page_size = 256;
  const AtlasLayout layout = PackRectangles(widths, heights, page_size);
  ASSERT_EQ(layout.placements.size(), widths.size());
  ASSERT_EQ(layout.page_widths.size(), layout.page_heights.size());
  const int num_pages = static_cast<int>(layout.page_widths.size());
  EXPECT_GT(num_pages, 1);
  std::vector<std::vector<int>> owner(num_pages, std::vector<int>(page_size * page_size, -1));
  long used_area = 0, rect_area = 0;
  for (std::size_t i = 0; i < widths.size(); ++i) {
    const PackedRect& r = layout.placements[i];
    ASSERT_GE(r.page, 0);
    ASSERT_LT(r.page, num_pages);
    ASSERT_GE(r.x, 0);
    ASSERT_GE(r.y, 0);
    ASSERT_LE(r.x + widths[i], layout.page_widths[r.page]);
    ASSERT_LE(r.y + heights[i], layout.page_heights[r.page]);
    for (int y = r.y; y < r.y + heights[i]; ++y) {
      for (int x = r.x; x < r.x + widths[i]; ++x) {
        ASSERT_EQ(owner[r.page][y * page_size + x], -1)
            << "rectangles overlap at " << x << "," << y;
        owner[r.page][y * page_size + x] = static_cast<int>(i);
      }
    }
    rect_area += static_cast<long>(widths[i]) * heights[i];
  }
  for (int p = 0; p < num_pages; ++p) {
    EXPECT_LE(layout.page_widths[p], page_size);
    EXPECT_LE(layout.page_heights[p], page_size);
    used_area += static_cast<long>(layout.page_widths[p]) * layout.page_heights[p];
  }
  const double fill = double(rect_area) / used_area;
  std::printf("%d pages, fill %.3f\n", num_pages, fill);
  EXPECT_GT(fill, 0.8);
}

TEST(PackRectangles, CropsASmallAtlasToItsExtent) {
  const AtlasLayout layout = PackRectangles({10, 20}, {5, 7}, 4096);
  ASSERT_EQ(layout.page_widths.size(), 1u);
  EXPECT_EQ(layout.page_widths[0], 30);
  EXPECT_EQ(layout.page_heights[0], 7);
}

TEST(PackRectangles, RejectsRectanglesLargerThanAPage) {
  EXPECT_THROW(PackRectangles({65}, {10}, 64), CheckError);
  EXPECT_THROW(PackRectangles({0}, {10}, 64), CheckError);
  EXPECT_TRUE(PackRectangles({}, {}, 64).page_widths.empty());
}

}  // namespace
}  // namespace reconduit
