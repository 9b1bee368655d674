# Board: generic ARMv8-A scope processor (NEON is part of the base ISA).
set(SCOPETRACK_BOARD_FLAGS "")
# GCC notes that std::pair<double, double> arguments are passed as GCC 10.1
# changed it to (-Wpsabi): an ABI note for mixing old objects, not a warning
# about this code.
add_compile_options(-Wno-psabi)
