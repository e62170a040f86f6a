# Cross build for aarch64 with Debian's g++-aarch64-linux-gnu (-DGF_CORE_ONLY=ON,
# scripts/check_arm64.sh). Programs built with it run under qemu-aarch64 -L /usr/aarch64-linux-gnu.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
# Another cross compiler (scripts/check_gcc9.sh: aarch64-linux-gnu-g++-9) through the environment,
# which CMake's try_compile projects inherit too.
if(DEFINED ENV{GF_AARCH64_CC})
  set(CMAKE_C_COMPILER $ENV{GF_AARCH64_CC})
else()
  set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
endif()
if(DEFINED ENV{GF_AARCH64_CXX})
  set(CMAKE_CXX_COMPILER $ENV{GF_AARCH64_CXX})
else()
  set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
endif()
set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
# try_run() during configure (none today) would run under qemu.
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64 -L /usr/aarch64-linux-gnu)
