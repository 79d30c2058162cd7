#include "core/texture/atlas_packing.h"

#include "core/util/logging.h"

#include <algorithm>
#include <numeric>

namespace reconduit {

AtlasLayout PackRectangles(const std::vector<int>& widths,
                           const std::vector<int>& heights,
                           int page_size) {
  THROW_CHECK_GE(page_size, 1);
  THROW_CHECK_EQ(widths.size(), heights.size());
  for (std::size_t i = 0; i < widths.size(); ++i) {
    THROW_CHECK(widths[i] >= 1 && widths[i] <= page_size && heights[i] >= 1 &&
                heights[i] <= page_size)
        << "rectangle " << i << " is " << widths[i] << "x" << heights[i] << ", page " << page_size;
  }
  std::vector<int> order(widths.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return heights[a] > heights[b]; });

  AtlasLayout layout;
  layout.placements.resize(widths.size());
  int page = -1, shelf_y = 0, shelf_height = 0, cursor_x = 0;
  for (const int i : order) {
    if (page >= 0 && cursor_x + widths[i] > page_size) {  // Next shelf.
      shelf_y += shelf_height;
      shelf_height = 0;
      cursor_x = 0;
    }
    if (page < 0 || shelf_y + heights[i] > page_size) {  // Next page.
      ++page;
      layout.page_widths.push_back(1);
      layout.page_heights.push_back(1);
      shelf_y = 0;
      shelf_height = 0;
      cursor_x = 0;
    }
    layout.placements[i] = {page, cursor_x, shelf_y};
    cursor_x += widths[i];
    shelf_height = std::max(shelf_height, heights[i]);
    layout.page_widths[page] = std::max(layout.page_widths[page], cursor_x);
    layout.page_heights[page] = std::max(layout.page_heights[page], shelf_y + heights[i]);
  }
  return layout;
}

}  // namespace reconduit
