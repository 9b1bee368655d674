# Board: generic x86-64 host (simulation, CI). Portable baseline ISA.
set(SCOPETRACK_BOARD_FLAGS "")
