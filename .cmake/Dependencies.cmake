# Finds the product's dependencies and exposes them as imported targets.
# Debian ships OpenCV's per-module -dev packages without OpenCVConfig.cmake
# (that comes with the libopencv-dev meta package, which we do not install),
# so the OpenCV modules are located by header and library here.

find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(Ceres 2.1 REQUIRED)
find_package(FlatBuffers REQUIRED)
find_package(PkgConfig REQUIRED)
find_package(Threads REQUIRED)
pkg_check_modules(LIBCAMERA IMPORTED_TARGET libcamera)

find_path(OPENCV_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)

# scopetrack_find_opencv_module(NAME [REQUIRED]) -> target OpenCV::NAME
function(scopetrack_find_opencv_module name)
  find_library(OPENCV_${name}_LIBRARY NAMES opencv_${name})
  if(OPENCV_${name}_LIBRARY)
    add_library(OpenCV::${name} SHARED IMPORTED GLOBAL)
    set_target_properties(OpenCV::${name} PROPERTIES
      IMPORTED_LOCATION ${OPENCV_${name}_LIBRARY}
      INTERFACE_INCLUDE_DIRECTORIES ${OPENCV_INCLUDE_DIR})
  elseif("REQUIRED" IN_LIST ARGN)
    message(FATAL_ERROR "OpenCV module '${name}' not found: run tools/setup-deps.sh")
  endif()
endfunction()

# core: product dependencies.
scopetrack_find_opencv_module(core REQUIRED)
scopetrack_find_opencv_module(features2d REQUIRED)
# Host tools and tests only (baselines, comparisons): imgproc, calib3d.
scopetrack_find_opencv_module(imgproc REQUIRED)
scopetrack_find_opencv_module(calib3d)
scopetrack_find_opencv_module(imgcodecs)  # scopetrack-soak's plot

find_program(FLATC_EXECUTABLE flatc REQUIRED)
find_program(FFMPEG_EXECUTABLE ffmpeg)
