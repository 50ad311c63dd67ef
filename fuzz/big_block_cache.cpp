// The mesh target's operator new: assimp's OBJ reader allocates two 16 MiB buffers per file and
// fills them; under ASan each is a fresh mapping, and on this VM the page faults took about
// 100 ms per input (55 executions a second). Here blocks of at least 1 MiB are kept after
// delete and handed out again, zeroed, to a request that fits. Each sits between poisoned
// guards, so a read or write past either end of it still reports (as ASan's redzones would),
// and a cached block is poisoned, so a use after delete reports too. Everything smaller, and
// every aligned new, is ASan's as before (malloc and free underneath, so the two never mix).
#include <sanitizer/asan_interface.h>

#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>

namespace {

constexpr std::size_t kLarge = std::size_t{1} << 20;
constexpr std::size_t kGuard = 4096;
constexpr int kSlots = 8;

struct Block {
  char* base = nullptr;       // malloc's pointer: guard, capacity, guard
  std::size_t capacity = 0;
  bool in_use = false;
};

Block blocks[kSlots];
std::mutex blocks_mutex;

void* allocate(std::size_t size) {
  if (size >= kLarge) {
    std::lock_guard<std::mutex> lock(blocks_mutex);
    Block* empty = nullptr;
    for (Block& block : blocks) {
      if (!block.base) { empty = empty ? empty : &block; continue; }
      if (block.in_use || block.capacity < size || block.capacity > 2 * size) continue;
      block.in_use = true;
      ASAN_UNPOISON_MEMORY_REGION(block.base + kGuard, size);
      // Zeros, as a fresh mapping reads: the last input's bytes left in a reused buffer let
      // assimp (not instrumented) parse past its data, and the run ended in an ASan internal
      // check (a chunk header overwritten) that no input reproduced alone.
      std::memset(block.base + kGuard, 0, size);
      return block.base + kGuard;
    }
    if (empty) {
      char* base = static_cast<char*>(std::malloc(size + 2 * kGuard));
      if (!base) throw std::bad_alloc();
      *empty = {base, size, true};
      ASAN_POISON_MEMORY_REGION(base, kGuard);
      ASAN_POISON_MEMORY_REGION(base + kGuard + size, kGuard);
      return base + kGuard;
    }
  }
  void* p = std::malloc(size ? size : 1);
  if (!p) throw std::bad_alloc();
  return p;
}

void release(void* p) {
  if (!p) return;
  {
    std::lock_guard<std::mutex> lock(blocks_mutex);
    for (Block& block : blocks) {
      if (block.base && block.base + kGuard == p) {
        block.in_use = false;
        ASAN_POISON_MEMORY_REGION(block.base + kGuard, block.capacity);
        return;
      }
    }
  }
  std::free(p);
}

}  // namespace

void* operator new(std::size_t size) { return allocate(size); }
void* operator new[](std::size_t size) { return allocate(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  try { return allocate(size); } catch (...) { return nullptr; }
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  try { return allocate(size); } catch (...) { return nullptr; }
}
void operator delete(void* p) noexcept { release(p); }
void operator delete[](void* p) noexcept { release(p); }
void operator delete(void* p, std::size_t) noexcept { release(p); }
void operator delete[](void* p, std::size_t) noexcept { release(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { release(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { release(p); }
