// Counting heap allocations in tests, to check that steady-state frame processing allocates
// nothing. Linking fb_test_allocations interposes malloc for the whole test process: that
// catches operator new (libstdc++ calls malloc), Eigen's aligned allocations and C library
// allocations (a FILE*, say) alike, which a replaced operator new alone would miss. glibc
// exports __libc_malloc for this kind of forwarding; sanitizer builds bring their own malloc,
// so there counting is unavailable and tests skip their allocation checks.
#pragma once

namespace fb::test {

// False in sanitizer and non-glibc builds.
bool allocation_counting_available();

// Counts every allocation of the process (all threads) while it lives. Not nestable.
class CountAllocations {
 public:
  CountAllocations();
  ~CountAllocations();
  CountAllocations(const CountAllocations&) = delete;
  CountAllocations& operator=(const CountAllocations&) = delete;
  long count() const;
};

// Counts the allocations of the constructing thread only (other threads, e.g. a driver's
// event thread, may allocate freely). Not nestable on one thread.
class CountThreadAllocations {
 public:
  CountThreadAllocations();
  ~CountThreadAllocations();
  CountThreadAllocations(const CountThreadAllocations&) = delete;
  CountThreadAllocations& operator=(const CountThreadAllocations&) = delete;
  long count() const;
};

}  // namespace fb::test
