// Backs each large allocation with transparent huge pages, for the mesh targets' speed only.
// assimp 5.2.5's OBJ reader allocates and fills a 16 MiB stream buffer per file (IOStreamBuffer's
// default cache, sized in its constructor, before it learns the file's size: a stream that
// reports a small size does not shrink it). ASan serves such a block with a fresh mmap every
// time, so each execution first-touches 4096 pages, and on a virtual machine a page fault is
// what the execution costs (perf: page faults and page clearing, not the reader). madvise
// changes which pages back the block, not what ASan checks: its redzones and shadow stay.
// Through the sanitizer's malloc hook, so without ASan (the ctest corpus replays) it is a no-op.
#pragma once

#include <cstddef>
#include <cstdint>

#include <sys/mman.h>

extern "C" __attribute__((weak)) int __sanitizer_install_malloc_and_free_hooks(
    void (*malloc_hook)(const volatile void*, std::size_t), void (*free_hook)(const volatile void*));

namespace incise::fuzz {

inline void advise_huge_pages(const volatile void* block, std::size_t size) {
  constexpr std::uintptr_t huge = std::uintptr_t{2} << 20;  // x86-64's PMD size
  if (size < 2 * huge) return;
  const auto begin = (reinterpret_cast<std::uintptr_t>(block) + huge - 1) & ~(huge - 1);
  const auto end = (reinterpret_cast<std::uintptr_t>(block) + size) & ~(huge - 1);
  if (end > begin) ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);  // a refusal only costs speed
}

inline void back_large_allocations_with_huge_pages() {
  static const bool installed = __sanitizer_install_malloc_and_free_hooks &&
                                __sanitizer_install_malloc_and_free_hooks(advise_huge_pages, [](const volatile void*) {});
  (void)installed;
}

}  // namespace incise::fuzz
