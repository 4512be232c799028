/* A full disk for one process, without a loop mount: LD_PRELOAD this library and set
 * FB_FAULT_ENOSPC_MATCH to a path substring. Every file opened for writing whose path contains
 * it then fails each write (write, pwrite, writev, fallocate) with ENOSPC, as a full
 * file system does; reads, and files elsewhere, are untouched. FB_FAULT_ENOSPC_AFTER=N lets the
 * first N bytes of each such file through (a disk that fills part-way through a file).
 * Used by tests/daemon/daemon_faults_test.cpp on the real faceboothd (issue 41). */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

#define MAX_FDS 4096

/* Per descriptor: 0 = not watched, else 1 + bytes written so far (capped). The table is the
 * shim's own state, guarded by a mutex; the product under test has no such state. */
static long long watched[MAX_FDS];
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;

static int matches(const char* path, int flags) {
  const char* match = getenv("FB_FAULT_ENOSPC_MATCH");
  if (match == NULL || *match == '\0' || path == NULL) return 0;
  if ((flags & (O_WRONLY | O_RDWR)) == 0) return 0;
  return strstr(path, match) != NULL;
}

static void track(int fd, const char* path, int flags) {
  if (fd < 0 || fd >= MAX_FDS) return;
  pthread_mutex_lock(&lock);
  watched[fd] = matches(path, flags) ? 1 : 0;
  pthread_mutex_unlock(&lock);
}

/* Returns 1 when a write of `n` bytes to `fd` must fail; else counts the bytes. */
static int full(int fd, size_t n) {
  if (fd < 0 || fd >= MAX_FDS) return 0;
  pthread_mutex_lock(&lock);
  int fail = 0;
  if (watched[fd] > 0) {
    const char* after = getenv("FB_FAULT_ENOSPC_AFTER");
    const long long allowed = after ? atoll(after) : 0;
    if (watched[fd] - 1 + (long long)n > allowed) {
      fail = 1;
    } else {
      watched[fd] += (long long)n;
    }
  }
  pthread_mutex_unlock(&lock);
  if (fail) errno = ENOSPC;
  return fail;
}

#define REAL(name)                           \
  static __typeof__(name)* real_##name = NULL; \
  if (real_##name == NULL) real_##name = (__typeof__(name)*)dlsym(RTLD_NEXT, #name)

static mode_t mode_arg(int flags, va_list ap) {
  return (flags & (O_CREAT | O_TMPFILE)) ? (mode_t)va_arg(ap, int) : 0;
}

int open(const char* path, int flags, ...) {
  REAL(open);
  va_list ap;
  va_start(ap, flags);
  const mode_t mode = mode_arg(flags, ap);
  va_end(ap);
  const int fd = real_open(path, flags, mode);
  track(fd, path, flags);
  return fd;
}
int open64(const char* path, int flags, ...) {
  REAL(open64);
  va_list ap;
  va_start(ap, flags);
  const mode_t mode = mode_arg(flags, ap);
  va_end(ap);
  const int fd = real_open64(path, flags, mode);
  track(fd, path, flags);
  return fd;
}
int openat(int dir, const char* path, int flags, ...) {
  REAL(openat);
  va_list ap;
  va_start(ap, flags);
  const mode_t mode = mode_arg(flags, ap);
  va_end(ap);
  const int fd = real_openat(dir, path, flags, mode);
  track(fd, path, flags);
  return fd;
}
int openat64(int dir, const char* path, int flags, ...) {
  REAL(openat64);
  va_list ap;
  va_start(ap, flags);
  const mode_t mode = mode_arg(flags, ap);
  va_end(ap);
  const int fd = real_openat64(dir, path, flags, mode);
  track(fd, path, flags);
  return fd;
}
int creat(const char* path, mode_t mode) {
  return open(path, O_CREAT | O_WRONLY | O_TRUNC, mode);
}
int close(int fd) {
  REAL(close);
  track(fd, NULL, 0);
  return real_close(fd);
}
ssize_t write(int fd, const void* buf, size_t n) {
  REAL(write);
  if (full(fd, n)) return -1;
  return real_write(fd, buf, n);
}
ssize_t pwrite(int fd, const void* buf, size_t n, off_t offset) {
  REAL(pwrite);
  if (full(fd, n)) return -1;
  return real_pwrite(fd, buf, n, offset);
}
ssize_t pwrite64(int fd, const void* buf, size_t n, off_t offset) {
  REAL(pwrite64);
  if (full(fd, n)) return -1;
  return real_pwrite64(fd, buf, n, offset);
}
ssize_t writev(int fd, const struct iovec* iov, int count) {
  REAL(writev);
  size_t n = 0;
  for (int i = 0; i < count; ++i) n += iov[i].iov_len;
  if (full(fd, n)) return -1;
  return real_writev(fd, iov, count);
}
int fallocate(int fd, int mode, off_t offset, off_t len) {
  REAL(fallocate);
  if (full(fd, (size_t)len)) return -1;
  return real_fallocate(fd, mode, offset, len);
}
int posix_fallocate(int fd, off_t offset, off_t len) {
  REAL(posix_fallocate);
  if (full(fd, (size_t)len)) return ENOSPC;
  return real_posix_fallocate(fd, offset, len);
}
