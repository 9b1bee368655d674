# Host toolchain: the system GCC. CPU flags live in platform/boards.
set(CMAKE_C_COMPILER gcc)
set(CMAKE_CXX_COMPILER g++)
