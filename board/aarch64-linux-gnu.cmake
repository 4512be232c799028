# CMake toolchain for Debian's crossbuild-essential-arm64 with arm64 multiarch libraries
# (dpkg --add-architecture arm64; apt-get install libfoo-dev:arm64). Used by
# scripts/cross-build; tests run under qemu-aarch64 through CMAKE_CROSSCOMPILING_EMULATOR.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

# Headers are shared (/usr/include), libraries come from the arm64 multiarch directory.
set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu /usr)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)

# pkg-config must look at the arm64 .pc files only.
set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/aarch64-linux-gnu/pkgconfig:/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")

find_program(FB_QEMU_AARCH64 NAMES qemu-aarch64-static qemu-aarch64)
if(FB_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${FB_QEMU_AARCH64} -L /usr/aarch64-linux-gnu)
endif()
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE arm64)
