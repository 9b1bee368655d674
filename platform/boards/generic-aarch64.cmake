# Board: generic ARMv8-A scope processor (NEON is part of the base ISA).
set(SCOPETRACK_BOARD_FLAGS "")
