# Board: x86-64 host with AVX2 + FMA (Haswell and later).
set(SCOPETRACK_BOARD_FLAGS -mavx2 -mfma -mbmi2 -mpopcnt)
add_compile_options(${SCOPETRACK_BOARD_FLAGS})
