# scopetrack_warnings: the warning set every project target uses.
add_library(scopetrack_warnings INTERFACE)
target_compile_options(scopetrack_warnings INTERFACE
  -Wall -Wextra -Wshadow -Wdouble-promotion -Wnon-virtual-dtor -Wcast-align
  -Wformat=2 -Wimplicit-fallthrough)
if(SCOPETRACK_WERROR)
  target_compile_options(scopetrack_warnings INTERFACE -Werror)
endif()
