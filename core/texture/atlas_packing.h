// Packing of rectangles (texture charts) into atlas pages of a bounded size.
//
// Shelf packing ("next fit decreasing height"): rectangles sorted by decreasing height are
// placed left to right on horizontal shelves; a rectangle that does not fit the shelf's width
// opens a new shelf below, one that does not fit the page's height opens a new page. With
// heights sorted, the space a shelf wastes is at most the height difference of its
// rectangles, which for the many similar small charts of a textured mesh is a few per cent
// (measured in atlas_packing_test: > 80 % of the used area filled on random charts); skyline or
// maxrects packing would gain a few per cent more at the price of a more complex search.
// Pages are cropped to the extent actually used, so a small mesh does not carry a mostly empty
// 4096² image; every page is at most page_size on each side, and more charts make more pages
// rather than a larger one.
#ifndef RECONDUIT_CORE_TEXTURE_ATLAS_PACKING_H_
#define RECONDUIT_CORE_TEXTURE_ATLAS_PACKING_H_

#include <vector>

namespace reconduit {

struct PackedRect {
  int page = 0;  // Index of the page holding the rectangle.
  int x = 0;     // Top-left corner on the page, pixels.
  int y = 0;
};

struct AtlasLayout {
  std::vector<PackedRect> placements;  // One per input rectangle, in input order.
  // Size of each page: the extent its rectangles use, each side in [1, page_size].
  std::vector<int> page_widths;
  std::vector<int> page_heights;
};

// Packs rectangles of the given sizes (pixels, each side in [1, page_size]) onto pages of at
// most page_size x page_size with no two rectangles overlapping. Throws CheckError for a size
// out of range or page_size < 1. Deterministic (ties in height keep the input order).
AtlasLayout PackRectangles(const std::vector<int>& widths,
                           const std::vector<int>& heights,
                           int page_size);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_TEXTURE_ATLAS_PACKING_H_
