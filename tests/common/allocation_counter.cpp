#include "tests/common/allocation_counter.hpp"

#include <atomic>
#include <cstdlib>

#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
#define FB_COUNT_MALLOC 1
#endif

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
thread_local bool t_counting = false;
thread_local long t_allocations = 0;
}  // namespace

#ifdef FB_COUNT_MALLOC
extern "C" void* __libc_malloc(std::size_t size);
extern "C" void* malloc(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (t_counting) ++t_allocations;
  return __libc_malloc(size);
}
#endif

namespace fb::test {

bool allocation_counting_available() {
#ifdef FB_COUNT_MALLOC
  // Proves the hook is live, so that a zero count means something.
  CountThreadAllocations probe_count;
  void* volatile probe = std::malloc(16);
  std::free(probe);
  return probe_count.count() == 1;
#else
  return false;
#endif
}

CountAllocations::CountAllocations() {
  g_allocations = 0;
  g_counting = true;
}
CountAllocations::~CountAllocations() {
  g_counting = false;
}
long CountAllocations::count() const {
  return g_allocations.load();
}

CountThreadAllocations::CountThreadAllocations() {
  t_allocations = 0;
  t_counting = true;
}
CountThreadAllocations::~CountThreadAllocations() {
  t_counting = false;
}
long CountThreadAllocations::count() const {
  return t_allocations;
}

}  // namespace fb::test
