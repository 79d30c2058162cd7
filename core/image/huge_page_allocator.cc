#include "core/image/huge_page_allocator.h"

#include <cstdint>
#include <memory>
#include <sys/mman.h>

namespace reconduit {
namespace {

constexpr std::size_t kHugePage = std::size_t{2} << 20;

std::size_t RoundUp(std::size_t bytes, std::size_t multiple) {
  return (bytes + multiple - 1) / multiple * multiple;
}

// Maps `length` bytes (a multiple of kHugePage) aligned to kHugePage: huge pages can only back
// aligned 2 MiB ranges. Over-maps by one huge page and unmaps the unaligned head and tail.
void* MapAligned(std::size_t length) {
  const std::size_t padded = length + kHugePage;
  void* raw = mmap(nullptr, padded, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) return nullptr;
  const auto begin = reinterpret_cast<std::uintptr_t>(raw);
  const std::uintptr_t aligned = RoundUp(begin, kHugePage);
  if (aligned > begin) munmap(raw, aligned - begin);
  const std::uintptr_t end = begin + padded;
  if (end > aligned + length)
    munmap(reinterpret_cast<void*>(aligned + length), end - aligned - length);
  void* data = reinterpret_cast<void*>(aligned);
  // Advice only: where huge pages are unavailable the mapping works with normal pages.
  madvise(data, length, MADV_HUGEPAGE);
  return data;
}

class HugePageAllocator final : public cv::MatAllocator {
 public:
  cv::UMatData* allocate(int dims,
                         const int* sizes,
                         int type,
                         void* data0,
                         std::size_t* step,
                         cv::AccessFlag flags,
                         cv::UMatUsageFlags usage) const override {
    // Dense layout, last dimension fastest, as OpenCV's standard allocator lays it out.
    std::size_t total = CV_ELEM_SIZE(type);
    for (int i = dims - 1; i >= 0; --i) total *= static_cast<std::size_t>(sizes[i]);
    if (data0 != nullptr || total < kMinHugeBytes) {
      return cv::Mat::getStdAllocator()->allocate(dims, sizes, type, data0, step, flags, usage);
    }
    if (step != nullptr) {
      std::size_t stride = CV_ELEM_SIZE(type);
      for (int i = dims - 1; i >= 0; --i) {
        step[i] = stride;
        stride *= static_cast<std::size_t>(sizes[i]);
      }
    }
    auto u = std::make_unique<cv::UMatData>(this);
    void* data = MapAligned(RoundUp(total, kHugePage));
    if (data == nullptr) {  // Out of address space or mappings: let malloc try.
      return cv::Mat::getStdAllocator()->allocate(dims, sizes, type, data0, step, flags, usage);
    }
    u->data = u->origdata = static_cast<uchar*>(data);
    u->size = total;
    return u.release();
  }

  bool allocate(cv::UMatData* u, cv::AccessFlag, cv::UMatUsageFlags) const override {
    return u != nullptr;
  }

  void deallocate(cv::UMatData* u) const override {
    if (u == nullptr) return;
    munmap(u->origdata, RoundUp(u->size, kHugePage));
    delete u;
  }
};

}  // namespace

cv::MatAllocator* HugePageMatAllocator() {
  static auto* const allocator = new HugePageAllocator();
  return allocator;
}

ScopedHugePageMatAllocator::ScopedHugePageMatAllocator()
    : previous_(cv::Mat::getDefaultAllocator()) {
  cv::Mat::setDefaultAllocator(HugePageMatAllocator());
}

ScopedHugePageMatAllocator::~ScopedHugePageMatAllocator() {
  cv::Mat::setDefaultAllocator(previous_);
}

}  // namespace reconduit
