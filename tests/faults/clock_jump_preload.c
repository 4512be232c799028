/* A wall clock that jumps, for one process: LD_PRELOAD this library. It adds an offset to
 * CLOCK_REALTIME (clock_gettime, gettimeofday, time) and leaves the monotonic clocks alone, as
 * NTP stepping the clock or an operator setting it does. The offset is
 *  - FB_FAULT_CLOCK_JUMP_S seconds (may be negative) once FB_FAULT_CLOCK_JUMP_AFTER_S seconds of
 *    monotonic time have passed since the process first read the clock (for a process under
 *    test), and/or
 *  - whatever the process adds by calling fb_fault_clock_jump(seconds), found with dlsym (for
 *    a test in the same process).
 * Used by tests/faults (faceboothd through a jump) and tests/camera_freenect (frame times). */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <sys/time.h>
#include <time.h>

static _Atomic long long added_ns = 0;
static _Atomic long long first_mono_ns = 0;

static int (*real_clock_gettime)(clockid_t, struct timespec*) = NULL;

static long long mono_ns(void) {
  struct timespec ts;
  if (real_clock_gettime == NULL)
    real_clock_gettime = (int (*)(clockid_t, struct timespec*))dlsym(RTLD_NEXT, "clock_gettime");
  real_clock_gettime(CLOCK_MONOTONIC, &ts);
  return (long long)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

void fb_fault_clock_jump(double seconds) { added_ns += (long long)(seconds * 1e9); }

static long long offset_ns(void) {
  long long offset = added_ns;
  const char* jump = getenv("FB_FAULT_CLOCK_JUMP_S");
  if (jump != NULL) {
    const long long now = mono_ns();
    long long expected = 0;
    atomic_compare_exchange_strong(&first_mono_ns, &expected, now);
    const char* after = getenv("FB_FAULT_CLOCK_JUMP_AFTER_S");
    const double after_s = after ? atof(after) : 0.0;
    if ((double)(now - first_mono_ns) >= after_s * 1e9) offset += (long long)(atof(jump) * 1e9);
  }
  return offset;
}

static int is_realtime(clockid_t id) {
  return id == CLOCK_REALTIME || id == CLOCK_REALTIME_COARSE;
}

int clock_gettime(clockid_t id, struct timespec* ts) {
  if (real_clock_gettime == NULL)
    real_clock_gettime = (int (*)(clockid_t, struct timespec*))dlsym(RTLD_NEXT, "clock_gettime");
  const int rc = real_clock_gettime(id, ts);
  if (rc != 0 || !is_realtime(id)) return rc;
  long long ns = (long long)ts->tv_sec * 1000000000LL + ts->tv_nsec + offset_ns();
  ts->tv_sec = ns / 1000000000LL;
  ts->tv_nsec = ns % 1000000000LL;
  if (ts->tv_nsec < 0) {
    ts->tv_nsec += 1000000000LL;
    ts->tv_sec -= 1;
  }
  return 0;
}

/* glibc declares tv nonnull; callers that pass NULL anyway must not crash here. */
#pragma GCC diagnostic ignored "-Wnonnull-compare"
int gettimeofday(struct timeval* tv, void* tz) {
  (void)tz;
  struct timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  if (tv != NULL) {
    tv->tv_sec = ts.tv_sec;
    tv->tv_usec = ts.tv_nsec / 1000;
  }
  return 0;
}

time_t time(time_t* out) {
  struct timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  if (out != NULL) *out = ts.tv_sec;
  return ts.tv_sec;
}
