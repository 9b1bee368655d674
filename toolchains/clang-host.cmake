# Host clang (used for the libFuzzer targets: -DSCOPETRACK_FUZZ=ON).
set(CMAKE_C_COMPILER clang-14)
set(CMAKE_CXX_COMPILER clang++-14)
