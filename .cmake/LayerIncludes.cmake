# The layers' include rule, checked when CMake configures the build.
#
# Every folder of core/ (a pipeline stage) and of hal/ (a role) is a library
# that may use only the folders its CMake target links. The compiler cannot
# see that: every target has the source root on its include path. So each
# folder's sources are read here, and a quoted include of a project folder
# that the target does not link stops the configure step with the file, the
# line and the folders it may use.
#
#   scopetrack_check_layer_includes(DIR <folder> ALLOWED <prefix>...)
#     <folder>  the folder whose *.h and *.cpp are read (not its subfolders)
#     <prefix>  include prefixes it may use, e.g. core/base/ or platform/
#
# Run as a script (cmake -DDIR=... -DALLOWED=a/;b/ -P LayerIncludes.cmake)
# the same check runs on any folder: the tests use that to show that an
# upward include is refused.

# Project folders an include can name; includes of anything else (the
# standard library, Eigen, OpenCV, generated headers of other trees) are not
# the layers' business.
set(_scopetrack_layer_roots core/ hal/ platform/ firmware_app/ tools/ tests/)

# <out> is TRUE when <text> starts with one of the prefixes that follow.
function(_scopetrack_starts_with_any out text)
  set(_found FALSE)
  foreach(_prefix IN LISTS ARGN)
    string(FIND "${text}" "${_prefix}" _at)
    if(_at EQUAL 0)
      set(_found TRUE)
    endif()
  endforeach()
  set(${out} ${_found} PARENT_SCOPE)
endfunction()

function(scopetrack_check_layer_includes)
  cmake_parse_arguments(ARG "" "DIR" "ALLOWED" ${ARGN})
  file(GLOB _files ${ARG_DIR}/*.h ${ARG_DIR}/*.cpp)
  set(_errors "")
  foreach(_file IN LISTS _files)
    file(STRINGS ${_file} _lines REGEX "^[ \t]*#[ \t]*include[ \t]*\"")
    foreach(_line IN LISTS _lines)
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]*)\".*$" "\\1" _inc "${_line}")
      _scopetrack_starts_with_any(_project "${_inc}" ${_scopetrack_layer_roots})
      if(NOT _project)
        continue()
      endif()
      _scopetrack_starts_with_any(_ok "${_inc}" ${ARG_ALLOWED})
      if(NOT _ok)
        string(APPEND _errors "\n  ${_file}: includes \"${_inc}\"")
      endif()
    endforeach()
  endforeach()
  if(_errors)
    string(REPLACE ";" " " _allowed "${ARG_ALLOWED}")
    message(FATAL_ERROR "layer rule broken in ${ARG_DIR}: it may include only ${_allowed}${_errors}")
  endif()
endfunction()

if(CMAKE_SCRIPT_MODE_FILE AND DIR)
  scopetrack_check_layer_includes(DIR ${DIR} ALLOWED ${ALLOWED})
endif()
