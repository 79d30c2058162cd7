// An OpenCV matrix allocator that backs large buffers with transparent huge pages.
//
// Why: SIFT on a 3072 px photo builds a Gaussian and a DoG pyramid on the doubled image,
// about 1.5 GB of float buffers that are touched once, freed, and allocated again for the next
// photo. With the default allocator each buffer is a fresh mmap(), so every 4 KiB page is a
// page fault on first touch: on a virtual machine measured here those faults took more time
// than SIFT itself (7.4 s system time for 2 photos, 5.8 s per photo in all). Advising the
// kernel to use 2 MiB pages (madvise(MADV_HUGEPAGE); Debian's kernels run transparent huge
// pages in "madvise" mode, where only advised ranges get them) makes that 512 times fewer
// faults: 1.4 s per photo. With the defrag setting also "madvise" (Debian's default), the
// first touch of a huge page may compact memory synchronously: a short stall on a host whose
// memory is fragmented, still far cheaper than 512 faults.
// Buffers below `kMinHugeBytes` go to OpenCV's standard allocator unchanged. Where the kernel
// has huge pages disabled the advice is ignored and this behaves like the standard allocator.
//
// Usage: ScopedHugePageMatAllocator while a stage creates large cv::Mat; matrices allocated
// in the scope may outlive it (each remembers its allocator, which is never destroyed).
// Scopes must nest (each restores the default it found), which holds while one pipeline
// runs per process, as in the worker and the command line.
//
// Thread-safety: the allocator itself is stateless and thread-safe; installing and removing
// it changes OpenCV's process-wide default, so do that from one thread while no other thread
// allocates matrices (the stages run one at a time).
#ifndef RECONDUIT_CORE_IMAGE_HUGE_PAGE_ALLOCATOR_H_
#define RECONDUIT_CORE_IMAGE_HUGE_PAGE_ALLOCATOR_H_

#include <opencv2/core.hpp>

#include <cstddef>

namespace reconduit {

// The process-wide instance (never destroyed).
cv::MatAllocator* HugePageMatAllocator();

// Buffers of at least this many bytes are mapped with huge-page advice.
inline constexpr std::size_t kMinHugeBytes = std::size_t{4} << 20;

// Makes HugePageMatAllocator() OpenCV's default allocator for its lifetime and restores the
// previous default afterwards.
class ScopedHugePageMatAllocator {
 public:
  ScopedHugePageMatAllocator();
  ~ScopedHugePageMatAllocator();
  ScopedHugePageMatAllocator(const ScopedHugePageMatAllocator&) = delete;
  ScopedHugePageMatAllocator& operator=(const ScopedHugePageMatAllocator&) = delete;

 private:
  cv::MatAllocator* previous_;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_HUGE_PAGE_ALLOCATOR_H_
