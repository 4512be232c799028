# CMake toolchain for Debian's crossbuild-essential-arm64 (aarch64-linux-gnu-gcc) against an arm64
# sysroot of Debian packages unpacked with dpkg -x (scripts/cross-build builds it in
# build-arm64-sysroot/root). Nothing :arm64 is installed into the host. Tests run under
# qemu-aarch64 through CMAKE_CROSSCOMPILING_EMULATOR.
#
#   cmake -S . -B build-arm64 -G Ninja -DCMAKE_TOOLCHAIN_FILE=board/aarch64-linux-gnu.cmake \
#         [-DFB_ARM64_SYSROOT=/path/to/sysroot]
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

if(NOT FB_ARM64_SYSROOT)
  if(DEFINED ENV{FB_ARM64_SYSROOT})
    set(FB_ARM64_SYSROOT "$ENV{FB_ARM64_SYSROOT}")
  else()
    get_filename_component(FB_ARM64_SYSROOT "${CMAKE_CURRENT_LIST_DIR}/../build-arm64-sysroot/root"
      ABSOLUTE)
  endif()
endif()
if(NOT EXISTS "${FB_ARM64_SYSROOT}/usr/include/stdio.h")
  message(FATAL_ERROR "no arm64 sysroot at '${FB_ARM64_SYSROOT}' (scripts/cross-build builds it)")
endif()
set(FB_ARM64_SYSROOT "${FB_ARM64_SYSROOT}" CACHE PATH "arm64 sysroot (dpkg -x of Debian packages)")
# try_compile projects re-read this file; hand the sysroot on to them.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES FB_ARM64_SYSROOT)

# --sysroot for compiler and linker; find_* look only inside it (programs on the host).
set(CMAKE_SYSROOT "${FB_ARM64_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH "${FB_ARM64_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# pkg-config: only the sysroot's arm64 .pc files, -I/-L re-rooted into the sysroot.
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${FB_ARM64_SYSROOT}")
set(ENV{PKG_CONFIG_LIBDIR}
  "${FB_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu/pkgconfig:${FB_ARM64_SYSROOT}/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")

# Test binaries (and gtest_discover_tests) run under user-mode qemu with the sysroot's loader and
# libraries.
find_program(FB_QEMU_AARCH64 NAMES qemu-aarch64-static qemu-aarch64)
if(FB_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${FB_QEMU_AARCH64} -L ${FB_ARM64_SYSROOT})
endif()
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE arm64)
# cpack's dpkg-shlibdeps finds the arm64 libraries here (and their symbols/shlibs in the
# sysroot's DEBIAN/ directory, see scripts/cross-build); run cpack with DEB_HOST_ARCH=arm64.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS_PRIVATE_DIRS
  "${FB_ARM64_SYSROOT}/lib/aarch64-linux-gnu;${FB_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu;${FB_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu/blas;${FB_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu/lapack")
